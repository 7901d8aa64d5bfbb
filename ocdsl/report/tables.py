"""Tables of a report, as plain data for the templates.

A table is a dict ``{"key", "caption", "columns", "rows", "note"}``; each cell is a
dict ``{"text": str, "cls": str}`` (``cls`` among ``num``, ``pass``, ``fail``, ``warn``,
``""``) or ``{"html": Markup}`` for pre-escaped content (symbol names with sub/superscripts).
Builders return ``None`` when the run folder has nothing for that table.
"""
from __future__ import annotations

import math
import re
from typing import Any, Iterable, Sequence

import numpy as np
from markupsafe import Markup, escape

from ocdsl.result import Result

GOOD_STATUS = ("optimal", "acceptable", "feasible", "stable")
GREEK_UNICODE = dict(zip(
    ("alpha beta gamma delta epsilon zeta eta theta iota kappa lambda mu nu xi pi rho sigma tau "
     "upsilon phi chi psi omega Gamma Delta Theta Lambda Xi Pi Sigma Upsilon Phi Psi Omega").split(),
    "αβγδεζηθικλμνξπρστυφχψωΓΔΘΛΞΠΣΥΦΨΩ"))


# --------------------------------------------------------------------- formatting
def fmt(v: Any, digits: int = 6) -> str:
    """Numbers with ``digits`` significant digits; ``—`` for missing values."""
    if v is None or (isinstance(v, str) and v == ""):
        return "—"
    if isinstance(v, (bool, np.bool_)):
        return "yes" if v else "no"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        f = float(v)
        if math.isnan(f):
            return "NaN"
        if math.isinf(f):
            return "∞" if f > 0 else "−∞"
        if f == int(f) and abs(f) < 1e9:
            return str(int(f))
        return f"{f:.{digits}g}".replace("-", "−")
    if isinstance(v, str):
        try:
            return fmt(float(v), digits) if re.fullmatch(r"\s*[-+]?(\d|\.\d|inf|nan).*", v, re.I) else v
        except ValueError:
            return v
    if isinstance(v, dict):
        return ", ".join(f"{k}: {fmt(x, digits)}" for k, x in v.items())
    if isinstance(v, (list, tuple)):
        if len(v) > 8:
            return f"[{', '.join(fmt(x, 4) for x in v[:6])}, … ({len(v)} values)]"
        return "[" + ", ".join(fmt(x, digits) for x in v) + "]"
    return str(v)


def cell(v: Any, cls: str | None = None, digits: int = 6) -> dict[str, Any]:
    if cls is None:
        cls = "num" if isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool) else ""
    return {"text": fmt(v, digits), "cls": cls}


def verdict(ok: Any) -> dict[str, Any]:
    if ok is None:
        return {"text": "—", "cls": ""}
    return {"text": "pass" if ok else "FAIL", "cls": "pass" if ok else "fail"}


def status_cell(status: str) -> dict[str, Any]:
    return {"text": status, "cls": "pass" if status in GOOD_STATUS else "fail"}


def name_html(name: str) -> Markup:
    """``theta_1`` -> ``θ<sub>1</sub>``; ``lambda_x`` -> ``λ<sub>x</sub>``."""
    name = str(name)
    base, sub = name, ""
    if "_" in name.strip("_"):
        base, sub = name.strip("_").split("_", 1)
    else:
        m = re.fullmatch(r"([A-Za-z]+?)(\d+)", name)
        if m:
            base, sub = m.groups()
    b = GREEK_UNICODE.get(base, base)
    html = Markup("<i>{}</i>").format(b) if len(b) == 1 else escape(b)
    if sub:
        html += Markup("<sub>{}</sub>").format(GREEK_UNICODE.get(sub, sub))
    return html


def unit_html(unit: str) -> Markup:
    """``m/s^2`` -> ``m/s<sup>2</sup>``."""
    parts = re.split(r"\^\(?([-+]?\d+(?:\.\d+)?)\)?", str(unit or ""))
    out = Markup("")
    for i, p in enumerate(parts):
        out += Markup("<sup>{}</sup>").format(p.replace("-", "−")) if i % 2 else escape(p)
    return out


def unit_cell(unit: str) -> dict[str, Any]:
    return {"html": unit_html(unit), "cls": ""}


def name_cell(name: str) -> dict[str, Any]:
    return {"html": name_html(name), "cls": "name"}


WIDE_COLUMNS = 7       # tables with more columns are set smaller (report.css: table.data.wide)


def table(key: str, caption: str, columns: Sequence[str], rows: list[list[dict]], note: str = "") -> dict | None:
    if not rows:
        return None
    return {"key": key, "caption": caption, "columns": list(columns), "rows": rows, "note": note,
            "wide": len(columns) > WIDE_COLUMNS, "very_wide": len(columns) > 2 * WIDE_COLUMNS - 2}


# ------------------------------------------------------------------------ problem
def finite_or_none(v: Any) -> float | None:
    """``float(v)`` when it is a finite number, else None (missing or non-numeric cells)."""
    try:
        f = float(v)
    except (TypeError, ValueError):
        return None
    return f if math.isfinite(f) else None


def variables_table(res: Result, kind: str) -> dict | None:
    """States or controls: name, unit, bounds, phases."""
    problem = res.problem or {}
    units = problem.get("units") or {}
    seen: dict[str, dict] = {}
    for pname, info in (problem.get("phases") or {}).items():
        for n in info.get(kind) or []:
            e = seen.setdefault(n, {"phases": [], "bounds": None})
            e["phases"].append(pname)
            b = (info.get("bounds") or {}).get(n)
            if b is not None and e["bounds"] is None:
                e["bounds"] = b
    if not seen:  # no description: fall back to the trajectory's columns
        for p in res.phases:
            for n in getattr(p, kind):
                seen.setdefault(n, {"phases": [], "bounds": None})["phases"].append(p.name)
    multi = len(problem.get("phases") or {}) > 1
    rows = []
    for n, e in seen.items():
        lo, hi = (e["bounds"] if isinstance(e["bounds"], (list, tuple)) and len(e["bounds"]) == 2
                  else (None, None))
        lo, hi = finite_or_none(lo), finite_or_none(hi)
        row = [name_cell(n), unit_cell(units.get(n, "")),
               cell(lo) if lo is not None else cell("−∞" if e["bounds"] else "—", "num"),
               cell(hi) if hi is not None else cell("∞" if e["bounds"] else "—", "num")]
        if multi:
            row.append(cell(", ".join(e["phases"]), ""))
        rows.append(row)
    cols = ["name", "unit", "lower bound", "upper bound"] + (["phases"] if multi else [])
    return table(kind, f"{kind.capitalize()} of the problem.", cols, rows)


def parameters_table(res: Result) -> dict | None:
    problem_params = (res.problem or {}).get("parameters") or {}
    units = (res.problem or {}).get("units") or {}
    names = list(problem_params) + [n for n in res.parameters if n not in problem_params]
    rows = []
    for n in names:
        info = problem_params.get(n) or {}
        if not isinstance(info, dict):
            info = {"value": info}
        value = res.parameters.get(n, info.get("value"))
        free = bool(info.get("free", False))
        overridden = (n in res.parameters and "value" in info and not free
                      and finite_or_none(info.get("value")) != finite_or_none(res.parameters[n]))
        note = "free (optimised)" if free else ("overridden (file: %s)" % fmt(info.get("value")) if overridden
                                                else "")
        rows.append([name_cell(n), cell(value), unit_cell(units.get(n, "")), cell(note, "")])
    return table("parameters", "Parameters and the values used in this run.",
                 ["name", "value", "unit", "note"], rows)


def method_table(res: Result) -> dict | None:
    rows = [[cell(k, "name"), cell(v, "num" if isinstance(v, (int, float)) and not isinstance(v, bool) else "")]
            for k, v in _flatten(res.method)]
    return table("method", "Method, mesh and solver options.", ["setting", "value"], rows)


def phases_table(res: Result) -> dict | None:
    """Per-phase summary (only for several phases)."""
    if len(res.phases) < 2:
        return None
    tf = res.tf if isinstance(res.tf, dict) else {}
    rows = []
    for p in res.phases:
        t = np.asarray(p.time, float)
        t0 = float(t[0]) if t.size else None
        t1 = float(t[-1]) if t.size else tf.get(p.name)
        rows.append([cell(p.name, "name"), cell(int(t.size)), cell(t0), cell(t1),
                     cell(t1 - t0 if t0 is not None and t1 is not None else None),
                     cell(len(p.states)), cell(len(p.controls))])
    return table("phases", "Phases of the solution.",
                 ["phase", "nodes", "t₀", "t_f", "duration", "states", "controls"], rows)


# ----------------------------------------------------------------------- solution
def badge_cell(b) -> dict[str, Any]:
    return {"text": b.text, "cls": {"pass": "pass", "fail": "fail", "warn": "warn"}.get(b.cls, "")}


def summary_table(res: Result) -> dict:
    from ocdsl.report.status import badges

    rows = []
    for b in badges(res):
        rows.append([cell(b.label, "name"), badge_cell(b)])
        if b.title:
            rows[-1][1] = {**rows[-1][1], "text": f"{b.text}: {b.title}"}
    sense = ((res.problem or {}).get("objective") or {}).get("sense")
    rows.append([cell("objective" + (f" ({sense})" if sense else ""), "name"), cell(res.objective, "num", 10)])
    for label, v in time_rows(res):
        rows.append([cell(label, "name"), cell(v, "num", 10)])
    rows.append([cell("iterations", "name"), cell(res.iterations)])
    for k in ("variables", "constraints", "nonzeros"):
        if k in (res.nlp or {}):
            rows.append([cell(f"NLP {k}", "name"), cell(res.nlp[k])])
    for k, v in (res.nlp or {}).items():
        if k not in ("variables", "constraints", "nonzeros"):
            rows.append([cell(f"NLP {k}", "name"), cell(v)])
    if "total" in (res.wall_time_s or {}):
        rows.append([cell("wall time total [s]", "name"), cell(res.wall_time_s["total"], "num", 4)])
    return table("summary", "Solution summary: the solver's status, the independent verification, the "
                 "certificate and the expect checks; \"overall\" is the exit code of ocdsl run.",
                 ["quantity", "value"], rows)


def time_rows(res: Result) -> list[tuple[str, Any]]:
    """Final times in physical time: a run whose independent variable is not time (a
    Sundman-transformed problem) carries its physical time as the state or expression
    ``problem.time_variable`` names; its end is the flight time."""
    tvar = (res.problem or {}).get("time_variable")
    unit = ((res.problem or {}).get("units") or {}).get("t")
    u = f" [{unit}]" if unit else ""
    if tvar:
        ends = [(p.name, physical_time(p, tvar)) for p in res.phases]
        ends = [(n, float(a[np.isfinite(a)][-1])) for n, a in ends if a is not None and np.isfinite(a).any()]
        out = [(f"flight time ({tvar}(t_f)){u}" + (f" ({n})" if len(ends) > 1 else ""), v) for n, v in ends]
        if isinstance(res.tf, (int, float)):
            out.append(("final value of the independent variable", res.tf))
        return out
    if isinstance(res.tf, dict):
        return [(f"final time t_f ({k}){u}", v) for k, v in res.tf.items()]
    return [(f"final time t_f{u}", res.tf)]


def physical_time(p, tvar: str) -> np.ndarray | None:
    for group in (p.states, p.extra, p.controls):
        if tvar in group:
            return np.asarray(group[tvar], float)
    return None


def wall_time_table(res: Result) -> dict | None:
    wt = {k: v for k, v in (res.wall_time_s or {}).items() if finite_or_none(v) is not None}
    stages = [(k, float(v)) for k, v in wt.items() if k != "total"]
    if not stages:
        return None
    total = float(wt.get("total", sum(v for _, v in stages)))
    rows = [[cell(k, "name"), cell(v, "num", 4), cell(100 * v / total if total > 0 else None, "num", 3)]
            for k, v in stages]
    rows.append([cell("total", "name total"), cell(total, "num total", 4), cell(100.0 if total > 0 else None, "num total", 3)])
    return table("wall_time", "Wall-time breakdown by stage.", ["stage", "time [s]", "share [%]"], rows)


COMPARE_TEXT = {"equal": "|error| ≤ tol", "at_most": "ocdsl ≤ ref + tol", "at_least": "ocdsl ≥ ref − tol"}


def tolerance_text(c: dict) -> str:
    """An expect check's band: the larger of rtol·|reference| and atol."""
    parts = []
    if c.get("rtol") is not None:
        parts.append(f"rtol {fmt(c['rtol'], 3)}")
    if c.get("atol") is not None:
        parts.append(f"atol {fmt(c['atol'], 3)}")
    return ", ".join(parts) or "—"


def compare_text(c: dict) -> str:
    return COMPARE_TEXT.get(c.get("compare") or "equal", str(c.get("compare")))


def expect_table(res: Result) -> dict | None:
    rows = []
    for c in res.expect or []:
        rows.append([cell(c.get("name", "?"), "name"), cell(c.get("reference"), "num", 10),
                     cell(c.get("value"), "num", 10), cell(c.get("error"), "num", 3),
                     cell(compare_text(c), "nowrap"), cell(tolerance_text(c), "nowrap"), verdict(c.get("passed"))])
    return table("expect", "Expected values (the file's expect block: reference, e.g. from the paper) "
                 "against ocdsl's, with the comparison and tolerance of each check.",
                 ["check", "reference", "ocdsl", "error", "comparison", "tolerance", "result"], rows)


def verification_table(res: Result) -> dict | None:
    """The independent verification (ocdsl/verify, ``result.json`` ``verification``): one row
    per check, its relative value against the tolerance it is held to."""
    v = res.verification
    if not isinstance(v, dict):
        return None
    rows = []
    for c in v.get("checks") or []:
        what = c.get("name", "?")
        if c.get("phase") and len(res.phases) > 1:
            what += f" ({c['phase']})"
        rows.append([cell(what, "name"), cell(c.get("detail") or "", ""), cell(c.get("value"), "num", 3),
                     cell("≤", ""), cell(c.get("limit"), "num", 3), cell(c.get("where") or "", ""),
                     verdict(c.get("passed"))])
    note = v.get("summary") or ""
    if v.get("mode") == "warn":
        note += " The file asks for verify: {mode: warn}: a failed check is reported but does not fail the run."
    if not rows:
        rows.append([cell("verification", "name"), cell(v.get("summary") or "", ""), cell(None), cell("", ""),
                     cell(v.get("tolerance"), "num", 3), cell("", ""),
                     {"text": str(v.get("status")), "cls": "fail" if v.get("status") in ("failed", "error") else ""}])
        note = ""
    return table("verification", "Independent verification of the returned trajectory (ocdsl/verify, "
                 "docs/verification.md): each value is relative and held to the tolerance beside it.",
                 ["check", "how", "value", "", "tolerance", "worst at", "result"], rows, note)


# certificate check -> (its measured value, the tolerance key, comparison, what it measures)
CERTIFICATE_CHECKS = {
    "hamiltonian": ("relative_max_deviation", "hamiltonian_max", "≤",
                    "max |H − expected| / scale (constant H where expected is none)"),
    "stationarity": ("max_relative", "stationarity", "≤", "max |∂H/∂u| / term size at interior nodes"),
    "switching": ("agreement", "sign_agreement", "≥", "share of saturated nodes where the sign of ∂H/∂u "
                  "picks that bound"),
    "path_multipliers": ("complementarity", "complementarity", "≤",
                         "max |μ (g − bound)| / term size (complementarity)"),
}


def certificate_phases(cert: Any) -> list[tuple[str | None, dict]]:
    if not isinstance(cert, dict):
        return []
    if isinstance(cert.get("phases"), dict):
        return [(p, c) for p, c in cert["phases"].items() if isinstance(c, dict)]
    return [(None, cert)]


def certificate_table(cert: Any) -> dict | None:
    """The optimality certificate (necessary conditions where costates exist): one row per
    check with its measured value, comparison and tolerance."""
    rows = []
    for phase, c in certificate_phases(cert):
        pre = f"{phase}: " if phase else ""
        if c.get("error") or c.get("skipped"):
            rows.append([cell(pre + "certificate", "name"), cell(c.get("error") or c.get("skipped"), ""),
                         cell(None), cell("", ""), cell(None), verdict(False if c.get("error") else None)])
            continue
        tol = c.get("tolerances") or {}
        for key, (vkey, tkey, op, what) in CERTIFICATE_CHECKS.items():
            d = c.get(key)
            if not isinstance(d, dict):
                continue
            val = d.get(vkey)
            extra = ""
            if key == "hamiltonian":
                exp = finite_or_none(d.get("expected"))
                extra = (f"; expected {fmt(exp + 0.0, 4)}" if exp is not None else "; expected constant")
            rows.append([cell(pre + key.replace("_", " "), "name"), cell(what + extra, ""), cell(val, "num", 3),
                         cell(op, ""), cell(tol.get(tkey), "num", 3), verdict(d.get("passed"))])
    if not rows:
        return None
    return table("certificate", "Optimality certificate: first-order necessary conditions (Pontryagin) "
                 "evaluated with the costates; the re-integration is the verification's (above).",
                 ["check", "what it measures", "value", "", "tolerance", "result"], rows)


def switch_table(cert: Any) -> dict | None:
    """Per control: the share of nodes at a bound and the switch times (bang-bang structure)."""
    rows = []
    for phase, c in certificate_phases(cert):
        per = ((c.get("bang_bang") or {}).get("per_control") or {}) if isinstance(c, dict) else {}
        for u, d in per.items():
            if not isinstance(d, dict):
                continue
            times = [finite_or_none(x) for x in d.get("switch_times") or []]
            times = [x for x in times if x is not None]
            seq = d.get("sequence") or []
            rows.append([cell(f"{phase}: {u}" if phase else u, "name"),
                         cell(100 * float(d.get("fraction_at_bound") or 0.0), "num", 3),
                         cell(len(times)), cell(", ".join(fmt(x, 5) for x in times) or "none", "list"),
                         cell(" ".join(map(str, seq)) if seq else "—", "list")])
    return table("switches", "Switching structure of each control: share of nodes at a bound and the "
                 "switch times (from the certificate).",
                 ["control", "at a bound [%]", "switches", "switch times", "bound sequence"], rows)


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


# -------------------------------------------------------------------- run tables
def column_table(key: str, caption: str, cols: dict[str, Any], max_rows: int = 40, digits: int = 6,
                 drop_constant: bool = False) -> dict | None:
    """A tables/<name>.csv (or study table) as rows; long tables are thinned evenly;
    ``drop_constant``: columns with one value in every row are named in the note instead."""
    if not cols:
        return None
    names = list(cols)
    constant = []
    if drop_constant and max((len(v) for v in cols.values()), default=0) > 1:
        for c in names:
            vals = {fmt(v) for v in cols[c]}
            if len(vals) == 1:
                constant.append(f"{c} = {vals.pop()}")
        names = [c for c in names if not any(x.startswith(f"{c} = ") for x in constant)] or list(cols)
    n = max((len(v) for v in cols.values()), default=0)
    idx = list(range(n))
    note = ""
    if n > max_rows:
        idx = sorted(set(np.linspace(0, n - 1, max_rows).round().astype(int).tolist()))
        note = f"{len(idx)} of {n} rows shown (evenly spaced); the full table is in the run folder."
    rows = []
    for i in idx:
        row = []
        for c in names:
            v = cols[c][i] if i < len(cols[c]) else None
            if c == "status":
                row.append(status_cell(str(v)))
            elif c == "pareto":
                row.append({"text": "Pareto" if _truthy(v) else "", "cls": "pass" if _truthy(v) else ""})
            else:
                row.append(cell(v, None, digits))
        rows.append(row)
    if constant:
        note = (note + " " if note else "") + "The same in every row: " + "; ".join(constant) + "."
    return table(key, caption, [c.replace("_", " ") for c in names], rows, note)


def _truthy(v: Any) -> bool:
    if isinstance(v, str):
        return v.strip().lower() in ("1", "1.0", "true", "yes", "y", "t")
    f = finite_or_none(v)
    return bool(f) if f is not None else False


def reintegration_table(res: Result) -> dict | None:
    """Per state: the re-integrated trajectory (``tables/reintegration_<phase>.csv``, written
    by the run's verification) against the solution's rows: largest and final deviation,
    and the largest relative to the state's range (``err_<state>``, the verification's measure)."""
    rows = []
    for tname, tab in sorted(res.tables.items()):
        if not (tname == "reintegration" or tname.startswith("reintegration_")) or "t" not in tab:
            continue
        phase = tname[len("reintegration_"):] if tname != "reintegration" else None
        phases = [p for p in res.phases if phase is None or p.name == phase]
        label = phase if phase and len(res.phases) > 1 else None
        t_r = np.asarray(tab["t"], float)
        for n, y_r in tab.items():
            if n == "t" or n.startswith("err_"):
                continue
            ts, ys = [], []
            for p in phases:
                if n in p.states:
                    ts.append(np.asarray(p.time, float))
                    ys.append(np.asarray(p.states[n], float))
            if not ts or t_r.size < 2:
                continue
            t_c, y_c = np.concatenate(ts), np.concatenate(ys)
            ok = np.isfinite(t_c) & np.isfinite(y_c)
            t_c, y_c = t_c[ok], y_c[ok]
            order = np.argsort(t_r, kind="stable")
            y_r = np.asarray(y_r, float)[order]
            dev = np.abs(np.interp(t_c, t_r[order], y_r) - y_c)
            if f"err_{n}" in tab:
                rel = float(np.nanmax(np.asarray(tab[f"err_{n}"], float)))
            else:
                rng = float(np.nanmax(y_c) - np.nanmin(y_c)) if y_c.size else 0.0
                rel = float(np.nanmax(dev)) / max(rng, 1e-300)
            rows.append([cell(f"{label}: {n}" if label else n, "name"), cell(float(np.nanmax(dev)), "num", 3),
                         cell(rel, "num", 3), cell(float(abs(y_r[-1] - y_c[-1])), "num", 3)])
    return table("reintegration", "Re-integration: the dynamics integrated from the solution's initial "
                 "state with its controls (the verification's trajectory, from the run folder) against "
                 "the solution's rows.",
                 ["state", "max |deviation|", "relative to its range", "final deviation"], rows)


def controller_metrics(extra: dict) -> dict[str, dict]:
    """Controller name -> its closed-loop metrics (``extra[<controller>]["metrics"]``, as the
    controller back end writes them), in the file's order."""
    return {k: v["metrics"] for k, v in (extra or {}).items()
            if isinstance(v, dict) and isinstance(v.get("metrics"), dict)}


def _threshold_label(key: str, unit: str) -> tuple[float, str]:
    thr = float(key.split("@", 1)[1])
    if unit == "rad":
        return thr, f"settling to {fmt(np.degrees(thr), 3)}° [s]"
    return thr, f"settling to {fmt(thr, 3)}{(' ' + unit) if unit else ''} [s]"


def controller_table(res: Result) -> dict | None:
    """The controllers side by side: settling time (every regulated state within each
    threshold), largest overshoot, peak control, cost, and the controller's time per
    update, from the metrics in ``result.json``."""
    mets = controller_metrics(res.extra)
    if not mets:
        return None
    units = (res.problem or {}).get("units") or {}
    first = next(iter(mets.values()))
    states = list((first.get("states") or {}))
    unit = units.get(states[0], "") if states and len({units.get(x, "") for x in states}) == 1 else ""
    settle = sorted((k for k in first if k.startswith("settling_time@")), key=lambda k: -float(k.split("@")[1]))
    heads = [_threshold_label(k, unit)[1] for k in settle]
    rows = []
    for name, m in mets.items():
        st = m.get("states") or {}
        over = [finite_or_none(v.get("overshoot_pct")) for v in st.values() if isinstance(v, dict)]
        over = [x for x in over if x is not None]
        peak = m.get("peak_control")
        peak = max(abs(float(x)) for x in peak) if isinstance(peak, list) and peak else finite_or_none(peak)
        ct = m.get("controller_time_s") or {}
        status = (res.extra.get(name) or {}).get("status", "")
        rows.append([cell(name, "name"), status_cell(str(status)) if status else cell("—"),
                     *[cell(m.get(k), "num", 4) for k in settle],
                     cell(max(over) if over else None, "num", 3), cell(peak, "num", 4),
                     cell(m.get("cost"), "num", 6), cell(m.get("control_cost"), "num", 5),
                     cell(1e3 * ct["mean"] if finite_or_none(ct.get("mean")) is not None else None, "num", 3),
                     cell(1e3 * ct["p95"] if finite_or_none(ct.get("p95")) is not None else None, "num", 3)])
    over_of = ", ".join(states) if states else "the states"
    return table("controllers", f"Controller comparison: settling time (every one of {over_of} within the "
                 f"threshold from then on), largest overshoot of {over_of}, peak control magnitude, the cost J "
                 "and its control part, and the controller's computation time per update.",
                 ["controller", "status", *heads, "overshoot [%]", "peak control", "cost J", "control cost",
                  "time/update mean [ms]", "95 % [ms]"], rows)


def closed_loop_table(tables: dict[str, dict[str, np.ndarray]], problem: dict,
                      extra: dict | None = None) -> dict | None:
    """Per closed-loop run: samples, final time, the final size of the regulated states
    (those the metrics name; all states otherwise) and the controller timing (the table's
    ``timing`` column, else the metrics' ``controller_time_s``)."""
    rows = []
    states = set()
    for info in (problem.get("phases") or {}).values():
        states |= set(info.get("states") or [])
    mets = controller_metrics(extra or {})
    for name, tab in sorted(tables.items()):
        if not name.startswith("closed_loop_") or "t" not in tab:
            continue
        cname = name[len("closed_loop_"):]
        m = mets.get(cname.rsplit(":", 1)[-1], {})
        t = np.asarray(tab["t"], float)
        regulated = [k for k in (m.get("states") or {}) if k in tab]
        sv = regulated or [k for k in tab if k in states] or [k for k in tab if k not in ("t", "timing")]
        final = np.array([np.asarray(tab[k], float)[-1] for k in sv]) if t.size else np.array([])
        timing = np.asarray(tab.get("timing", []), float) * 1e3
        timing = timing[np.isfinite(timing)]
        ct = m.get("controller_time_s") or {}
        mean = float(np.mean(timing)) if timing.size else (1e3 * ct["mean"] if "mean" in ct else None)
        p95 = float(np.percentile(timing, 95)) if timing.size else (1e3 * ct["p95"] if "p95" in ct else None)
        mx = float(np.max(timing)) if timing.size else (1e3 * ct["max"] if "max" in ct else None)
        rows.append([cell(cname, "name"), cell(int(t.size)), cell(float(t[-1]) if t.size else None),
                     cell(float(np.linalg.norm(final)) if final.size else None, "num", 4),
                     cell(mean, "num", 4), cell(p95, "num", 4), cell(mx, "num", 4)])
    return table("closed_loop", "Closed-loop runs: final size of the regulated states ("
                 + (", ".join(sorted({k for m in mets.values() for k in (m.get('states') or {})})) or "all states")
                 + ") and the controller's time per update.",
                 ["controller", "samples", "final t", "final ‖x‖", "mean [ms]", "95 % [ms]", "max [ms]"], rows)


# ----------------------------------------------------------------------- studies
def runs_table(results: list[Result], labels: list[str] | None = None) -> dict | None:
    """One row per run: status, objective, t_f, iterations, NLP size, wall time, checks,
    and the parameters that differ between runs."""
    if not results:
        return None
    labels = labels or [r.name for r in results]
    pnames: list[str] = []
    for r in results:
        pnames += [k for k in r.parameters if k not in pnames]
    varying = [k for k in pnames
               if len({fmt(r.parameters.get(k)) for r in results}) > 1]
    rows = []
    for lab, r in zip(labels, results):
        tf = r.tf
        if isinstance(tf, dict):
            tf = sum(v for v in tf.values() if finite_or_none(v) is not None) if tf else None
        n_ok = sum(bool(c.get("passed")) for c in r.expect)
        row = [cell(lab, "name"), status_cell(r.status), cell(r.objective, "num", 8), cell(tf, "num", 8),
               cell(r.iterations), cell((r.nlp or {}).get("variables")),
               cell((r.wall_time_s or {}).get("total"), "num", 4),
               ({"text": f"{n_ok}/{len(r.expect)}", "cls": "pass" if n_ok == len(r.expect) else "fail"}
                if r.expect else cell(None))]
        row += [cell(r.parameters.get(k)) for k in varying]
        rows.append(row)
    return table("runs", "Compared runs.", ["run", "status", "objective", "t_f", "iterations",
                                            "NLP variables", "wall time [s]", "checks"] + varying, rows)


def expect_comparison_table(results: list[Result], labels: list[str]) -> dict | None:
    rows = []
    for lab, r in zip(labels, results):
        for c in r.expect or []:
            rows.append([cell(lab, "name"), cell(c.get("name", "?"), ""), cell(c.get("reference"), "num", 10),
                         cell(c.get("value"), "num", 10), cell(c.get("error"), "num", 3), verdict(c.get("passed"))])
    return table("expect_all", "Expected values of every run.",
                 ["run", "check", "reference", "ocdsl", "error", "result"], rows)
