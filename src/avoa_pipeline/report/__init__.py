"""From aggregates to the paper's tables and the check of its claims.

- :mod:`.stats`: equal-budget readings of the histories, ranks, Friedman, Holm-Wilcoxon.
- :mod:`.tables`: Tables 1-24 as DataFrames and :func:`.tables.write_table` (CSV, Markdown,
  LaTeX, written atomically).
- :mod:`.claims`: :func:`.claims.claims`, the paper's claims decided under the paper's protocol
  and at equal evaluations.
- :mod:`.figures` (Figures 1-21), :mod:`.gap_figures`, :mod:`.real_figures`: the package's only
  drawing (each imported on its own; they need matplotlib).

The submodules are imported here, their functions are not re-exported (``report.claims`` is the
module, ``report.claims.claims`` the function). Every function takes DataFrames or dicts and
returns DataFrames or writes files; none reads global state.
"""

from . import claims, stats, tables

__all__ = ["claims", "stats", "tables"]
