"""Measured cell data: import into the canonical form and the real-data experiments
(see docs/real-data.md)."""
