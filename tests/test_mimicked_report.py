"""Reports that explain (issue 50): a candidate set aside as mimicked is named with its mimic, the
free parameter whose column is closest to its own, and how to test it (a constant yaw moment
``N0`` hidden in synthetic runs and absorbed by the neutral rudder angle ``dR0``)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from diagnosis_view import diagnosis_view, discovery_view

from bayesid.analysis.gap import discovery as dv
from bayesid.analysis.gap.discovery.selection import LinearisedProblem, Selection
from bayesid.report.diagnosis import _discovery_lines


def _report(residuals: dict, free=("Nv", "Nr", "Nvvr", "dR0")) -> str:
    """The discovery section's text for a hand-built ``discovery`` entry of ``diagnosis.json``."""
    D = {
        "verdict": "no term of the library explains it",
        "heldout_rms_before_m": 0.5,
        "heldout_rms_after_m": 0.5,
        "library_size": 119,
        "settings": {"max_order": 3, "dofs": ["Y", "N"], "free": list(free), "min_probability": 0.5},
        "residuals": {"forces": {}, "explained": 0.1, "projected_rms": 0.4, **residuals},
        "discovered": [],
    }
    return "\n".join(_discovery_lines(diagnosis_view(discovery=discovery_view(**D))))


def _by(parameter, cosine, shift_effect, span=0.999):
    return {"parameter": parameter, "cosine": cosine, "shift": 0.07, "shift_effect": shift_effect, "span_cosine": span}


def test_the_report_names_a_mimicked_term_with_its_mimic_and_how_to_test_it():
    # 45 mimicked; N0 first by the stand-in order although higher-order terms are more collinear
    # with theirs; only the five first are named
    others = [f"Nterm{i}" for i in range(44)]
    by = {"N0": _by("dR0", 0.9912, 4.5)}
    by.update({t: _by("Nvvr", 0.9998 - 1e-4 * i, 1.2) for i, t in enumerate(others)})
    text = _report({"mimicked": [*others, "N0"], "mimicked_by": by})
    assert "45 set aside because a refit of the free coefficients reproduces them (*mimicked*)" in text
    assert "N0 is mimicked by dR0 (column cosine 0.991; the fit moved dR0 from its start by 0.07, 4.5 times" in text
    assert "refit with dR0 held (`--free` without dR0) to test it." in text
    # next come four of Nvvr's (cosine truncated: 0.9998 reads 0.999, never 1), then the rest by count
    assert "Nterm0, Nterm1, Nterm2 and Nterm3 are mimicked by Nvvr (column cosine 0.999, 0.999, 0.999, 0.999;" in text
    assert "to test them" in text and "Nterm4" not in text
    assert "The other 40 with theirs: `discovery.residuals.mimicked_by` in diagnosis.json." in text
    assert text.index("N0 is mimicked") < text.index("Nterm0")


def test_a_mimic_that_is_not_a_free_coefficient_or_mimics_only_in_part_gets_no_hold_advice():
    by = {
        "Nvv": _by("track0.waves.nuisance0", 0.97, 2.0),
        "Nrrr": {"parameter": "Nr", "cosine": 0.62, "span_cosine": 0.998},  # a combination mimics it
    }
    text = _report({"mimicked": ["Nrrr", "Nvv"], "mimicked_by": by})
    assert "Nvv is mimicked by track0.waves.nuisance0 (column cosine 0.970; the fit moved" in text
    assert "Nrrr is mimicked by Nr (column cosine 0.620; with all the free parameters together 0.998)." in text
    assert "to test it" not in text and "`--free` without" not in text


def test_an_older_diagnosis_without_mimics_keeps_its_sentence():
    text = _report({"mimicked": ["N0", "Nvvv"]})
    assert "2 set aside because a refit of the free coefficients reproduces them. 0.4 of the training" in text


def test_select_terms_attributes_a_constant_column_to_the_free_coefficient_it_is_collinear_with():
    # free columns: Nr (a wave), dR0 (nearly constant: a rudder offset's yaw moment), Yv (noise);
    # candidates: N0 (constant, within the free span but for 1 %), Nvvv (nearly Nr) and Nx (free)
    rng = np.random.default_rng(3)
    n = 4000
    t = np.linspace(0.0, 200.0, n)
    S = np.column_stack([np.sin(0.3 * t), 1.0 + 0.1 * np.sin(0.05 * t), rng.normal(size=n)])
    C = np.column_stack(
        [np.ones(n) + 0.01 * rng.normal(size=n), np.sin(0.3 * t) + 0.05 * np.cos(0.3 * t), rng.normal(size=n)]
    )
    names = ["N0", "Nvvv", "Nx"]
    r = 0.5 * C[:, 2] + 0.1 * rng.normal(size=n)
    # the fit moved dR0 far and Nr a little: dR0 is the likelier stand-in, though N0's column is the
    # less collinear with its mimic's
    shift = np.array([0.001, 0.05, 0.0])
    rms = float(np.sqrt(np.mean(r**2)))
    y, X = dv._project(S, -r, C)
    problem = LinearisedProblem(
        y,
        X,
        np.sqrt(np.mean(C**2, axis=0)),
        np.array_split(np.arange(n), 40),
        rms,
        dv._mimics(S, ["Nr", "dR0", "Yv"], C, names, shift, rms),
    )
    sel = dv.select_terms(problem, names, dv.DiscoveryOptions(n_models=20), np.random.default_rng(1))
    assert sel.mimicked == ["N0", "Nvvv"]
    assert list(sel.mimicked_by) == ["N0", "Nvvv"]
    m = sel.mimicked_by["N0"]
    assert m["parameter"] == "dR0" and 0.99 < m["cosine"] < sel.mimicked_by["Nvvv"]["cosine"]
    assert m["span_cosine"] > 0.995 and m["shift"] == 0.05
    assert math.isclose(m["shift_effect"], 0.05 * np.sqrt(np.mean(S[:, 1] ** 2)) / rms)
    assert sel.mimicked_by["Nvvv"]["parameter"] == "Nr"
    assert "Nx" not in sel.mimicked_by
    # without the mimics (a hand-built problem) nothing is attributed, the rest as before
    problem = replace(problem, mimics={})
    assert dv.select_terms(problem, names, dv.DiscoveryOptions(n_models=20), np.random.default_rng(1)).mimicked_by == {}


def _n0_zigzags():
    """KVLCC2 zigzags with a constant yaw moment N0 = 0.003 hidden, no velocity log (the case of
    issue 50): the vehicle and four runs (two to train, two held out)."""
    from bayesid.data.track import Track
    from bayesid.models import ship
    from bayesid.models.ship.trials import TrialOptions, propulsion_point, simulate_trial

    kv = ship.load_ship("kvlcc2_7m")
    truth = kv.with_coefficients({"N0": 0.003})
    speed, rpm = propulsion_point(truth, 1.179)
    rng = np.random.default_rng(2030)
    noise = {"x": 0.01, "y": 0.01, "psi": math.radians(0.05)}
    runs, clock = [], 7200.0
    for angle, check in ((20, 20), (-10, 10), (15, 10), (-25, 5)):
        tr = simulate_trial(
            truth, "zigzag", angle, check_deg=check, speed=speed, rpm=rpm, options=TrialOptions(duration=100.0)
        ).track
        data = {k: np.asarray(tr[k], float) + rng.normal(0, sd, tr.n_samples) for k, sd in noise.items()}
        data.update(delta_r=np.asarray(tr["delta_r"], float), n=np.asarray(tr["n"], float))
        runs.append(Track(tr.t + clock, data, name=f"z{angle}_{check}"))
        clock += tr.t[-1] + 60.0
    return kv, runs


def test_a_hidden_constant_yaw_moment_is_attributed_to_the_neutral_rudder_angle():
    # the fit moves dR0 more than any other free parameter, and N0's mimic is dR0
    from bayesid.analysis.gap import DiagnoseOptions, diagnose

    kv, runs = _n0_zigzags()
    options = DiagnoseOptions(candidates=(), window_s=60.0, max_nfev=10, discover=None)
    d = diagnose(kv, list(kv.free), runs[:2], runs[2:], options, rng=np.random.default_rng(0))
    names = dv.candidate_terms(d.base.model, dv.MAX_ORDER, ("Y", "N"))
    problem = dv.linearised_problem(d.setup, d.base, (), names, d.fit_sd)
    m = problem.mimics["N0"]
    assert m["parameter"] == "dR0" and m["cosine"] > 0.95 and m["shift"] > 0
    assert m["shift_effect"] == max(v["shift_effect"] for v in problem.mimics.values())
    sel = dv.select_terms(problem, names, dv.DiscoveryOptions(n_models=20), np.random.default_rng(0))
    assert "N0" in sel.mimicked and next(iter(sel.mimicked_by)) == "N0"


def test_one_mimicked_term_per_mimic_is_refitted_likeliest_first():
    # issue 49: the selection sets aside a term whose column a free coefficient's reproduces; the
    # likeliest of them are refitted all the same, one per mimic (the same mimic twice tests one
    # likeness twice), whatever the mimic is
    from bayesid.analysis.gap.discovery.selection import mimicked_refits

    by = {
        "Nabsvr": _by("Ncf", 0.97, 3.0),
        "Nvabsr": _by("Ncf", 0.96, 2.5),
        "Y0": _by("track0.waves.nuisance0", 0.99, 2.0),
        "N0": _by("dR0", 0.946, 1.2),
        "Nrrr": _by("Nr", 0.62, 1.0),
    }
    sel = Selection(mimicked=list(by), mimicked_by=by)
    assert mimicked_refits(sel, 2) == ["Nabsvr", "Y0"]
    assert mimicked_refits(sel, 9) == ["Nabsvr", "Y0", "N0", "Nrrr"]
    assert mimicked_refits(sel, 0) == [] and mimicked_refits(Selection(), 2) == []


def test_a_kept_mimicked_term_competes_with_the_others_its_mimic_reproduces():
    # a hidden Nvvr on the submarine without a velocity log: Nv mimics Nvabsr, Nvvr and Nvrr; Nvabsr is
    # refitted (the likeliest) and, once kept, the others of its mimic are refitted too, so that the
    # runs, not the construction, say whether it stands alone
    from bayesid.analysis.gap.discovery.selection import mimicked_companions

    by = {
        "Nvabsr": _by("Nv", 0.99, 3.0),
        "Yvvr": _by("Yv", 0.98, 2.0),
        "Nvvr": _by("Nv", 0.988, 3.0),
        "Nvrr": _by("Nv", 0.97, 3.0),
        "Nvvv": _by("Nv", 0.96, 3.0),
    }
    sel = Selection(mimicked=list(by), mimicked_by=by)
    assert mimicked_companions(sel, "Nvabsr", 2) == ["Nvvr", "Nvrr"]
    assert mimicked_companions(sel, "Nvabsr", 9) == ["Nvvr", "Nvrr", "Nvvv"]
    assert mimicked_companions(sel, "Yvvr", 2) == [] and mimicked_companions(sel, "N0", 2) == []


def test_the_report_gives_a_mimicked_refits_result_in_place_of_the_advice_to_run_it():
    by = {"N0": _by("dR0", 0.9912, 4.5), "Nvv": _by("dR0", 0.95, 1.0), "Nrrr": _by("Nr", 0.97, 0.8)}
    rows = [
        {
            "term": "N0",
            "refitted_as": "mimicked",
            "kept": True,
            "coefficient": 0.00297,
            "heldout_rms_before_m": 0.5,
            "heldout_rms_after_m": 0.031,
        },
        {
            "term": "Nrrr",
            "refitted_as": "mimicked",
            "kept": False,
            "coefficient": 0.01,
            "heldout_rms_before_m": 0.5,
            "heldout_rms_after_m": 0.7,
            "reason": "fits the training runs but not the held-out ones",
        },
        {"term": "Nvv", "refitted_as": "selected", "kept": False, "heldout_rms_after_m": 0.6},
    ]
    D = {"mimicked": list(by), "mimicked_by": by}
    from bayesid.report.diagnosis import _mimicked_text

    text = _mimicked_text(D, ["Nr", "dR0"], refit_rows=rows)
    assert (
        "refitted all the same, every coefficient free (N0 0.00297, held-out RMS 0.5 -> 0.031 m), it passes the "
        "kept test; the others: refit with dR0 held (`--free` without dR0) to test it." in text
    ), text
    assert (
        "refitted all the same, every coefficient free (Nrrr 0.01, held-out RMS 0.5 -> 0.7 m), it does not pass "
        "the kept test (fits the training runs but not the held-out ones)." in text
    )
    assert "refit with Nr held" not in text
    # without the refits, the advice as before
    assert "refit with dR0 held (`--free` without dR0) to test them." in _mimicked_text(D, ["Nr", "dR0"])


def test_a_constant_yaw_moment_the_selection_sets_aside_is_refitted_and_kept():
    # issue 49/50: dR0 reproduces N0's column, so the selection sets N0 aside as mimicked and nothing
    # it selects passes the kept test; refitted all the same (every coefficient free: the rudder's
    # other forces tell dR0 from N0), N0 lands near the truth (measured 0.00297 against 0.003;
    # held-out 0.866 -> 0.043 m) and is kept
    from bayesid.analysis.gap import DiagnoseOptions, diagnose
    from bayesid.report.diagnosis import _discovery_lines

    kv, runs = _n0_zigzags()
    found = dv.DiscoveryOptions(n_alternatives=1)
    options = DiagnoseOptions(candidates=(), window_s=60.0, max_nfev=10, discover=found, design=None)
    d = diagnose(kv, list(kv.free), runs[:2], runs[2:], options, rng=np.random.default_rng(0))
    D = d.discovery.to_dict()
    assert "N0" in D["residuals"]["mimicked"]
    row = next(r for r in D["discovered"] if r["term"] == "N0")
    assert row["refitted_as"] == "mimicked" and row["kept"], row
    assert abs(row["coefficient"] / 0.003 - 1) < 0.1
    assert D["found"][0] == "N0" and d.verdict.startswith("unexplained -> discovered: N0"), d.verdict
    assert D["heldout_rms_after_m"] < 0.2 * D["heldout_rms_before_m"]
    text = "\n".join(_discovery_lines(diagnosis_view(discovery=D)))
    assert "N0 is mimicked by dR0" in text and "refitted all the same, every coefficient free (N0 0.00" in text
    # without the refits of mimicked terms (the default), nothing is kept: what the refit adds
    plain = DiagnoseOptions(candidates=(), window_s=60.0, max_nfev=10, discover=dv.DiscoveryOptions(), design=None)
    d0 = diagnose(kv, list(kv.free), runs[:2], runs[2:], plain, rng=np.random.default_rng(0))
    assert d0.discovery.found == [] and "N0" not in [r.term for r in d0.discovery.discovered]
