"""Names that must be known without importing numerical code (the CLI parses with them)."""

ALGORITHMS = ("nelder_mead", "quasi_newton", "ga", "gwo", "run", "avoa", "gto")
"""The paper's seven algorithms, in the column order of its Tables 4-24."""

CURRENT_SIGNS = ("discharge-positive", "charge-positive")
"""The two cycler conventions for the current's sign; the pipeline's own is the first."""

CYCLERS = ("arbin", "maccor", "neware", "biologic", "basytec")
"""The cyclers whose raw exports ``importers/cycler.py`` reads (``convert``, ``--cycler``)."""

CURRENT_FROM = ("counters", "channel")
"""Where a converted export's interval currents come from: its charge counters or its channel."""
