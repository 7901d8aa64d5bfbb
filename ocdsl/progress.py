"""Progress of a long stage (swarm, continuation, refinement, mesh, study): the stage, how
far it is, the elapsed time and an ETA.

On a terminal one line is rewritten in place (``\\r``); anywhere else (a log, a pipe, CI)
plain lines are written at most every ``interval`` seconds, plus one when the stage ends,
so a log shows the same facts without control characters. The ETA is the elapsed time per
finished step times the steps left; a stage with no known count (``total=None``) shows no
ETA, one whose count is an upper bound says so (``at_most=True``).
"""
from __future__ import annotations

import sys
import time
from typing import IO


def format_seconds(s: float) -> str:
    if s < 60:
        return f"{s:.1f} s" if s < 10 else f"{s:.0f} s"
    m, s = divmod(int(round(s)), 60)
    if m < 60:
        return f"{m} min {s:02d} s"
    h, m = divmod(m, 60)
    return f"{h} h {m:02d} min"


class Stage:
    """``with Stage("swarm", total=600) as bar: bar.update(k, "best J 12.3")``."""

    def __init__(self, name: str, total: int | None = None, *, enabled: bool = True,
                 stream: IO[str] | None = None, interval: float = 10.0, at_most: bool = False,
                 clock=time.monotonic):
        self.name, self.total, self.at_most = name, total, at_most
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled
        self.tty = enabled and bool(getattr(self.stream, "isatty", lambda: False)())
        self.interval = interval if not self.tty else 0.25
        self.clock = clock
        self.start = clock()
        self.done = 0
        self.detail = ""
        self._last = -float("inf")
        self._width = 0

    def __enter__(self) -> "Stage":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def line(self, final: bool = False) -> str:
        elapsed = self.clock() - self.start
        parts = [self.name]
        if self.total:
            frac = min(self.done / self.total, 1.0)
            count = f"{self.done}/{'<=' if self.at_most else ''}{self.total}"
            if self.tty and not final:
                n = 20
                filled = int(round(frac * n))
                count = f"[{'#' * filled}{'.' * (n - filled)}] {count}"
            parts.append(count)
        elif self.done:
            parts.append(f"{self.done}")
        parts.append(f"elapsed {format_seconds(elapsed)}")
        if final:
            parts[-1] = f"done in {format_seconds(elapsed)}"
        elif self.total and self.done:
            left = max(self.total - self.done, 0) * elapsed / self.done
            parts.append(f"ETA {'<= ' if self.at_most else ''}{format_seconds(left)}")
        if self.detail:
            parts.append(self.detail)
        return "  ".join(parts)

    def update(self, done: int | None = None, detail: str | None = None) -> None:
        if done is not None:
            self.done = done
        if detail is not None:
            self.detail = detail
        if not self.enabled:
            return
        now = self.clock()
        if now - self._last < self.interval:
            return
        self._last = now
        self._write(self.line())

    def close(self, detail: str | None = None) -> None:
        if detail is not None:
            self.detail = detail
        if not self.enabled:
            return
        self._write(self.line(final=True), end=True)
        self.enabled = False

    def _write(self, text: str, end: bool = False) -> None:
        if self.tty:
            pad = max(self._width - len(text), 0)
            self._width = len(text)
            self.stream.write("\r" + text + " " * pad + ("\n" if end else ""))
        else:
            self.stream.write(text + "\n")
        self.stream.flush()


def say(enabled: bool, text: str) -> None:
    """One line on stderr, where progress is shown (a note beside a stage's own line)."""
    if enabled:
        print(text, file=sys.stderr, flush=True)


def console():
    """The rich console of ocdsl's summaries and tables. Off a terminal (a pipe, a log, CI)
    lines are never hard-wrapped: rich's default 80 columns would break a headline such as
    "solver optimal, verification verified" in two, and `grep verified` would miss it."""
    from rich.console import Console

    if sys.stdout.isatty():
        return Console()
    return Console(width=240, soft_wrap=True)
