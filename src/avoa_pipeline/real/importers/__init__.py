"""Importers of measured cells: raw files → checked canonical records (``records.write``);
none imports ``model/`` (docs/real-data.md)."""
