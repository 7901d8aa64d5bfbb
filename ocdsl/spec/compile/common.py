"""Shared names of the compiler's modules: limits, name pattern, small numeric helpers."""
from __future__ import annotations

import math
import re
from typing import Any

import sympy as sp

from ..errors import FollowOnError
from ..schema import PseudospectralMethod

PSEUDOSPECTRAL = ("LG", "LGR", "LGL", "LGR-start")
NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
MAX_VARIABLES = 1000   # states + controls of a model (docs/problem-language.md, "Input limits")
MAX_CONSTRAINTS = 1000  # constraints of a phase, and links (about 1 ms each to compile)


def _broken_table(name: str):
    def call(*_):
        raise FollowOnError(f"table '{name}' has an error (reported at its line)")
    return call


def _validate_method(method: dict) -> Any:
    return _method_class(method).model_validate(method)


def _method_class(method: dict):
    """The spec class of a `method:` block: pseudospectral, or the one its back end registered."""
    kind = method.get("transcription", "LGR")
    if not isinstance(kind, str):
        raise ValueError(f"transcription: a method name such as LGR, not {kind!r}")
    if kind in PSEUDOSPECTRAL:
        return PseudospectralMethod
    from ...methods import method_spec_class  # other back ends register their method specs

    return method_spec_class(kind)


def _is_number(e: sp.Expr) -> bool:
    return bool(getattr(e, "is_number", False)) and (e.is_finite or e in (sp.oo, -sp.oo))


def _num(x: float):
    return x if math.isfinite(x) else None


def _guess_value_ok(value) -> bool:
    """A guess is a number, a list of numbers or {t: [...], values: [...]}, all finite."""
    def numbers(v):
        return isinstance(v, list) and len(v) > 0 and all(_finite(x) for x in v)
    if isinstance(value, dict):
        return set(value) == {"t", "values"} and numbers(value["t"]) and numbers(value["values"]) \
            and len(value["t"]) == len(value["values"])
    return _finite(value) or numbers(value)


def _finite(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _midpoint(lo, hi) -> float:
    if lo is not None and hi is not None:
        return 0.5 * (lo + hi)
    return lo if lo is not None else (hi if hi is not None else 0.0)
