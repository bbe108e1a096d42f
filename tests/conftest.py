import importlib.util
import math
import os
from pathlib import Path

import numpy as np
import pytest

# Under pytest-xdist (``-n``) each worker is a process of its own: give each one numba thread, so
# that two workers on two cores do not share them four ways (set before numba is first imported).
if os.environ.get("PYTEST_XDIST_WORKER"):
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")

from bayesid.data.track import Track  # noqa: E402
from bayesid.data.vehicle import load_vehicle  # noqa: E402

#: The test files that take longest, longest first: seconds of their tests in a cold run from a
#: clean clone on 2 cores (``--durations=40``; test_ship 222 with ../shared/data/real, whose
#: study smoke test it runs, and about 40 without; test_discovery_nps 216 before it was split in
#: two, test_discovery 120, test_gap 103, test_gap_userdata 82, test_study_posterior 79, ...).
#: With ``--dist loadfile`` a worker takes one file at a time in collection order
#: (``--no-loadscope-reorder`` in pyproject.toml keeps that order): handing the long files out
#: first keeps a worker from starting a long file while the other has nothing left to do. The
#: list only orders the files; a stale entry costs balance, never a test.
LONGEST_FIRST = (
    "test_ship.py",
    "test_discovery_nps_starts.py",
    "test_discovery.py",
    "test_gap.py",
    "test_gap_userdata.py",
    "test_study_posterior.py",
    "test_discovery_nps.py",
    "test_codegen.py",
    "test_third_order_terms.py",
    "test_calibration.py",
    "test_term_products.py",
    "test_mimicked_report.py",
    "test_cli_inputs.py",
    "test_reference.py",
    "test_sample_budget.py",
    "test_compare_terms.py",
    "test_surge_discovery.py",
    "test_imo.py",
)


def pytest_collection_modifyitems(session, config, items):
    """Run the files of :data:`LONGEST_FIRST` first, in its order; the others after them, in
    the order pytest collected them (a stable sort: the tests within a file keep theirs)."""
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))


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


def n0_against_nabsdr(kv=None):
    """Two KVLCC2 structures (a constant yaw moment ``N0``, one in |rudder| ``Nabsdr``), the first
    the truth, and a zigzag-like training run: ``(stages, setup)`` for the design's tests.

    Parameters
    ----------
    kv : Ship, optional
        The hull (default: the packaged ``kvlcc2_7m``).
    """
    from types import SimpleNamespace

    from bayesid.analysis.gap.candidates import Setup, Stage
    from bayesid.models import ship

    kv = ship.load_ship("kvlcc2_7m") if kv is None else kv
    stages = {}
    for name, value in (("N0", 0.0008), ("Nabsdr", 0.0016)):
        m = ship.ShipModel(kv.with_coefficients({name: value}), free=[name], dt=0.2)
        stages[name] = Stage(m, SimpleNamespace(p=m.start()), {}, {}, None, np.zeros(0))
    train = [kvlcc2_square_wave_track()]
    setup = Setup(kv, ["N0"], train, train, 0.2, "horizontal", 15.0, 60.0, "measured", None)
    return stages, setup


def yaw_moment_effect():
    """A constant body-frame yaw moment (parameter ``N_Nm``, N m) outside the term table, so a world
    with it does not share the model's ``Nconst`` code (tests/test_discovery_nps*.py)."""
    from bayesid.models import effects as ef

    class YawMoment(ef.Effect):
        def exo(self, ctx, inputs, q, nu):
            coef = np.zeros((q.shape[0], 1, 6))
            coef[:, 0, 5] = q[:, 0]
            return np.ones((q.shape[0], ctx.n_steps, 1)), coef

    return YawMoment("yaw_moment", ("N_Nm",), (-1e4,), (1e4,), (0.0,), (10.0,), exo_columns=1)


def load_study(name: str):
    """The module of ``studies/<name>.py``, loaded from its file (the studies are scripts, not a
    package the tests import)."""
    spec = importlib.util.spec_from_file_location(name, Path(__file__).resolve().parents[1] / "studies" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
