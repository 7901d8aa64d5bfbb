"""The document being built: sections of tables, figures and equations, numbered in
order; equations typeset offline by matplotlib's mathtext."""
from __future__ import annotations

import base64
import io
import re
import warnings
from typing import Any, Callable, Iterable

from ocdsl.report import figures as F


class ReportError(RuntimeError):
    """A report could not be written (bad input, or no PDF engine)."""


class NotARunFolder(ReportError):
    """The folder given to ``ocdsl report`` is not a run or study folder: the caller's input,
    exit 2 like a missing folder (it was 1, unseen33 F12)."""

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

def _append(doc: Doc, sub: Doc, title: str) -> None:
    for s in sub.sections:
        s["title"] = title if s["id"] == "problem" else s["title"]
        doc.sections.append(s)
    doc.warnings += sub.warnings
    _renumber(doc)
