"""A term added on top of another in a combination competes with the terms that could take its
place there, refitted on top of the same first term (issue 49): its alternatives do not come from
single-term refits, which lack the first term."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
from diagnosis_view import diagnosis_view, scores

from bayesid.analysis.gap import discovery as dv
from bayesid.analysis.gap.candidates import Stage
from bayesid.analysis.gap.discovery import confirmation as cf
from bayesid.analysis.gap.verdict import Thresholds
from bayesid.models import ship
from bayesid.tasks import jsonable

TERMS = ("Nvvr", "Nrdrdr", "Nvdrdr", "Yvvr")


def _model():
    kv = ship.load_ship("kvlcc2_7m").with_coefficients(dict.fromkeys(TERMS, 0.0))
    return ship.ShipModel(kv, free=list(TERMS), dt=0.2)


def _stage(model, windows, coefficients, cost):
    w = np.asarray(windows, float)
    rms = float(np.sqrt(np.mean(w**2)))
    fit = SimpleNamespace(coefficients=lambda: dict(coefficients), cost=cost, bic=1000.0 * cost, p=np.zeros(3))
    held = scores(rms, per_track_rms_position_m={"z": rms})
    return Stage(model, fit, scores(rms), held, None, w)


def test_the_second_terms_competitors_are_refitted_on_top_of_the_first(monkeypatch):
    rng = np.random.default_rng(3)
    m, n = _model(), 24
    base = 0.9 + 0.05 * rng.random(n)
    first = 0.6 + 0.05 * rng.random(n)  # Nvvr alone
    both = 0.3 + 0.02 * rng.random(n)  # Nvvr + Nrdrdr
    ref = _stage(m, base, {}, 1.0)
    chain = [_stage(m, first, {"Nvvr": 1.0}, 0.5), _stage(m, both, {"Nvvr": 1.1, "Nrdrdr": 2.0}, 0.2)]
    # on top of Nvvr, Nvdrdr predicts as well as Nrdrdr (window by window); Yvvr clearly worse
    on_top = {
        "Nvdrdr": _stage(m, both + 0.002 * rng.standard_normal(n), {"Nvvr": 1.1, "Nvdrdr": 3.0}, 0.2),
        "Yvvr": _stage(m, both + 0.25, {"Nvvr": 1.0, "Yvvr": 0.5}, 0.4),
    }
    calls = []

    def fake_fit_on_top(values, term, cur, *_):
        calls.append((dict(values), term, cur))
        return on_top[term]

    monkeypatch.setattr(cf, "_fit_on_top", fake_fit_on_top)
    # the single-term refits separated Nvdrdr from Nrdrdr: alone, Nrdrdr looked unique
    single = {"Nrdrdr": [{"term": "Nvdrdr", "separable": True, "heldout_rms_m": 0.7}], "Nvvr": []}
    runs = (np.zeros(n, int), ["z"])
    out, stages = cf.combined_competitors(
        ["Nvvr", "Nrdrdr"],
        chain,
        single,
        ["Nvvr", "Nvdrdr", "Yvvr"],
        cf.Refits(ref, None, (), {}, 10, 0.1, Thresholds(), runs, dict.fromkeys(TERMS, 0.0)),
    )
    # each competitor refitted once, on top of the first term as the combination fitted it
    assert [c[1] for c in calls] == ["Nvdrdr", "Yvvr"]
    assert all(c[0] == {"Nvvr": 1.0} and c[2] is chain[0] for c in calls)
    alts = dv.alternatives(out)
    assert [a["term"] for a in alts["Nrdrdr"]] == ["Nvdrdr"]
    assert alts["Nrdrdr"][0]["on_top_of"] == ["Nvvr"]
    assert alts["Nrdrdr"][0]["passed_kept_test"]
    assert [a["term"] for a in dv.separated(out)["Nrdrdr"]] == ["Yvvr"]
    assert out["Nvvr"] == []  # the first term's comparison stands as it was
    assert set(stages["Nrdrdr"]) == {"Nrdrdr", "Nvdrdr", "Yvvr"} and stages["Nrdrdr"]["Nrdrdr"] is chain[1]
    assert dv._verdict(["Nvvr", "Nrdrdr"], 0.3, 0.5, alts) == (
        "discovered: Nvvr+Nrdrdr (not separable from Nvdrdr on these runs)"
    )


def test_the_report_says_the_competitors_were_refitted_in_the_place_of_the_added_term():
    from bayesid.report.diagnosis import _alternatives_lines

    m = _model()
    w = np.full(6, 0.3)
    alt = {"term": "Nvdrdr", "coefficient": 3.0, "heldout_rms_m": 0.31, "window_p_value": 0.4, "on_top_of": ["Nvvr"]}
    rows = [
        {"term": t, "dof": "N", "kept": True, "inclusion_probability": 0.5, "heldout_rms_after_m": 0.6}
        for t in ("Nvvr", "Nrdrdr")
    ]
    stages = {"Nvvr": _stage(m, w * 2, {"Nvvr": 1.0}, 0.5), "Nrdrdr": _stage(m, w * 2.2, {"Nrdrdr": 1.0}, 0.5)}
    combined = {"Nrdrdr": {"Nrdrdr": _stage(m, w, {"Nvvr": 1.0, "Nrdrdr": 2.0}, 0.2)}}
    d = dv.Discovery(
        ["Nvvr", "Nrdrdr"], "", rows, {}, {}, 3, 1.0, 0.3, {}, [], [], {}, 0.0,
        alternatives={"Nvvr": [], "Nrdrdr": [alt]}, stages=stages, combined_stages=combined,
    )  # fmt: skip
    # the models stay out of the JSON, which reads back
    doc = d.to_dict()
    assert not set(doc) & set(dv.MODEL_FIELDS)
    json.dumps(jsonable(doc), allow_nan=False)
    assert dv.Discovery.from_dict(doc).to_dict() == doc
    items = {i["term"]: i for i in d.terms()}
    assert items["Nrdrdr"]["heldout_rms_on_top_m"] == 0.3 and "heldout_rms_on_top_m" not in items["Nvvr"]
    text = "\n".join(_alternatives_lines(diagnosis_view(discovered=list(items.values()))))
    assert "**Nrdrdr** (held-out 0.3 m) is not separable" in text
    assert "Nrdrdr was added on top of Nvvr: each competitor above was refitted in its place" in text


def test_the_design_separates_an_added_term_from_its_competitors_as_refitted_in_its_place(monkeypatch):
    import importlib
    import math

    from bayesid.data.track import Track
    from bayesid.tasks import Runner

    dg = importlib.import_module("bayesid.analysis.gap.diagnose")
    calls = []
    monkeypatch.setattr(dg, "design", lambda stages, setup, options: calls.append(dict(stages)) or [{"name": "r"}])
    monkeypatch.setattr(dg, "standard_predictions", lambda models, setup, options: dict(models))
    t = np.arange(0.0, 150.0, 0.5)
    zigzag = Track(t, {"x": 0 * t, "delta_r": math.radians(20) * np.sign(np.sin(2 * np.pi * t / 40))}, name="z")
    turn = Track(t, {"x": 0 * t, "delta_r": 0.6 * (t > 5)}, name="turn")  # a held-out run of another kind
    setup = SimpleNamespace(train=[zigzag], heldout=[turn])
    found = SimpleNamespace(
        found=["Nvvr", "Nrdrdr"],
        alternatives={"Nvvr": [], "Nrdrdr": [{"term": "Nvdrdr"}]},
        stages={"Nvvr": "Nvvr alone", "Nrdrdr": "Nrdrdr alone", "Nvdrdr": "Nvdrdr alone"},
        combined_stages={"Nrdrdr": {"Nrdrdr": "Nvvr+Nrdrdr", "Nvdrdr": "Nvvr+Nvdrdr"}},
        reference="ref",
    )
    rows, predictions = dg._design(found, setup, object(), Runner())
    assert calls == [{"Nrdrdr": "Nvvr+Nrdrdr", "Nvdrdr": "Nvvr+Nvdrdr"}]
    assert predictions == {"base model": "ref", "Nrdrdr": "Nvvr+Nrdrdr", "Nvdrdr": "Nvvr+Nvdrdr"}


def test_a_surrogate_added_first_is_dropped_once_the_term_it_stood_for_joins_it(monkeypatch):
    """Backward elimination (confirmation.prune): Yvvr, added first, predicts nothing on top of
    Nvvr that Nvvr alone does not; Nrdrdr still adds to Nvvr and stays."""
    rng = np.random.default_rng(5)
    m, n = _model(), 24
    noise = 0.02 * rng.random(n)
    err = {  # held-out window errors of each model, by its terms
        ("Yvvr",): 0.6 + noise,
        ("Nvvr",): 0.45 + noise,
        ("Nrdrdr",): 0.7 + noise,
        ("Yvvr", "Nvvr"): 0.45 + noise + 0.001 * rng.standard_normal(n),
        ("Yvvr", "Nvvr", "Nrdrdr"): 0.3 + noise,
        ("Nvvr", "Nrdrdr"): 0.3 + noise + 0.001 * rng.standard_normal(n),
        ("Yvvr", "Nrdrdr"): 0.5 + noise,
    }
    st = {k: _stage(m, w, dict.fromkeys(k, 1.0), 0.1 * w.mean()) for k, w in err.items()}
    calls = []

    def fake_fit_on_top(values, term, cur, *_):
        calls.append((*values, term))
        return st[(*values, term)]

    monkeypatch.setattr(cf, "_fit_on_top", fake_fit_on_top)
    found = ["Yvvr", "Nvvr", "Nrdrdr"]
    chain = [st[("Yvvr",)], st[("Yvvr", "Nvvr")], st[("Yvvr", "Nvvr", "Nrdrdr")]]
    singles = {t: st[(t,)] for t in found}
    ref = _stage(m, 0.9 + noise, {}, 1.0)
    runs = (np.zeros(n, int), ["z"])
    fits = cf.Refits(ref, None, (), {}, 10, 0.1, Thresholds(), runs, dict.fromkeys(TERMS, 0.0))
    kept, new_chain, dropped = cf.prune(found, chain, singles, fits)
    assert kept == ["Nvvr", "Nrdrdr"] and dropped == ["Yvvr"]
    assert new_chain == [st[("Nvvr",)], st[("Nvvr", "Nrdrdr")]]
    assert ("Nvvr", "Nrdrdr") in calls and ("Yvvr", "Nrdrdr") in calls
    # nothing redundant: nothing dropped, no fit
    calls.clear()
    assert cf.prune(["Nvvr", "Nrdrdr"], [st[("Nvvr",)], st[("Nvvr", "Nrdrdr")]], singles, fits)[2] == []
