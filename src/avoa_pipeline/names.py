"""Names that must be known without importing numerical code (the CLI parses with them)."""

ALGORITHMS = ("nelder_mead", "quasi_newton", "ga", "gwo", "run", "avoa", "gto")
"""The paper's seven algorithms, in the column order of its Tables 4-24."""
