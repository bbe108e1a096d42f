"""One message channel (issue 51): a labelled run of the task layer shows a tqdm bar on stderr when
its runner reports progress, run serially, on joblib's workers or on Dask, starting at the count a
journal already holds; the runner's messages are records of the ``bayesid`` logger; the ``bayesid``
logger set above INFO (``bayesid -q``) silences bars and messages, and the command leaves the
logger as it found it. ``bayesid fit --starts`` shows its bar of starts, and ``-q`` none."""

from __future__ import annotations

import json
import logging
import math

import pytest

from bayesid import cli
from bayesid.tasks import Journal, Runner, Task, run_tasks


def _roots(n=4):
    # math.sqrt: importable by name in the workers, and cheap
    return [Task(f"t{i}", {"x": i}, (float(i),)) for i in range(n)]


@pytest.fixture
def package_logger():
    """The ``bayesid`` logger, its level put back after the test."""
    logger = logging.getLogger("bayesid")
    old = logger.level
    yield logger
    logger.setLevel(old)


@pytest.mark.parametrize("where", [{"jobs": 1}, {"jobs": 2}], ids=["serial", "joblib"])
def test_a_labelled_run_shows_its_bar_on_stderr(where, capsys):
    out = Runner(**where, progress=True).run(math.sqrt, _roots(), label="roots")
    assert out == [math.sqrt(i) for i in range(4)]
    cap = capsys.readouterr()
    assert "roots" in cap.err and "4/4" in cap.err and "task" in cap.err
    assert cap.out == ""


def test_a_run_on_dask_shows_its_bar(capsys):
    pytest.importorskip("distributed")
    out = Runner(scheduler="local:1", progress=lambda m: None).run(math.sqrt, _roots(3), label="roots")
    assert out == [math.sqrt(i) for i in range(3)]
    err = capsys.readouterr().err
    assert "roots" in err and "3/3" in err


def test_no_bar_without_a_label_or_from_a_silent_runner(capsys):
    Runner(progress=True).run(math.sqrt, _roots())
    Runner(jobs=2).run(math.sqrt, _roots(), label="roots")
    assert capsys.readouterr().err == ""


def test_a_resumed_run_starts_its_bar_at_the_journaled_count(tmp_path, capsys):
    journal = Journal(tmp_path / "j.jsonl", {"what": "roots"})
    first = run_tasks(math.sqrt, _roots(2), Runner(journal=journal))
    assert capsys.readouterr().err == ""
    resumed = Runner(journal=Journal(tmp_path / "j.jsonl", {"what": "roots"}), progress=True)
    out = resumed.run(math.sqrt, _roots(4), label="roots")
    assert out[:2] == first and out == [math.sqrt(i) for i in range(4)]
    err = capsys.readouterr().err
    assert "2/4" in err and "4/4" in err and "0/4" not in err
    # everything journaled: nothing to run, no bar; the journal holds one line per task
    assert resumed.run(math.sqrt, _roots(4), label="roots") == out
    assert capsys.readouterr().err == ""
    lines = (tmp_path / "j.jsonl").read_text().splitlines()
    assert len(lines) == 5 and [json.loads(x)["key"] for x in lines[1:]] == ["t0", "t1", "t2", "t3"]


def test_messages_are_records_of_the_package_logger(caplog):
    with caplog.at_level(logging.INFO, logger="bayesid"):
        Runner(progress=True).say("base fit")
        Runner().say("not said: a silent runner")
    assert [(r.name, r.levelno, r.getMessage()) for r in caplog.records] == [
        ("bayesid.tasks", logging.INFO, "base fit")
    ]


def test_the_package_logger_above_info_silences_bars_and_messages(package_logger, capsys, caplog):
    heard = []
    package_logger.setLevel(logging.WARNING)
    for progress in (True, heard.append):
        runner = Runner(jobs=2, progress=progress)
        runner.say("starts")
        assert runner.bar("fit") is None
        assert runner.run(math.sqrt, _roots(), label="roots") == [math.sqrt(i) for i in range(4)]
    assert capsys.readouterr().err == "" and heard == [] and not caplog.records
    package_logger.setLevel(logging.NOTSET)  # nothing set: a runner asked for progress gives it
    Runner(progress=heard.append).say("starts")
    assert heard == ["starts"] and Runner(progress=True).bar("fit") == "fit"


def test_the_command_shows_the_package_records_on_stderr(package_logger, capsys):
    with cli._messages(logging.INFO):
        Runner(progress=True).say("multistart: 2 more start(s)")
        logging.getLogger("bayesid.tasks").debug("not shown")
        logging.getLogger("bayesid.tasks").warning("a worker was lost")
    with cli._messages(logging.WARNING):
        Runner(progress=True).say("not shown with -q")
    with cli._messages(logging.DEBUG):
        logging.getLogger("bayesid.tasks").debug("task t1 done")
    err = capsys.readouterr().err
    assert err == "  multistart: 2 more start(s)\nwarning: a worker was lost\ndebug: [bayesid.tasks] task t1 done\n"
    assert package_logger.level == logging.NOTSET and not package_logger.handlers


@pytest.fixture(scope="module")
def zigzag(tmp_path_factory):
    path = tmp_path_factory.mktemp("progress") / "z.csv"
    argv = ["simulate", "--vehicle", "nps_auv2", "--mode", "horizontal", "--manoeuvre", "zigzag", "--angle", "20"]
    assert cli.main([*argv, "--duration", "60", "--sample", "0.5", "--out", str(path)]) == 0
    return path


def _fit(zigzag, out, *first):
    fit = ["fit", "--vehicle", "nps_auv2", "--train", str(zigzag), "--starts", "2", "--max-nfev", "5"]
    return cli.main([*first, *fit, "--free", "Yv,Nr,Ndr", "--out", str(out)])


def test_fit_starts_shows_its_bar_and_quiet_hides_it(zigzag, tmp_path, capsys):
    capsys.readouterr()
    assert _fit(zigzag, tmp_path / "a") == 0
    cap = capsys.readouterr()
    assert "starts: 100%" in cap.err and "2/2" in cap.err
    assert "  multistart: 2 more start(s)" in cap.out
    assert _fit(zigzag, tmp_path / "b", "-q") == 0
    cap = capsys.readouterr()
    # the bar's label, not the word: a warning may name the output folder (this test's tmp_path holds "starts")
    assert "starts:" not in cap.err and "%|" not in cap.err and "multistart" not in cap.out
    assert "wrote" in cap.out  # the command's own result line stays
    a, b = (json.loads((tmp_path / d / "model.json").read_text()) for d in "ab")
    assert a["p"] == b["p"] and a["multistart"]["sorted_costs"] == b["multistart"]["sorted_costs"]
    assert logging.getLogger("bayesid").level == logging.NOTSET


def test_sample_and_diagnose_show_their_bars_and_quiet_hides_them(zigzag, tmp_path, capsys):
    """Issue 51: the task layer's bar shows in ``bayesid sample`` (the importance draws) and
    ``bayesid diagnose`` (each candidate's fit of round 1); ``-q`` hides both."""
    held = tmp_path / "z10.csv"
    argv = ["simulate", "--vehicle", "nps_auv2", "--mode", "horizontal", "--manoeuvre", "zigzag", "--angle", "10"]
    assert cli.main([*argv, "--duration", "60", "--sample", "0.5", "--out", str(held)]) == 0
    fit = ["fit", "--vehicle", "nps_auv2", "--train", str(zigzag), "--free", "Yv,Nr,Ndr", "--max-nfev", "5"]
    assert cli.main([*fit, "--out", str(tmp_path / "fit")]) == 0
    sample = ["sample", "--model", str(tmp_path / "fit" / "model.json"), "--train", str(zigzag)]
    sample += ["--method", "importance", "--draws", "100", "--max-minutes", "1"]
    diag = ["diagnose", "--vehicle", "nps_auv2", "--train", str(zigzag), "--heldout", str(held), "--free", "Yv,Nr"]
    diag += ["--candidates", "thrust", "--max-nfev", "3", "--no-design"]
    capsys.readouterr()
    assert cli.main([*sample, "--out", str(tmp_path / "s")]) == 0
    assert "importance draws: 100%" in capsys.readouterr().err
    assert cli.main([*diag, "--out", str(tmp_path / "d")]) == 0
    err = capsys.readouterr().err
    assert "round 1: thrust" in err and "%|" in err
    assert cli.main(["-q", *sample, "--out", str(tmp_path / "s2")]) == 0
    assert cli.main(["-q", *diag, "--out", str(tmp_path / "d2")]) == 0
    assert "%|" not in capsys.readouterr().err


def test_the_calibration_folds_show_their_bar_and_quiet_hides_it(zigzag, tmp_path, capsys):
    """Issue 51: the leave-one-run-out calibration of ``bayesid fit`` shows the task layer's bar."""
    runs = [str(zigzag)]
    for angle in ("10", "15"):
        path = tmp_path / f"z{angle}.csv"
        argv = ["simulate", "--vehicle", "nps_auv2", "--mode", "horizontal", "--manoeuvre", "zigzag", "--angle", angle]
        assert cli.main([*argv, "--duration", "60", "--sample", "0.5", "--out", str(path)]) == 0
        runs.append(str(path))
    fit = ["fit", "--vehicle", "nps_auv2", "--train", *runs, "--free", "Yv,Nr,Ndr", "--max-nfev", "5"]
    fit += ["--calibration", "loro", "--calibration-draws", "3"]
    capsys.readouterr()
    assert cli.main([*fit, "--out", str(tmp_path / "a")]) == 0
    cap = capsys.readouterr()
    assert "calibration: 100%" in cap.err and "3/3" in cap.err
    assert cli.main(["-q", *fit, "--out", str(tmp_path / "b")]) == 0
    assert "calibration:" not in capsys.readouterr().err  # (the file names may say calibration)
