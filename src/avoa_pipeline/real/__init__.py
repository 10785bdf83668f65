"""Measured cells: :mod:`.experiments` (what ``model/`` makes of the records that
:mod:`avoa_pipeline.importers` wrote); see docs/real-data.md."""
