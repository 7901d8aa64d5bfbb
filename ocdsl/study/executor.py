"""One engine for every multi-solve feature: serial, local processes, or a Dask cluster.

Sweeps, multi-starts, Monte Carlo, Pareto points and PSO swarms all submit picklable
tasks here. Three back ends behind one small interface (:class:`Executor`):

- ``serial``: in this process, one task at a time (debugging, tiny studies);
- ``processes`` (default): a :class:`concurrent.futures.ProcessPoolExecutor` of
  persistent worker processes started through a ``forkserver`` that has already imported
  ocdsl, so process start and imports are paid once per worker, never per task. A worker
  that dies (segfault, OOM) breaks the pool: the pool is rebuilt and the lost tasks are
  resubmitted (a task that kills its worker twice fails with :class:`WorkerLost`);
- ``dask``: an existing ``distributed`` cluster (``scheduler="tcp://HOST:PORT"``) or a
  ``distributed.Client`` object. Dask reschedules the tasks of a lost worker itself.

Per-worker state (the built problem, a compiled integrator) goes through
:func:`worker_cache`, a module-level cache that lives as long as the worker process, so
model build is also paid once per worker.
"""
from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
import socket
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable

from .spec import StudyError

# --------------------------------------------------------------------------------------
# per-worker cache
# --------------------------------------------------------------------------------------
_CACHE: dict[Any, Any] = {}
_CACHE_LOCK = threading.Lock()
_CACHE_STATS = {"builds": 0, "hits": 0, "build_s": 0.0}
_KEY_LOCKS: dict[Any, threading.Lock] = {}


def worker_cache(key: Any, build: Callable[[], Any], max_items: int = 8) -> Any:
    """Return ``build()`` cached under ``key`` in this (worker) process.

    Keys should say what makes the value stale, e.g. ``("problem", path, mtime_ns, size)``.
    Thread-safe (Dask workers may run several threads); at most ``max_items`` values are
    kept (oldest dropped)."""
    with _CACHE_LOCK:
        if key in _CACHE:
            _CACHE_STATS["hits"] += 1
            return _CACHE[key]
        lock = _KEY_LOCKS.setdefault(key, threading.Lock())
    with lock:
        with _CACHE_LOCK:
            if key in _CACHE:
                _CACHE_STATS["hits"] += 1
                return _CACHE[key]
        t0 = time.perf_counter()
        value = build()
        dt = time.perf_counter() - t0
        with _CACHE_LOCK:
            _CACHE[key] = value
            _CACHE_STATS["builds"] += 1
            _CACHE_STATS["build_s"] += dt
            while len(_CACHE) > max_items:
                _CACHE.pop(next(iter(_CACHE)))
    return value


def cache_stats() -> dict[str, float]:
    with _CACHE_LOCK:
        return dict(_CACHE_STATS)


def worker_info() -> dict[str, Any]:
    """Host and pid of the process running a task (recorded in the study table)."""
    return {"host": socket.gethostname(), "pid": os.getpid()}


def _noop(x: Any = None) -> dict[str, Any]:
    return {**worker_info(), "x": x}


# --------------------------------------------------------------------------------------
# executor
# --------------------------------------------------------------------------------------
class WorkerLost(RuntimeError):
    """The worker process running a task died: for local processes, when the task ran
    alone after a pool break; on a cluster, Dask's ``allowed-failures`` times."""


@dataclass(eq=False)
class Handle:
    """A submitted task. ``result()`` returns its value or raises its exception."""

    fn: Callable
    args: tuple
    fut: Any = None
    attempts: int = 1
    key: str | None = None
    isolated: bool = False
    _ex: "Executor | None" = field(default=None, repr=False)

    def done(self) -> bool:
        return self.fut is not None and self.fut.done()

    def result(self) -> Any:
        return self._ex._result(self)


def default_workers() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


OWNER_POLL_S = 1.0


def _exit_with_owner(owner: int, started: str | None = None) -> None:
    """Worker initializer: end this worker when the process that owns the pool is gone.

    A worker's parent is the fork server, not the study process, so a study killed with
    SIGKILL (no shutdown) left its idle workers, and with them the fork server, running
    for good (measured: a forkserver and two workers per killed study, still there an hour
    later). A daemon thread polls the owner and exits the worker once it is gone: no longer
    there, a zombie (killed but not reaped by its parent: ``os.kill(pid, 0)`` still succeeds
    on one, and the workers held the caller's pipes open), or its pid reused by a process
    that started at another time (``started``, from /proc where there is one)."""
    def watch() -> None:
        while True:
            time.sleep(OWNER_POLL_S)
            if not owner_alive(owner, started):
                os._exit(0)

    threading.Thread(target=watch, name="ocdsl-owner-watch", daemon=True).start()


def process_start(pid: int) -> str | None:
    """The start time of ``pid`` (clock ticks after boot, /proc/PID/stat field 22), or None
    where there is no /proc."""
    fields = _proc_stat(pid)
    return fields[19] if fields else None


def _proc_stat(pid: int) -> list[str] | None:
    """The fields of /proc/PID/stat after the command name (state first), or None."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return text[text.rindex(")") + 2:].split()


def owner_alive(pid: int, started: str | None = None) -> bool:
    """Whether ``pid`` is a live process (not a zombie; the same process when ``started``)."""
    if Path("/proc/self/stat").exists():
        fields = _proc_stat(pid)
        if fields is None or fields[0] in ("Z", "X", "x"):
            return False
        return started is None or fields[19] == started
    try:            # no /proc: a zombie cannot be told from a live process here
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:   # alive, another user's
        pass
    return True


class Executor:
    """``Executor(workers=None, serial=False, scheduler=None)``; a context manager.

    ``kind`` is ``serial``, ``processes`` or ``dask``; ``workers`` the number of task
    slots. ``submit(fn, *args)`` returns a :class:`Handle`; ``wait(handles, timeout)``
    returns ``(done, not_done)`` as soon as one is done; ``map(fn, items)`` runs a batch
    and returns the results in order (PSO swarms, Pareto scans)."""

    # imported once in the fork server (only our own light modules: an import error in a
    # preloaded module would take the server down); heavy imports (Pyomo, SymPy) happen at
    # a worker's first task and stay for its life.
    PRELOAD = ["ocdsl.study.run", "ocdsl.study.demo"]

    def __init__(self, workers: int | None = None, serial: bool = False,
                 scheduler: Any = None, connect_timeout: float = 3.0):
        if workers is not None and workers < 1:
            raise StudyError(f"--workers must be at least 1 (got {workers})")
        self._client = None
        self._own_client = False
        self._pool: cf.ProcessPoolExecutor | None = None
        self._inflight: set[Handle] = set()   # submitted to the pool
        self._suspects: list[Handle] = []     # in the pool when it broke; re-run alone
        self._suspect: Handle | None = None   # the one running alone now
        self._held: list[Handle] = []         # submitted while isolating suspects
        self.scheduler = None
        if scheduler is not None and serial:
            raise StudyError("--serial and --scheduler exclude each other")
        if serial:
            self.kind, self.workers = "serial", 1
        elif scheduler is not None:
            self.kind = "dask"
            self._connect(scheduler, connect_timeout)
            self.workers = self._dask_slots()
        else:
            self.kind = "processes"
            self.workers = workers or default_workers()
            self._start_pool()

    # ---- set-up ----------------------------------------------------------------------
    def _connect(self, scheduler: Any, timeout: float) -> None:
        from distributed import Client
        if isinstance(scheduler, Client):
            self._client, self.scheduler = scheduler, scheduler.scheduler.address
            return
        addr = str(scheduler)
        if "://" not in addr:
            addr = "tcp://" + addr
        proto, _, rest = addr.partition("://")
        host, _, port = rest.rpartition(":")
        if proto not in ("tcp", "tls", "inproc", "ws", "wss", "ucx") or not host or not port.isdigit():
            raise StudyError(f"bad scheduler address {scheduler!r}: expected tcp://HOST:PORT")
        try:
            self._client = Client(addr, timeout=timeout, set_as_default=False)
        except (OSError, TimeoutError) as exc:
            raise StudyError(f"cannot reach the Dask scheduler at {addr} within {timeout:g} s "
                             f"({type(exc).__name__}: {exc}); start it with `dask scheduler` "
                             "and check the address") from None
        self._own_client = True
        self.scheduler = addr

    def _dask_slots(self) -> int:
        try:
            info = self._client.scheduler_info()
            return max(1, sum(w.get("nthreads", 1) for w in info.get("workers", {}).values()))
        except Exception:  # pragma: no cover
            return 1

    def _start_pool(self) -> None:
        ctx = multiprocessing.get_context("forkserver")
        # modules imported once in the fork server, inherited by every worker it forks
        ctx.set_forkserver_preload(self.PRELOAD)
        self._pool = cf.ProcessPoolExecutor(max_workers=self.workers, mp_context=ctx,
                                            initializer=_exit_with_owner,
                                            initargs=(os.getpid(), process_start(os.getpid())))

    # ---- tasks -----------------------------------------------------------------------
    @property
    def capacity(self) -> int:
        """How many tasks to keep in flight so that no slot idles."""
        if self.kind == "serial":
            return 1
        if self.kind == "dask":
            self.workers = self._dask_slots()
            return max(2, 2 * self.workers)
        return self.workers + 1

    def submit(self, fn: Callable, *args: Any, key: str | None = None) -> Handle:
        h = Handle(fn, args, key=key, _ex=self)
        if self.kind == "processes":
            self._check_broken()
        if self.kind == "processes" and (self._suspects or self._suspect is not None):
            self._held.append(h)  # isolating the culprit of a pool break: wait
        else:
            h.fut = self._submit_raw(fn, args, key)
            if self.kind == "processes":
                self._inflight.add(h)
        return h

    def _submit_raw(self, fn: Callable, args: tuple, key: str | None) -> Any:
        if self.kind == "serial":
            fut: cf.Future = cf.Future()
            try:
                fut.set_result(fn(*args))
            except BaseException as exc:  # noqa: BLE001 - handed back to the caller
                if isinstance(exc, KeyboardInterrupt):
                    raise
                fut.set_exception(exc)
            return fut
        if self.kind == "processes":
            return self._pool.submit(fn, *args)
        kw = {"pure": False}
        if key:
            kw["key"] = key
        return self._client.submit(fn, *args, **kw)

    def wait(self, handles: Iterable[Handle], timeout: float | None = None
             ) -> tuple[set[Handle], set[Handle]]:
        handles = list(handles)
        if not handles:
            return set(), set()
        if self.kind == "processes":
            self._check_broken()
            self._pump()
        by_fut = {h.fut: h for h in handles if h.fut is not None}
        if not by_fut:  # all held back (cannot happen while the caller waits on a suspect)
            time.sleep(min(timeout or 0.05, 0.05))
            return set(), set(handles)
        if self.kind == "dask":
            from distributed import wait as dwait
            try:
                with self._client.as_current():  # our client need not be the default one
                    res = dwait(list(by_fut), timeout=timeout, return_when="FIRST_COMPLETED")
                done_f = res.done
            except TimeoutError:
                done_f = {f for f in by_fut if f.done()}
        else:
            done_f, _ = cf.wait(list(by_fut), timeout=timeout, return_when=cf.FIRST_COMPLETED)
        done = {by_fut[f] for f in done_f}
        if self.kind == "processes":
            self._check_broken()
            self._pump()
            done = {h for h in handles if h.done()}
        return done, set(handles) - done

    def _check_broken(self) -> None:
        if getattr(self._pool, "_broken", False) or any(
                h.fut is not None and _broken(h.fut) for h in self._inflight):
            self._recover()

    def _recover(self) -> None:
        """A worker died and took the pool down: rebuild the pool. The tasks that were in
        it become suspects, re-run one at a time, alone, so that only the task that kills
        its worker when running alone fails (:class:`WorkerLost`); the others succeed."""
        try:
            self._pool.shutdown(wait=False, cancel_futures=True)
        except Exception:  # pragma: no cover
            pass
        self._start_pool()
        for h in list(self._inflight):
            if h.fut is not None and h.fut.done() and not _broken(h.fut):
                continue
            self._inflight.discard(h)
            if h.isolated:
                f: cf.Future = cf.Future()
                f.set_exception(WorkerLost(
                    f"the worker process died while running this task alone "
                    f"({h.attempts} attempts){_unguarded_script_hint()}"))
                h.fut = f
            else:
                h.fut = None
                self._suspects.append(h)
        if self._suspect is not None and self._suspect.fut is None:
            self._suspect = None

    def _pump(self) -> None:
        """Submit the next suspect once the pool is empty; then what was held back."""
        self._inflight = {h for h in self._inflight if not h.done()}
        if self._suspect is not None and self._suspect.done():
            self._suspect = None
        if self._suspect is None and self._suspects and not self._inflight:
            h = self._suspects.pop(0)
            h.attempts += 1
            h.isolated = True
            h.fut = self._pool.submit(h.fn, *h.args)
            self._inflight.add(h)
            self._suspect = h
        if self._suspect is None and not self._suspects and self._held:
            for h in self._held:
                h.fut = self._pool.submit(h.fn, *h.args)
                self._inflight.add(h)
            self._held = []

    def _result(self, h: Handle) -> Any:
        if h.fut is None:
            raise RuntimeError("task not started yet")
        if self.kind == "dask":
            from distributed.scheduler import KilledWorker
            try:
                return h.fut.result()
            except KilledWorker as exc:
                raise WorkerLost(f"workers died while running this task: {exc}") from None
        return h.fut.result()

    def cancel(self, handles: Iterable[Handle]) -> None:
        for h in handles:
            if h in self._held:
                self._held.remove(h)
            if h in self._suspects:
                self._suspects.remove(h)
            try:
                h.fut.cancel()
            except Exception:  # pragma: no cover
                pass

    def map(self, fn: Callable, items: Iterable[Any]) -> list[Any]:
        """Run ``fn(item)`` for every item, on every slot, and return results in order
        (raises the first task exception)."""
        items = list(items)
        if self.kind == "dask":
            futs = self._client.map(fn, items, pure=False)
            return self._client.gather(futs)
        handles = [self.submit(fn, it) for it in items]
        pending = set(handles)
        while pending:
            _, pending = self.wait(pending)
        return [h.result() for h in handles]

    def warm_up(self) -> float:
        """Start every worker (process start and imports) and return the seconds it took."""
        t0 = time.perf_counter()
        if self.kind == "processes":
            self.map(_noop, range(self.workers))
        elif self.kind == "dask":
            self._client.run(os.getpid)
        return time.perf_counter() - t0

    def describe(self) -> str:
        if self.kind == "serial":
            return "serial"
        if self.kind == "processes":
            return f"{self.workers} local processes"
        return f"Dask cluster {self.scheduler} ({self.workers} worker threads)"

    # ---- shutdown --------------------------------------------------------------------
    def close(self, kill: bool = False) -> None:
        if self._pool is not None:
            procs = list(getattr(self._pool, "_processes", {}) .values()) if kill else []
            self._pool.shutdown(wait=not kill, cancel_futures=True)
            for p in procs:  # Ctrl-C: do not wait for running solves
                try:
                    p.terminate()
                except Exception:  # pragma: no cover
                    pass
            self._pool = None
        if self._client is not None and self._own_client:
            try:
                self._client.close(timeout=5)
            except Exception:  # pragma: no cover
                pass
        self._client = None

    def __enter__(self) -> "Executor":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close(kill=exc[0] is not None)



def _unguarded_script_hint() -> str:
    """Where the parent runs a script: the workers import it, and a top level that starts
    the study again kills each of them while it starts (unseen52 F3: every point "the worker
    process died", the study "complete", exit 0, nothing about the script)."""
    import sys

    main = sys.modules.get("__main__")
    path = getattr(main, "__file__", None)
    if not path or getattr(main, "__spec__", None) is not None:     # `python -m`, or no script
        return ""
    return (f"; if the script {path} starts the study at its top level, guard it with "
            "`if __name__ == \"__main__\":` (worker processes import the script, and each would start "
            "it again)")

def _broken(fut: Any) -> bool:
    if not fut.done() or fut.cancelled():
        return False
    return isinstance(fut.exception(), cf.process.BrokenProcessPool)
