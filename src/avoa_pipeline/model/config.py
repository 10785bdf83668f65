"""A model configuration (:class:`Config`): the OCV source, the elements added to the base, the
paper's load. ``ecm`` re-exports it."""

from __future__ import annotations

from dataclasses import dataclass

from . import elements
from .layout import element_params
from .ocv_source import OcvTable


@dataclass(frozen=True)
class Config:
    """A model configuration: the OCV source, the elements added to the base, the load."""

    effects: tuple[str, ...] = ()
    table: OcvTable | None = None  # None: the paper's rational OCV with free Vnom, β
    load_ohm: float | None = None  # the paper's load resistor across the cell

    def __post_init__(self):
        for e in self.effects:
            el = elements.get(e)
            if el.requires and el.requires not in self.effects:
                raise ValueError(f"element {e!r} needs {el.requires!r}")
            why = el.conflict(self.table is not None, self.load_ohm is not None)
            if why:
                raise ValueError(f"element {e!r}: {why}")

    @property
    def ocv_kind(self) -> str:
        return "rational" if self.table is None else "table"

    def names(self) -> tuple[str, ...]:
        """Internal names of this configuration's parameters (base first, then elements)."""
        out = list(element_params("base", self.ocv_kind))
        for e in self.effects:
            out.extend(element_params(e))
        return tuple(out)

    def with_effect(self, effect: str) -> Config:
        return Config((*self.effects, effect), self.table, self.load_ohm)

    @property
    def name(self) -> str:
        base = "table" if self.table is not None else "rational"
        return "+".join((base, *self.effects))
