"""The real-data experiments: canonical records → numbers and tables with ``model/``; their
figures are drawn in ``report/real_figures.py`` (docs/real-data.md)."""
