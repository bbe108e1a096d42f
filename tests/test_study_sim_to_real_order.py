"""studies/sim_to_real.py hands its cases to the workers longest first, by a previous run's journal
(the longest-processing-time rule), and reads a journal it cannot use as no hint at all."""

import json

from conftest import load_study

from bayesid.tasks import Task


def test_cases_without_a_previous_time_first_then_the_longest(tmp_path):
    study = load_study("sim_to_real")
    path = tmp_path / "journal.jsonl"
    lines = [{"journal": "bayesid", "version": 1, "identity": {}}]
    lines += [{"key": k, "params": {}, "result": {}, "seconds": s} for k, s in (("a", 5.0), ("b", 80.0), ("c", 20.0))]
    path.write_text("\n".join(json.dumps(x) for x in lines) + "\n" + '{"key": "torn', encoding="utf-8")
    took = study.previous_seconds(path)
    assert took == {"a": 5.0, "b": 80.0, "c": 20.0}
    tasks = [Task(k, {}, ()) for k in ("a", "b", "new", "c", "other")]
    assert [t.key for t in study.longest_first(tasks, took)] == ["new", "other", "b", "c", "a"]
    assert study.previous_seconds(tmp_path / "absent.jsonl") == {}
    assert [t.key for t in study.longest_first(tasks, {})] == ["a", "b", "new", "c", "other"]
