"""avoa-pipeline: reproducible Li-ion battery model identification (Fahmy et al. 2023).

The Python API (docs/api.md)::

    from avoa_pipeline import diagnose, load_model, read_record

Its names are imported on first use (a module ``__getattr__``, PEP 562), so that
``python -m avoa_pipeline`` and the workflow's jobs start no slower for it.
"""

__version__ = "0.1.0"

_API = {
    "diagnose": ("diagnosis", "diagnose"),
    "Diagnosis": ("diagnosis", "Diagnosis"),
    "load_model": ("api", "load_model"),
    "read_record": ("api", "read_record"),
    "Model": ("api", "Model"),
}
__all__ = ["__version__", *_API]


def __getattr__(name: str):
    if name not in _API:  # a submodule's name then falls through to the import system
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    from importlib import import_module

    module, attr = _API[name]
    value = getattr(import_module(f".{module}", __name__), attr)
    globals()[name] = value  # once
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_API})
