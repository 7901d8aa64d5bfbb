"""Pyomo's notes that are not the user's business, kept off standard output.

ocdsl says what matters itself, once and in its own words: a guess outside a variable's
bounds (the guess notes; Pyomo's W1002 per variable, unseen24), a solution a hair outside a
bound after Ipopt's bound relaxation (Pyomo warns per variable when it is loaded), and the NL
writer's note that `scaling: auto`'s factors name variables it does not write (unused or
fixed ones, which it skips; printed before the status line it read as a problem, unseen27).
"""
from __future__ import annotations

import logging
from contextlib import contextmanager
from typing import Iterator


class _ScalingSuffixNote(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        return "export suffix 'scaling_factor'" not in record.getMessage()


def quiet() -> None:
    logging.getLogger("pyomo.core").setLevel(logging.ERROR)
    writer = logging.getLogger("pyomo.repn.plugins.nl_writer")
    if not any(isinstance(f, _ScalingSuffixNote) for f in writer.filters):
        writer.addFilter(_ScalingSuffixNote())


@contextmanager
def evaluation_unlogged() -> Iterator[None]:
    """Pyomo logs an expression it cannot evaluate, whole ("ERROR: evaluating object as
    numeric value: ..."), before it raises: where ocdsl reports the failure in its own words,
    the log stays off the console."""
    log = logging.getLogger("pyomo.common.numeric_types")
    was, log.disabled = log.disabled, True
    try:
        yield
    finally:
        log.disabled = was
