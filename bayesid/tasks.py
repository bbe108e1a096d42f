"""Many independent tasks, one way to run them: serially, on joblib's reusable worker processes
(loky, ``--jobs N``), or on a Dask cluster through joblib's Dask backend (``--scheduler
tcp://HOST:PORT`` for an existing cluster, ``--scheduler local:N`` for a ``LocalCluster`` of N
worker processes); with a resumable journal of finished tasks.

Every command and study that runs independent tasks (the candidates of a gap diagnosis, the
starts of a multistart fit, the cases of a benchmark, the ensembles of a posterior) calls
:func:`run_tasks`. The function a task runs must be importable by name (a module-level
function of the package or of a study script), because workers are separate processes: they
import the package once and load the cached compiled kernels (``~/.cache/bayesid/kernels``)
the first time a model is simulated, then keep both for every later task.

Cores. Each worker process runs one task at a time, with BLAS on one thread in every mode
(threadpoolctl), so a task's numbers do not depend on where it ran: a multithreaded BLAS sums
in another order (measured: a serial run and a worker's differ at 1e-16 relative in ΔBIC). Its
numba kernels use ``threads`` threads
(default: the machine's cores divided by the local workers, so 2 workers on 2 cores use one
thread each and never oversubscribe). numba's ``workqueue`` threading layer (the package
default) must not be entered from two threads of one process at once, so
Dask workers are processes with one thread (``LocalCluster(processes=True,
threads_per_worker=1)``; start an external cluster's workers with ``--nthreads 1``), and a
process-wide lock makes a worker with several threads run its tasks one after another rather
than abort.

Journal (:class:`Journal`). With ``journal=`` each finished task is appended as one JSON line
(key, parameters, result, seconds) to a file in the output folder, flushed to disk before the
next result is taken. The first line records the run's identity (data digest, seed, settings): a
journal written under another identity is refused, naming what differs. A re-run skips the tasks
already in the journal and returns their stored results; a task lost with its worker (or with the
whole run) is simply run again, so the results equal those of an uninterrupted run. Results go
through JSON on the way in and on the way out, so a resumed result and a fresh one are the same
object, to the last digit.

Errors. A task that raises does not stop the others: it comes back as a :class:`TaskError`
holding its key, parameters and the worker's traceback; it is not journaled, so a re-run tries it
again.

Messages. What a step says while it runs goes through :meth:`Runner.say`: with
``Runner(progress=True)`` each message is an INFO record of the ``bayesid.tasks`` logger (the
package's loggers are ``logging.getLogger("bayesid")`` and its children; the library adds no
handler, the ``bayesid`` command puts one on stderr), with a callable it is passed to it. A runner
that reports progress also shows a tqdm bar on stderr over the tasks of a labelled run
(:meth:`Runner.run`), in this process as each result comes back, whichever way the tasks run.
The ``bayesid`` logger set above INFO (``bayesid -q``) silences both. Finished and resumed
tasks are DEBUG records (``bayesid -v``), a lost worker a WARNING.
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import os
import sys
import threading
import time
import traceback
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = [
    "Runner",
    "Task",
    "TaskError",
    "Journal",
    "run_tasks",
    "parse_scheduler",
    "check_jobs",
    "digest",
    "jsonable",
    "record_fields",
    "add_arguments",
    "parse_checked",
    "JOURNAL_VERSION",
]

#: Format version of a journal file's header.
JOURNAL_VERSION = 1

_log = logging.getLogger(__name__)

#: Help texts of the two options every command and study with many tasks takes.
JOBS_HELP = "worker processes for independent tasks (joblib, loky backend); 1 runs them in this process"
SCHEDULER_HELP = (
    "run the tasks on Dask instead: tcp://HOST:PORT for an existing cluster (workers started with "
    "--nthreads 1), local:N for a LocalCluster of N worker processes (needs pip install "
    "'bayesid[dask]')"
)


def add_arguments(parser, jobs_default: int = 1) -> None:
    """Add ``--jobs N`` and ``--scheduler ADDRESS`` to an argparse parser (commands and studies).

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The parser.
    jobs_default : int, default 1
        Default of ``--jobs``.
    """
    parser.add_argument("--jobs", type=int, default=jobs_default, help=JOBS_HELP)
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS", help=SCHEDULER_HELP)


def parse_checked(parser, argv=None):
    """``parser.parse_args(argv)`` with ``--jobs`` and ``--scheduler`` checked
    (:func:`check_jobs`): a bad value ends with the parser's usage error (exit code 2).

    Parameters
    ----------
    parser : argparse.ArgumentParser
        A parser with the options of :func:`add_arguments`.
    argv : list of str, optional
        The arguments; default ``sys.argv[1:]``.

    Returns
    -------
    argparse.Namespace
        The parsed arguments.
    """
    args = parser.parse_args(argv)
    try:
        check_jobs(args.jobs, args.scheduler)
    except ValueError as exc:
        parser.error(str(exc))
    return args


def record_fields(record: type, d: Mapping, what: str, skip=(), extra=()) -> dict:
    """The constructor arguments of dataclass ``record`` read from its JSON object ``d``: every key a
    field of ``record`` (but those in ``skip``, written only by the code), checked.

    Parameters
    ----------
    record : type
        A dataclass.
    d : Mapping
        The JSON object (``record.to_dict()`` as written).
    what : str
        The record's name in messages (``"diagnosis"``).
    skip : sequence of str
        Fields not in the JSON (models, caches); they keep their defaults.
    extra : sequence of str
        Keys of the JSON that are not fields (derived ones), ignored.

    Returns
    -------
    dict
        ``{field: value}`` for ``record(**...)``.

    Raises
    ------
    ValueError
        A key that is no field of ``record`` (nor in ``extra``), or a field without a default missing,
        named.
    """
    import dataclasses

    fs = [f for f in dataclasses.fields(record) if f.name not in skip]
    names = {f.name for f in fs}
    unknown = sorted(set(d) - names - set(extra))
    if unknown:
        raise ValueError(f"{what}: unknown key(s) {unknown}")
    required = [f.name for f in fs if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING]
    missing = sorted(n for n in required if n not in d)
    if missing:
        raise ValueError(f"{what}: missing key(s) {missing}")
    return {k: v for k, v in d.items() if k in names}


def jsonable(x):
    """``x`` with numpy arrays and scalars as Python lists and numbers, tuples as lists, keys as
    strings, and non-finite floats as the strings ``"nan"``, ``"inf"``, ``"-inf"`` (strict JSON).
    The one JSON form of the package: journals and report files.

    Parameters
    ----------
    x : object
        A nest of dicts, lists, tuples, numpy arrays and scalars.

    Returns
    -------
    object
        The JSON-able copy (other objects pass through unchanged).
    """
    if isinstance(x, Mapping):  # dicts and the records that read as one (protocol.Scores)
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, (np.floating, float)):
        x = float(x)
        return x if math.isfinite(x) else ("inf" if x > 0 else "-inf" if x < 0 else "nan")
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def _dumps(obj, sort_keys: bool = True) -> str:
    return json.dumps(jsonable(obj), sort_keys=sort_keys, separators=(",", ":"), allow_nan=False)


def digest(obj) -> str:
    """SHA-256 of an object's canonical JSON (:func:`jsonable`, sorted keys): a data digest for a
    journal's identity. Arrays are hashed by value: pass the data, not its file name.

    Parameters
    ----------
    obj : object
        What to hash (JSON-able through :func:`jsonable`).

    Returns
    -------
    str
        The hex digest.
    """
    return hashlib.sha256(_dumps(obj).encode()).hexdigest()


@dataclass(frozen=True)
class Task:
    """One independent task.

    Parameters
    ----------
    key : str
        Unique within a run; names the task in messages and in the journal.
    params : dict
        JSON-able description of the task (stored in the journal, printed when the task fails;
        a journaled task is matched by key *and* params).
    args : tuple, default ()
        Passed to the task function after nothing else: ``fn(*args)``. It may hold large
        objects (tracks, models); it is pickled to the worker, never stored.
    """

    key: str
    params: dict = field(default_factory=dict)
    args: tuple = ()


@dataclass
class TaskError:
    """A task that raised. Returned in the task's place by :func:`run_tasks`.

    Parameters
    ----------
    key : str
        The task's key.
    params : dict
        Its parameters.
    error : str
        The exception as text.
    traceback : str, default ""
        The worker's traceback.
    """

    key: str
    params: dict
    error: str
    traceback: str = ""

    def __str__(self) -> str:
        return f"task {self.key} {json.dumps(jsonable(self.params))} failed: {self.error}"


class Journal:
    """Append-only JSON-lines record of finished tasks (one file in an output folder).

    Line 1: ``{"journal": "bayesid", "version": 1, "identity": {...}}``; then one line per
    finished task: ``{"key", "params", "result", "seconds"}``. A last line cut short by a killed
    run is dropped when the file is opened (the task runs again).

    Parameters
    ----------
    path : str or Path
        The file (created with its folder when absent).
    identity : dict
        JSON-able: what the results depend on besides each task's parameters (data digest, seed,
        settings, code version of the design).

    Raises
    ------
    ValueError
        The file is not a journal (or of another version), a line other than the last is not
        JSON, or the file was written under another identity (the message names the file and the
        keys that differ).
    """

    def __init__(self, path, identity: dict):
        self.path = Path(path)
        self.identity = json.loads(_dumps(identity))
        self.records: dict[str, dict] = {}
        if self.path.exists() and self.path.stat().st_size > 0:
            self._load()
        else:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            with open(self.path, "w", encoding="utf-8") as f:
                f.write(_dumps({"journal": "bayesid", "version": JOURNAL_VERSION, "identity": self.identity}) + "\n")
                f.flush()
                os.fsync(f.fileno())

    def _load(self) -> None:
        text = self.path.read_text(encoding="utf-8")
        lines = text.split("\n")
        try:
            head = json.loads(lines[0])
            assert head.get("journal") == "bayesid"
        except (ValueError, AssertionError, AttributeError):
            raise ValueError(f"{self.path}: not a bayesid task journal (line 1)") from None
        if head.get("version") != JOURNAL_VERSION:
            raise ValueError(
                f"{self.path}: journal version {head.get('version')}, this bayesid writes "
                f"{JOURNAL_VERSION}; use another output folder"
            )
        old = head.get("identity", {})
        if old != self.identity:
            # nested identities (an options object's fields) are compared field by field
            was, now = _flat(old), _flat(self.identity)
            keys = sorted(k for k in set(was) | set(now) if was.get(k) != now.get(k))
            what = "; ".join(
                f"{k}: journal {json.dumps(was.get(k))[:80]}, this run {json.dumps(now.get(k))[:80]}" for k in keys
            )
            raise ValueError(
                f"{self.path}: written by a run with other inputs ({what}); its results do not "
                "apply. Use another output folder, or start over (--fresh where offered)"
            )
        body = lines[1:]
        if body and body[-1] == "":
            body = body[:-1]
        torn = False
        for i, line in enumerate(body):
            try:
                rec = json.loads(line)
            except ValueError:
                if i == len(body) - 1:  # cut short by a killed run: that task runs again
                    torn = True
                    break
                raise ValueError(f"{self.path}: line {i + 2} is not JSON (edited?)") from None
            self.records[rec["key"]] = rec
        if torn or (text and not text.endswith("\n")):
            keep = [lines[0]] + body[: len(body) - 1 if torn else len(body)]
            tmp = self.path.with_suffix(self.path.suffix + ".tmp")
            tmp.write_text("\n".join(keep) + "\n", encoding="utf-8")
            os.replace(tmp, self.path)

    def get(self, task: Task):
        """The stored record of a task.

        Parameters
        ----------
        task : Task
            The task.

        Returns
        -------
        dict or None
            The record (with ``result``), or None when the task has not finished.

        Raises
        ------
        ValueError
            When the key was journaled with other parameters.
        """
        rec = self.records.get(task.key)
        if rec is None:
            return None
        if rec["params"] != json.loads(_dumps(task.params)):
            raise ValueError(
                f"{self.path}: task {task.key} was journaled with other parameters "
                f"({json.dumps(rec['params'])[:200]}); use another output folder or start over"
            )
        return rec

    def add(self, task: Task, result, seconds: float) -> dict:
        """Append a finished task (flushed and synced).

        Parameters
        ----------
        task : Task
            The task.
        result : object
            Its JSON-able result.
        seconds : float
            Its run time, s.

        Returns
        -------
        dict
            Its record as read back (``key``, ``params``, ``result``, ``seconds``).
        """
        # the result keeps its key order (reports are built from it)
        line = _dumps({"key": task.key, "params": task.params, "result": result, "seconds": seconds}, sort_keys=False)
        with open(self.path, "a", encoding="utf-8") as f:
            f.write(line + "\n")
            f.flush()
            os.fsync(f.fileno())
        rec = json.loads(line)
        self.records[task.key] = rec
        return rec


def _flat(d, prefix: str = "") -> dict:
    """``{"a": {"b": 1}}`` as ``{"a.b": 1}``: the fields of a nested identity by dotted name."""
    out = {}
    for k, v in d.items():
        if isinstance(v, dict) and v:
            out.update(_flat(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def check_jobs(jobs, scheduler, option_jobs: str = "--jobs", option_scheduler: str = "--scheduler") -> None:
    """Check the worker options.

    Parameters
    ----------
    jobs : int
        Worker processes.
    scheduler : str or None
        Dask scheduler option.
    option_jobs : str, default "--jobs"
        Name of the jobs option in messages.
    option_scheduler : str, default "--scheduler"
        Name of the scheduler option in messages.

    Raises
    ------
    ValueError
        Naming the option for ``jobs < 1`` or a scheduler address that is neither ``local:N``
        (N >= 1) nor ``tcp://HOST:PORT`` / another Dask address with ``://``.
    """
    if int(jobs) < 1:
        raise ValueError(f"{option_jobs} must be at least 1, not {jobs}")
    if scheduler is not None:
        parse_scheduler(scheduler, option_scheduler)


def parse_scheduler(text: str, option: str = "--scheduler") -> tuple[str, object]:
    """Parse a scheduler option.

    Parameters
    ----------
    text : str
        ``local:N`` or a Dask address with a protocol (``tcp://HOST:PORT``).
    option : str, default "--scheduler"
        Name of the option in messages.

    Returns
    -------
    tuple
        ``("local", N)`` for ``local:N`` or ``("address", text)`` for an address.

    Raises
    ------
    ValueError
        Naming the option for anything else.
    """
    text = str(text).strip()
    if text.startswith("local:"):
        try:
            n = int(text[6:])
        except ValueError:
            n = 0
        if n < 1:
            raise ValueError(f"{option} {text}: local:N needs a whole number of workers N >= 1")
        return "local", n
    if "://" in text and text.split("://", 1)[1]:
        return "address", text
    raise ValueError(f"{option} {text}: give tcp://HOST:PORT (an existing Dask scheduler) or local:N")


# numba's workqueue layer: one parallel kernel per process at a time; re-entrant, since a task may
# run tasks of its own in this process (a study case that runs a diagnosis)
_LOCK = threading.RLock()


class _Call:
    """The picklable wrapper a worker runs: sets numba's threads, runs the task, and returns
    (index, "ok", result, seconds) or (index, "error", message, traceback) instead of raising."""

    def __init__(self, fn: Callable, threads: int | None):
        self.fn, self.threads = fn, threads

    def __call__(self, i: int, args: tuple):
        from threadpoolctl import threadpool_limits

        t0 = time.perf_counter()
        # BLAS on one thread in every mode: a multithreaded BLAS sums in another order, and the
        # serial run (2 BLAS threads) would differ from a worker's (1) in the last digits
        with _LOCK, threadpool_limits(limits=1, user_api="blas"):
            try:
                if self.threads:
                    import numba

                    from ._numba import use_package_threading_layer

                    use_package_threading_layer()
                    numba.set_num_threads(max(1, min(int(self.threads), numba.config.NUMBA_NUM_THREADS)))
                out = self.fn(*args)
            except Exception as exc:  # noqa: BLE001 - reported with the task's parameters, others go on
                return i, "error", f"{type(exc).__name__}: {exc}", traceback.format_exc()
        return i, "ok", out, time.perf_counter() - t0


def _lost_worker_errors() -> tuple:
    errs = []
    try:
        from joblib.externals.loky.process_executor import TerminatedWorkerError

        errs.append(TerminatedWorkerError)
    except ImportError:  # pragma: no cover
        pass
    try:
        from distributed import KilledWorker

        errs.append(KilledWorker)
    except ImportError:
        pass
    from concurrent.futures.process import BrokenProcessPool

    errs.append(BrokenProcessPool)
    return tuple(errs)


def _dask_client(scheduler: str):
    """A distributed Client for ``local:N`` (a LocalCluster of N one-thread worker processes,
    closed with the client) or an existing scheduler address."""
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise ValueError(
            f"--scheduler {scheduler}: Dask is not installed; pip install 'bayesid[dask]' "
            "(or -e '.[dask]' in a checkout)"
        ) from None
    kind, val = parse_scheduler(scheduler)
    if kind == "local":
        cluster = LocalCluster(n_workers=val, threads_per_worker=1, processes=True, dashboard_address=None)
        return Client(cluster), cluster
    try:
        return Client(val, timeout=30), None
    except OSError as exc:
        raise ValueError(f"--scheduler {val}: cannot connect ({exc})") from None


def _quiet() -> bool:
    """Whether the package's progress is turned off: the ``bayesid`` logger (or a child of it on
    the way to ``bayesid.tasks``) set above INFO (``bayesid -q``), or logging disabled at INFO.
    The root logger does not count: a program that configured no logging and asked a runner for
    progress keeps its bars."""
    if logging.root.manager.disable >= logging.INFO:
        return True
    lg = _log
    while lg is not None and (lg.name == "bayesid" or lg.name.startswith("bayesid.")):
        if lg.level != logging.NOTSET:
            return lg.level > logging.INFO
        lg = lg.parent
    return False


@dataclass(frozen=True)
class Runner:
    """How a step runs its independent tasks, and where it reports its progress: the one object
    passed where parallel work happens (as emcee's ``pool`` or pyPESTO's ``Engine``).

    Parameters
    ----------
    jobs : int, default 1
        Worker processes (joblib's loky backend) when ``scheduler`` is None; 1 runs the tasks in
        this process.
    scheduler : str, optional
        ``"local:N"`` or a Dask scheduler address (:func:`run_tasks`).
    journal : Journal, optional
        The resumable record of finished tasks of the run.
    progress : bool or callable, optional
        Where the step's progress messages go (:meth:`say`): True, INFO records of the
        ``bayesid.tasks`` logger (the ``bayesid`` command shows them on stderr; a program sees
        them once it configures logging, ``logging.basicConfig(level=logging.INFO)``); a
        callable, ``progress(message)`` (a study that writes its own lines). When it is set,
        long loops also show tqdm bars on stderr. None: silent. The ``bayesid`` logger set above
        INFO (``bayesid -q``) silences messages and bars alike.

    Raises
    ------
    ValueError
        ``jobs < 1`` or a malformed scheduler (:func:`check_jobs`).
    """

    jobs: int = 1
    scheduler: str | None = None
    journal: Journal | None = None
    progress: Callable[[str], None] | bool | None = None

    def __post_init__(self):
        check_jobs(self.jobs, self.scheduler)

    def _reports(self) -> bool:
        return self.progress is not None and self.progress is not False and not _quiet()

    def say(self, message: str) -> None:
        """Report a progress message: an INFO record of the ``bayesid.tasks`` logger, or the
        runner's callable's (nothing when the runner is silent or the ``bayesid`` logger is set
        above INFO).

        Parameters
        ----------
        message : str
            The message.
        """
        if not self._reports():
            return
        if callable(self.progress):
            self.progress(message)
        else:
            _log.info(message)

    def bar(self, label: str) -> str | None:
        """The label of a progress bar (tqdm, on stderr).

        Parameters
        ----------
        label : str
            The label.

        Returns
        -------
        str or None
            ``label``, or None when the runner reports no progress (silent, or the ``bayesid``
            logger set above INFO).
        """
        return label if self._reports() else None

    def where(self) -> str:
        """Where the tasks run, for messages.

        Returns
        -------
        str
            The scheduler, or ``"N worker(s)"``.
        """
        return self.scheduler or f"{self.jobs} worker(s)"

    def run(self, fn: Callable, tasks: Sequence[Task], *, label: str | None = None, on_done=None) -> list:
        """:func:`run_tasks` with this runner's workers, journal and progress.

        Parameters
        ----------
        fn : callable
            Module-level task function.
        tasks : sequence of Task
            The tasks.
        label : str, optional
            Label of a tqdm bar over the tasks on stderr, shown when the runner reports progress
            (:meth:`bar`) and some task is not journaled yet.
        on_done : callable, optional
            ``on_done(task, result_or_TaskError, seconds)`` as each new task finishes.

        Returns
        -------
        list
            One result (or :class:`TaskError`) per task, in task order.
        """
        return run_tasks(fn, tasks, self, on_done=on_done, bar=self.bar(label) if label else None)


def run_tasks(
    fn: Callable,
    tasks: Sequence[Task],
    runner: Runner = Runner(),
    *,
    threads: int | None = None,
    on_done: Callable | None = None,
    retries: int = 2,
    bar: str | None = None,
) -> list:
    """Run ``fn(*task.args)`` for every task; return the results in task order.

    Parameters
    ----------
    fn : callable
        Module-level function (importable by the workers); its result must be JSON-able
        (:func:`jsonable`) when a journal is given.
    tasks : sequence of Task
        The tasks (unique keys; ValueError otherwise).
    runner : Runner, default Runner()
        ``jobs`` worker processes (joblib's loky backend) when its ``scheduler`` is None (1 runs
        the tasks in this process, one after another), or a ``scheduler`` (``"local:N"`` or a
        Dask scheduler address ``tcp://HOST:PORT``: the tasks run on Dask through joblib's Dask
        backend, ``jobs`` then ignored); its ``journal`` of the run: finished tasks are skipped
        and their stored results returned, every newly finished task is appended before the
        next result is taken. Its progress reporter is not used here: ``bar`` labels a bar
        (:meth:`Runner.run` passes its label when the runner reports progress).
    threads : int, optional
        Numba threads per task (default: cores // local workers; on an external cluster numba's
        own default).
    on_done : callable, optional
        ``on_done(task, result_or_TaskError, seconds)``, called in this process as each new task
        finishes (not for journaled ones).
    retries : int, default 2
        Times the remaining tasks are resubmitted after a worker process died (a killed or
        crashed worker fails every task it held; they run again).
    bar : str, optional
        Label of a tqdm progress bar over the tasks on stderr, advanced in this process as each
        result comes back (serially, from joblib's workers or from Dask's), starting at the
        journaled count; None, or nothing left to run: no bar.

    Returns
    -------
    list
        One entry per task: its result (read back through JSON when journaled, so a resumed and
        a fresh run return equal objects) or a :class:`TaskError`.

    Raises
    ------
    ValueError
        Duplicate keys, a malformed scheduler address, Dask missing or unreachable, a journal of
        another run (:class:`Journal`).
    """
    tasks = list(tasks)
    keys = [t.key for t in tasks]
    if len(set(keys)) != len(keys):
        raise ValueError(f"task keys repeat: {sorted({k for k in keys if keys.count(k) > 1})}")
    jobs, scheduler, journal = runner.jobs, runner.scheduler, runner.journal
    out: list = [None] * len(tasks)
    todo = []
    for i, t in enumerate(tasks):
        rec = journal.get(t) if journal is not None else None
        if rec is not None:
            out[i] = rec["result"]
        else:
            todo.append(i)
    if len(todo) < len(tasks):
        _log.debug("%d of %d tasks from the journal %s", len(tasks) - len(todo), len(tasks), journal.path)
    label, bar = bar, None
    if label is not None and todo:
        from tqdm import tqdm

        bar = tqdm(total=len(tasks), initial=len(tasks) - len(todo), desc=label, unit="task", file=sys.stderr)

    def finish(i, status, payload, extra):
        t = tasks[i]
        if status == "ok":
            res = journal.add(t, payload, extra)["result"] if journal is not None else payload
            secs = extra
            _log.debug("task %s done in %.2f s", t.key, secs)
        else:
            res, secs = TaskError(t.key, t.params, payload, extra), float("nan")
            _log.debug("task %s failed: %s", t.key, payload)
        out[i] = res
        if bar is not None:
            bar.update(1)
        if on_done is not None:
            on_done(t, res, secs)

    try:
        if scheduler is None and int(jobs) == 1:
            call = _Call(fn, threads)
            for i in todo:
                finish(*call(i, tasks[i].args))
        else:
            _run_parallel(fn, tasks, todo, jobs, scheduler, threads, finish, retries)
    finally:
        if bar is not None:
            bar.close()
    return out


def _run_parallel(fn, tasks, todo, jobs, scheduler, threads, finish, retries) -> None:
    import joblib

    client = cluster = None
    if scheduler is not None:
        client, cluster = _dask_client(scheduler)
        if threads is None and cluster is not None:
            threads = max(1, (os.cpu_count() or 1) // len(cluster.workers))
        # the backend uses this client (one it made itself would outlive the cluster and retry for 30 s)
        config = joblib.parallel_config(backend="dask", client=client)
        n_jobs = -1
    else:
        threads = threads or max(1, (os.cpu_count() or 1) // int(jobs))
        config = joblib.parallel_config(backend="loky", inner_max_num_threads=threads)
        n_jobs = int(jobs)
    call = _Call(fn, threads)
    lost = _lost_worker_errors()
    pending = list(todo)
    try:
        for attempt in range(int(retries) + 1):
            done = set()
            try:
                with config:
                    gen = joblib.Parallel(n_jobs=n_jobs, return_as="generator_unordered", batch_size=1)(
                        joblib.delayed(call)(i, tasks[i].args) for i in pending
                    )
                    for i, status, payload, extra in gen:
                        done.add(i)
                        finish(i, status, payload, extra)
                return
            except lost as exc:
                pending = [i for i in pending if i not in done]
                _log.warning(
                    "a worker was lost (%s); %s",
                    type(exc).__name__,
                    f"{len(pending)} task(s) run again" if attempt < int(retries) else "its tasks fail",
                )
                if attempt == int(retries):
                    for i in pending:
                        finish(i, "error", f"worker lost ({type(exc).__name__}: {exc})", "")
                    return
    finally:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
