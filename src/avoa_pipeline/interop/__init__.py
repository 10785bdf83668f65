"""A fitted model taken to other simulators (``python -m avoa_pipeline export``).

``pybamm``: PyBaMM's Thevenin equivalent-circuit model (docs/pybamm.md).
"""
