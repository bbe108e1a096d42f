"""The designed run's length for the run-by-run separation test: the sample-size formula, checked
against the test itself by simulation, and the sizing of the best designed runs."""

import math
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import kvlcc2_square_wave_track

from bayesid.analysis.gap import design as dz
from bayesid.analysis.gap.candidates import Setup, Stage
from bayesid.analysis.gap.verdict import run_separation_test
from bayesid.data.track import Track
from bayesid.models import ship


def test_run_test_windows_is_the_one_sided_sample_size():
    from scipy import stats

    m, s, runs = math.log(2.0), 0.5, 4
    z = stats.norm.ppf(1 - 0.01 / runs) + stats.norm.ppf(0.8)
    assert dz.run_test_windows(m, s, runs) == pytest.approx((z * s / (m - math.log(1.1))) ** 2)
    assert dz.run_test_windows(math.log1p(0.1), s, runs) == math.inf  # no more than the margin: never
    assert dz.run_test_windows(math.log(50.0), 0.01, 1) == 2.0  # the test needs two windows
    more = [dz.run_test_windows(math.log(2.0), s, r) for r in (1, 4, 16)]
    assert more == sorted(more)  # a larger Bonferroni factor needs more windows
    with pytest.raises(ValueError, match="log_sd"):
        dz.run_test_windows(m, 0.0, runs)
    with pytest.raises(ValueError, match="power"):
        dz.run_test_windows(m, s, runs, power=1.0)


@pytest.mark.parametrize("ratio, sd", [(2.0, 0.5), (1.5, 0.3)])
def test_the_sized_run_gives_the_run_test_its_power(ratio, sd):
    # three held-out runs on which two models tie, a designed run on which the second is `ratio`
    # times worse, with the window scatter `sd`: at the windows run_test_windows asks for, the
    # run-by-run test finds it about 80 % of the time; at a third of them far less often
    rng = np.random.default_rng(7)
    n = math.ceil(dz.run_test_windows(math.log(ratio), sd, 4))
    found = {}
    for windows in (n, max(2, n // 3)):
        hits = 0
        for _ in range(400):
            sizes = [6, 6, 6, windows]
            d = np.concatenate([rng.normal(0.0, sd, 6) for _ in range(3)] + [rng.normal(math.log(ratio), sd, windows)])
            runs = np.repeat(np.arange(4), sizes)
            hits += run_separation_test(np.ones(d.size), np.exp(d), runs).p_second_worse < 0.01
        found[windows] = hits / 400
    assert 0.7 <= found[n] <= 0.95, (n, found)
    assert found[max(2, n // 3)] < found[n] - 0.2, found


def test_the_expected_window_log_ratio_averages_over_windows():
    a = np.zeros((4, 3))
    b = np.zeros((4, 3))
    b[2:, 0] = 3.0  # the second window 3 m apart in x
    got = dz.expected_window_log_ratio(a, b, np.array([0, 0, 1, 1]), pos_var=1.0)
    assert got == pytest.approx(0.5 * (0.0 + 0.5 * math.log(10.0)))
    assert math.isnan(dz.expected_window_log_ratio(a, b * np.nan, np.array([0, 0, 1, 1]), 1.0))


def _stub(windows, W):
    model = SimpleNamespace(context=lambda track, *a, **k: SimpleNamespace(W=W[track.name]))
    return Stage(model, None, {}, {}, None, np.asarray(windows, float))


def test_the_window_scatter_is_pooled_within_runs():
    t = np.arange(0.0, 10.0)
    held = [Track(t, {"x": t}, name="a"), Track(t, {"x": t}, name="b")]
    setup = Setup(None, [], held, held, 0.1, "horizontal", 10.0, 10.0, "measured", None)
    W = {"a": 3, "b": 2}
    e0 = [1.0, 1.0, 1.0, 1.0, 1.0]
    e1 = np.exp([0.1, 0.3, 0.5, 2.0, 2.2])  # run b is worse throughout: its mean is not scatter
    got = dz.window_log_sd({"k": _stub(e0, W), "alt": _stub(e1, W)}, setup)
    ss = (0.1 - 0.3) ** 2 + 0 + (0.5 - 0.3) ** 2 + 2 * 0.1**2
    assert got == pytest.approx(math.sqrt(ss / 3))
    assert dz.window_log_sd({"k": _stub(e0, W), "alt": _stub(e1[:4], W)}, setup) is None  # windows do not match


def test_the_best_designed_runs_are_lengthened_for_the_run_test():
    # two KVLCC2 structures (a constant yaw moment and one in |rudder|) whose held-out windows
    # scatter: the best runs get the windows the run test needs, at most max_windows
    kv = ship.load_ship("kvlcc2_7m")
    train = [kvlcc2_square_wave_track()]
    stages = {}
    for name, value, windows in (("N0", 0.0008, [0.1, 1.0] * 2), ("Nabsdr", 0.0016, [1.0, 0.1] * 2)):
        m = ship.ShipModel(kv.with_coefficients({name: value}), free=[name], dt=0.2)
        stages[name] = Stage(m, SimpleNamespace(p=m.start()), {}, {}, None, np.asarray(windows))
    setup = Setup(kv, ["N0"], train, train, 0.2, "horizontal", 15.0, 30.0, "measured", None)
    options = dz.DiscriminationOptions(n_draws=0, max_windows=6, sized_rows=2)
    rows = dz.design(stages, setup, options)
    assert rows == sorted(rows, key=lambda r: (-len(r["decidable_pairs"]), -r["separation"]))
    sd = rows[0]["run_test"]["log_sd"]
    assert sd == pytest.approx(math.log(10.0) * math.sqrt(4 / 3))  # four windows' log ratios +-2.3 about 0
    sized = [r for r in rows if r["run_test"]["sized_from_s"] is not None]
    assert sized, [r["run_test"] for r in rows[:3]]
    for r in sized:
        assert r["duration_s"] > r["run_test"]["sized_from_s"]
        assert r["duration_s"] <= options.max_windows * setup.window_s + 1e-9
        assert r["run_test"]["windows"] == round(r["duration_s"] / setup.window_s)
        assert r["inputs"]["t"][-1] == pytest.approx(r["duration_s"] - 0.1)
    # a given duration is the user's: nothing is sized
    fixed = dz.design(stages, setup, dz.DiscriminationOptions(n_draws=0, duration_s=120.0))
    assert all(r["run_test"]["sized_from_s"] is None and r["duration_s"] == 120.0 for r in fixed)
    pair = fixed[0]["run_test"]["pairs"]["N0 vs Nabsdr"]
    assert pair["expected_ratio"] >= 1.0 and (pair["windows_needed"] is None or pair["windows_needed"] >= 2.0)
