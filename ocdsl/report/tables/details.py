"""The back end's details (multi-start, extra keys) without machine paths or host names."""
from __future__ import annotations

import re
from typing import Any, Iterable

from ocdsl.result import Result
from ocdsl.report.tables.cells import GOOD_STATUS, cell, fmt, status_cell, table


def starts_table(res: Result) -> dict | None:
    """Multi-start records (``extra["starts"]``: list of dicts)."""
    recs = (res.extra or {}).get("starts")
    if not isinstance(recs, list) or len(recs) < 2 or not all(isinstance(r, dict) for r in recs):
        return None
    cols: list[str] = []
    for r in recs:
        cols += [k for k in r if k not in cols]
    maximize = ((res.problem or {}).get("objective") or {}).get("sense") == "maximize"
    objs = [r.get("objective") for r in recs if isinstance(r.get("objective"), (int, float))
            and str(r.get("status", "optimal")) in GOOD_STATUS]
    best = (max if maximize else min)(objs, default=None)
    rows = []
    for r in recs:
        row = [status_cell(str(r[c])) if c == "status" else cell(r.get(c), None, 10 if c == "objective" else 6)
               for c in cols]
        rows.append(row)
    return table("starts", "Multi-start: every start and its result" +
                 (f" (best objective {fmt(best, 10)})." if best is not None else "."), cols, rows)


MACHINE_KEYS = ("host", "hostname", "client_host", "worker_host", "user", "pid", "cwd")


def machine_free(v: Any) -> Any:
    """A value without this machine's details: an absolute path becomes its file name."""
    if isinstance(v, str) and re.match(r"^(/|[A-Za-z]:[\\/])\S+$", v.strip()):
        return v.strip().rstrip("/").rsplit("/", 1)[-1]
    return v


def extra_table(res: Result, skip: Iterable[str] = ("mesh_history", "ipopt_history", "starts", "mesh")) -> dict | None:
    """The back end's own details (``result.json`` ``extra``), for the appendix: no host
    names, file names instead of paths."""
    rows = [[cell(k, "name"), cell(machine_free(v))] for k, v in _flatten({k: v for k, v in (res.extra or {}).items()
                                                                           if k not in skip})
            if k.rsplit(".", 1)[-1] not in MACHINE_KEYS]
    return table("extra", "Back-end details (result.json, extra).", ["item", "value"], rows)


def _flatten(d: Any, prefix: str = "") -> list[tuple[str, Any]]:
    out: list[tuple[str, Any]] = []
    if isinstance(d, dict):
        for k, v in d.items():
            key = f"{prefix}.{k}" if prefix else str(k)
            if isinstance(v, dict) and v:
                out += _flatten(v, key)
            else:
                out.append((key, v))
    return out
