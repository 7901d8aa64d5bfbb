"""The problem-file block ``controller:`` (closed-loop laws LQR, SDRE, Theta-D).

Example (configs/seed3_attitude.yaml)::

    controller:
      type: [lqr, sdre, theta-d]          # one law, or several run side by side
      Q: [0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.05, 0.05, 0.05]   # a diagonal, or a full matrix
      R: [1, 1, 1]
      auxiliary: [hx, hy, hz]             # plant states not regulated (wheel momentum)
      sdc: given                          # auto (default) | given
      A: {"1,7": "1", "1,8": "sin(phi)*tan(theta)", ...}   # 1-based entries, others 0
      saturation: null                    # |u_i| <= s, or per control, or [lo, hi] pairs
      theta_d: {terms: 3, k: [1, 1], a: [0.5, 0.5], A0: origin}
      simulate:
        x0: {phi: 10deg, theta: 10deg, psi: 10deg, wx: 0.01, wy: 0.01, wz: 0.01}
        horizon: 150
        step: 0.05
        update: 0.05                      # control update period (multiple of step)
        integrator: rk4                   # rk4 | euler | rk45 | dop853

Numbers may be written ``10deg`` (converted to radians). Other text (``pi/18``, the
entries of a given A or B) goes through :func:`parse_expression`, the hook to the
project's safe expression parser (:mod:`ocdsl.spec.expr`); nothing is ``eval``-ed or
``sympify``-ed here.
"""
from __future__ import annotations

import math
import re
from typing import Literal, Mapping, Union

import numpy as np
import sympy as sp
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

Number = Union[float, str]
ControllerType = Literal["lqr", "sdre", "theta-d"]
_DEG = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*deg\s*$")


def parse_expression(text: str, symbols: Mapping[str, sp.Basic]) -> sp.Expr:
    """Hook: parse ``text`` into SymPy using only the names in ``symbols``.

    Wired to the project's safe parser (:func:`ocdsl.spec.expr.parse_expression`, a
    whitelist over Python's ``ast``). If that module is missing, a clear error is raised;
    this function never falls back to ``sympify``.
    """
    try:
        from ocdsl.spec.expr import Scope
        from ocdsl.spec.expr import parse_expression as _parse
    except ImportError as exc:  # pragma: no cover - the lead's parser is part of the package
        raise NotImplementedError("expression parsing needs ocdsl.spec.expr (not available)") from exc
    return _parse(text, Scope(names=dict(symbols)))


def to_number(value: Number, symbols: Mapping[str, sp.Basic] | None = None) -> float:
    """A YAML number, ``'10deg'``, or a constant expression such as ``'pi/18'``."""
    if isinstance(value, bool):
        raise ValueError(f"expected a number, got {value!r}")
    if isinstance(value, (int, float)):
        out = float(value)
    else:
        m = _DEG.match(value)
        if m:
            out = math.radians(float(m.group(1)))
        else:
            try:
                out = float(value)
            except ValueError:
                expr = parse_expression(value, symbols or {})
                if expr.free_symbols:
                    raise ValueError(f"{value!r} must be a number, it uses "
                                     f"{sorted(map(str, expr.free_symbols))}") from None
                out = float(expr)
    if not math.isfinite(out):
        raise ValueError(f"non-finite number {value!r}")
    return out


def degree_inputs(values: Mapping[str, Number] | list) -> list[str]:
    """Names whose value the file wrote in degrees (``phi: 10deg``): reports draw them in degrees."""
    if not isinstance(values, Mapping):
        return []
    return [k for k, v in values.items() if isinstance(v, str) and _DEG.match(v)]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class ThetaDSettings(_Strict):
    """Theta-D design: T0..T_{terms-1}; D_i = k_i exp(-a_i t) RHS_i; A0 of the split."""

    terms: int = Field(3, ge=1, le=10)
    k: Union[float, list[float]] = 1.0
    a: Union[float, list[float]] = 0.5
    A0: Union[Literal["origin", "jacobian_at_origin"], list[list[float]]] = "origin"
    lyapunov: Literal["schur", "scipy"] = "schur"

    @model_validator(mode="after")
    def _lengths(self):
        for name in ("k", "a"):
            v = getattr(self, name)
            if isinstance(v, list) and len(v) != self.terms - 1:
                raise ValueError(f"theta_d.{name} has {len(v)} values, needs terms - 1 = {self.terms - 1}")
        a = self.a if isinstance(self.a, list) else [self.a]
        if any(x < 0 for x in a):
            raise ValueError("theta_d.a must be >= 0")
        return self


class SimulateSpec(_Strict):
    """Closed-loop simulation settings."""

    x0: Union[list[Number], dict[str, Number]]
    horizon: float = Field(gt=0)
    step: float = Field(gt=0)
    update: float | None = Field(None, gt=0)
    integrator: Literal["rk4", "euler", "rk45", "dop853"] = "rk4"
    metric_states: list[str] | None = None
    settle_bands: list[Number] = Field(default_factory=list)
    check_times: list[float] = Field(default_factory=list)
    stable_ratio: float = Field(1e-2, gt=0)

    @model_validator(mode="after")
    def _update_multiple(self):
        if self.update is not None:
            r = self.update / self.step
            if r < 1 - 1e-9 or abs(r - round(r)) > 1e-6:
                raise ValueError(f"simulate.update ({self.update}) must be a multiple of simulate.step ({self.step})")
        if self.step > self.horizon:
            raise ValueError("simulate.step is longer than the horizon")
        # a check time past the horizon gave a NaN column in silence (unseen35 F12)
        late = [t for t in self.check_times if float(t) > self.horizon]
        if late:
            raise ValueError(f"simulate.check_times {late} lie past the horizon {self.horizon:g}: "
                             "nothing is simulated there")
        return self

    def initial_state(self, names: list[str]) -> np.ndarray:
        """x0 for the plant states ``names`` (a mapping leaves unnamed states at 0)."""
        if isinstance(self.x0, dict):
            unknown = sorted(set(self.x0) - set(names))
            if unknown:
                raise ValueError(f"simulate.x0: unknown states {unknown}; states: {names}")
            return np.array([to_number(self.x0.get(n, 0.0)) for n in names])
        if len(self.x0) != len(names):
            raise ValueError(f"simulate.x0 has {len(self.x0)} values for {len(names)} states {names}")
        return np.array([to_number(v) for v in self.x0])


class RobustnessSpec(_Strict):
    """Plant-only parameter perturbation: each named parameter times each factor."""

    parameters: list[str] = Field(min_length=1)
    factors: list[float] = Field(min_length=1)

    @field_validator("factors")
    @classmethod
    def _positive(cls, v):
        if any(f <= 0 for f in v):
            raise ValueError("robustness factors must be positive")
        return v


Entries = Union[list[list[Number]], dict[str, Number]]


class ControllerSpec(_Strict):
    """One ``controller:`` block (see the module docstring)."""

    type: Union[ControllerType, list[ControllerType]]
    name: str | None = None
    Q: Union[list[Number], list[list[Number]]]
    R: Union[list[Number], list[list[Number]]]
    states: list[str] | None = None
    auxiliary: list[str] = Field(default_factory=list)
    sdc: Literal["auto", "given"] = "auto"
    split: Literal["even", "first", "last"] = "even"
    A: Entries | None = None
    B: Entries | None = None
    saturation: Union[float, list[float], list[list[float]], None] = None
    theta_d: ThetaDSettings = Field(default_factory=ThetaDSettings)
    simulate: SimulateSpec
    robustness: RobustnessSpec | None = None

    @model_validator(mode="after")
    def _consistent(self):
        types = self.types()
        if len(set(types)) != len(types):
            raise ValueError(f"controller.type lists a law twice: {types}")
        if self.sdc == "given" and self.A is None:
            raise ValueError("sdc: given needs the matrix A (entries as expressions)")
        if self.sdc == "auto" and (self.A is not None or self.B is not None):
            raise ValueError("A/B are only read with sdc: given")
        for key in ("Q", "R"):
            _square_or_diag(getattr(self, key), key)
        if isinstance(self.A, dict):
            for k in self.A:
                _entry_index(k, "A")
        if isinstance(self.B, dict):
            for k in self.B:
                _entry_index(k, "B")
        return self

    def types(self) -> list[str]:
        return list(self.type) if isinstance(self.type, list) else [self.type]

    def expand(self) -> list["ControllerSpec"]:
        """One spec per law (``type`` a list -> several specs sharing the rest)."""
        types = self.types()
        return [self.model_copy(update={"type": t, "name": t if len(types) > 1 else (self.name or t)})
                for t in types]

    def label(self) -> str:
        return self.name or "+".join(self.types())

    def matrix(self, key: str, n: int) -> np.ndarray:
        """Q or R as an n x n array (a list is its diagonal); symmetric, checked."""
        M = _square_or_diag(getattr(self, key), key)
        if M.shape != (n, n):
            raise ValueError(f"controller.{key} is {M.shape[0]}x{M.shape[1]}, expected {n}x{n}")
        if not np.allclose(M, M.T):
            raise ValueError(f"controller.{key} is not symmetric")
        ev = np.linalg.eigvalsh(0.5 * (M + M.T))
        if key == "R" and ev.min() <= 0:
            raise ValueError("controller.R must be positive definite")
        if key == "Q" and ev.min() < -1e-12 * max(1.0, abs(ev).max()):
            raise ValueError("controller.Q must be positive semidefinite")
        return M

    def given_matrix(self, key: str, shape: tuple[int, int],
                     symbols: Mapping[str, sp.Basic]) -> sp.Matrix | None:
        """The given A or B as a SymPy matrix (entries parsed with :func:`parse_expression`)."""
        entries = getattr(self, key)
        if entries is None:
            return None
        M = sp.zeros(*shape)
        if isinstance(entries, dict):
            for k, v in entries.items():
                i, j = _entry_index(k, key)
                if not (1 <= i <= shape[0] and 1 <= j <= shape[1]):
                    raise ValueError(f"controller.{key}[{k}] is outside the {shape[0]}x{shape[1]} matrix")
                M[i - 1, j - 1] = _expr(v, symbols)
        else:
            if len(entries) != shape[0] or any(len(r) != shape[1] for r in entries):
                raise ValueError(f"controller.{key} must be {shape[0]}x{shape[1]}")
            for i, row in enumerate(entries):
                for j, v in enumerate(row):
                    M[i, j] = _expr(v, symbols)
        return M


def _expr(v: Number, symbols) -> sp.Expr:
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return sp.Float(v) if isinstance(v, float) else sp.Integer(v)
    return parse_expression(str(v), symbols)


def _entry_index(key: str, what: str) -> tuple[int, int]:
    m = re.fullmatch(r"\s*(\d+)\s*,\s*(\d+)\s*", str(key))
    if not m:
        raise ValueError(f"controller.{what}: entry key {key!r} must be 'i,j' (1-based row, column)")
    return int(m.group(1)), int(m.group(2))


def _square_or_diag(value, key: str) -> np.ndarray:
    if value and isinstance(value[0], list):
        rows = [[to_number(v) for v in r] for r in value]
        if any(len(r) != len(rows) for r in rows):
            raise ValueError(f"controller.{key} must be square")
        return np.array(rows, float)
    if any(isinstance(v, list) for v in value):
        raise ValueError(f"controller.{key}: mix of numbers and rows")
    d = [to_number(v) for v in value]
    if not d:
        raise ValueError(f"controller.{key} is empty")
    return np.diag(d)
