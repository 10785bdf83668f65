"""Measured cell data: :mod:`.importers` (raw files → canonical records) and :mod:`.experiments`
(what ``model/`` makes of them); see docs/real-data.md."""
