import os

import pytest

os.environ.setdefault("PYBAMM_DISABLE_TELEMETRY", "true")


@pytest.fixture(scope="session")
def cfg():
    from avoa_pipeline import config

    return config.load()
