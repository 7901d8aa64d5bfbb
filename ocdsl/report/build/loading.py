"""Reading a run folder or a study folder as the report needs it (never re-solves), and
what an older run folder lacks."""
from __future__ import annotations

import csv
import json
import re
from pathlib import Path
from typing import Any

import numpy as np

from ocdsl.result import Result
from ocdsl.report import figures as F
from ocdsl.report.build.document import NotARunFolder, ReportError
from ocdsl.report.tables.cells import GOOD_STATUS as GOOD


# ============================================================================== loading
def _is_run(d: Path) -> bool:
    return (d / "result.json").is_file()


def _natural_key(p: Path) -> list:
    return [int(s) if s.isdigit() else s for s in re.split(r"(\d+)", p.name)]


def _find_runs(folder: Path, depth: int = 2) -> list[Path]:
    out: list[Path] = []
    if depth <= 0 or not folder.is_dir():
        return out
    for d in sorted((d for d in folder.iterdir() if d.is_dir() and not d.name.startswith(".")), key=_natural_key):
        if _is_run(d):
            out.append(d)
        else:
            out += _find_runs(d, depth - 1)
    return out


def points_verification(run_dir: Path) -> dict[str, Any] | None:
    """A Pareto set's verdict from its points' run folders (``points/*/result.json``, each
    verified by ocdsl/verify): verified when every point is."""
    pts = sorted(Path(run_dir).glob("points/*/result.json"))
    if not pts:
        return None
    st = []
    for f in pts:
        try:
            st.append(((json.loads(f.read_text()).get("verification") or {}).get("status")))
        except (OSError, ValueError):
            st.append("error")
    n_ok = sum(s == "verified" for s in st)
    return {"status": "verified" if n_ok == len(st) else "failed", "checks": [], "tolerance": None,
            "summary": f"{n_ok} of {len(st)} points verified (points/*/result.json)"}


def load_run(run_dir: Path) -> tuple[Result, list[str]]:
    """``Result.read`` with a fallback: a run folder with a broken or missing trajectory
    still gives the scalars of ``result.json`` (and a note). A Pareto set without its own
    verdict takes its points'."""
    from ocdsl import run_folder

    if any(c.split(" ")[0] == "result.json" for c in run_folder.changed_since_written(run_dir)):
        # every verdict a report prints comes from result.json: an edited one made a failed run
        # "optimal, verified, overall ok (exit 0)" under "the verdicts ... of the run as ocdsl
        # wrote it" (unseen43 F1, F2 in a comparison)
        raise ReportError(f"{run_dir}/result.json was changed after ocdsl wrote it: its verdicts (status, "
                          "verification, certificate, expect) are no longer ocdsl's, and a report would present "
                          "them as such. Nothing was written: run the problem file again, or restore the file")
    res, notes = _load_run(run_dir)
    if res.verification is None:
        res.verification = points_verification(run_dir)
    return res, notes


def _load_run(run_dir: Path) -> tuple[Result, list[str]]:
    try:
        return Result.read(run_dir), []
    except Exception as exc:  # noqa: BLE001
        note = f"the run folder could not be read in full ({type(exc).__name__}: {exc})"
    try:
        data = json.loads((run_dir / "result.json").read_text())
    except Exception as exc:  # noqa: BLE001
        raise NotARunFolder(f"{run_dir}: not a readable run folder (result.json: {exc})") from exc
    fields = set(Result.__dataclass_fields__) - {"phases", "tables"}
    kw = {k: v for k, v in data.items() if k in fields}
    kw.setdefault("name", run_dir.name)
    kw.setdefault("status", "error")
    res = Result(**kw)
    for name in data.get("tables") or []:
        try:
            from ocdsl.result import read_csv
            res.tables[name] = read_csv(run_dir / "tables" / f"{name}.csv")
        except Exception:  # noqa: BLE001
            pass
    return res, [note]


def read_study_table(folder: Path) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Rows of ``study.csv`` (numbers converted) and the ``study.json`` object."""
    rows: list[dict[str, Any]] = []
    meta: dict[str, Any] = {}
    if (folder / "study.json").is_file():
        try:
            meta = json.loads((folder / "study.json").read_text())
        except Exception:  # noqa: BLE001
            meta = {}
        if isinstance(meta, list):
            meta = {"rows": meta}
    if (folder / "study.csv").is_file():
        with open(folder / "study.csv", newline="") as fh:
            for r in csv.DictReader(fh):
                rows.append({k: _num(v) for k, v in r.items() if k is not None})
    elif isinstance(meta, dict):
        for key in ("rows", "points", "table", "results"):
            if isinstance(meta.get(key), list) and all(isinstance(x, dict) for x in meta[key]):
                rows = [dict(x) for x in meta[key]]
                break
    return rows, meta if isinstance(meta, dict) else {}


def _num(v: Any) -> Any:
    if isinstance(v, str):
        s = v.strip()
        if re.fullmatch(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?|[-+]?(inf|nan)", s, re.I):
            f = float(s)
            return int(f) if re.fullmatch(r"[-+]?\d+", s) else f
        if s.lower() in ("true", "false"):
            return s.lower() == "true"
    return v

def has_hamiltonian(p) -> bool:
    return any(k in p.extra for k in F.HAMILTONIAN_KEYS)


def reintegration_tables(res: Result) -> dict[str, dict[str, np.ndarray]]:
    """Phase name (None: the only phase of an older folder) -> the re-integrated
    trajectory the run wrote (``tables/reintegration_<phase>.csv``, ocdsl/verify)."""
    out = {}
    for name, tab in sorted(res.tables.items()):
        if (name == "reintegration" or name.startswith("reintegration_")) and "t" in tab:
            out[name[len("reintegration_"):] if name != "reintegration" else None] = tab
    return out


def missing_notes(res: Result) -> list[str]:
    """What an older run folder lacks; the report says so and computes nothing itself."""
    notes = []
    if any(p.costates and p.controls and not has_hamiltonian(p) for p in res.phases):
        notes.append("This run folder holds costates but not the Hamiltonian or its control gradients "
                     "(written by an ocdsl that did not record them): the Hamiltonian figures are left "
                     "out. Re-run the problem file to get them.")
    if res.phases and res.status in GOOD and not reintegration_tables(res) and res.verification is None:
        notes.append("This run folder has no independent verification and no re-integrated trajectory "
                     "(written by an ocdsl before ocdsl/verify): re-run the problem file to get them.")
    return notes
