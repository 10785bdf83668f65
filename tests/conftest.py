import os

import pytest

os.environ.setdefault("PYBAMM_DISABLE_TELEMETRY", "true")
# one BLAS thread: scipy's L-BFGS-B calls BLAS on tiny vectors, and spinning BLAS threads on a
# busy 2-core machine make it up to 30x slower (measured); set before numpy is imported
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")


@pytest.fixture(scope="session")
def cfg():
    from avoa_pipeline import config

    return config.load()
