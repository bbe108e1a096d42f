"""Manoeuvre generators."""

import json
import math

import numpy as np
import pytest

from bayesid.models import dynamics
from bayesid.models import manoeuvres as mv
from bayesid.models.simulate import Simulator, simulate


def test_spiral_is_ten_minutes_within_limits(nps):
    m = mv.spiral(nps)
    assert m.duration == pytest.approx(600.0)
    assert np.all(m.inputs[:, 3] == nps.nominal_rpm)
    assert np.max(np.abs(m.inputs[:, 0])) == pytest.approx(nps.limits.rudder_max)
    assert np.all(np.diff(m.inputs[:, 0]) >= 0)  # rudder only ever steps up: a tightening spiral


def test_limits_are_enforced(nps):
    with pytest.raises(ValueError, match="delta_r.*exceeds"):
        mv.turning_circle(nps, 25.0)


@pytest.mark.parametrize("angle", [10.0, 20.0])
def test_zigzag_reverses_on_heading(nps, angle):
    m = mv.zigzag(nps, angle, duration=120.0)
    res = simulate(nps, m, mode="horizontal")
    psi = np.degrees(res.states[0][:, 5])
    rud = m.inputs[:, 0]
    k_exec = int(round(10.0 / m.dt))
    switches = np.flatnonzero(np.diff(np.sign(rud[k_exec:])) != 0) + k_exec + 1
    assert len(switches) >= 4
    for k in switches:
        # the rudder changed on the step after the heading crossed +-angle (within one step's turn)
        assert abs(abs(psi[k]) - angle) < 0.6
    assert np.max(np.abs(rud)) == pytest.approx(math.radians(angle))
    # positive first rudder turns to port: first trigger at -angle
    assert psi[switches[0]] < 0


# ---------------------------------------------------------------------------------------------
# Extended library: pull-out, reverse spiral, speed steps, multisine, PRBS, vertical zigzag.


DT = 0.1
LIBRARY_KEYS = [
    "spiral",
    "turn+20",
    "turn-20",
    "zigzag10_10",
    "zigzag20_20",
    "pull_out",
    "reverse_spiral",
    "speed_steps",
    "multisine",
    "prbs",
    "vertical_zigzag10_10",
]


@pytest.fixture(scope="module")
def lib(nps):
    return mv.library(nps)


def _run(nps, m, mode):
    res = Simulator(nps, m, mode=mode).run()
    assert res.status[0] == 0, f"{m.name} diverged in {mode} at step {res.fail_step[0]}"
    return res.states[0]


def _changes(col):
    """Indices k where input k differs from input k-1."""
    return np.flatnonzero(np.diff(col) != 0) + 1


@pytest.mark.parametrize(
    "angle, expected",
    [
        (10.0, [100, 150, 257, 370, 484, 599, 715, 832, 949, 1066, 1183]),
        (20.0, [100, 151, 265, 391, 522, 656, 792, 929, 1067]),
    ],
)
def test_zigzag_unchanged_by_kernel_generalisation(nps, angle, expected):
    # rudder-change steps of the heading zigzag before the kernel was generalised (same 120 s run)
    m = mv.zigzag(nps, angle)
    assert _changes(m.inputs[:, 0]).tolist() == expected
    # the old entry point is the generic kernel with (input 0, state 5)
    sim = Simulator(nps, m)
    tcoef, Minv = (a[0] for a in sim.kernel_arrays())
    n = m.n_steps
    outs = [np.empty((n + 1, 12)) for _ in range(2)]
    inps = [np.empty((n, 4)) for _ in range(2)]
    args = (
        math.radians(angle),
        math.radians(angle),
        1.0,
        -1.0,
        10.0,
        0.0,
        sim.vp,
        sim.tfac,
        sim.tdof,
        tcoef,
        Minv,
        sim.xs,
        sim.ws,
    )
    dynamics.simulate_zigzag(sim.s0, n, DT, 1500.0, *args, outs[0], inps[0])
    dynamics.simulate_triggered_zigzag(sim.s0, n, DT, 1500.0, 0, 5, *args, outs[1], inps[1])
    assert np.array_equal(inps[0], inps[1]) and np.array_equal(inps[0], m.inputs)


def test_library_set(nps, lib):
    assert list(lib) == LIBRARY_KEYS
    total = 0.0
    for key, m in lib.items():
        assert m.name == key and m.dt == DT and m.description
        json.dumps(m.parameters)
        nps.limits.check(m.inputs, where=key)
        assert 120.0 <= m.duration <= 600.0
        assert np.array_equal(m.initial_state, mv.steady_state(nps))
        total += m.duration
    assert total == pytest.approx(2740.0)
    # only the vertical zigzag moves the stern planes; nothing moves the bow planes
    assert [k for k, m in lib.items() if np.any(m.inputs[:, 1] != 0)] == ["vertical_zigzag10_10"]
    assert all(np.all(m.inputs[:, 2] == 0) for m in lib.values())


@pytest.mark.parametrize("mode", ["horizontal", "6dof"])
def test_pull_out_yaw_rate_decays(nps, lib, mode):
    m = lib["pull_out"]
    rud = np.degrees(m.inputs[:, 0])
    assert np.all(rud[:100] == 0) and np.allclose(rud[100:700], 20.0) and np.all(rud[700:] == 0)
    r = np.degrees(_run(nps, m, mode)[:, 11])
    r_rel = r[700]  # yaw rate at release: steady turn to port
    assert -4.8 < r_rel < -4.3
    assert abs(r[690] - r_rel) < 0.02  # near-steady over the last second of the hold
    assert abs(r[700 + 100]) < 0.15 * abs(r_rel)  # 10 s after release
    assert abs(r[700 + 400]) < 0.002 * abs(r_rel)  # 40 s after release
    assert abs(r[-1]) < 1e-3  # decays to zero: directionally stable
    assert mv.pull_out(nps, -20.0).name == "pull_outm20"


def test_reverse_spiral_holds_each_target(nps, lib):
    m = lib["reverse_spiral"]
    p = m.parameters
    targets = np.array(p["yaw_rates_deg_s"])
    assert m.duration == pytest.approx(10.0 + 30.0 * len(targets))
    assert np.all(m.inputs[:100, 0] == 0)
    # open-loop replay of the recorded rudder reproduces the closed loop (same RK4 step)
    r6 = np.degrees(_run(nps, m, "6dof")[:, 11])
    for i, target in enumerate(targets):
        a, b = 100 + 300 * i, 100 + 300 * (i + 1)
        settled = r6[a + 201 : b + 1]  # last 10 s of each 30 s hold
        assert np.mean(settled) == pytest.approx(p["steady_yaw_rate_deg_s"][i], abs=1e-9)
        assert abs(np.mean(settled) - target) < 0.05
        assert np.max(np.abs(r6[a + 61 : b + 1] - target)) < 0.1  # within 0.1 deg/s after 6 s
    assert not any(p["saturated"])
    # directionally stable: steady rudder decreases monotonically with yaw rate (N'dr < 0)
    assert np.all(np.diff(p["steady_rudder_deg"]) > 0) and np.all(np.diff(targets) < 0)
    # the same rudder history in the horizontal model: the same turns, slightly faster (no roll)
    rh = np.degrees(_run(nps, m, "horizontal")[:, 11])
    for i, target in enumerate(targets):
        assert abs(np.mean(rh[100 + 300 * i + 201 : 100 + 300 * (i + 1) + 1]) - target) < 0.15
    # a yaw rate beyond the steady full-rudder turn cannot be held once the speed has dropped:
    # the rudder saturates at the limit (over 30 s it is still held, from the approach speed)
    m5 = mv.reverse_spiral(nps, yaw_rates_deg_s=(5.0,), hold_s=90.0)
    assert m5.parameters["saturated"] == [True]
    assert np.max(np.abs(m5.inputs[:, 0])) == pytest.approx(nps.limits.rudder_max)
    assert m5.parameters["steady_yaw_rate_deg_s"][0] < 4.6


@pytest.mark.parametrize("mode", ["horizontal", "6dof"])
def test_speed_steps_change_u_in_the_step_direction(nps, lib, mode):
    m = lib["speed_steps"]
    p = m.parameters
    rpms = [1500.0] + p["rpm_steps"]
    edges = [100 + 800 * i for i in range(len(rpms))]  # 10 s straight, then 80 s per step
    for i, k in enumerate(edges):
        assert np.all(m.inputs[k - 1 if i else 0 : k, 3] == rpms[i])
    assert np.all(m.inputs[:, 0] == 0)
    u = _run(nps, m, mode)[:, 6]
    for i in range(1, len(rpms)):
        a, b = edges[i - 1], edges[i]
        du = np.diff(u[a + 1 : b + 1])
        if rpms[i] > rpms[i - 1]:
            assert u[b] > u[a] + 0.1 and np.all(du > -1e-9)
        else:
            assert u[b] < u[a] - 0.1 and np.all(du < 1e-9)
    # back at 1500 rpm, u approaches the steady speed from below
    assert nps.steady_speed(1500.0) - 0.1 < u[-1] < nps.steady_speed(1500.0)
    with pytest.raises(ValueError, match="n = .*exceeds"):
        mv.speed_steps(nps, rpm_steps=(1600.0,))
    mr = mv.speed_steps(nps, rpm_steps=(1500.0, 1000.0), hold_s=60.0, rudder_deg=10.0)
    assert np.all(mr.inputs[:100, 0] == 0) and np.allclose(mr.inputs[100:, 0], math.radians(10.0))


def test_multisine_scaled_to_peak_within_limit(nps, lib):
    m = lib["multisine"]
    p = m.parameters
    rud = m.inputs[:, 0]
    assert np.max(np.abs(rud)) == pytest.approx(math.radians(10.0), rel=1e-12)
    assert np.max(np.abs(rud)) <= nps.limits.rudder_max
    assert np.allclose(p["phases_rad"], mv.schroeder_phases(8)) and p["schroeder"]
    tau = np.arange(m.n_steps - 100) * DT
    rebuilt = math.radians(p["component_amplitude_deg"]) * sum(
        np.sin(2 * math.pi * f * tau + ph) for f, ph in zip(p["frequencies_hz"], p["phases_rad"])
    )
    assert np.allclose(rud[100:], rebuilt, atol=1e-12) and np.all(rud[:100] == 0)
    for mode in ("horizontal", "6dof"):
        _run(nps, m, mode)
    with pytest.raises(ValueError, match="delta_r.*exceeds"):
        mv.multisine(nps, amplitude_deg=25.0)
    with pytest.raises(ValueError, match="frequencies"):
        mv.multisine(nps, frequencies_hz=(0.1, 6.0))


def test_prbs_reproducible_binary_min_hold(nps, lib):
    m = lib["prbs"]
    assert np.array_equal(m.inputs, mv.prbs(nps, rng=np.random.default_rng(0)).inputs)
    other = mv.prbs(nps, rng=np.random.default_rng(1))
    assert not np.array_equal(m.inputs, other.inputs)
    amp = math.radians(10.0)
    for mm in (m, other):
        rud = mm.inputs[:, 0]
        assert np.all(rud[:100] == 0) and np.all(np.abs(np.abs(rud[100:]) - amp) < 1e-15)
        ch = _changes(rud)
        assert ch[0] == 100
        holds = np.diff(np.append(ch, mm.n_steps))[:-1]  # the last hold may be cut by the end
        assert np.all(holds >= 50) and np.all(holds % 50 == 0)
        assert [float(k * DT) for k in ch[1:]] == pytest.approx(mm.parameters["switch_times_s"])
    for mode in ("horizontal", "6dof"):
        _run(nps, m, mode)
    with pytest.raises(TypeError, match="Generator"):
        mv.prbs(nps, rng=0)


def test_vertical_zigzag_reverses_planes_on_pitch(nps, lib):
    m = lib["vertical_zigzag10_10"]
    ds = m.inputs[:, 1]
    assert np.all(m.inputs[:, 0] == 0) and np.max(np.abs(ds)) == pytest.approx(math.radians(10.0))
    th = np.degrees(_run(nps, m, "6dof")[:, 4])
    dth = th - th[100]
    ch = _changes(ds)
    assert ch[0] == 100 and ds[100] > 0
    assert len(ch) >= 5
    for k in ch[1:]:
        # planes reversed on the step after |theta change| reached 10 deg, in the planes' direction
        assert abs(dth[k]) >= 10.0 and abs(dth[k - 1]) < 10.0
        assert np.sign(dth[k]) == -np.sign(ds[k - 1])  # M'ds < 0: positive planes pitch nose down
    assert dth[ch[1]] < 0  # dives first
    assert np.max(np.abs(dth)) < 12.0  # overshoot past the trigger is small
    assert m.parameters["switch_times_s"] == pytest.approx([k * DT for k in ch])
    with pytest.raises(ValueError, match="horizontal mode ignores"):
        Simulator(nps, m, mode="horizontal")
