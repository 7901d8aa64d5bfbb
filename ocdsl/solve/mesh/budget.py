"""Time and memory bounds on the symbolic steps of mesh refinement.

A symbolic step (SymPy differentiation and solving on the user's model) can take minutes
and many gigabytes on a large model (shuttle re-entry: the boundary-control derivation of
the previous code grew the process past 9 GB). ``bounded`` runs such a step in a forked
child process whose address space may grow by at most ``megabytes`` (``RLIMIT_AS``) and
which is killed after ``seconds``; the parent gets the (pickled) result, or None and a
note that says which step was skipped and why. Without ``fork`` (not POSIX) the step runs
in-process, unbounded, and the note says so.
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from typing import Any, Callable


@dataclass
class Budget:
    """The ``mesh:`` block's ``symbolic``, ``symbolic_time`` and ``symbolic_memory``; the
    notes of skipped steps collect here (the run's message and mesh history show them)."""

    enabled: bool = True
    seconds: float = 10.0
    megabytes: float = 1000.0
    notes: list[str] = field(default_factory=list)

    @classmethod
    def of(cls, spec) -> "Budget":
        return cls(bool(spec.symbolic), float(spec.symbolic_time), float(spec.symbolic_memory))


def _address_space() -> int:
    """This process's virtual size in bytes (Linux), 0 when unknown."""
    try:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError):
        return 0


def _child(conn, fn, args, limit: int) -> None:
    try:
        if limit > 0:
            import resource

            soft, hard = resource.getrlimit(resource.RLIMIT_AS)
            want = limit if hard == resource.RLIM_INFINITY else min(limit, hard)
            resource.setrlimit(resource.RLIMIT_AS, (want, hard))
        conn.send(("ok", fn(*args)))
    except MemoryError:
        conn.send(("memory", None))
    except BaseException as exc:  # noqa: BLE001 - reported to the parent, never raised there
        conn.send(("error", f"{type(exc).__name__}: {exc}"))
    finally:
        conn.close()


def bounded(fn: Callable[..., Any], args: tuple, budget: Budget, what: str) -> Any:
    """``fn(*args)`` within the budget, or None (with a note in ``budget.notes``)."""
    if not budget.enabled:
        return None
    import multiprocessing as mp

    try:
        ctx = mp.get_context("fork")
    except ValueError:
        budget.notes.append(f"{what}: run without a time or memory bound (no fork on this platform)")
        return fn(*args)
    limit = _address_space() + int(budget.megabytes * 2 ** 20) if _address_space() else 0
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(send, fn, args, limit), daemon=True)
    start = time.perf_counter()
    proc.start()
    send.close()
    try:
        if not recv.poll(budget.seconds):
            budget.notes.append(f"{what}: skipped, it took more than {budget.seconds:g} s "
                                "(mesh: {symbolic_time: ...} raises the bound, {symbolic: false} turns it off)")
            return None
        kind, value = recv.recv()
    except (EOFError, OSError):
        kind, value = "error", "the child process ended without a result"
    finally:
        if proc.is_alive():
            proc.kill()
        proc.join()
        recv.close()
    if kind == "memory":
        budget.notes.append(f"{what}: skipped, it needed more than {budget.megabytes:g} MB "
                            "(mesh: {symbolic_memory: ...} raises the bound, {symbolic: false} turns it off)")
        return None
    if kind == "error":
        budget.notes.append(f"{what}: skipped ({value}) after {time.perf_counter() - start:.2f} s")
        return None
    return value
