"""Monte-Carlo sweeps as tasks: serially, on a local Dask cluster, or on a cluster you have.

A sweep is a list of run specifications (JSON-able dicts with a unique ``"key"``) and a pure
top-level function ``run(spec) -> dict`` (seeds come from the spec, never from the worker's
state, so a run gives the same record wherever it runs). :func:`run_sweep` skips the specs
whose key is already in the JSONL log, executes the others, and appends each record to the
log as soon as it completes (one line, flushed): the log is the only state, so a sweep that
is killed half way continues where it stopped when started again.

Execution:

* ``workers=None, scheduler=None``: in this process, one run after the other;
* ``workers=N``: a :class:`distributed.LocalCluster` of N process workers, one thread each
  (one JAX process per worker; the persistent compilation cache ``CDPRID_CACHE_DIR`` is
  inherited, so each kernel compiles once per machine);
* ``scheduler="tcp://host:8786"``: an existing Dask cluster (``dask scheduler`` /
  ``dask worker``, or dask-jobqueue on SLURM/PBS; docs/cluster.md).

``dask`` and ``distributed`` are the optional extra ``pip install cdprid[cluster]``; the
serial path needs neither.
"""

from __future__ import annotations

import inspect
import json
import os
import time
from collections.abc import Callable
from pathlib import Path

from cdprid.base._errors import InputError

__all__ = ["load_log", "run_sweep"]


def load_log(path) -> dict:
    """Records of a JSONL log by key (a truncated last line, from a kill, is ignored).

    Parameters
    ----------
    path : path-like
        The JSONL log; a missing file is an empty log.

    Returns
    -------
    dict
        ``{key: record}`` of every parseable line that is a dict with a ``"key"``.
    """
    done = {}
    p = Path(path)
    if not p.exists():
        return done
    for line in p.read_text().splitlines():
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            continue
        if isinstance(rec, dict) and "key" in rec:
            done[rec["key"]] = rec
    return done


def _append(path: Path, rec: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    cut = False  # a last line cut by a kill: start on a new line
    if path.exists() and path.stat().st_size:
        with open(path, "rb") as fh:
            fh.seek(-1, os.SEEK_END)
            cut = fh.read(1) != b"\n"
    with open(path, "a") as fh:
        fh.write(("\n" if cut else "") + json.dumps(rec) + "\n")
        fh.flush()
        os.fsync(fh.fileno())


def _worker_path(run: Callable) -> None:
    """Local workers import ``run`` by module name: its module's folder goes on their path
    (a benchmark script's folder, a user's script's folder)."""
    try:
        here = str(Path(inspect.getsourcefile(run)).resolve().parent)
    except TypeError:
        return
    paths = [x for x in os.environ.get("PYTHONPATH", "").split(os.pathsep) if x]
    if here not in paths:
        os.environ["PYTHONPATH"] = os.pathsep.join([here, *paths])


def _client(workers: int | None, scheduler: str | None):
    try:
        from distributed import Client, LocalCluster
    except ImportError:  # pragma: no cover - depends on the environment
        raise InputError("running on a Dask cluster needs dask and distributed: "
                         "pip install 'cdprid[cluster]'.") from None
    if scheduler:
        try:
            return Client(scheduler, timeout=SCHEDULER_TIMEOUT_S), None
        except (OSError, TimeoutError, ValueError) as exc:  # unreachable, refused, bad address
            raise InputError(f"scheduler {scheduler!r}: cannot connect to a Dask scheduler there "
                             f"within {SCHEDULER_TIMEOUT_S:g} s ({type(exc).__name__}: "
                             f"{str(exc).splitlines()[0] if str(exc) else 'no detail'}); check "
                             "the address (tcp://host:8786) and that `dask scheduler` runs."
                             ) from None
    cluster = LocalCluster(n_workers=int(workers), threads_per_worker=1, processes=True,
                           dashboard_address=None)
    return Client(cluster), cluster


def _tagged(run: Callable, spec: dict) -> dict:
    """Run one spec and tag the record with its key (what the log is indexed by)."""
    return {**run(spec), "key": spec["key"]}


#: Seconds to wait for an existing Dask scheduler before giving up with one sentence.
SCHEDULER_TIMEOUT_S = 10.0


def _check_where(workers, scheduler) -> None:
    """Refuse, before anything starts, a worker count that is not a positive integer (a
    LocalCluster of -2 workers waited forever) and a scheduler address that is not text."""
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                or workers < 1):
        raise InputError(f"workers={workers!r}: give a positive number of local workers (or "
                         "None to run here).")
    if scheduler is not None and (not isinstance(scheduler, str) or not scheduler.strip()):
        raise InputError(f"scheduler={scheduler!r}: give the scheduler's address, e.g. "
                         "'tcp://host:8786'.")


def run_sweep(specs: list, run: Callable, log, workers: int | None = None,
              scheduler: str | None = None, progress: Callable | None = print) -> list:
    """Run every spec not yet in ``log``; returns the records of all specs, in spec order.

    Parameters
    ----------
    specs : list of dict
        Each JSON-able with a unique ``"key"``.
    run : callable
        A top-level (picklable) function ``spec -> dict`` (JSON-able).
    log : path
        The JSONL log (appended to; read first to skip what is done).
    workers : int, optional
        Start a local cluster of that many process workers (a positive integer).
    scheduler : str, optional
        Address of an existing Dask scheduler (overrides ``workers``); one that cannot be
        reached within :data:`SCHEDULER_TIMEOUT_S` is an :class:`~cdprid.base.InputError`.
    progress : callable, optional
        Called with one line per completed run (default ``print``; None is silent).

    Returns
    -------
    list of dict
        The record of every spec (from the log or this run), in spec order, each tagged
        with its ``"key"``.

    Raises
    ------
    InputError
        Repeated spec keys, a worker count below 1, or an unreachable scheduler.
    """
    _check_where(workers, scheduler)
    log = Path(log)
    keys = [s["key"] for s in specs]
    if len(set(keys)) != len(keys):
        raise InputError("run_sweep: the spec keys are not unique.")
    done = load_log(log)
    todo = [s for s in specs if s["key"] not in done]
    say = progress or (lambda _msg: None)
    say(f"sweep: {len(specs)} runs, {len(specs) - len(todo)} already in {log}, "
        f"{len(todo)} to run" + (f" on {scheduler}" if scheduler else
                                 f" on {workers} local workers" if workers else " here"))
    t0 = time.perf_counter()
    if todo and (workers or scheduler):
        from distributed import as_completed

        _worker_path(run)
        client, cluster = _client(workers, scheduler)
        try:
            futures = [client.submit(_tagged, run, s, key=f"cdprid-{s['key']}", pure=False)
                       for s in todo]
            for k, fut in enumerate(as_completed(futures), 1):
                rec = fut.result()
                _append(log, rec)
                done[rec["key"]] = rec
                say(f"[{time.perf_counter() - t0:7.1f} s] {k}/{len(todo)} {rec['key']}")
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    else:
        for k, s in enumerate(todo, 1):
            rec = _tagged(run, s)
            _append(log, rec)
            done[rec["key"]] = rec
            say(f"[{time.perf_counter() - t0:7.1f} s] {k}/{len(todo)} {rec['key']}")
    return [done[k] for k in keys if k in done]
