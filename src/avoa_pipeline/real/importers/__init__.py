"""Importers: measured cells' raw files → checked canonical records; none imports ``model/``."""
