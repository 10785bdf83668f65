"""Importers: measured cells' raw files → checked canonical records. They sit just above
``records`` and below ``model/`` and ``inputs`` (docs/architecture.md, the layers)."""
