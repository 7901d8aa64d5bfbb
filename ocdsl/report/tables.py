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


def table(key: str, caption: str, columns: Sequence[str], rows: list[list[dict]], note: str = "") -> dict | None:
    if not rows:
        return None
    return {"key": key, "caption": caption, "columns": list(columns), "rows": rows, "note": note}


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
def summary_table(res: Result) -> dict:
    rows = [[cell("status", "name"), status_cell(res.status)]]
    if res.message:
        rows.append([cell("message", "name"), cell(res.message, "")])
    sense = ((res.problem or {}).get("objective") or {}).get("sense")
    rows.append([cell("objective" + (f" ({sense})" if sense else ""), "name"), cell(res.objective, "num", 10)])
    if isinstance(res.tf, dict):
        for k, v in res.tf.items():
            rows.append([cell(f"final time t_f ({k})", "name"), cell(v, "num", 10)])
    else:
        rows.append([cell("final time t_f", "name"), cell(res.tf, "num", 10)])
    rows.append([cell("iterations", "name"), cell(res.iterations)])
    for k in ("variables", "constraints", "nonzeros"):
        if k in (res.nlp or {}):
            rows.append([cell(f"NLP {k}", "name"), cell(res.nlp[k])])
    for k, v in (res.nlp or {}).items():
        if k not in ("variables", "constraints", "nonzeros"):
            rows.append([cell(f"NLP {k}", "name"), cell(v)])
    if "total" in (res.wall_time_s or {}):
        rows.append([cell("wall time total [s]", "name"), cell(res.wall_time_s["total"], "num", 4)])
    if res.expect:
        n_ok = sum(bool(c.get("passed")) for c in res.expect)
        rows.append([cell("expect checks passed", "name"),
                     {"text": f"{n_ok} of {len(res.expect)}", "cls": "pass" if n_ok == len(res.expect) else "fail"}])
    if res.certificate:
        ok = _overall(res.certificate)
        rows.append([cell("optimality certificate", "name"), verdict(ok) if ok is not None else cell("present", "")])
    return table("summary", "Solution summary.", ["quantity", "value"], rows)


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


def expect_table(res: Result) -> dict | None:
    rows = []
    for c in res.expect or []:
        tol = []
        if c.get("rtol") is not None:
            tol.append(f"rtol {fmt(c['rtol'], 3)}")
        if c.get("atol") is not None:
            tol.append(f"atol {fmt(c['atol'], 3)}")
        rows.append([cell(c.get("name", "?"), "name"), cell(c.get("reference"), "num", 10),
                     cell(c.get("value"), "num", 10), cell(c.get("error"), "num", 3),
                     cell(", ".join(tol) or "—", ""), verdict(c.get("passed"))])
    return table("expect", "Expected values (reference, e.g. from the paper) against ocdsl's.",
                 ["check", "reference", "ocdsl", "error", "tolerance", "result"], rows)


_PASS_KEYS = ("passed", "pass", "ok", "satisfied", "valid", "verified", "success")


def _overall(cert: Any) -> bool | None:
    if isinstance(cert, dict):
        for k in _PASS_KEYS:
            if isinstance(cert.get(k), (bool, np.bool_)):
                return bool(cert[k])
        subs = [_overall(v) for v in cert.values() if isinstance(v, (dict, list))]
        subs = [s for s in subs if s is not None]
        return all(subs) if subs else None
    if isinstance(cert, list):
        subs = [s for s in (_overall(v) for v in cert) if s is not None]
        return all(subs) if subs else None
    return None


def certificate_table(cert: Any) -> dict | None:
    """Any certificate dict, one row per top-level item: its numbers as ``key = value``
    and, when it carries a pass flag (``passed``, ``ok``, ...), a coloured verdict."""
    if not cert:
        return None
    if not isinstance(cert, dict):
        cert = {"certificate": cert}
    rows = []
    overall = _overall(cert)
    if overall is not None:
        rows.append([cell("overall", "name"), cell("", ""), verdict(overall)])

    def details(d: dict) -> str:
        return "; ".join(f"{k} = {fmt(v, 4)}" for k, v in _flatten(d)
                         if k.rsplit(".", 1)[-1] not in _PASS_KEYS or not isinstance(v, (bool, np.bool_)))

    def flag(d: dict) -> bool | None:
        return next((bool(d[k]) for k in _PASS_KEYS if isinstance(d.get(k), (bool, np.bool_))), None)

    for k, v in cert.items():
        if k in _PASS_KEYS and isinstance(v, (bool, np.bool_)):
            continue
        if isinstance(v, dict):
            ok = flag(v)
            rows.append([cell(k, "name"), cell(details(v) or "—", "details"),
                         verdict(ok) if ok is not None else cell("", "")])
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            for i, x in enumerate(v):
                label = x.get("name") or x.get("check") or x.get("label") or str(i)
                rest = {kk: y for kk, y in x.items() if kk not in ("name", "check", "label")}
                ok = flag(rest)
                rows.append([cell(f"{k}[{label}]", "name"), cell(details(rest) or "—", "details"),
                             verdict(ok) if ok is not None else cell("", "")])
        else:
            rows.append([cell(k, "name"), cell(v, "details"), cell("", "")])
    return table("certificate", "Optimality certificate (first-order necessary conditions and "
                 "re-integration).", ["item", "values", "verdict"], rows)


def starts_table(res: Result) -> dict | None:
    """Multi-start records (``extra["starts"]``: list of dicts)."""
    recs = (res.extra or {}).get("starts")
    if not isinstance(recs, list) or len(recs) < 2 or not all(isinstance(r, dict) for r in recs):
        return None
    cols: list[str] = []
    for r in recs:
        cols += [k for k in r if k not in cols]
    best = min((r.get("objective") for r in recs if isinstance(r.get("objective"), (int, float))), default=None)
    rows = []
    for r in recs:
        row = [status_cell(str(r[c])) if c == "status" else cell(r.get(c), None, 10 if c == "objective" else 6)
               for c in cols]
        rows.append(row)
    return table("starts", "Multi-start: every start and its result" +
                 (f" (best objective {fmt(best, 10)})." if best is not None else "."), cols, rows)


def extra_table(res: Result, skip: Iterable[str] = ("mesh_history", "ipopt_history", "starts")) -> dict | None:
    rows = [[cell(k, "name"), cell(v)] for k, v in _flatten({k: v for k, v in (res.extra or {}).items()
                                                             if k not in skip})]
    return table("extra", "Back-end details.", ["item", "value"], rows)


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
def column_table(key: str, caption: str, cols: dict[str, Any], max_rows: int = 40, digits: int = 6) -> dict | None:
    """A tables/<name>.csv (or study table) as rows; long tables are thinned evenly."""
    if not cols:
        return None
    names = list(cols)
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
    return table(key, caption, names, rows, note)


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


def closed_loop_table(tables: dict[str, dict[str, np.ndarray]], problem: dict) -> dict | None:
    rows = []
    states = set()
    for info in (problem.get("phases") or {}).values():
        states |= set(info.get("states") or [])
    for name, tab in sorted(tables.items()):
        if not name.startswith("closed_loop_") or "t" not in tab:
            continue
        t = np.asarray(tab["t"], float)
        sv = [k for k in tab if k in states] or [k for k in tab if k not in ("t", "timing")]
        final = np.array([np.asarray(tab[k], float)[-1] for k in sv]) if t.size else np.array([])
        timing = np.asarray(tab.get("timing", []), float) * 1e3
        timing = timing[np.isfinite(timing)]
        rows.append([cell(name[len("closed_loop_"):], "name"), cell(int(t.size)),
                     cell(float(t[-1]) if t.size else None),
                     cell(float(np.linalg.norm(final)) if final.size else None, "num", 4),
                     cell(float(np.mean(timing)) if timing.size else None, "num", 4),
                     cell(float(np.percentile(timing, 95)) if timing.size else None, "num", 4),
                     cell(float(np.max(timing)) if timing.size else None, "num", 4)])
    return table("closed_loop", "Closed-loop runs: final state and controller timing per update.",
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
