import pytest

from bayesid.data.vehicle import load_vehicle


@pytest.fixture(scope="session")
def nps():
    """NPS AUV II as packaged (polynomial cross-flow terms)."""
    return load_vehicle("nps_auv2")
