"""Issue 51: the typed records of the gap diagnosis (NoiseFloor, CandidateRow, Remainder, BaseCheck,
TermRow) read as the JSON dicts they write, write them key for key and in the order diagnosis.json
has always had, read them back (to_dict -> from_dict -> to_dict), and document every field. The
records come from a real diagnosis of KVLCC2 runs with a hidden term (tests/test_discovery.py)."""

from __future__ import annotations

import dataclasses
import json
import pickle
import re

import pytest
from test_discovery import _runs

from bayesid.analysis import gap
from bayesid.analysis.gap import discovery as dv
from bayesid.analysis.gap.diagnose import Diagnosis
from bayesid.analysis.gap.discovery.confirmation import decide, refit_row
from bayesid.analysis.gap.records import BaseCheck, CandidateRow, NoiseFloor, Record, Remainder, TermRow
from bayesid.analysis.gap.verdict import Thresholds
from bayesid.tasks import jsonable

RECORDS = [NoiseFloor, CandidateRow, Remainder, BaseCheck, TermRow]

#: the keys, in order, that diagnosis.json had before the records (reports/ written by then)
KEYS = {
    NoiseFloor: ("heldout_rms_m", "heading_rms_deg", "by_channel", "coefficient_draws", "diverged_share"),  # issue 67, appended
    Remainder: ("heldout_rms_m", "fraction_of_excess", "significant"),
    CandidateRow: (
        "effect", "heldout_rms_m", "train_rms_m", "delta_bic", "excess_removed", "share_of_excess",
        "heldout_shrinkage", "parameters", "heading_rms_deg", "window_p_value", "nfev", "fit_seconds", "role",
        "parameter_sd", "undetermined",  # issue 69, appended
    ),
    BaseCheck: ("train_rms_at_window_m", "heldout_rms_m", "ratio", "threshold", "starts", "suspect", "message", "multistart"),
    TermRow: (
        "term", "dof", "inclusion_probability", "group_inclusion_probability", "group", "regression_coefficient",
        "heldout_rms_before_m", "train_rms_before_m", "coefficient", "coefficient_sd", "heldout_rms_after_m",
        "train_rms_after_m", "shrinkage", "heldout_shrinkage", "delta_bic", "refit_failed", "window_p_value",
        "heldout_windows_after_m", "excess_removed", "worst_run", "refitted_as", "kept", "reason",
    ),
}  # fmt: skip


@pytest.fixture(scope="module")
def diagnosis():
    kv, train, held = _runs({"Nabsdr": 0.002})
    options = gap.DiagnoseOptions(
        candidates=("current", "delay"), window_s=60.0, max_nfev=20, base_starts=1, discover=dv.DiscoveryOptions()
    )
    return gap.diagnose(kv, kv.free, train, held, options)


def _records(d) -> list:
    """Every record of a diagnosis, with a base check as --train-starts auto writes it and a term
    row whose every fit failed."""
    D = d.discovered
    failed = refit_row(D.discovered[0].term, None, D.reference, None, 0.1)
    check = dataclasses.replace(
        d.base_check,
        train_starts={"fitted_train_rms_at_window_m": 0.2, "kinematic_train_rms_at_window_m": 0.3, "used": "fitted"},
    )
    rows = [r for rnd in d.rounds for r in rnd]
    return [d.noise_floor, d.remainder, d.base_check, check, *rows, *D.discovered, replace_as(failed)]


def replace_as(row):
    """A failed refit as discover() finishes it: decided, then told how it was refitted."""
    return dataclasses.replace(decide(row, True, gap.Thresholds()), refitted_as="selected")


def _text(x) -> str:
    return json.dumps(jsonable(x), allow_nan=False)


def test_the_diagnosis_fields_are_records_and_every_kind_is_covered(diagnosis):
    d = diagnosis
    assert isinstance(d.noise_floor, NoiseFloor) and isinstance(d.remainder, Remainder)
    assert isinstance(d.base_check, BaseCheck) and d.base_check.multistart is not None
    assert d.ranking and all(
        isinstance(r, CandidateRow) and r.role in (None, "cause", "contributor") for r in d.ranking
    )
    assert d.discovered is not None and d.discovered.discovered
    assert all(isinstance(r, TermRow) and r.kept is not None for r in d.discovered.discovered)
    assert {type(r) for r in _records(d)} == set(RECORDS)


def test_each_record_reads_as_the_dict_it_writes_in_the_old_key_order(diagnosis):
    for rec in _records(diagnosis):
        out = rec.to_dict()
        assert dict(rec) == out and rec == out and list(rec) == list(out) and len(rec) == len(out)
        assert all(rec[k] is out[k] or rec[k] == out[k] for k in out)
        keys = KEYS[type(rec)]
        if isinstance(rec, BaseCheck) and rec.train_starts is not None:
            keys = (*keys[:-1], "train_starts", "multistart")
        if isinstance(rec, CandidateRow) and rec.failed_fit is not None:  # issue 69: only where a fit failed
            keys = (*keys, "failed_fit")
        if isinstance(rec, TermRow) and not rec.refitted:  # every fit failed: as refit_row wrote it
            keys = (*keys[:8], "kept", "reason", "refitted_as")
        assert tuple(out) == keys, type(rec).__name__
        with pytest.raises(KeyError):
            rec["no such key"]


def test_to_dict_from_dict_to_dict_round_trips_through_json(diagnosis):
    for rec in _records(diagnosis):
        text = _text(rec.to_dict())
        back = type(rec).from_dict(json.loads(text))
        assert type(back) is type(rec)
        assert _text(back.to_dict()) == text
        assert list(back.to_dict()) == list(rec.to_dict())
        assert _text(pickle.loads(pickle.dumps(rec)).to_dict()) == text  # records travel to worker processes


def test_a_diagnosis_and_its_discovery_read_back_with_their_records(diagnosis):
    text = _text(diagnosis.to_dict())
    back = Diagnosis.from_dict(json.loads(text))
    assert isinstance(back.noise_floor, NoiseFloor) and isinstance(back.remainder, Remainder)
    assert isinstance(back.base_check, BaseCheck)
    assert isinstance(back.thresholds, Thresholds) and back.thresholds == diagnosis.thresholds
    with pytest.raises(ValueError, match=r"thresholds: unknown key\(s\) \['none_ration'\]"):
        Thresholds.from_dict({"none_ration": 1.5})
    assert all(isinstance(r, CandidateRow) for rnd in back.rounds for r in rnd)
    assert [r.effect for r in back.ranking] == [r.effect for r in diagnosis.ranking]
    assert _text(back.to_dict()) == text
    D = dv.Discovery.from_dict(json.loads(_text(diagnosis.discovered.to_dict())))
    assert all(isinstance(r, TermRow) for r in D.discovered)
    assert _text(D.to_dict()) == _text(diagnosis.discovered.to_dict())
    json.dumps(diagnosis.to_dict())  # plain JSON, no record left inside


def test_the_term_rows_shrinkage_is_written_twice_from_one_field(diagnosis):
    row = next(r for r in diagnosis.discovered.discovered if r.refitted)
    assert row["heldout_shrinkage"] == row["shrinkage"] == row.heldout_shrinkage == row.shrinkage
    assert "heldout_shrinkage" not in {f.name for f in dataclasses.fields(TermRow)}
    undecided = dataclasses.replace(row, kept=None, reason=None)
    assert "kept" not in undecided and "reason" not in undecided.to_dict()
    decided = decide(undecided, True, gap.Thresholds())
    assert decided is not undecided and (decided.kept, decided.reason) == (row.kept, row.reason)


def test_from_dict_names_unknown_and_missing_keys(diagnosis):
    raw = diagnosis.remainder.to_dict()
    with pytest.raises(ValueError, match=r"remainder: unknown key\(s\) \['significnat'\]"):
        Remainder.from_dict({**raw, "significnat": True})
    with pytest.raises(ValueError, match=r"candidate: missing key\(s\) \['effect'\]"):
        CandidateRow.from_dict({k: v for k, v in diagnosis.ranking[0].items() if k != "effect"})


def _documented(cls) -> set:
    """The names of the Parameters section of a class docstring (``name : type`` lines)."""
    doc = cls.__doc__.split("Parameters\n    ----------\n", 1)[1].split("\n    Notes\n", 1)[0]
    return set(re.findall(r"^    (\w+) : ", doc, flags=re.M))


@pytest.mark.parametrize("cls", RECORDS, ids=lambda c: c.__name__)
def test_every_field_of_a_record_is_documented(cls):
    # a field added without a docstring entry fails here
    names = {f.name for f in dataclasses.fields(cls)}
    assert _documented(cls) == names, f"{cls.__name__}: document {sorted(names - _documented(cls))}"
    for alias in cls._ALIASES:
        assert f"``{alias}``" in cls.__doc__, f"{cls.__name__}: document the alias {alias}"
    assert issubclass(cls, Record) and cls.__dataclass_params__.frozen


def test_a_term_row_of_another_shape_reads_back_as_the_dict_it_is(diagnosis):
    row = next(r for r in diagnosis.discovered.discovered if r.refitted).to_dict()
    assert isinstance(TermRow.read(row), TermRow)
    older = {k: v for k, v in row.items() if k not in ("refit_failed", "refitted_as")}  # before those existed
    assert TermRow.read(older) == older and type(TermRow.read(older)) is dict
    hand = {"term": "Nvvr", "dof": "N", "kept": True}
    assert TermRow.read(hand) == hand
