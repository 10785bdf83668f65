"""The model library's elements, one module each, in one registry (:data:`REGISTRY`).

An element is what a model may add to its base (the OCV, R0, one RC branch, the capacity and the
initial SOC): each module defines ``ELEMENT`` (:class:`.element.Element`, which lists every part
an element declares), its physics stated once in its ``kernel`` (:class:`.element.Kernel`: its
columns, flags, and code for the compiled simulator's slots). Adding one: its module here, its
line in the tuple below (the order is the ladder's order of trying them, ``selection.ladder``),
``python -m avoa_pipeline.model.loopgen --write`` (the compiled simulator, ``model/_simulator.py``,
is written from the base's statement and every element's; its columns follow the registry), and
its row in docs/gap-diagnosis.md. ``tests/unit/test_elements.py`` fails while a part is missing,
``tests/unit/test_loopgen.py`` while the simulator is not rewritten.
"""

from __future__ import annotations

import sys

from . import (
    butler_volmer,
    bv_arrhenius,
    capacity_temperature,
    coulombic_efficiency,
    current_offset,
    diffusion,
    entropic,
    hysteresis,
    ocv_shape,
    r0_charge,
    r0_soc,
    r1_soc,
    second_rc,
    soc_resistance,
    thermal,
    thermal_tau,
    third_rc,
    voltage_offset,
)
from .element import Element, missing_parts

REGISTRY: dict[str, Element] = {
    m.ELEMENT.name: m.ELEMENT
    for m in (
        second_rc,
        third_rc,
        soc_resistance,
        diffusion,
        hysteresis,
        butler_volmer,
        thermal,
        ocv_shape,
        current_offset,
        voltage_offset,
        coulombic_efficiency,
        r0_soc,
        r1_soc,
        r0_charge,
        bv_arrhenius,
        thermal_tau,
        entropic,
        capacity_temperature,
    )
}
NAMES = tuple(REGISTRY)
"""Elements a model may add to its base, by their one name (config, CLI, JSON, file names)."""


def register(element: Element) -> None:
    """Adds ``element`` to the registry, after the package's own (the ladder tries it last): a
    plug-in's element, or a test's toy. Before the model library is imported: ``model.ecm`` lays
    out its columns and compiles its simulator for the registry it finds (``model/loopgen.py``)."""
    global NAMES
    if "avoa_pipeline.model.ecm" in sys.modules:
        raise RuntimeError(f"element {element.name!r}: register it before "
                           "avoa_pipeline.model.ecm is imported (its columns and compiled "
                           "simulator follow the registry)")  # fmt: skip
    if element.name in REGISTRY:
        raise ValueError(f"element {element.name!r} is registered already")
    missing = missing_parts(element)
    if missing:
        raise ValueError(f"element {element.name!r}: {'; '.join(missing)}")
    REGISTRY[element.name] = element
    NAMES = tuple(REGISTRY)


def get(name: str) -> Element:
    if name not in REGISTRY:
        raise ValueError(f"unknown element {name!r}; choose from {', '.join(NAMES)}")
    return REGISTRY[name]
