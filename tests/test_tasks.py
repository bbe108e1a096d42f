"""The task layer (issue 32): the same results serially, on loky workers and on a Dask
LocalCluster; a task that raises is reported with its parameters and the others finish; a journal
resumes finished tasks, survives a run killed mid-line and refuses another run's identity; a
worker that dies has its task run again."""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

import cloudpickle
import numpy as np
import pytest

from bayesid.tasks import Journal, Runner, Task, TaskError, check_jobs, digest, parse_scheduler, run_tasks

# the workers cannot import this test module by name: ship its functions by value
cloudpickle.register_pickle_by_value(sys.modules[__name__])


def work(x: int, fail: bool = False, log: str | None = None):
    """A deterministic task: some floating-point arithmetic on x (raises when ``fail``); appends x
    to ``log`` when given, so a test can see which tasks actually ran."""
    if log:
        with open(log, "a") as f:
            f.write(f"{x}\n")
    if fail:
        raise RuntimeError(f"cannot do {x}")
    rng = np.random.default_rng(x)
    a = rng.normal(size=(20, 20))
    return {
        "x": x,
        "value": float(np.linalg.eigvalsh(a @ a.T).max()),
        "vector": (a[0] / 3).tolist(),
        "nan": float("nan"),
    }


def die_once(x: int, marker: str):
    """Task 2 kills its worker process the first time it runs (the marker records it)."""
    time.sleep(0.2)
    if x == 2 and not os.path.exists(marker):
        Path(marker).write_text("died")
        os._exit(13)
    return {"x": x, "pid_ok": True}


def _tasks(n=6, failing=(), log=None):
    return [Task(f"t{i}", {"x": i}, (i, i in failing, log)) for i in range(n)]


def test_serial_and_loky_give_the_same_results_and_report_a_failing_task():
    serial = run_tasks(work, _tasks(failing={3}), Runner(jobs=1))
    loky = run_tasks(work, _tasks(failing={3}), Runner(jobs=2))
    assert isinstance(serial[3], TaskError) and isinstance(loky[3], TaskError)
    assert serial[3].params == {"x": 3} and "RuntimeError: cannot do 3" in str(loky[3]) and '"x": 3' in str(loky[3])
    assert "Traceback" in loky[3].traceback
    ok = [i for i in range(6) if i != 3]
    for i in ok:  # the others ran and agree to the last digit (NaN included)
        assert json.dumps(serial[i]) == json.dumps(loky[i])


def test_dask_local_cluster_gives_the_same_results():
    pytest.importorskip("distributed")
    serial = run_tasks(work, _tasks(4), Runner(jobs=1))
    dask = run_tasks(work, _tasks(4), Runner(scheduler="local:2"))
    assert [json.dumps(r) for r in serial] == [json.dumps(r) for r in dask]


def test_journal_resumes_and_equals_an_uninterrupted_run(tmp_path):
    log = tmp_path / "ran.txt"
    ident = {"data": digest([1, 2, 3]), "seed": 7}
    whole = run_tasks(work, _tasks(5, log=None), Runner(journal=Journal(tmp_path / "a.jsonl", ident)))
    # a run that stopped after three tasks, the third cut mid-line by a kill
    j = Journal(tmp_path / "b.jsonl", ident)
    run_tasks(work, _tasks(3, log=None), Runner(journal=j))
    text = (tmp_path / "b.jsonl").read_text()
    (tmp_path / "b.jsonl").write_text(text[:-25])
    resumed = run_tasks(work, _tasks(5, log=str(log)), Runner(journal=Journal(tmp_path / "b.jsonl", ident), jobs=2))
    assert sorted(int(v) for v in log.read_text().split()) == [2, 3, 4]  # 0 and 1 were not run again
    assert json.dumps(resumed) == json.dumps(whole)
    assert whole[0]["nan"] == "nan"  # results go through the journal's strict JSON
    lines = (tmp_path / "b.jsonl").read_text().splitlines()
    assert len(lines) == 6 and all(json.loads(s) for s in lines)


def test_journal_of_other_data_or_seed_is_refused(tmp_path):
    Journal(tmp_path / "j.jsonl", {"data": digest([1, 2]), "seed": 1})
    with pytest.raises(ValueError, match=r"j.jsonl.*seed: journal 1, this run 2"):
        Journal(tmp_path / "j.jsonl", {"data": digest([1, 2]), "seed": 2})
    with pytest.raises(ValueError, match="data"):
        Journal(tmp_path / "j.jsonl", {"data": digest([1, 3]), "seed": 1})
    (tmp_path / "k.jsonl").write_text("x,y\n1,2\n")
    with pytest.raises(ValueError, match="not a bayesid task journal"):
        Journal(tmp_path / "k.jsonl", {})


def test_a_journaled_key_with_other_parameters_is_refused(tmp_path):
    j = Journal(tmp_path / "j.jsonl", {"seed": 1})
    run_tasks(work, [Task("a", {"x": 1}, (1,))], Runner(journal=j))
    with pytest.raises(ValueError, match="task a was journaled with other parameters"):
        run_tasks(work, [Task("a", {"x": 2}, (2,))], Runner(journal=Journal(tmp_path / "j.jsonl", {"seed": 1})))


def test_a_lost_worker_loses_no_finished_task_and_its_task_runs_again(tmp_path):
    marker = str(tmp_path / "marker")
    j = Journal(tmp_path / "j.jsonl", {"seed": 0})
    out = run_tasks(die_once, [Task(f"t{i}", {"x": i}, (i, marker)) for i in range(6)], Runner(jobs=2, journal=j))
    assert Path(marker).exists()  # the worker did die
    assert out == [{"x": i, "pid_ok": True} for i in range(6)]
    assert len(Journal(tmp_path / "j.jsonl", {"seed": 0}).records) == 6


def test_options_are_checked_by_name():
    with pytest.raises(ValueError, match="--jobs must be at least 1"):
        check_jobs(0, None)
    for bad in ("local:0", "local:x", "myhost:8786", ""):
        with pytest.raises(ValueError, match="--scheduler"):
            check_jobs(1, bad)
    assert parse_scheduler("local:3") == ("local", 3)
    assert parse_scheduler("tcp://10.0.0.1:8786") == ("address", "tcp://10.0.0.1:8786")
    with pytest.raises(ValueError, match="repeat"):
        run_tasks(work, [Task("a", {}, (1,)), Task("a", {}, (2,))])
