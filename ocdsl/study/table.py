"""The study table (study.csv, study.json) rewritten as points finish, the progress line,
and the summary printed at the end."""
from __future__ import annotations

import csv
import io
import json
import math
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ocdsl import run_folder

from .points import GOOD
from .spec import Point

if TYPE_CHECKING:
    from .run import StudyResult



class _Table:
    FIXED = ["seed", "status", "ok", "verification", "objective", "objective_from", "tf", "iterations",
             "wall_time_s", "host", "warm_start", "message"]

    def __init__(self, out_dir: Path, points: list[Point], info: dict[str, Any]):
        self.out_dir, self.info = out_dir, info
        self.pnames: list[str] = []
        for p in points:
            for k in p.parameters:
                if k not in self.pnames:
                    self.pnames.append(k)
        self.tagnames = [t for t in ("sweep", "sample", "start")
                         if any(t in p.tags for p in points)]
        self.rows: dict[str, dict[str, Any]] = {}
        for p in points:
            self.rows[p.id] = {"id": p.id, **{k: p.parameters.get(k) for k in self.pnames},
                               **{t: p.tags.get(t) for t in self.tagnames},
                               "seed": p.seed, "status": "pending", "ok": None, "verification": None,
                               "objective": None, "objective_from": None, "tf": None,
                               "iterations": None, "wall_time_s": None, "host": None,
                               "warm_start": None, "message": ""}
        self.sense = "minimize"
        self._last_write = 0.0
        self._write_cost = 0.0

    def set(self, pid: str, summary: dict[str, Any], meta: dict[str, Any]) -> None:
        self.sense = summary.pop("sense", self.sense) or self.sense
        row = self.rows[pid]
        row.update(summary)
        # what the number is, in the files as on the console (unseen54 F7: an infeasible
        # point's last iterate in study.csv/json like a solution)
        row["objective_from"] = None if row.get("objective") is None else (
            "last iterate" if _last_iterate(row) else "solution")
        row.update(host=meta.get("host"), warm_start=meta.get("warm_start"))

    def counts(self) -> dict[str, int]:
        """``ok``: points whose own run is ok (solved, expect checks passed, verified or not
        applicable, certificate not failed: ``Result.ok``); a solved point that fails one of
        those counts as failed (unseen9 F3: "6 ok, 0 failed" for 5 points whose expect failed)."""
        st = [r["status"] for r in self.rows.values()]
        done = sum(s != "pending" for s in st)
        ok = sum(_point_ok(r) for r in self.rows.values())
        return {"points": len(st), "done": done, "ok": ok, "failed": done - ok,
                "pending": len(st) - done}

    def best(self) -> dict[str, Any] | None:
        """The best objective among the points that are ok (solved, verified, expect met): a
        point that failed its verification is no study's best (unseen33 F4: "best: p0000"
        with 0 of 3 points ok)."""
        good = [r for r in self.rows.values() if r["status"] in GOOD and _point_ok(r)
                and r["objective"] is not None and math.isfinite(r["objective"])]
        if not good:
            return None
        sign = -1.0 if self.sense == "maximize" else 1.0
        return min(good, key=lambda r: sign * r["objective"])

    def columns(self) -> list[str]:
        return ["id", *self.pnames, *self.tagnames, *self.FIXED]

    def write(self, state: str, extra: dict[str, Any] | None = None, force: bool = False) -> None:
        """Rewrite study.json and study.csv atomically (throttled to a few % of the run
        time for very large studies; always when ``force``)."""
        now = time.perf_counter()
        if not force and now - self._last_write < 20 * self._write_cost:
            return
        t0 = time.perf_counter()
        cols = self.columns()
        buf = io.StringIO()
        w = csv.writer(buf)
        w.writerow(cols)
        for r in self.rows.values():
            w.writerow([_cell(r.get(c)) for c in cols])
        doc = {**self.info, "state": state, "updated": time.strftime("%Y-%m-%dT%H:%M:%S"),
               "counts": self.counts(), "best": self.best(), "columns": cols,
               "points": list(self.rows.values()), **(extra or {})}
        # csv first: a reader that sees state=complete in study.json finds a full csv too
        run_folder.atomic_write_text(self.out_dir / "study.csv", buf.getvalue())
        run_folder.atomic_write_text(self.out_dir / "study.json", json.dumps(_jsonable(doc), indent=1))
        self._last_write = time.perf_counter()
        self._write_cost = self._last_write - t0


def _cell(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, (dict, list)):
        return json.dumps(v)
    return str(v)


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return str(obj)
    return obj


# --------------------------------------------------------------------------------------
# progress display
# --------------------------------------------------------------------------------------
class _Progress:
    """Points done of the total, elapsed, ETA, counts and the best point (ocdsl/progress.py:
    one live line on a terminal, plain lines in a log)."""

    def __init__(self, title: str, total: int, quiet: bool):
        from ..progress import Stage

        self.bar = Stage(title, total, enabled=not quiet)

    def update(self, counts: dict[str, int], running: int, best: dict | None) -> None:
        b = "-" if best is None else f"{best['objective']:.6g} ({best['id']})"
        self.bar.update(counts["done"], f"ok {counts['ok']}  failed {counts['failed']}  running {running}  best {b}")

    def stop(self) -> None:
        self.bar.close()


def _final_table(res: StudyResult, quiet: bool) -> None:
    if quiet:
        return
    from rich.table import Table

    from ..progress import console as make_console
    console = make_console()
    rows = res.rows
    shown = rows
    if len(rows) > 40:
        fails = [r for r in rows if r["status"] != "pending" and not _point_ok(r)][:10]
        good = sorted((r for r in rows if r["status"] in GOOD and r["objective"] is not None),
                      key=lambda r: r["objective"])[:15]
        shown = sorted(good + fails, key=lambda r: r["id"])
    t = Table(title=f"study {res.out_dir}  ({res.counts['ok']} ok, {res.counts['failed']} "
                    f"failed of {res.counts['points']}; {res.executor}; "
                    f"{res.wall_time_s:.1f} s)")
    pn = res.parameter_names[:6]
    for c in ["id", *pn, "status", "ok", "verification", "objective", "tf", "iter", "wall s", "host"]:
        t.add_column(c, justify="right" if c not in ("id", "status", "ok", "verification", "host") else "left")
    for r in shown:
        pending = r["status"] == "pending"
        style = "yellow" if pending else ("" if _point_ok(r) else "red")
        tf = r["tf"]
        t.add_row(r["id"], *[_fmt(r.get(k)) for k in pn], r["status"], "" if pending else ("yes" if _point_ok(r) else "no"),
                  str(r.get("verification") or ""),
                  _objective_cell(r),
                  _fmt(tf) if not isinstance(tf, dict) else json.dumps(tf),
                  _fmt(r["iterations"]), _fmt(r["wall_time_s"], 3), str(r["host"] or ""),
                  style=style)
    console.print(t)
    if len(shown) < len(rows):
        console.print(f"(best 15 and first failures shown; all {len(rows)} rows in "
                      f"{res.out_dir / 'study.csv'})")
    if res.best:
        console.print(f"best: {res.best['id']} objective {res.best['objective']:.10g}")


def _objective_cell(r: dict) -> str:
    """A point's objective, labelled where its run found no solution (an infeasible point's
    last iterate was shown as its objective, 25, beside points that solved; unseen50 F6)."""
    text = _fmt(r["objective"])
    if text and _last_iterate(r):
        text += " (last iterate)"
    return text


def _last_iterate(r: dict) -> bool:
    """The row's objective is the solver's last iterate, not a solution's."""
    return r["status"] not in GOOD + ("acceptable", "mesh_not_converged", "time_limit")


def _fmt(v: Any, digits: int = 6) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return f"{v:.{digits}g}"
    return str(v)


def _point_ok(row: dict[str, Any]) -> bool:
    """A point's own ``ok``; a row of an older study folder without it: its solver status."""
    if row.get("ok") is None:
        return row["status"] in GOOD
    return bool(row["ok"])
