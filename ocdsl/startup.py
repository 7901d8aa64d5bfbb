"""Garbage collection while a command's heavy modules load (issue 26, start-up).

Importing SymPy, pydantic, NumPy and Pyomo makes some hundred thousand long-lived objects
(modules, classes, functions); the cyclic collector walks them again and again while they
load and frees none of them: 50-100 ms of CPU of a small ``ocdsl run`` (about 260
collections). In a process that is one command (the console script, ``cli.entry``) the
collector pauses while they load, and what was made meanwhile is then handed straight to
the oldest generation (``gc.freeze`` + ``gc.unfreeze``, as ``transcribe/pseudospectral.py``
does after a build) instead of being walked by young collections and promoted generation
by generation. Nothing is kept alive longer: a full collection still sees all of it.

In-process callers (the Python API, tests calling ``cli.main``) keep the collector as it
was. Each window acts once per process: a later solve in the same process (a pareto
file's points) finds its modules loaded.
"""
from __future__ import annotations

import gc
from contextlib import contextmanager
from typing import Iterator

_one_command = False
_used: set[str] = set()


def one_command_process() -> None:
    """Called by the console script: this process runs one command, then ends."""
    global _one_command
    _one_command = True


@contextmanager
def loading(window: str) -> Iterator[None]:
    """Around a command's imports: no collection while they run, then what they made goes
    to the oldest generation (only in a one-command process, where the collector is on,
    the first time ``window`` is entered)."""
    if not _one_command or not gc.isenabled() or window in _used:
        yield
        return
    _used.add(window)
    gc.disable()
    try:
        yield
    finally:
        gc.freeze()
        gc.unfreeze()
        gc.enable()
