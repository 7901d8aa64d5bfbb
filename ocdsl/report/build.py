"""Build HTML and PDF reports from run folders (never re-solves).

Public API (stable; the CLI calls these):

``make_report(run_dir, formats=("html", "pdf"), *, out_dir=None, engine="auto") -> list[Path]``
    Report of one run folder, written as ``report.html`` / ``report.pdf`` into the run
    folder (or ``out_dir``). Returns the paths written, in the order of ``formats``.

``make_comparison_report(run_dirs, out_dir, formats=("html", "pdf"), *, title=None, engine="auto") -> list[Path]``
    One report comparing several run folders and/or study folders (a folder with
    ``study.csv``/``study.json`` and one run folder per point, or any folder holding run
    folders), written to ``out_dir/report.html`` and ``out_dir/report.pdf``.

``make_index(report_dirs, out_path, paper_numbers, *, title=...) -> Path``
    ``reports/index.html``: every paper number against ocdsl's (``paper_numbers`` is a list
    of dicts ``{study, quantity, paper, ocdsl, error, passed, report_link}``) and a link to
    each report folder in ``report_dirs``.

The HTML is one self-contained file: figures are embedded PNG (``data:`` URIs), equations
are rendered offline by matplotlib's mathtext, and nothing refers to the network. The PDF
is made from the same HTML with WeasyPrint (CSS paged media: A4 pages, page numbers,
repeated table headers); when WeasyPrint cannot be imported, headless Chromium is used if
installed. ``engine`` forces one (``"weasyprint"`` or ``"chromium"``).
"""
from __future__ import annotations

import base64
import csv
import io
import json
import os
import re
import shutil
import subprocess
import tempfile
import warnings
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

import numpy as np

from ocdsl import run_folder
from ocdsl.result import Result
from ocdsl.report import figures as F
from ocdsl.report import status as S
from ocdsl.report import tables as T

TEMPLATES = Path(__file__).with_name("templates")
GOOD = ("optimal", "acceptable", "feasible", "stable")
FORMATS = ("html", "pdf")
CHROMIUM_CANDIDATES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
STUDY_OUTPUT_COLS = {"status", "objective", "tf", "t_f", "iterations", "wall_time", "wall_time_s",
                     "host", "message", "run", "run_dir", "folder", "dir", "path", "pareto", "seed",
                     "point", "index", "id", "name", "family", "label", "solution", "elapsed",
                     "worker", "attempt", "started", "finished", "nlp_variables", "ok"}


class ReportError(RuntimeError):
    """A report could not be written (bad input, or no PDF engine)."""


# =============================================================================== document
class Doc:
    """Sections of blocks, numbering tables, figures and equations in document order."""

    def __init__(self) -> None:
        self.sections: list[dict] = []
        self.n_tables = self.n_figures = self.n_equations = 0
        self.warnings: list[str] = []
        self.files: dict[str, bytes] = {}     # figures/<key>.svg|pdf, written beside the report

    def section(self, sid: str, title: str) -> list[dict]:
        self.sections.append({"id": sid, "title": title, "blocks": []})
        return self.sections[-1]["blocks"]

    def table(self, blocks: list[dict], tab: dict | None) -> None:
        if tab:
            self.n_tables += 1
            blocks.append({"type": "table", "number": self.n_tables, **tab})

    def figures(self, blocks: list[dict], figs: Iterable[F.Fig]) -> None:
        for f in figs:
            try:
                width_cm = f.figure.get_figwidth() * 2.54
                svg, pdf = F.to_svg(f.figure), F.to_pdf(f.figure)
            finally:
                f.figure.clear()
            self.n_figures += 1
            name = f"figures/{re.sub(r'[^A-Za-z0-9_.-]+', '_', f.key)}"
            while f"{name}.svg" in self.files:
                name += "_"
            self.files[f"{name}.svg"], self.files[f"{name}.pdf"] = svg, pdf
            blocks.append({"type": "figure", "number": self.n_figures, "file": name,
                           "src": "data:image/svg+xml;base64," + base64.b64encode(svg).decode("ascii"),
                           "caption": f.caption, "width_cm": min(width_cm, 16.5)})

    def equations(self, blocks: list[dict], title: str | None, items: list[tuple[str, str, str]]) -> None:
        """``items``: (latex, fallback text, tag) triples."""
        out = []
        for latex, text, tag in items:
            self.n_equations += 1
            img = math_image(latex) if latex else None
            e = {"number": self.n_equations, "alt": text or latex, "tag": tag, "src": None}
            if img:
                e.update(img)
            out.append(e)
        if out:
            blocks.append({"type": "equations", "title": title, "entries": out})

    def guard(self, what: str, fn: Callable[[], Any]) -> Any:
        """Run one optional part; a failure becomes a note in the report, never an error."""
        try:
            return fn()
        except Exception as exc:  # noqa: BLE001
            self.warnings.append(f"{what}: {type(exc).__name__}: {exc}")
            return None


# ============================================================================= equations
_MATH_FIXES = [
    (re.compile(r"\\text\{([^{}]*)\}"), r"\\mathrm{\1}"),
    (re.compile(r"\\operatorname\{([^{}]*)\}"), r"\\mathrm{\1}"),
    (re.compile(r"\\limits"), ""),
    (re.compile(r"\\displaystyle"), ""),
    (re.compile(r"\\,|\\;|\\!"), r"\\ "),
    (re.compile(r"\\middle"), ""),
]


def math_image(latex: str, fontsize: float = 11.5, dpi: int = 220) -> dict | None:
    """Render LaTeX with matplotlib mathtext to a PNG data URI; ``None`` if mathtext
    cannot parse it (the report then shows the source text)."""
    from matplotlib import rc_context
    from matplotlib.font_manager import FontProperties
    from matplotlib.mathtext import math_to_image

    src = latex.strip().strip("$").strip()
    if not src:
        return None
    candidates = [src]
    fixed = src
    for pat, rep in _MATH_FIXES:
        fixed = pat.sub(rep, fixed)
    if fixed != src:
        candidates.append(fixed)
    for cand in candidates:
        buf = io.BytesIO()
        try:
            with rc_context({"mathtext.fontset": "cm"}), warnings.catch_warnings():
                warnings.simplefilter("ignore")
                math_to_image(f"${cand}$", buf, prop=FontProperties(size=fontsize), dpi=dpi, format="png")
        except Exception:  # noqa: BLE001  (mathtext parse errors are ValueError, some others)
            continue
        data = buf.getvalue()
        w, h = int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")
        return {"src": "data:image/png;base64," + base64.b64encode(data).decode("ascii"),
                "w": w / dpi * 72.0, "h": h / dpi * 72.0}
    return None


_FUNCS = {"sin", "cos", "tan", "exp", "log", "sinh", "cosh", "tanh", "arcsin", "arccos", "arctan", "min", "max"}


def text_to_latex(text: str) -> str:
    """A constraint as written (``x(tf) == 2``, ``0 <= u <= 1``, ``v**2 + w``) as mathtext,
    for files that give no LaTeX; the report falls back to the text if mathtext refuses it."""
    s = str(text)
    s = re.sub(r"\*\*\s*(\w+(?:\.\d+)?|\([^()]*\))", lambda m: "^{%s}" % m.group(1).strip("()"), s)

    def ident(m: re.Match) -> str:
        w = m.group(0)
        if w in ("t0", "tf"):
            return "t_{%s}" % w[1:]
        if w in _FUNCS:
            return "\\" + w
        if w == "sqrt":
            return r"\mathrm{sqrt}"
        return F.tex_name(w)

    s = re.sub(r"(?<![\\\w])[A-Za-z_]\w*", ident, s)
    for a, b in (("==", "="), ("<=", r" \leq "), (">=", r" \geq "), ("!=", r" \neq "), ("*", r" \cdot ")):
        s = s.replace(a, b)
    return s


def _dynamics_latex(state: str, latex: str) -> str:
    s = latex.strip().strip("$")
    if re.search(r"(?<![<>\\])=", s) or s.startswith(("\\dot", "\\frac{d")):
        return s
    return r"\dot{%s} = %s" % (F.tex_name(state), s)


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
        raise ReportError(f"{run_dir}: not a readable run folder (result.json: {exc})") from exc
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


# ============================================================================ sections
def _problem_section(doc: Doc, res: Result) -> None:
    prob = res.problem or {}
    if not prob and not res.parameters and not res.method:
        return
    b = doc.section("problem", "Problem")
    if prob.get("description"):
        b.append({"type": "text", "text": prob["description"]})
    doc.table(b, doc.guard("states table", lambda: T.variables_table(res, "states")))
    doc.table(b, doc.guard("controls table", lambda: T.variables_table(res, "controls")))
    doc.table(b, doc.guard("parameters table", lambda: T.parameters_table(res)))
    phases = prob.get("phases") or {}
    multi = len(phases) > 1
    groups: dict[str, list[str]] = {}      # phases with the same equations are typeset once
    for pname, info in phases.items():
        key = json.dumps({k: info.get(k) for k in ("dynamics_latex", "expressions_latex", "constraints",
                                                    "constraints_latex", "t0", "tf")}, sort_keys=True, default=str)
        groups.setdefault(key, []).append(pname)
    for names in groups.values():
        pname, info = names[0], phases[names[0]]
        where = (f" — phase {pname}" if len(names) == 1 else
                 " — phases " + ", ".join(names)) if multi else ""
        dyn = [(_dynamics_latex(s, lt), f"d{s}/dt = {lt}", "") for s, lt in (info.get("dynamics_latex") or {}).items()]
        doc.guard("dynamics", lambda: doc.equations(b, "Dynamics" + where, dyn))
        exprs = [(f"{F.tex_name(k)} = {lt}", f"{k} = {lt}", "") for k, lt in (info.get("expressions_latex") or {}).items()]
        if exprs:
            doc.guard("expressions", lambda: doc.equations(b, "Expressions" + where, exprs))
        texts = list(info.get("constraints") or [])
        lats = list(info.get("constraints_latex") or [])
        n = max(len(texts), len(lats))
        cons = [(lats[i] if i < len(lats) and lats[i] else text_to_latex(texts[i]) if i < len(texts) else "",
                 texts[i] if i < len(texts) else "", "") for i in range(n)]
        times = []
        for k, sym in (("t0", "t_0"), ("tf", "t_f")):
            v = info.get(k)
            if v is None:
                continue
            times.append((f"{sym} = {T.fmt(v)}" if v != "free" else r"%s\ \mathrm{free}" % sym,
                          f"{k} = {v}", ""))
        doc.guard("constraints", lambda: doc.equations(b, "Constraints and boundary conditions" + where,
                                                      cons + times))
    obj = prob.get("objective") or {}
    if obj:
        sense = obj.get("sense", "minimize")
        lat = obj.get("latex") or ""
        items = [((r"\mathrm{%s}\quad " % sense) + lat if lat else "", f"{sense} {obj.get('text', '')}", "")]
        doc.guard("objective", lambda: doc.equations(b, "Objective", items))
    links = prob.get("links") or []
    if links:
        doc.guard("links", lambda: doc.equations(b, "Phase links", [("", str(x), "") for x in links]))
    doc.table(b, doc.guard("method table", lambda: T.method_table(res)))


def _solution_section(doc: Doc, res: Result, notes: list[str]) -> None:
    b = doc.section("solution", "Solution")
    if res.status not in GOOD or (res.message and res.status not in GOOD):
        hint = {"infeasible": "The solver found no point satisfying the constraints: check bounds, "
                              "boundary conditions and the initial guess.",
                "max_iter": "The iteration limit was reached before convergence: raise it, refine the "
                            "initial guess, or scale the problem.",
                "error": "The run stopped with an error before a solution was found.",
                "mesh_not_converged": "The mesh refinement did not reach its tolerance.",
                "unstable": "The closed loop diverged.",
                "not_run": "This point was not run."}.get(res.status, "")
        b.append({"type": "diagnosis", "status": res.status, "message": res.message, "hint": hint})
    for n in notes:
        b.append({"type": "note", "text": n})
    doc.table(b, doc.guard("summary table", lambda: T.summary_table(res)))
    doc.table(b, doc.guard("wall-time table", lambda: T.wall_time_table(res)))
    doc.table(b, doc.guard("phases table", lambda: T.phases_table(res)))
    doc.table(b, doc.guard("expect table", lambda: T.expect_table(res)))
    doc.table(b, doc.guard("verification table", lambda: T.verification_table(res)))
    doc.table(b, doc.guard("certificate table", lambda: T.certificate_table(res.certificate)))
    doc.table(b, doc.guard("switch table", lambda: T.switch_table(res.certificate)))
    doc.table(b, doc.guard("multi-start table", lambda: T.starts_table(res)))
    hist = (res.extra or {}).get("ipopt_history")
    if hist:
        doc.guard("solver history", lambda: doc.figures(b, F.fig_solver_history(hist)))


def _figures_section(doc: Doc, res: Result) -> None:
    if not any(len(p.time) for p in res.phases):
        return
    cl = F.closed_loop_tables(res.tables)
    if cl and all(p.name in cl for p in res.phases):
        return      # a controller file's phases are its closed-loop runs: drawn once, in their section
    b = doc.section("trajectory", "Trajectory")
    if res.status not in GOOD:
        b.append({"type": "note", "text": f"The run ended with status {res.status}: the figures show the "
                                          "solver's last iterate, not a verified solution."})
    for what, fn in (("state/control figures", F.fig_states_controls), ("costate figure", F.fig_costates),
                     ("Hamiltonian figures", F.fig_hamiltonian), ("trajectory view", F.fig_positions),
                     ("other time histories", F.fig_other_extra)):
        doc.guard(what, lambda fn=fn: doc.figures(b, fn(res)))
    if reintegration_tables(res):
        b2 = doc.section("reintegration", "Re-integration check")
        doc.table(b2, doc.guard("re-integration table", lambda: T.reintegration_table(res)))
        doc.guard("re-integration figure", lambda: doc.figures(b2, F.fig_reintegration(res)))


def _mesh_table(res: Result) -> dict[str, np.ndarray] | None:
    if "mesh_history" in res.tables:
        return res.tables["mesh_history"]
    mh = (res.extra or {}).get("mesh_history")
    if isinstance(mh, dict) and mh and all(isinstance(v, list) for v in mh.values()):
        return {k: np.asarray(v, float) for k, v in mh.items()}
    if isinstance(mh, list) and mh and all(isinstance(x, dict) for x in mh):
        keys = [k for k in mh[0] if all(isinstance(x.get(k), (int, float)) for x in mh)]
        return {k: np.asarray([x[k] for x in mh], float) for k in keys}
    return None


def _tables_sections(doc: Doc, res: Result) -> None:
    cl = F.closed_loop_tables(res.tables)
    if cl:
        b = doc.section("closed-loop", "Closed-loop simulation")
        doc.table(b, doc.guard("controller table", lambda: T.controller_table(res)))
        doc.table(b, doc.guard("closed-loop table", lambda: T.closed_loop_table(res.tables, res.problem, res.extra)))
        doc.guard("closed-loop figures", lambda: doc.figures(b, F.fig_closed_loop(res.tables, res.problem)))
    mh = doc.guard("mesh history", lambda: _mesh_table(res))
    if mh:
        b = doc.section("mesh", "Mesh refinement")
        doc.table(b, doc.guard("mesh table", lambda: T.column_table(
            "mesh_history", "Mesh refinement history.", mh, max_rows=30, drop_constant=True)))
        hist = (res.extra or {}).get("mesh_history")
        tol = T.finite_or_none(((res.method or {}).get("mesh") or {}).get("tolerance")
                               if isinstance((res.method or {}).get("mesh"), dict) else None)
        doc.guard("mesh figure", lambda: doc.figures(b, F.fig_mesh_history(
            mh, hist if isinstance(hist, list) else None, res.tables.get("mesh_error"), tol)))
    for name, tab in sorted(res.tables.items()):
        if name.startswith("pareto") or "pareto" in tab:
            b = doc.section(f"tab-{name}", f"Pareto set ({name})")
            rows = _rows_of(tab)
            crit = _criteria(rows, {"objectives": (res.extra or {}).get("objectives")})
            doc.table(b, doc.guard(f"table {name}", lambda: T.column_table(name, f"Solutions ({name}).", tab)))
            if crit:
                doc.guard("Pareto figure", lambda: doc.figures(b, F.fig_pareto(rows, crit, res.problem.get("units"))))
    other = [n for n in sorted(res.tables) if n not in ("mesh_history", "mesh_error")
             and not n.startswith(("closed_loop_", "reintegration"))
             and not (n.startswith("pareto") or "pareto" in res.tables[n])]
    if other:
        b = doc.section("tables", "Other tables in the run folder")
        for n in other:
            parts = split_columns(res.tables[n])
            for i, cols in enumerate(parts):
                part = f" (part {i + 1} of {len(parts)}: {', '.join(list(cols)[1:3])}, ...)" if len(parts) > 1 else ""
                doc.table(b, doc.guard(f"table {n}", lambda n=n, cols=cols, part=part: T.column_table(
                    n, f"Table tables/{n}.csv{part}.", cols)))


def split_columns(cols: dict[str, Any], per: int = 9) -> list[dict[str, Any]]:
    """A table too wide for the page as several, each with the first (key) column: by the
    prefix before the first "." when the columns have one (``lqr.cost``, ``sdre.cost``),
    else ``per`` columns at a time."""
    names = list(cols)
    if len(names) <= per + 1:
        return [cols]
    key, rest = names[0], names[1:]
    groups: dict[str, list[str]] = {}
    if all("." in n for n in rest):
        for n in rest:
            groups.setdefault(n.split(".", 1)[0], []).append(n)
    if not groups or any(len(g) > per for g in groups.values()):
        groups = {str(i): rest[i:i + per] for i in range(0, len(rest), per)}
    return [{key: cols[key], **{n: cols[n] for n in g}} for g in groups.values()]


def _rows_of(cols: dict[str, np.ndarray]) -> list[dict[str, Any]]:
    n = max((len(v) for v in cols.values()), default=0)
    return [{k: (v[i] if i < len(v) else None) for k, v in cols.items()} for i in range(n)]


def _criteria(rows: list[dict], meta: dict) -> tuple[str, str] | None:
    """The two Pareto criteria: named by study.json (``criteria``/``objectives``, possibly
    under ``pareto``), else the first two numeric columns that are not bookkeeping."""
    if not rows:
        return None
    for src in (meta, meta.get("pareto") if isinstance(meta.get("pareto"), dict) else {}):
        for key in ("criteria", "objectives"):
            v = src.get(key) if isinstance(src, dict) else None
            if isinstance(v, list) and len(v) >= 2:
                names = [x if isinstance(x, str) else (x.get("name") if isinstance(x, dict) else None) for x in v]
                if all(n in rows[0] for n in names[:2] if n):
                    if names[0] and names[1]:
                        return names[0], names[1]
    numeric = [k for k in rows[0] if k not in STUDY_OUTPUT_COLS and k != "t"
               and sum(T.finite_or_none(r.get(k)) is not None for r in rows) >= max(1, len(rows) // 2)]
    return (numeric[0], numeric[1]) if len(numeric) >= 2 else None


# ================================================================================ output
_INNER_HYPHEN = re.compile(r"(?<=\w)-(?=\w)")


def nobreak(text: Any) -> Any:
    """Hyphens inside words as non-breaking hyphens: a table cell never breaks
    "bang-bang" across lines."""
    from markupsafe import Markup, escape

    if isinstance(text, Markup):
        return text
    return Markup(_INNER_HYPHEN.sub("\u2011", str(escape(text))))


def _env():
    import jinja2
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(str(TEMPLATES)), autoescape=True,
                             trim_blocks=False, lstrip_blocks=False)
    env.filters["nobreak"] = nobreak
    return env


def _render(doc: Doc, title: str, subtitle: str, meta: list[tuple[str, str]], badges: Sequence = ()) -> str:
    if doc.warnings:
        b = doc.section("warnings", "Notes on this report")
        b.append({"type": "warnings", "entries": doc.warnings})
    return _env().get_template("report.html.j2").render(
        title=title, subtitle=subtitle, meta=meta, badges=list(badges), sections=doc.sections,
        build=S.ocdsl_build())


def _atomic_write(path: Path, data: bytes | str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    run_folder.atomic_write_text(path, data)


def _output_folder(out_dir: Path, names: Sequence[str]) -> None:
    """Reports go into an ocdsl folder (a run, a study) or a new one, never over files
    ocdsl did not write (ocdsl/run_folder.py)."""
    if out_dir.is_dir() and run_folder.read_marker(out_dir) is not None:
        return
    if (out_dir / "result.json").is_file():
        return                  # a run folder of an ocdsl from before the marker: its reports are ocdsl's
    try:
        run_folder.check_destination(out_dir, "comparison")
    except run_folder.FolderError as e:
        raise ReportError(str(e)) from None
    out_dir.mkdir(parents=True, exist_ok=True)
    run_folder.write_marker(out_dir, "comparison", names)


def chromium_binary() -> str | None:
    for name in CHROMIUM_CANDIDATES:
        p = shutil.which(name)
        if p:
            return p
    return None


def _pdf_weasyprint(html: str, pdf: Path) -> None:
    import logging
    import weasyprint  # noqa: PLC0415  (optional: needs Pango; raises OSError without it)
    logging.getLogger("weasyprint").setLevel(logging.ERROR)
    logging.getLogger("fontTools").setLevel(logging.ERROR)
    data = weasyprint.HTML(string=html, base_url=str(pdf.parent)).write_pdf()
    _atomic_write(pdf, data)


def _pdf_chromium(html: str, pdf: Path) -> None:
    exe = chromium_binary()
    if exe is None:
        raise FileNotFoundError("no chromium binary on PATH")
    with tempfile.TemporaryDirectory(prefix="ocdsl-report-") as tmp:
        src = Path(tmp) / "report.html"
        src.write_text(html, encoding="utf-8")
        out = Path(tmp) / "report.pdf"
        cmd = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
               "--disable-background-networking", "--disable-component-update", "--disable-sync",
               f"--user-data-dir={tmp}/profile", "--no-pdf-header-footer",
               f"--print-to-pdf={out}", src.as_uri()]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=180)
        if not out.is_file() or out.stat().st_size == 0:
            raise OSError(f"chromium made no PDF (exit {proc.returncode}): {proc.stderr[-500:]}")
        _atomic_write(pdf, out.read_bytes())


PDF_ENGINES: dict[str, Callable[[str, Path], None]] = {"weasyprint": _pdf_weasyprint, "chromium": _pdf_chromium}


def write_pdf(html: str, pdf: Path, engine: str = "auto") -> str:
    """Write ``pdf`` from ``html``; returns the engine used. ``auto`` tries WeasyPrint, then
    Chromium."""
    names = list(PDF_ENGINES) if engine == "auto" else [engine]
    errors = []
    for name in names:
        if name not in PDF_ENGINES:
            raise ReportError(f"unknown PDF engine {name!r}; choose from {sorted(PDF_ENGINES)} or 'auto'")
        try:
            PDF_ENGINES[name](html, pdf)
            return name
        except (ImportError, OSError, subprocess.SubprocessError) as exc:
            errors.append(f"{name}: {type(exc).__name__}: {exc}")
    raise ReportError("could not write the PDF report (" + "; ".join(errors) + "). Install WeasyPrint "
                      "(pip install weasyprint; Debian packages libpango-1.0-0 libpangoft2-1.0-0) "
                      "or Debian's chromium, or ask for formats=('html',).")


def _write_outputs(html: str, out_dir: Path, formats: Sequence[str], engine: str, stem: str = "report",
                   files: dict[str, bytes] | None = None) -> list[Path]:
    formats = tuple(formats)
    bad = [f for f in formats if f not in FORMATS]
    if bad:
        raise ReportError(f"unknown report format(s) {bad}; choose from {list(FORMATS)}")
    written: dict[str, Path] = {}
    _output_folder(out_dir, [f"{stem}.{f}" for f in formats])
    run_folder.claim(out_dir, [f"{stem}.{f}" for f in formats])
    if files:       # each figure as SVG and PDF, for reuse in a paper
        marker = run_folder.read_marker(out_dir)
        if marker is not None:     # an earlier report's figures (ocdsl's own, listed) go
            stale = [n for n in marker.get("entries", []) if n.startswith("figures/") and n not in files]
            for name in stale:
                (out_dir / name).unlink(missing_ok=True)
            run_folder.write_marker(out_dir, marker["kind"], [n for n in marker.get("entries", []) if n not in stale],
                                    partial=marker.get("partial", False))
        run_folder.claim(out_dir, ["figures", *files])
        for name, data in files.items():
            _atomic_write(out_dir / name, data)
    if "html" in formats:
        written["html"] = out_dir / f"{stem}.html"
        _atomic_write(written["html"], html)
    if "pdf" in formats:
        written["pdf"] = out_dir / f"{stem}.pdf"
        write_pdf(html, written["pdf"], engine)
    return [written[f] for f in formats if f in written]


# ============================================================================ public API
def build_run_html(run_dir: str | os.PathLike) -> str:
    """The HTML of one run folder's report (what :func:`make_report` writes)."""
    return _build_run(Path(run_dir))[0]


def _build_run(run_dir: Path) -> tuple[str, dict[str, bytes]]:
    run_dir = Path(run_dir)
    if not _is_run(run_dir):
        raise ReportError(f"{run_dir}: not a run folder (no result.json)")
    res, notes = load_run(run_dir)
    doc = Doc()
    notes = notes + missing_notes(res)
    if res.status in GOOD:      # the problem first, as a paper would
        _problem_section(doc, res)
        _solution_section(doc, res, notes)
    else:                       # a failed run: its diagnosis first
        _solution_section(doc, res, notes)
        _problem_section(doc, res)
    _figures_section(doc, res)
    _tables_sections(doc, res)
    extra = doc.guard("back-end table", lambda: T.extra_table(res))
    if extra:
        doc.table(doc.section("appendix", "Appendix: back-end details"), extra)
    prob = res.problem or {}
    title = prob.get("name") or res.name
    meta = [("run", run_dir.name)]
    if res.objective is not None:
        meta.append(("objective", T.fmt(res.objective)))
    if res.method.get("name") or res.method.get("method"):
        meta.append(("method", str(res.method.get("name") or res.method.get("method"))))
    return _render(doc, title, prob.get("description", "") if not prob.get("phases") else "", meta,
                   S.badges(res)), doc.files


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


def _renumber(doc: Doc) -> None:
    """Renumber tables, figures and equations in document order (after moving sections)."""
    n = {"table": 0, "figure": 0, "equations": 0}
    for s in doc.sections:
        for b in s["blocks"]:
            if b["type"] in ("table", "figure"):
                n[b["type"]] += 1
                b["number"] = n[b["type"]]
            elif b["type"] == "equations":
                for e in b["entries"]:
                    n["equations"] += 1
                    e["number"] = n["equations"]


def make_report(run_dir: str | os.PathLike, formats: Sequence[str] = ("html", "pdf"), *,
                out_dir: str | os.PathLike | None = None, engine: str = "auto") -> list[Path]:
    """Write the report of one run folder.

    ``formats`` is any of ``"html"``, ``"pdf"``; files are ``report.html`` and ``report.pdf``
    in the run folder (or ``out_dir``). Returns the written paths in ``formats`` order.
    Reads only the run folder; a failed run (no trajectory) still gets a report with its
    diagnosis. Raises :class:`ReportError` if ``run_dir`` is not a run folder or no PDF
    engine is available (the HTML is written first).
    """
    run_dir = Path(run_dir)
    html, files = _build_run(run_dir)
    return _write_outputs(html, Path(out_dir) if out_dir else run_dir, formats, engine, files=files)


def build_comparison_html(run_dirs: Sequence[str | os.PathLike], title: str | None = None) -> str:
    return _build_comparison(run_dirs, title)[0]


def _build_comparison(run_dirs: Sequence[str | os.PathLike], title: str | None = None) -> tuple[str, dict[str, bytes]]:
    entries: list[tuple[str, Path]] = []       # (label, run folder)
    studies: list[tuple[Path, list[dict], dict]] = []
    for d in [Path(x) for x in ([run_dirs] if isinstance(run_dirs, (str, os.PathLike)) else run_dirs)]:
        if _is_run(d):
            entries.append((d.name, d))
        elif d.is_dir():
            rows, meta = read_study_table(d)
            runs = _find_runs(d)
            if not runs and not rows:
                raise ReportError(f"{d}: neither a run folder nor a study folder (no result.json, no run folders)")
            studies.append((d, rows, meta))
            entries += [(str(r.relative_to(d)) if len(run_dirs) == 1 else f"{d.name}/{r.relative_to(d)}", r)
                        for r in runs]
        else:
            raise ReportError(f"{d}: no such folder")
    results, labels, notes = [], [], []
    for lab, d in entries:
        try:
            r, n = load_run(d)
        except ReportError as exc:
            notes.append(str(exc))
            continue
        results.append(r)
        labels.append(lab)
        notes += [f"{lab}: {x}" for x in n]
    doc = Doc()
    doc.warnings += notes
    for folder, rows, meta in studies:
        _study_section(doc, folder, rows, meta, results)
    if results:
        b = doc.section("runs", "Runs compared")
        doc.table(b, doc.guard("runs table", lambda: T.runs_table(results, labels)))
        doc.table(b, doc.guard("expect table", lambda: T.expect_comparison_table(results, labels)))
        for lab, r in zip(labels, results):
            if r.status not in GOOD and r.message:
                b.append({"type": "note", "text": f"{lab} ({r.status}): {r.message}"})
        shown = [(lab, r) for lab, r in zip(labels, results) if r.phases][:40]
        if shown:
            for lab, r in shown:
                r.name = lab
            doc.guard("comparison figures", lambda: doc.figures(b, F.fig_compare_runs([r for _, r in shown])))
            if len(shown) < sum(bool(r.phases) for r in results):
                b.append({"type": "note", "text": f"Figures show the first {len(shown)} runs with a trajectory."})
        merged: dict[str, dict[str, np.ndarray]] = {}
        for lab, r in zip(labels, results):
            for k, v in F.closed_loop_tables(r.tables).items():
                merged[f"closed_loop_{k if len(results) == 1 else lab + ':' + k}"] = v
        if merged:
            prob = next((r.problem for r in results if r.problem), {})
            b2 = doc.section("closed-loop", "Closed-loop comparison")
            doc.table(b2, doc.guard("closed-loop table", lambda: T.closed_loop_table(merged, prob)))
            doc.guard("closed-loop figures", lambda: doc.figures(b2, F.fig_closed_loop(merged, prob)))
        names = {(r.problem or {}).get("name") for r in results}
        if len(names) == 1 and results[0].problem:
            sub = Doc()
            _problem_section(sub, results[0])
            _append(doc, sub, "Problem (common to the runs; values of the first run)")
    if not title:
        inputs = [Path(x).name for x in ([run_dirs] if isinstance(run_dirs, (str, os.PathLike)) else run_dirs)]
        if studies and len(inputs) == 1:
            title = f"Study {studies[0][0].name}"
        else:
            title = "Comparison of " + ", ".join(inputs[:5]) + (f" and {len(inputs) - 5} more" if len(inputs) > 5 else "")
    return _render(doc, title, "", [("runs", str(len(results)))], study_badges(results)), doc.files


def study_badges(results: Sequence[Result]) -> list[S.Badge]:
    """A comparison's badges: how many runs converged, were verified and are ok."""
    n = len(results)
    if not n:
        return [S.Badge("runs", "none", "fail")]
    conv = sum(r.status in GOOD for r in results)
    ver = sum(r.verified or (r.verification or {}).get("status") == "not_applicable" for r in results)
    ok = sum(r.ok for r in results)
    out = [S.Badge("solver", f"{conv} of {n} converged", "pass" if conv == n else "fail"),
           S.Badge("verification", f"{ver} of {n} verified", "pass" if ver == n else "fail")]
    certs = [S.certificate_passed(r.certificate) for r in results if r.certificate]
    if certs:
        out.append(S.Badge("certificate", f"{sum(c is True for c in certs)} of {len(certs)} pass",
                           "pass" if all(c is True for c in certs) else "fail"))
    out.append(S.Badge("overall", f"{ok} of {n} ok", "pass" if ok == n else "fail"))
    return out


def _append(doc: Doc, sub: Doc, title: str) -> None:
    for s in sub.sections:
        s["title"] = title if s["id"] == "problem" else s["title"]
        doc.sections.append(s)
    doc.warnings += sub.warnings
    _renumber(doc)


def swept_parameters(meta: dict) -> tuple[list[str], str]:
    """The parameters a study sweeps, from ``study.json``'s spec (``sweep: {grid | zip |
    list | random ...: {name: ...}}``), and how: ``zip`` moves its parameters together (a
    one-dimensional sweep along the first). Empty when the spec names none."""
    spec = meta.get("spec")
    if isinstance(spec, str):
        return [], ""
    sweep = (spec or {}).get("sweep") if isinstance(spec, dict) else None
    if not isinstance(sweep, dict):
        return [], ""
    for how, body in sweep.items():
        if isinstance(body, dict) and body:
            return [str(k) for k in body], str(how)
    return [], ""


#: study.csv columns that are bookkeeping, not results: left out of the study table
STUDY_BOOKKEEPING = ("sweep", "host", "warm_start", "seed", "message", "worker", "client_host")


def study_columns(rows: list[dict], swept: Sequence[str]) -> dict[str, list]:
    """study.csv as columns for reading: the swept parameters first, a per-phase ``tf``
    (a JSON object per row) as one column per phase, bookkeeping columns and empty ones
    left out (messages go to notes for the rows that failed)."""
    if not rows:
        return {}
    names = [k for k in rows[0] if k not in STUDY_BOOKKEEPING]
    order = [k for k in swept if k in names] + [k for k in names if k not in swept]
    cols: dict[str, list] = {}
    for k in order:
        vals = [r.get(k) for r in rows]
        parsed = [_json_obj(v) for v in vals]
        if any(isinstance(v, dict) for v in parsed):
            keys: list[str] = []
            for v in parsed:
                keys += [x for x in (v or {}) if x not in keys]
            for x in keys:
                cols[f"{k} ({x})"] = [(v or {}).get(x) for v in parsed]
        elif any(v not in (None, "") for v in vals):
            cols[k] = vals
    return cols


def _json_obj(v: Any) -> Any:
    if isinstance(v, dict):
        return v
    if isinstance(v, str) and v.startswith("{"):
        try:
            return json.loads(v)
        except ValueError:
            return None
    return None


def _study_meta_rows(folder: Path, meta: dict) -> list[list[dict]]:
    """The study definition without machine details: file names, not paths; no host names."""
    rows = []
    for k, v in meta.items():
        if k in ("points", "best", "columns", "client_host", "host", "spec") or isinstance(v, list) and len(v) > 8:
            continue
        if k.endswith("_file") and isinstance(v, str):
            v = Path(v).name
        if isinstance(v, dict):
            v = ", ".join(f"{a} {T.fmt(b)}" for a, b in v.items())
        rows.append([T.cell(k.replace("_", " "), "name"), T.cell(v)])
    swept, how = swept_parameters(meta)
    if swept:
        rows.append([T.cell("swept", "name"), T.cell(f"{', '.join(swept)} ({how})")])
    return rows


def _study_section(doc: Doc, folder: Path, rows: list[dict], meta: dict, results: list[Result]) -> None:
    b = doc.section(f"study-{folder.name}", f"Study {meta.get('name') or folder.name}")
    mrows = _study_meta_rows(folder, meta)
    if mrows:
        doc.table(b, T.table("study-meta", "Study definition (study.json).", ["item", "value"], mrows))
    swept, how = swept_parameters(meta)
    if rows:
        cols = study_columns(rows, swept)
        doc.table(b, doc.guard("study table", lambda: T.column_table(
            f"study-{folder.name}", "Study table (study.csv), one row per point; the solver's message "
            "is given below for the points that did not converge.", cols, max_rows=60, drop_constant=True)))
        for r in rows:
            if str(r.get("status")) not in GOOD and r.get("message"):
                b.append({"type": "note", "text": f"{r.get('id', '?')} ({r.get('status')}): "
                                                  f"{str(r['message']).splitlines()[0][:300]}"})
        if any("pareto" in r for r in rows):
            crit = _criteria(rows, meta)
            if crit:
                units = next((r.problem.get("units") for r in results if r.problem), {})
                doc.guard("Pareto figure", lambda: doc.figures(b, F.fig_pareto(rows, crit, units)))
            else:
                b.append({"type": "note", "text": "The study has Pareto flags but its two criteria could "
                                                  "not be identified (name them in study.json: criteria)."})
            return
        units = next((r.problem.get("units") for r in results if r.problem), {})
        maximize = next((((r.problem or {}).get("objective") or {}).get("sense") == "maximize"
                         for r in results if r.problem), False)
        outputs = [c for c in cols if c == "objective" or c == "tf" or c.startswith("tf (")]
        one_d = bool(swept) and (len(swept) == 1 or how == "zip")
        if not swept:   # no declared sweep: a single varying input column is one
            varying = [k for k in cols if k not in STUDY_OUTPUT_COLS and k not in outputs
                       and all(isinstance(r.get(k), (int, float)) for r in rows) and len({r.get(k) for r in rows}) > 1]
            if len(varying) == 1:
                swept, one_d = varying, True
        if one_d:
            doc.guard("sweep figure", lambda: doc.figures(b, F.fig_sweep(
                [dict(zip(cols, vals)) for vals in zip(*cols.values())], swept[0], outputs, units,
                objective_label="objective (maximize)" if maximize else "objective")))
        elif len(rows) >= 8:
            doc.guard("histograms", lambda: doc.figures(b, F.fig_histograms(rows, [o for o in outputs if o in rows[0]][:2])))


def make_comparison_report(run_dirs: Sequence[str | os.PathLike] | str | os.PathLike,
                           out_dir: str | os.PathLike, formats: Sequence[str] = ("html", "pdf"), *,
                           title: str | None = None, engine: str = "auto") -> list[Path]:
    """Write one report comparing several runs and/or whole studies.

    ``run_dirs``: run folders, study folders (``study.csv``/``study.json`` with one run
    folder per point, or any folder holding run folders), or a single such folder. Writes
    ``out_dir/report.html`` and ``out_dir/report.pdf`` (per ``formats``) and returns the
    written paths. Contents: the study tables (with the Pareto front or the sweep figure
    when the study has one), a per-run comparison table, every run's expect checks, states
    and controls of all runs overlaid, closed-loop comparisons, and the common problem.
    """
    html, files = _build_comparison(run_dirs, title)
    return _write_outputs(html, Path(out_dir), formats, engine, files=files)


def make_index(report_dirs: Sequence[str | os.PathLike], out_path: str | os.PathLike,
               paper_numbers: Sequence[dict[str, Any]], *, title: str = "ocdsl reproductions") -> Path:
    """Write ``out_path`` (e.g. ``reports/index.html``): a table of every reference number
    against ocdsl's and a list of links to the reports in ``report_dirs`` with their badges.

    ``paper_numbers``: dicts as :func:`ocdsl.report.reproduce.expect_numbers` makes them
    (``study, quantity, paper`` (printed in the paper) or ``other`` (another reference, with
    ``source``), ``ocdsl, error, compare, tolerance, verification, verdict, test,
    report_link``); ``report_link`` (a path to a report file or folder) is made relative to
    the index. Links are relative, so the folder can be moved or published as is.
    """
    from ocdsl.report import reproduce as R

    out_path = Path(out_path)
    base = out_path.parent.resolve()

    def rel(p: Any) -> str | None:
        if not p:
            return None
        p = Path(p)
        if p.is_dir() or (not p.suffix and not p.exists()):
            p = p / "report.html"
        p = p if p.is_absolute() else (Path.cwd() / p)
        return os.path.relpath(p.resolve(), base).replace(os.sep, "/")

    vcls = {"verified": "pass", "failed": "fail", "error": "fail"}
    dcls = {R.REPRODUCED: "pass", R.AGREES: "pass", R.SHOWN_WRONG: "warn", R.NOT_REPRODUCED: "fail",
            R.DIFFERS: "fail"}
    numbers = []
    for r in paper_numbers:
        verdict = r.get("verdict") or (R.REPRODUCED if r.get("passed") else R.NOT_REPRODUCED)
        ver = r.get("verification")
        numbers.append({"study": r.get("study", ""), "quantity": r.get("quantity", ""),
                        "paper": T.fmt(r.get("paper"), 8) if r.get("paper") is not None else "",
                        "other": T.fmt(r.get("other"), 8) if r.get("other") is not None else "",
                        "source": r.get("source", ""), "kind": r.get("kind", ""),
                        "ocdsl": T.fmt(r.get("ocdsl"), 8), "error": T.fmt(r.get("error"), 3),
                        "list": any(isinstance(r.get(k), str) and "," in r.get(k) for k in ("ocdsl", "paper", "other")),
                        "compare": r.get("compare", ""), "tolerance": r.get("tolerance", ""),
                        "verification": S.VERIFICATION_TEXT.get(ver, str(ver)), "vcls": vcls.get(ver, ""),
                        "verdict": verdict, "cls": dcls.get(verdict, ""), "test": r.get("test"),
                        "link": rel(r.get("report_link"))})
    reports = []
    for d in report_dirs:
        d = Path(d)
        title_r, marks = d.name, []
        if _is_run(d):
            try:
                res, _ = load_run(d)
                title_r = (res.problem or {}).get("name") or res.name or d.name
                marks = S.badges(res)
            except Exception:  # noqa: BLE001
                marks = [S.Badge("result.json", "unreadable", "fail")]
        elif (d / "study.csv").is_file() or (d / "study.json").is_file():
            rows, meta = read_study_table(d)
            title_r = _study_title(d, meta)
            marks = _study_row_badges(rows)
        reports.append({"title": f"{title_r} ({d.name})" if title_r != d.name else title_r,
                        "link": rel(d), "badges": marks})
    paper_rows = [n for n in numbers if n["paper"]]
    other_rows = [n for n in numbers if not n["paper"]]
    counts = {k: sum(n["verdict"] == k for n in paper_rows) for k in (R.REPRODUCED, R.SHOWN_WRONG, R.NOT_REPRODUCED)}
    counts_other = {k: sum(n["verdict"] == k for n in other_rows) for k in (R.AGREES, R.DIFFERS)}
    verified = sum(n["verdict"] == R.REPRODUCED and n["verification"] == "verified" for n in paper_rows)
    html = _env().get_template("index.html.j2").render(
        title=title, numbers=numbers, reports=reports, counts=counts, counts_other=counts_other,
        n_paper=len(paper_rows), n_other=len(other_rows), n_verified=verified, build=S.ocdsl_build())
    _atomic_write(out_path, html)
    return out_path


def _study_title(folder: Path, meta: dict) -> str:
    for key in ("title", "name"):
        if isinstance(meta.get(key), str) and meta[key]:
            return meta[key]
    plan = folder / "plan.json"
    if plan.is_file():
        try:
            p = json.loads(plan.read_text())
            if isinstance(p, dict) and isinstance(p.get("name"), str):
                return p["name"]
        except ValueError:
            pass
    return folder.name


def _study_row_badges(rows: list[dict]) -> list[S.Badge]:
    """A study's badges from study.csv: points converged, verified, and ok."""
    n = len(rows)
    if not n:
        return [S.Badge("points", "none", "fail")]
    conv = sum(str(r.get("status")) in GOOD for r in rows)
    out = [S.Badge("solver", f"{conv} of {n} converged", "pass" if conv == n else "fail")]
    if any("verification" in r for r in rows):
        ver = sum(str(r.get("verification")) in ("verified", "not_applicable") for r in rows)
        out.append(S.Badge("verification", f"{ver} of {n} verified", "pass" if ver == n else "fail"))
    else:
        out.append(S.Badge("verification", "not recorded", "neutral"))
    return out
