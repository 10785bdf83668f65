"""``python -m avoa_pipeline.real``: ``python -m avoa_pipeline real`` under the name the docs use
(``commands/real/``)."""

import sys
from functools import partial

# importing the CLI first sets one BLAS thread before numpy loads (cli.py says why)
from ..cli import build_parser as _build_parser
from ..cli import main as _main

PROG = "python -m avoa_pipeline.real"
build_parser = partial(_build_parser, "real", PROG)
main = partial(_main, group="real", prog=PROG)

if __name__ == "__main__":
    sys.exit(main())
