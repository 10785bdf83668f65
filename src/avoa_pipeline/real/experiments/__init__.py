"""Real-data experiments: records → tables with ``model/`` (drawn by ``report.real_figures``)."""
