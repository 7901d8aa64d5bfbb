"""Cells and tables as plain data: number formatting, symbol names and units as HTML,
the table dict the templates read."""
from __future__ import annotations

import math
import re
from typing import Any, Sequence

import numpy as np
from markupsafe import Markup, escape


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


def truthy(v: Any) -> bool:
    """A flag cell (``pareto``: 1, "True", "yes") as a bool; missing or unreadable is False."""
    if isinstance(v, str):
        return v.strip().lower() in ("1", "1.0", "true", "yes", "y", "t")
    f = finite_or_none(v)
    return bool(f) if f is not None else False
