"""Closing the loop (issue 49): an earlier round's kept terms and alternatives are refitted and
judged again once the designed run is added (``DiscoveryOptions.compare``, ``--compare``),
whatever the new selection picks."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bayesid.analysis.gap import discovery as dv
from bayesid.cli.options import compare_terms
from bayesid.models import build_model, load_any_vehicle


def test_compare_takes_a_sequence_of_names_each_once():
    assert dv.DiscoveryOptions(compare=["Nvvr", "Nvabsvabsr", "Nvvr"]).compare == ("Nvvr", "Nvabsvabsr")
    with pytest.raises(ValueError, match="sequence of term names"):
        dv.DiscoveryOptions(compare="Nvvr")


def test_a_compared_name_that_is_not_a_candidate_is_named():
    model = build_model(load_any_vehicle("nps_auv2"), ["Nv", "Nr"])
    dv.check_compare(model, dv.DiscoveryOptions(compare=("Nvvr", "Nvabsvabsr", "Yrrr")))
    with pytest.raises(ValueError, match="Nfoo is not among") as e:
        dv.check_compare(model, dv.DiscoveryOptions(compare=("Nvvr", "Nfoo")))
    assert "Nvvr" not in str(e.value)
    # a free coefficient, and a term of a degree of freedom not searched, are not candidates
    with pytest.raises(ValueError, match="Nr, Yrrr are not among"):
        dv.check_compare(model, dv.DiscoveryOptions(compare=("Nr", "Yrrr"), dofs=("N",)))


def test_the_compare_option_reads_names_or_an_earlier_rounds_diagnosis(tmp_path):
    assert compare_terms("") == ()
    assert compare_terms(" Nvvr, Nvabsvabsr ,Nvvr") == ("Nvvr", "Nvabsvabsr")
    with pytest.raises(ValueError, match="empty term name"):
        compare_terms("Nvvr,,Nrrr")
    earlier = {
        "discovered": [
            {"term": "Nvabsvabsr", "kept": True, "alternatives": [{"term": "Nvvr"}, {"term": "Nvrr"}]},
            {"term": "Yvvr", "kept": False, "alternatives": []},
            {"term": "Ndrdrdr", "kept": True, "alternatives": [{"term": "Nvvr"}]},
        ]
    }
    path = tmp_path / "diagnosis.json"
    path.write_text(json.dumps(earlier))
    assert compare_terms(str(path)) == ("Nvabsvabsr", "Ndrdrdr", "Nvvr", "Nvrr")
    path.write_text(json.dumps({"discovered": [{"term": "Yvvr", "kept": False}]}))
    with pytest.raises(ValueError, match="kept no term"):
        compare_terms(str(path))
    path.write_text("[1, 2]")
    with pytest.raises(ValueError, match="not a diagnosis.json"):
        compare_terms(str(path))
    with pytest.raises(ValueError, match="no such file"):
        compare_terms(str(tmp_path / "missing.json"))


def test_a_compared_term_the_selection_passes_over_is_refitted_and_judged():
    # the constant yaw moment of tests/test_mimicked_report.py: the selection sets N0 aside (dR0
    # mimics it) and, without refits of mimicked terms, keeps nothing; asked for, N0 is refitted
    # with every coefficient free, lands near the truth (0.003) and is kept. Nothing else changes:
    # the selected terms are refitted as before.
    from test_mimicked_report import _n0_zigzags

    from bayesid.analysis.gap import DiagnoseOptions, diagnose

    kv, runs = _n0_zigzags()
    found = dv.DiscoveryOptions(compare=("N0",))
    options = DiagnoseOptions(candidates=(), window_s=60.0, max_nfev=10, discover=found, design=None)
    d = diagnose(kv, list(kv.free), runs[:2], runs[2:], options, rng=np.random.default_rng(0))
    D = d.discovery.to_dict()
    row = next(r for r in D["discovered"] if r["term"] == "N0")
    assert row["refitted_as"] == "compared" and row["kept"], row
    assert abs(row["coefficient"] / 0.003 - 1) < 0.1
    assert D["found"][0] == "N0", D["found"]
    assert list(D["settings"]["compare"]) == ["N0"]
    assert sum(r["refitted_as"] == "compared" for r in D["discovered"]) == 1


def test_the_report_says_what_became_of_each_compared_term():
    from diagnosis_view import discovery_view

    from bayesid.report.diagnosis import _compared_lines

    D = {
        "found": ["Nvabsvabsr"],
        "settings": {"compare": ["Nvabsvabsr", "Nvvr", "Nvrr", "Nrrr", "Yvvr", "Nvvv"]},
        "alternatives": {"Nvabsvabsr": [{"term": "Nvvr"}]},
        "separated": {
            "Nvabsvabsr": [
                {"term": "Nvrr", "separated_by": "heldout", "separating_run": "designed_turn", "run_error_ratio": 1.62},
                {"term": "Nrrr", "separated_by": "training", "train_separating_run": "z20", "train_error_ratio": 1.3},
            ]
        },
        "discovered": [
            {"term": "Yvvr", "kept": False, "reason": "fits the training runs but not the held-out ones"},
            {"term": "Nvabsvabsr", "kept": True},
        ],
    }
    text = "\n".join(_compared_lines(discovery_view(**D)))
    assert "Nvabsvabsr: kept;" in text
    assert "Nvvr: an alternative of Nvabsvabsr (the runs do not separate them)" in text
    assert "Nvrr: set apart from Nvabsvabsr by the held-out runs, run designed_turn, error ratio 1.62" in text
    assert "Nrrr: set apart from Nvabsvabsr by the training runs, run z20, error ratio 1.3" in text
    assert "Yvvr: not kept: fits the training runs but not the held-out ones" in text
    assert "Nvvv: not refitted." in text
    assert _compared_lines(discovery_view()) == []
