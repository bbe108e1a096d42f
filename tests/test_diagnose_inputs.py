"""The gap diagnosis reads the logged inputs the way the user asks (``DiagnoseOptions.inputs``,
``bayesid diagnose --inputs``; ``discover`` and ``design`` take the fit's): every model it builds,
the base, the candidates and discovery's refits, reconstructs the rudder between samples alike.

Before, ``bayesid diagnose`` warned on a coarse log to "fit with --inputs rate" but had no such
option, and held the rudder between samples: on the HSVA zigzags logged at 2 Hz that half-interval
lag stood in for the rudder delay the model lacks (base held-out RMS 1.82 m held, 2.40 m at the
gear's rate, 2.69 m from the 20 Hz logs with any reading; measured with the CLI)."""

import json
import math

import numpy as np
import pytest

from bayesid.analysis import gap
from bayesid.analysis.gap.discovery.library import augmented_model
from bayesid.cli import main
from bayesid.data.track import Track, write_csv
from bayesid.models import ship
from bayesid.models.ship.trials import TrialOptions, propulsion_point, simulate_trial

FREE = ["Yv", "Nr", "gR"]  # few free coefficients: the reading of the rudder, not the fit, is the point


def _runs(log_s: float = 1.0):
    """KVLCC2 zigzags flown by the packaged model (no delay, the rudder at its gear's 15.8 deg/s),
    logged every ``log_s`` s (x, y, psi, u, v, r and the rudder sampled). Measured at 1 s: base
    held-out RMS 0.325 m held, 0.128 m linear, 0.056 m at the gear's rate (noise floor 0.074 m)."""
    kv = ship.load_ship("kvlcc2_7m")
    speed, rpm = propulsion_point(kv, 1.179)
    rng = np.random.default_rng(3)
    out = []
    for angle, check in ((20, 20), (-15, 10), (10, 10), (-20, 5)):
        tr = simulate_trial(
            kv,
            "zigzag",
            angle,
            check_deg=check,
            speed=speed,
            rpm=rpm,
            options=TrialOptions(duration=120.0, rudder_rate_deg_s=15.8),
        ).track
        t = np.arange(0.0, float(tr.t[-1]) + 1e-9, log_s)
        data = {
            k: np.interp(t, tr.t, np.asarray(tr[k], float)) for k in ("x", "y", "psi", "u", "v", "r", "delta_r", "n")
        }
        for k, sd in (("x", 0.01), ("y", 0.01), ("psi", math.radians(0.05))):
            data[k] = data[k] + rng.normal(0.0, sd, t.size)
        out.append(Track(t, data, name=f"z{angle}_{check}"))
    return kv, out[:2], out[2:]


@pytest.fixture(scope="module")
def runs():
    return _runs()


def _diagnose(runs, inputs):
    kv, train, held = runs
    options = gap.DiagnoseOptions(candidates=("delay",), window_s=60.0, max_nfev=8, max_effects=1, inputs=inputs)
    return gap.diagnose(kv, FREE, train, held, options, rng=np.random.default_rng(0))


def test_every_model_of_the_diagnosis_reads_the_rudder_at_the_gears_rate(runs):
    rate = _diagnose(runs, "rate")
    hold = _diagnose(runs, "hold")
    assert rate.base.model.inputs == "rate" and rate.base.model.rudder_rate_deg_s == 15.8
    assert rate.after.model.inputs == "rate" and hold.base.model.inputs == "hold"
    # discovery's models with every candidate term (and its refits: from the same setup)
    m, ctxs = augmented_model(rate.setup, (), {"N0": 0.0}, 60.0)
    assert m.inputs == "rate" and m.rudder_rate_deg_s == 15.8 and ctxs[0].input_reconstruction == "rate"
    assert rate.settings["inputs"] == "rate" and "inputs" not in hold.settings  # hold: the JSON as before
    # the truth has no delay: read at the gear's rate the base model (the truth) predicts the held-out
    # zigzags better than with the rudder held a half interval late between 1 s samples
    assert rate.gap_before["heldout_rms_m"] < 0.5 * hold.gap_before["heldout_rms_m"], (
        rate.gap_before["heldout_rms_m"],
        hold.gap_before["heldout_rms_m"],
    )


def test_bad_readings_are_refused_by_name():
    with pytest.raises(ValueError, match="inputs must be one of hold, linear, rate, not 'cubic'"):
        gap.DiagnoseOptions(inputs="cubic")
    with pytest.raises(ValueError, match="rudder_rate_deg_s must be a positive number"):
        gap.DiagnoseOptions(inputs="rate", rudder_rate_deg_s=-3.0)
    # a gear rate the reading would not use: refused, not recorded and ignored
    with pytest.raises(ValueError, match="--rudder-rate is the gear's rate of --inputs rate: with --inputs hold"):
        gap.DiagnoseOptions(rudder_rate_deg_s=10.0)
    from bayesid.estimation.options import FitOptions

    with pytest.raises(ValueError, match="with --inputs linear it would not be used"):
        FitOptions(inputs="linear", rudder_rate_deg_s=10.0)


def test_the_commands_take_the_reading_and_record_it(runs, tmp_path, capsys):
    kv, train, held = runs
    paths = {}
    for tr in train + held:
        paths[tr.name] = tmp_path / f"{tr.name}.csv"
        write_csv(tr, paths[tr.name])
    tr_, ho = [str(paths[t.name]) for t in train], [str(paths[t.name]) for t in held]
    common = ["--max-nfev", "5", "--no-discover", "--candidates", "delay", "--max-effects", "1"]
    assert main(["-q", "diagnose", "--vehicle", "kvlcc2_7m", "--free", ",".join(FREE), "--train", *tr_, "--heldout", *ho, "--inputs", "rate", *common, "--out", str(tmp_path / "d")]) == 0  # fmt: skip
    d = json.loads((tmp_path / "d" / "diagnosis.json").read_text())
    assert d["settings"]["inputs"] == "rate"
    # discover refits the fit's model: it reads the rudder as that fit did
    assert main(["-q", "fit", "--vehicle", "kvlcc2_7m", "--free", ",".join(FREE), "--train", *tr_, "--inputs", "linear", "--max-nfev", "5", "--out", str(tmp_path / "f")]) == 0  # fmt: skip
    assert main(["-q", "discover", "--model", str(tmp_path / "f" / "model.json"), "--train", *tr_, "--heldout", *ho, "--max-nfev", "5", "--out", str(tmp_path / "disc")]) == 0  # fmt: skip
    d = json.loads((tmp_path / "disc" / "diagnosis.json").read_text())
    assert d["settings"]["inputs"] == "linear"
    capsys.readouterr()
    # the rate reading for a vessel whose file gives no gear rate, and none given: refused by name
    code = main(["-q", "diagnose", "--vehicle", "nps_auv2", "--train", *tr_, "--heldout", *ho, "--inputs", "rate", "--out", str(tmp_path / "e")])  # fmt: skip
    assert code == 2 and "inputs 'rate' needs the steering gear's rate" in capsys.readouterr().err
