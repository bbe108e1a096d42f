import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

from bayesid.data.track import Track
from bayesid.data.vehicle import load_vehicle


@pytest.fixture(scope="session")
def nps():
    """NPS AUV II as packaged (polynomial cross-flow terms)."""
    return load_vehicle("nps_auv2")


def kvlcc2_square_wave_track() -> Track:
    """A 120 s KVLCC2 7 m track at the approach speed (1.179 m/s, 613.8 rpm) with a +-20 deg
    square-wave rudder and no motion logged beyond a straight course: the design's tests simulate
    their own runs from its approach condition and inputs."""
    t = np.arange(0.0, 120.0, 0.5)
    z = 0 * t
    return Track(
        t,
        {
            "x": 1.179 * t,
            "y": z,
            "psi": z,
            "u": z + 1.179,
            "delta_r": math.radians(20) * np.sign(np.sin(t / 7)),
            "n": z + 613.8,
        },
    )


def load_study(name: str):
    """The module of ``studies/<name>.py``, loaded from its file (the studies are scripts, not a
    package the tests import)."""
    spec = importlib.util.spec_from_file_location(name, Path(__file__).resolve().parents[1] / "studies" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
