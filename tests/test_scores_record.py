"""Typed records (issue 51): the protocol's scores are a frozen ``Scores`` record that reads as the
JSON dict it writes, and reads back from that JSON."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from bayesid.protocol import Scores, pooled_scores
from bayesid.tasks import jsonable


def _errors():
    rng = np.random.default_rng(0)
    return [{"x": rng.normal(0, 0.3, 50), "y": rng.normal(0, 0.4, 50), "psi": rng.normal(0, 0.01, 50)}]


def test_pooled_scores_is_a_frozen_record_read_as_the_dict_it_writes():
    s = pooled_scores(_errors())
    assert isinstance(s, Scores)
    assert list(s) == ["rms", "rms_position_m", "max_position_m", "rms_heading_deg", "n_samples"]
    assert s["rms_position_m"] == s.rms_position_m == pytest.approx(0.5, rel=0.15)
    assert s.get("log_likelihood") is None and "log_likelihood" not in s
    with pytest.raises(KeyError):
        s["log_likelihood"]
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.rms_position_m = 0.0
    assert s == dict(s) and {**s} == s.to_dict()


def test_scores_read_back_from_their_json_with_non_finite_values():
    s = dataclasses.replace(
        pooled_scores([{"x": np.ones(4), "y": np.zeros(4)}]),
        per_track_rms_position_m={"run 1": 1.0},
        log_likelihood=-3.5,
    )
    assert np.isnan(s.rms_heading_deg)  # no heading logged
    text = json.dumps(jsonable(s), allow_nan=False)  # strict JSON: NaN as "nan"
    back = Scores.from_dict(json.loads(text))
    assert np.isnan(back.rms_heading_deg) and back.per_track_rms_position_m == {"run 1": 1.0}
    assert back.log_likelihood == -3.5 and back.rms == s.rms


def test_scores_from_a_dict_name_the_unknown_and_the_missing_keys():
    d = pooled_scores(_errors()).to_dict()
    with pytest.raises(ValueError, match=r"unknown key\(s\) \['rms_postion_m'\]"):
        Scores.from_dict({**d, "rms_postion_m": 1.0})
    with pytest.raises(ValueError, match=r"missing key\(s\) \['n_samples'\]"):
        Scores.from_dict({k: v for k, v in d.items() if k != "n_samples"})
