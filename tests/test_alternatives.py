"""Structural identifiability (issue 49): which terms the runs cannot separate from a kept term
(alternatives by the paired window test), the run that would separate them (the J divergence of
the alternatives' predictive distributions, Box & Hill 1967), and the manoeuvre kinds a
held-out test covers."""

from __future__ import annotations

import dataclasses
import json
import math
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import n0_against_nabsdr
from diagnosis_view import scores

from bayesid.analysis.gap import design as dz
from bayesid.analysis.gap import discovery as dv
from bayesid.analysis.gap.candidates import Setup, Stage
from bayesid.analysis.gap.records import DesignedRun, PairOutlook, RunTestOutlook
from bayesid.analysis.gap.verdict import Thresholds
from bayesid.data.track import Track
from bayesid.models import runs as mr
from bayesid.models import ship
from bayesid.tasks import jsonable


def _stage(windows):
    return Stage(None, None, {}, {}, None, np.asarray(windows, float))


def test_a_term_whose_windows_are_as_good_is_an_alternative_and_a_worse_one_is_not():
    rng = np.random.default_rng(0)
    best = 0.3 + 0.05 * rng.random(20)
    rows = [
        {"term": "Nvvr", "kept": True, "heldout_rms_after_m": 0.31},
        {"term": "Yvvdr", "kept": True, "heldout_rms_after_m": 0.32},  # as good, window by window
        {"term": "Nrrdr", "kept": True, "heldout_rms_after_m": 0.60},  # passes alone, clearly worse
        {"term": "Nabsv", "kept": False, "heldout_rms_after_m": 0.31},  # failed the kept test, no refit
        {"term": "Nvrr", "kept": False, "heldout_rms_after_m": 0.305},  # failed it, but predicts as well
        {"term": "Yrrr", "kept": False, "heldout_rms_after_m": 0.33},  # failed it, and predicts worse
    ]
    stages = {
        "Nvvr": _stage(best),
        "Yvvdr": _stage(best + 0.002 * rng.standard_normal(20)),
        "Nrrdr": _stage(best + 0.3),
        "Nvrr": _stage(best - 0.002 * rng.standard_normal(20)),
        "Yrrr": _stage(best + 0.002 * rng.standard_normal(20)),
    }
    compared = dv.compare_structures(["Nvvr"], rows, stages, Thresholds())
    alts = dv.alternatives(compared)
    assert [a["term"] for a in alts["Nvvr"]] == ["Nvrr", "Yvvdr"]
    assert [a["term"] for a in dv.separated(compared)["Nvvr"]] == ["Nrrdr"]
    assert [a["passed_kept_test"] for a in alts["Nvvr"]] == [False, True]
    assert all(a["window_p_value"] >= Thresholds().partial_p for a in alts["Nvvr"])
    alts = {"Nvvr": [a for a in alts["Nvvr"] if a["term"] == "Yvvdr"]}
    v = dv._verdict(["Nvvr"], 0.31, 0.5, alts)
    assert v == "discovered: Nvvr (not separable from Yvvdr on these runs)"
    assert dv._verdict(["Nvvr"], 0.31, 0.5, {"Nvvr": []}) == "discovered: Nvvr"  # alone only when none survives
    # an alternative the held-out runs show better (it failed the kept test on its own, or was not added on
    # top of the kept term) is named as favoured, not as a tie
    better = dv.compare_structures(
        ["Nvvr"],
        [*rows, {"term": "N0", "kept": False, "heldout_rms_after_m": 0.1}],
        {**stages, "N0": _stage(best / 3)},
        Thresholds(),
    )
    entry = next(a for a in dv.alternatives(better)["Nvvr"] if a["term"] == "N0")
    assert entry["favoured"]  # an alternative (not separated), and a better one
    assert not any(a["favoured"] for a in dv.alternatives(better)["Nvvr"] if a["term"] != "N0")
    v = dv._verdict(["Nvvr"], 0.31, 0.5, {"Nvvr": [a for a in dv.alternatives(better)["Nvvr"] if a["term"] != "Nvrr"]})
    assert v == "discovered: Nvvr (not separable from Yvvdr on these runs; the held-out runs favour N0)"


def _two_structures(rng, designed):
    """Window errors of a kept term and a competitor: equal on 3 held-out runs of 5 windows, and
    on a designed run of 3 windows the competitor ``designed`` times worse."""
    kept = 0.4 * np.exp(0.15 * rng.standard_normal(18))
    other = kept * np.exp(0.03 * rng.standard_normal(18))
    other[15:] = kept[15:] * designed
    runs = np.repeat(np.arange(4), [5, 5, 5, 3])
    return kept, other, runs


def test_one_designed_run_separates_two_structures_that_the_pooled_window_test_cannot():
    rng = np.random.default_rng(3)
    kept, other, runs = _two_structures(rng, 2.0)
    assert dv.paired_window_test(other, kept) > 0.01  # 3 windows of 18: the pooled ranks do not move
    res = dv.run_separation_test(kept, other, runs)
    assert res.p_second_worse < 0.01 and res.run_second_worse == 3
    assert res.ratio_by_run[3] == pytest.approx(2.0)
    assert res.p_first_worse > 0.5
    rows = [
        {"term": "Nvvr", "kept": True, "heldout_rms_after_m": 0.40},
        {"term": "Nvabsvabsr", "kept": True, "heldout_rms_after_m": 0.45},
    ]
    stages = {"Nvvr": _stage(kept), "Nvabsvabsr": _stage(other)}
    names = ["zz1", "zz2", "tc", "designed"]
    entry = dv.compare_structures(["Nvvr"], rows, stages, Thresholds(), runs, names)["Nvvr"][0]
    assert entry["separable"] and entry["separating_run"] == "designed"
    assert entry["run_error_ratio"] == pytest.approx(2.0)
    assert dv.compare_structures(["Nvvr"], rows, stages, Thresholds())["Nvvr"][0]["separable"] is False


@pytest.mark.parametrize("designed", [1.0, 1.05])
def test_a_run_where_two_structures_agree_within_the_margin_separates_nothing(designed):
    hits = 0
    for seed in range(200):
        kept, other, runs = _two_structures(np.random.default_rng(seed), designed)
        hits += dv.run_separation_test(kept, other, runs).p_second_worse < 0.01
    assert hits <= 4  # the level (1 %), with room for sampling


def test_a_competitor_better_on_some_run_stays_an_alternative():
    rng = np.random.default_rng(4)
    kept, other, runs = _two_structures(rng, 2.0)
    other[:5] = kept[:5] / 2.0  # better on the first run, worse on the designed one
    rows = [
        {"term": "Nvvr", "kept": True, "heldout_rms_after_m": 0.40},
        {"term": "Yvvdr", "kept": True, "heldout_rms_after_m": 0.45},
    ]
    stages = {"Nvvr": _stage(kept), "Yvvdr": _stage(other)}
    compared = dv.compare_structures(["Nvvr"], rows, stages, Thresholds(), runs)
    assert [a["term"] for a in dv.alternatives(compared)["Nvvr"]] == ["Yvvdr"]


@pytest.mark.parametrize("turn_ratio, kept", [(1.5, False), (1.0, True)])
def test_a_term_that_makes_one_held_out_run_worse_does_not_carry_and_is_not_kept(turn_ratio, kept):
    """Issue 49 (KVLCC2): a term that improves four zigzags' windows by a third passes the
    pooled window test, but if it predicts a held-out turning circle worse than the model
    without it, it is not kept, and the reason names the run."""
    rng = np.random.default_rng(7)
    ref = 0.6 * np.exp(0.15 * rng.standard_normal(28))
    term = ref * np.exp(0.05 * rng.standard_normal(28))
    term[:24] *= 0.67  # four zigzags of six windows each
    term[24:] *= turn_ratio  # the turning circle's four windows
    runs = np.repeat(np.arange(5), [6, 6, 6, 6, 4])
    names = ["z1", "z2", "z3", "z4", "turn35"]
    worst = dv._worst_run(_stage(ref), _stage(term), (runs, names), 0.1)
    row = {
        "delta_bic": -50.0,
        "heldout_shrinkage": 0.2,
        "window_p_value": dv.paired_window_test(ref, term),
        "excess_removed": 0.3,
        "worst_run": worst,
    }
    assert row["window_p_value"] < Thresholds().partial_p  # the pooled test alone would keep it
    dv._decide(row, True, Thresholds())
    assert row["kept"] is kept
    if not kept:
        assert worst["run"] == "turn35" and worst["error_ratio"] > 1.3
        assert "turn35" in row["reason"] and "does not carry" in row["reason"]
    assert dv._worst_run(_stage(ref), _stage(term), None, 0.1) is None  # without the runs' layout


def test_a_kept_term_a_held_out_run_shows_worse_than_another_goes_after_it():
    """The pooled held-out RMS favours the surrogate (it ties on three runs and is a little
    better there), but the designed run shows it twice as far off: the hidden term goes first."""
    rng = np.random.default_rng(3)
    kept, other, runs = _two_structures(rng, 2.0)  # "other" worse on the designed run only
    kept[15:], other[15:] = kept[15:] / 5.0, other[15:] / 5.0  # a run the models predict well
    other[:15] *= 0.97  # within the margin elsewhere
    ms = lambda w: Stage(None, None, {}, scores(float(np.sqrt(np.mean(w**2)))), None, w)  # noqa: E731
    stages = {"Nvabsvabsr": ms(other), "Nvvr": ms(kept)}
    assert stages["Nvabsvabsr"].held["rms_position_m"] < stages["Nvvr"].held["rms_position_m"]
    names = ["z1", "z2", "z3", "designed"]
    assert dv.dominance_order(["Nvabsvabsr", "Nvvr"], stages, Thresholds(), (runs, names)) == ["Nvvr", "Nvabsvabsr"]
    # without the runs' layout, or with runs that never separate them: by held-out RMS
    by_rms = sorted(stages, key=lambda n: stages[n].held["rms_position_m"])
    assert dv.dominance_order(["Nvvr", "Nvabsvabsr"], stages, Thresholds()) == by_rms
    tie = {"A": ms(kept), "B": ms(kept * np.exp(0.01 * rng.standard_normal(kept.size)))}
    assert dv.dominance_order(["B", "A"], tie, Thresholds(), (runs, names)) == sorted(
        tie, key=lambda n: tie[n].held["rms_position_m"]
    )


def _trained(held, train=None, runs=None):
    """A single-term refit with per-window held-out errors and, optionally, training errors."""
    held = np.asarray(held, float)
    rms = float(np.sqrt(np.mean(held**2)))
    tw = None if train is None else np.asarray(train, float)
    return Stage(None, None, {}, scores(rms), None, held, tw, runs)


def _tied_heldout_training_apart(rng, ratio):
    """Held-out windows (3 zigzags of 5) on which two structures tie, and training windows (2
    zigzags of 6 and a designed pull-out of 4) on which the second follows the pull-out
    ``ratio`` times worse."""
    held = 0.4 * np.exp(0.15 * rng.standard_normal(15))
    held_b = held * np.exp(0.03 * rng.standard_normal(15))
    train = 0.2 * np.exp(0.15 * rng.standard_normal(16))
    train_b = train * np.exp(0.03 * rng.standard_normal(16))
    train_b[12:] *= ratio
    truns = np.repeat(np.arange(3), [6, 6, 4])
    return (held, train), (held_b, train_b), truns


def test_the_training_runs_separate_two_structures_the_held_out_runs_tie():
    """Issue 49 (closing the loop with the designed run in the training runs): the held-out
    zigzags cannot tell the hidden term from its surrogate, the designed run in training can;
    the alternative is then separated, by the training runs, and the report says so."""
    rng = np.random.default_rng(11)
    (h, t), (hb, tb), truns = _tied_heldout_training_apart(rng, 2.0)
    runs = np.repeat(np.arange(3), 5)
    rows = [
        {"term": "Nabsdr", "kept": True, "heldout_rms_after_m": 0.40},
        {"term": "Nabsrabsdr", "kept": True, "heldout_rms_after_m": 0.40},
    ]
    stages = {"Nabsdr": _trained(h, t, truns), "Nabsrabsdr": _trained(hb, tb, truns)}
    e = dv.compare_structures(["Nabsdr"], rows, stages, Thresholds(), runs, ["z1", "z2", "z3"])["Nabsdr"][0]
    assert e["window_p_value"] > 0.01 and (e["run_p_value"] or 1) > 0.01  # the held-out runs tie them
    assert e["separable"] and e["separated_by"] == "training"
    assert e["train_separating_run"] == "2" and e["train_error_ratio"] == pytest.approx(2.0, rel=0.05)
    assert e["train_run_p_value"] < 0.01
    named = dv.compare_structures(["Nabsdr"], rows, stages, Thresholds(), runs, None, ["z1", "z2", "pull-out"])
    assert named["Nabsdr"][0]["train_separating_run"] == "pull-out"
    from bayesid.report.diagnosis import _separated_cell

    cell = _separated_cell(named["Nabsdr"][0])  # the report says which data separated them
    assert cell.startswith("Nabsrabsdr (held-out 0.4 m, not separated there; on the training run pull-out 1.99x")
    # the other way round the training runs show the kept term better: not separated, an alternative
    flip = dv.compare_structures(["Nabsrabsdr"], rows, stages, Thresholds(), runs)["Nabsrabsdr"][0]
    assert not flip["separable"] and flip["separated_by"] is None
    # and the kept order follows the training runs where the held-out runs tie
    assert dv.dominance_order(["Nabsrabsdr", "Nabsdr"], stages, Thresholds(), (runs, ["z1", "z2", "z3"])) == [
        "Nabsdr",
        "Nabsrabsdr",
    ]
    # without training windows (an older stage) nothing changes: an alternative
    bare = {k: _trained(v.windows) for k, v in stages.items()}
    e = dv.compare_structures(["Nabsdr"], rows, bare, Thresholds(), runs)["Nabsdr"][0]
    assert not e["separable"] and e["train_window_p_value"] is None


def test_the_training_runs_do_not_overrule_a_held_out_run_that_favours_the_competitor():
    rng = np.random.default_rng(12)
    (h, t), (hb, tb), truns = _tied_heldout_training_apart(rng, 2.0)
    hb[:5] = h[:5] / 2.0  # the competitor predicts the first held-out run twice as well
    runs = np.repeat(np.arange(3), 5)
    rows = [
        {"term": "Nabsdr", "kept": True, "heldout_rms_after_m": 0.40},
        {"term": "Nabsrabsdr", "kept": True, "heldout_rms_after_m": 0.40},
    ]
    stages = {"Nabsdr": _trained(h, t, truns), "Nabsrabsdr": _trained(hb, tb, truns)}
    e = dv.compare_structures(["Nabsdr"], rows, stages, Thresholds(), runs)["Nabsdr"][0]
    assert e["train_run_p_value"] < 0.01  # the training runs alone would separate them
    assert not e["separable"] and e["kept_worse_run"] == "0"


@pytest.mark.parametrize("ratio", [1.0, 1.05])
def test_training_windows_that_agree_within_the_margin_separate_at_about_the_level(ratio):
    hits = 0
    for seed in range(200):
        (_, t), (_, tb), truns = _tied_heldout_training_apart(np.random.default_rng(seed), ratio)
        k, o = _trained(np.ones(6), t, truns), _trained(np.ones(6), tb, truns)
        hits += dv.training_separation(k, o, Thresholds()).separated
    assert hits <= 6  # the pooled and the run-by-run test at 1 % each, with room for sampling


def test_the_run_test_refuses_arrays_of_different_lengths():
    with pytest.raises(ValueError, match="differ in length"):
        dv.run_separation_test(np.ones(5), np.ones(5), np.zeros(4, int))


def test_the_top_level_discovered_list_marks_the_final_terms_and_their_alternatives():
    rows = [
        {"term": "Nvvr", "dof": "N", "kept": True, "inclusion_probability": 0.4, "heldout_rms_after_m": 0.31},
        {"term": "Yvvdr", "dof": "Y", "kept": True, "inclusion_probability": 0.9, "heldout_rms_after_m": 0.32},
        {"term": "Nrrdr", "dof": "N", "kept": False, "reason": "why not", "inclusion_probability": 0.8},
    ]
    alt = [{"term": "Yvvdr", "heldout_rms_m": 0.32, "window_p_value": 0.4}]
    D = dv.Discovery(["Nvvr"], "", rows, {}, {}, 3, 1.0, 0.31, {}, [], [], {}, 0.0, alternatives={"Nvvr": alt})
    items = {d["term"]: d for d in D.terms()}
    assert items["Nvvr"]["kept"] and items["Nvvr"]["separable"] is False and items["Nvvr"]["alternatives"] == alt
    assert not items["Yvvdr"]["kept"] and "not on top of Nvvr" in items["Yvvdr"]["reason"]
    assert not items["Nrrdr"]["kept"] and items["Nrrdr"]["reason"] == "why not"
    assert items["Nrrdr"]["separable"] is None


def test_the_j_divergence_is_zero_for_one_model_and_grows_with_the_mean_difference():
    t = np.arange(0.0, 10.0, 0.5)
    m = np.zeros((t.size, 3))
    v = np.zeros((t.size, 3))
    nv = np.array([0.01, 0.01, 1e-4])
    assert dz.separation((t, m, v), (t, m, v), nv, 1.0) == 0.0
    m2 = m.copy()
    m2[:, 0] = 0.1  # 1 sd of x noise at every kept sample (10 of them, 1 s apart)
    assert dz.separation((t, m, v), (t, m2, v), nv, 1.0) == pytest.approx(10 * 0.5 * 0.01 * (2 / 0.01))
    # parameter uncertainty on both sides widens both predictive distributions: less separation
    wide = dz.separation((t, m, v + 0.01), (t, m2, v + 0.01), nv, 1.0)
    assert 0 < wide < dz.separation((t, m, v), (t, m2, v), nv, 1.0)


def _rate_limited(order: np.ndarray, rate: float, dt: float) -> np.ndarray:
    """A rudder that follows ``order`` at most ``rate`` (rad/s), sampled every ``dt`` s."""
    out = np.zeros_like(order)
    for i in range(1, order.size):
        out[i] = out[i - 1] + np.clip(order[i] - out[i - 1], -rate * dt, rate * dt)
    return out


@pytest.mark.parametrize(
    "kind, make",
    [
        ("zigzag", lambda t: math.radians(20) * np.sign(np.sin(2 * np.pi * t / 40)) * (t > 5)),
        ("turning_circle", lambda t: math.radians(35) * (t > 5)),
        ("pull_out", lambda t: math.radians(20) * ((t > 5) & (t < 60))),
        ("straight", lambda t: 0.0 * t),
        ("other", lambda t: math.radians(5) * np.sin(t / 3) + math.radians(10) * np.sin(t / 11)),
        # a 35 deg zigzag of a slow gear (10 deg/s): a fifth of the rudder-over samples on the ramps
        ("zigzag", lambda t: _rate_limited(np.radians(35) * np.sign(np.sin(2 * np.pi * t / 60)), np.radians(10), 0.5)),
        # a turn after 40 s of course keeping with +-3 deg corrections (not the reversals of a zigzag)
        ("turning_circle", lambda t: math.radians(3) * np.sign(np.sin(t)) * (t < 40) + math.radians(35) * (t > 45)),
    ],
)
def test_the_manoeuvre_kind_of_a_run_is_read_from_its_rudder(kind, make):
    t = np.arange(0.0, 150.0, 0.5)
    assert dz.manoeuvre_kind(Track(t, {"x": 0 * t, "delta_r": make(t)})) == kind


def test_the_designed_runs_separate_two_structures_and_none_separates_a_model_from_itself():
    # two KVLCC2 models that differ by an asymmetric yaw moment: a constant one (N0) against one in
    # |rudder| (Nabsdr); the same zigzag split cannot tell the two apart everywhere, a turn can
    kv = ship.load_ship("kvlcc2_7m")
    stages = {}
    for name, value in (("N0", 0.0008), ("Nabsdr", 0.0016), ("N0 again", 0.0008)):
        term = name.split()[0]
        m = ship.ShipModel(kv.with_coefficients({term: value}), free=[term], dt=0.2)
        stages[name] = Stage(m, SimpleNamespace(p=m.start()), {}, {}, None, np.zeros(0))
    t = np.arange(0.0, 120.0, 0.5)
    z = 0 * t
    noise = np.random.default_rng(1).normal
    train = [
        Track(
            t,
            {
                "x": 1.179 * t + noise(0, 0.01, t.size),
                "y": noise(0, 0.01, t.size),
                "psi": noise(0, math.radians(0.05), t.size),
                "u": z + 1.179,
                "delta_r": math.radians(20) * np.sign(np.sin(t / 7)),
                "n": z + 10.23 * 60,
            },
        )
    ]
    setup = Setup(kv, ["N0"], train, train, 0.2, "horizontal", 15.0, 60.0, "measured", None)
    rows = dz.design(stages, setup, dz.DiscriminationOptions(n_draws=0, duration_s=120.0))
    assert rows and rows == sorted(rows, key=lambda r: (-len(r["decidable_pairs"]), -r["separation"]))
    kinds = {r["kind"] for r in rows}
    assert {"turning_circle", "zigzag", "pull_out"} <= kinds
    for r in rows:  # no run separates the model from itself: not separable by the menu, not ranked on
        assert r["pairs"]["N0 vs N0 again"] == pytest.approx(0.0, abs=1e-9)
        assert set(r["menu_inseparable"]) == {"N0 vs N0 again"}
        assert r["worst_pair"] in ("N0 vs Nabsdr", "Nabsdr vs N0 again") and r["separation"] > 0.0
        assert r["pairs"]["N0 vs Nabsdr"] >= 0.0
    best_pair = max(rows, key=lambda r: r["pairs"]["N0 vs Nabsdr"])
    assert best_pair["pairs"]["N0 vs Nabsdr"] > 5.0, best_pair
    # a constant moment acts at zero rudder, a moment in |rudder| does not: a run without rudder
    # (the speed change) tells them apart, as much as the run that separates them best
    straight = next(r for r in rows if r["kind"] == "speed_change")
    assert straight["pairs"]["N0 vs Nabsdr"] > 5.0
    assert set(rows[0]["predicted"]) == set(stages)


def _designed(name, separation=0.0, pairs=None, outlook=None, inseparable=None, **run):
    """A designed run (:class:`DesignedRun`) with only what a test reads set."""
    pairs = pairs or {}
    worst = min(((v, k) for k, v in pairs.items() if np.isfinite(v)), default=(separation, ("K", "A")))
    fields = dict(kind="turning_circle", rudder_deg=35.0, check_deg=None, side="port", rpm=600.0, duration_s=90.0)
    fields.update(run)
    return DesignedRun(
        name=name,
        separation=worst[0] if pairs else separation,
        worst_pair=worst[1],
        pairs=pairs,
        max_position_difference_m=1.0,
        run_test=outlook or RunTestOutlook(3, 0.2, {}),
        menu_inseparable=inseparable,
        **fields,
    )


def test_runs_are_ranked_on_the_pairs_some_run_separates_and_the_others_are_named():
    AB, AC, BC = ("A", "B"), ("A", "C"), ("B", "C")
    rows = [
        _designed("turn", pairs={AB: 900.0, AC: 4.0, BC: 800.0}),
        _designed("zigzag", pairs={AB: 50.0, AC: 6.0, BC: 60.0}),
        _designed("pull-out", pairs={AB: 300.0, AC: 1.0, BC: float("nan")}),
    ]
    ranked = dz.rank_by_separable_pairs(rows, 20.0)
    assert [r.name for r in ranked] == ["turn", "pull-out", "zigzag"]
    assert ranked[0].worst_pair == BC and ranked[0].separation == 800.0
    assert ranked[1].worst_pair == AB  # B vs C not simulated on it
    assert all(r.menu_inseparable == {AC: {"best_run": "zigzag", "separation": 6.0}} for r in ranked)
    assert rows[0].menu_inseparable is None  # the ranking returns new rows, the old ones stay
    # the JSON keys the pairs "A vs B", and reads them back
    assert ranked[0].to_dict()["menu_inseparable"] == {"A vs C": {"best_run": "zigzag", "separation": 6.0}}
    assert ranked[0].to_dict()["worst_pair"] == "B vs C"
    assert DesignedRun.from_dict(json.loads(json.dumps(jsonable(ranked[2].to_dict())))).to_dict().keys() == (
        ranked[2].to_dict().keys()
    )
    # nothing separable: ranked on every pair, each named
    ranked = dz.rank_by_separable_pairs(rows, 1e4)
    assert set(ranked[0].menu_inseparable) == {AB, AC, BC}
    assert ranked[0].name == "zigzag" and ranked[0].separation == 6.0


def test_runs_the_run_test_could_decide_come_before_larger_divergences():
    """A run whose divergence is large but whose expected window error ratio is within the run
    test's margin would not change the decision: the design asks first for the run on which the
    run test could separate the kept term from its alternatives within max_windows windows."""

    def row(name, separation, needed, inseparable=()):
        outlook = RunTestOutlook(3, 0.2, {("K", k): PairOutlook(1.2, w) for k, w in needed.items()})
        return _designed(name, separation, outlook=outlook, inseparable={("K", p): {} for p in inseparable})

    rows = [
        row("turn 35", 900.0, {"A": float("inf"), "B": 40.0}),  # large divergence, nothing decidable
        row("turn 18", 120.0, {"A": 6.0, "B": 9.0}),  # one pair within 8 windows
        row("pull-out", 200.0, {"A": 7.5, "B": None}),  # one pair; larger divergence than turn 18
        row("zigzag", 50.0, {"A": 3.0, "B": 2.0}, inseparable=["B"]),  # B: no run separates it
    ]
    ranked = dz.rank_by_decidable_pairs(rows, 8)
    assert [r.name for r in ranked] == ["pull-out", "turn 18", "zigzag", "turn 35"]
    assert ranked[0].decidable_pairs == [("K", "A")] and ranked[-1].decidable_pairs == []
    assert ranked[2].decidable_pairs == [("K", "A")]  # the menu-inseparable pair does not count
    assert ranked[0].to_dict()["decidable_pairs"] == ["K vs A"]
    # with room for more windows turn 18 decides both pairs and comes first
    assert [r.name for r in dz.rank_by_decidable_pairs(rows, 10)][:2] == ["turn 18", "pull-out"]
    # nothing decidable anywhere: the divergence ranks the runs, as before
    assert [r.name for r in dz.rank_by_decidable_pairs(rows, 1)] == ["turn 35", "pull-out", "turn 18", "zigzag"]


def _n0_against_nabsdr():
    """Two KVLCC2 structures (a constant yaw moment, one in |rudder|), the first the truth, and a
    zigzag-like training run."""
    return n0_against_nabsdr()


def _window_rms(stage, run, window_s):
    t, mean, _ = dz.predictive(stage, np.asarray(stage.fit.p)[None], run, window_s)
    dx = mean[:, 0] - np.interp(t, run.t, run["x"])
    dy = mean[:, 1] - np.interp(t, run.t, run["y"])
    return float(np.sqrt(np.nanmean(dx**2 + dy**2)))


def test_the_top_designed_run_flown_by_the_truth_rejects_the_wrong_structure():
    stages, setup = _n0_against_nabsdr()
    rows = dz.design(stages, setup, dz.DiscriminationOptions(n_draws=0, duration_s=120.0))
    top, last = rows[0], rows[-1]
    assert top["separation"] > 5.0 and top["inputs"]["t"][0] == 0.0
    approach = mr.approach_condition(setup.train)
    truth = stages["N0"]
    errors = {}
    for row in (top, last):
        u = row["inputs"]
        run = mr.simulate_run(
            truth.model, truth.fit.p, mr.input_track(u["t"], u["delta_r"], u["n"], approach), approach
        )
        assert run is not None
        errors[row["name"]] = {k: _window_rms(st, run, setup.window_s) for k, st in stages.items()}
    # the truth predicts its own run; the other structure misses the top run by far more than
    # the training noise (1 cm), and by more than on the run ranked last
    assert errors[top["name"]]["N0"] < 0.005  # interpolation between the model's steps
    assert errors[top["name"]]["Nabsdr"] > 0.2, errors
    assert errors[top["name"]]["Nabsdr"] > errors[last["name"]]["Nabsdr"]


def test_the_report_writes_the_top_runs_input_schedules(tmp_path):
    from bayesid.report.diagnosis import _design_lines, _write_design_runs

    pull = dict(kind="pull_out", side="port", rudder_deg=20, check_deg=None, rpm=600, duration_s=90)
    inputs = {"t": [0.0, 0.1], "delta_r": [0.0, 0.01], "n": [600.0, 600.0]}
    rows = [_designed("zigzag 20/20 port", 3.0, **pull), _designed("pull out 20 deg port", 3.0, **pull)]
    rows[0] = dataclasses.replace(rows[0], inputs=inputs)
    _write_design_runs(rows, tmp_path)
    path = tmp_path / "design_runs" / "1_zigzag_20_20_port.csv"
    lines = path.read_text().splitlines()  # a comment line, then a plain header row
    assert lines[0].startswith("# designed run 1: zigzag 20/20 port") and lines[1] == "t,delta_r,n"
    data = np.loadtxt(path, delimiter=",", skiprows=2)
    assert data.shape == (2, 3) and data[1, 1] == pytest.approx(0.01)
    assert not (tmp_path / "design_runs" / "2_pull_out_20_deg_port.csv").exists()
    rows[0] = dataclasses.replace(rows[0], inputs=None, inputs_csv="design_runs/1_zigzag_20_20_port.csv")
    text = "\n".join(_design_lines(rows))
    assert "`design_runs/1_zigzag_20_20_port.csv`" in text and "Not separable" not in text
    insep = {("Nvvr", "Nvabsvabsr"): {"best_run": "zigzag 20/20 port", "separation": 6.8}}
    rows[0] = dataclasses.replace(rows[0], menu_inseparable=insep)
    text = "\n".join(_design_lines(rows))
    assert "**Not separable by the standard manoeuvres**: no run of the menu separates Nvvr from Nvabsvabsr" in text
    # a run lengthened for the run test says from what, and the windows its hardest separable pair needs
    outlook = RunTestOutlook(
        8,
        0.2,
        {
            ("K", "A"): PairOutlook(1.19, 40.4),
            ("K", "B"): PairOutlook(1.5, 6.2),
            ("K", "C"): PairOutlook(1.05, float("inf")),
        },
        sized_from_s=180,
    )
    rows[0] = dataclasses.replace(rows[0], duration_s=480, run_test=outlook)
    row = next(x for x in "\n".join(_design_lines(rows)).splitlines() if x.startswith("| pull out"))
    assert "| 480 (from 180) |" in row and "| 41 (x1.19, K vs A); 1 of 3 pairs within the margin |" in row


@pytest.mark.parametrize("argv", [["--alternatives", "0"], ["--no-design"], ["--alternatives", "-1"]])
def test_design_refuses_options_that_leave_nothing_to_design(argv, tmp_path, capsys):
    from bayesid import cli

    code = cli.main(
        ["design", "--model", str(tmp_path / "m.json"), "--train", "a.csv", "--heldout", "b.csv"]
        + argv
        + ["--out", str(tmp_path / "o")]
    )
    err = capsys.readouterr().err
    assert code == 2 and ("--alternatives" in err or "--no-design" in err), err


def test_each_alternative_predicts_the_standard_manoeuvres_the_training_runs_lack():
    stages, setup = _n0_against_nabsdr()
    runs = dz.standard_predictions(stages, setup, dz.DiscriminationOptions(n_draws=0, duration_s=200.0))
    names = [r["name"] for r in runs]
    assert names == [
        "turning circle 35 deg port",
        "turning circle 35 deg starboard",
        "zigzag 10/10 port",
        "zigzag 20/20 port",
    ]
    turns = [r for r in runs if r["kind"] == "turning_circle"]
    assert all(not r["in_training_kinds"] for r in turns)  # the training run is a zigzag
    assert all(r["in_training_kinds"] for r in runs if r["kind"] == "zigzag")
    for r in runs:
        assert set(r["models"]) == {"N0", "Nabsdr"}
        for m in r["models"].values():
            for v in m.values():
                assert np.isfinite(v["value"]) and v["low"] == v["value"] == v["high"]  # no draws
                assert v["n_finite"] == v["n"] == 1
    # a constant yaw moment turns the ship one way: its port and starboard circles differ
    td = {r["side"]: r["models"]["N0"]["tactical_diameter_m"]["value"] for r in turns}
    assert abs(td["port"] - td["starboard"]) > 0.01 * td["port"], td


def test_a_kept_term_that_predicts_a_run_of_another_kind_worse_is_flagged():
    from functools import partial

    from bayesid.analysis.gap.diagnose import worse_on_other_kinds

    reference = {"per_track_rms_position_m": {"z1": 0.5, "turn": 0.3, "z2": 0.6}}
    kinds = {"train": ["zigzag", "zigzag"], "heldout": ["zigzag", "turning_circle", "zigzag"]}
    worse = partial(worse_on_other_kinds, reference=reference, heldout_tracks=["z1", "turn", "z2"])
    worse = partial(worse, manoeuvre_kinds=kinds, thresholds=None)
    # better on the zigzags it was chosen on, worse on the turn
    item = {"term": "Nvdrabsdr", "heldout_rms_by_run_m": {"z1": 0.2, "turn": 0.45, "z2": 0.25}}
    flagged = worse(item)
    assert flagged == [{"run": "turn", "kind": "turning_circle", "rms_m": 0.45, "reference_rms_m": 0.3}]
    item["heldout_rms_by_run_m"]["turn"] = 0.25
    assert worse(item) == []
    # within the separation margin (a real Esso turn: 0.473 against 0.472 m) is no warning
    item["heldout_rms_by_run_m"]["turn"] = 0.32
    assert worse(item) == []


def test_an_index_whose_estimate_diverged_says_so_and_counts_the_draws_that_did_not():
    from bayesid.report.diagnosis import _index_cell

    v = dz._spread([np.nan, 20.0, 21.0, np.nan])
    assert np.isnan(v["value"]) and (v["n_finite"], v["n"]) == (2, 4) and 20.0 <= v["low"] <= v["high"] <= 21.0
    cell = _index_cell(v)
    assert cell.startswith("estimate: diverged") and "(2 of 4 runs)" in cell
    assert _index_cell(dz._spread([np.nan, np.nan])) == "diverged or not reached"
    assert _index_cell(dz._spread([12.0, 11.0, 13.0])).startswith("12 [")


def _zigzag_track(name, side=1.0):
    t = np.arange(0.0, 150.0, 0.5)
    return Track(t, {"x": 0 * t, "delta_r": side * math.radians(20) * np.sign(np.sin(2 * np.pi * t / 40))}, name=name)


@pytest.mark.parametrize("held_kind, designed", [("zigzag", True), ("turning_circle", False)])
def test_a_term_kept_alone_and_tested_only_on_zigzags_gets_a_run_of_another_kind(monkeypatch, held_kind, designed):
    """KVLCC2 HSVA: Nvdrabsdr kept alone, every held-out run a zigzag like the training runs; the
    design ranks the runs that would test it against the model without it. A held-out run of
    another kind already tests it: no design."""
    import importlib

    from bayesid.tasks import Runner

    dg = importlib.import_module("bayesid.analysis.gap.diagnose")
    calls = []
    monkeypatch.setattr(dg, "design", lambda stages, setup, options: calls.append(list(stages)) or [{"name": "r"}])
    monkeypatch.setattr(dg, "standard_predictions", lambda models, setup, options: list(models))
    t = np.arange(0.0, 150.0, 0.5)
    held = _zigzag_track("h") if held_kind == "zigzag" else Track(t, {"x": 0 * t, "delta_r": 0.6 * (t > 5)}, name="h")
    setup = SimpleNamespace(train=[_zigzag_track("a"), _zigzag_track("b", -1.0)], heldout=[held])
    found = SimpleNamespace(
        found=["Nvdrabsdr"], alternatives={"Nvdrabsdr": []}, stages={"Nvdrabsdr": "stage"}, reference="ref"
    )
    rows, predictions = dg._design(found, setup, object(), Runner())
    if designed:
        assert calls == [["Nvdrabsdr", dg.WITHOUT_TERMS]]
        assert predictions == ["base model", "Nvdrabsdr"]
    else:
        assert calls == [] and rows == []


def test_a_discovery_reads_back_from_its_json():
    """Issue 51: ``Discovery.from_dict`` of the ``discovery`` entry of diagnosis.json gives the
    result whose JSON is that entry; a misspelt key is named."""
    import json

    from bayesid.tasks import jsonable

    rows = [{"term": "Nvvr", "dof": "N", "kept": True, "heldout_rms_after_m": 0.31, "worst_run": None}]
    alt = [{"term": "Yvvdr", "heldout_rms_m": 0.32, "window_p_value": 0.4, "kept_worse_run": None}]
    D = dv.Discovery(["Nvvr"], "discovered: Nvvr", rows, {"Nvvr": 0.9}, {}, 3, 1.0, 0.31, {}, [1.0], [0.3], {}, 0.5)
    D.alternatives = {"Nvvr": alt}
    text = json.dumps(jsonable(D.to_dict()), allow_nan=False)
    back = dv.Discovery.from_dict(json.loads(text))
    assert back.found == ["Nvvr"] and back.alternatives == {"Nvvr": alt} and back.stages == {}
    assert json.dumps(jsonable(back.to_dict()), allow_nan=False) == text
    with pytest.raises(ValueError, match=r"unknown key\(s\) \['fund'\]"):
        dv.Discovery.from_dict({**json.loads(text), "fund": []})
