"""avoa-pipeline: reproducible Li-ion battery model identification (Fahmy et al. 2023)."""

__version__ = "0.1.0"
