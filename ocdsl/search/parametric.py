"""The parametric method: controls as series, a decision vector, the penalty fitness.

Decision vector (digest eq. 34, generalised): [search parameters (integers such as
N_rev, continuous ones), tf (when free), the series coefficients of every control in
order (Fourier: a0, a1..aN, b1..bN)].

Fitness (eqs. 31-35): J = objective + sum_i max((|e_i| - zeta_i)/zeta_i, 0) over the
terminal equality constraints e_i(x(tf), parameters) = 0 (inequalities: their violation
over zeta_i). A run whose integration fails gets ``failure_fitness``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from ocdsl.simulate import ControlLayout, compile_model, evaluate_controls, final_states, simulate
from ocdsl.symbolic.model import Model


@dataclass(frozen=True)
class Variable:
    name: str
    lower: float
    upper: float
    integer: bool = False


@dataclass(frozen=True)
class Terminal:
    """``lower <= expr <= upper`` in final states and decision variables, tolerance zeta."""

    expr: sp.Expr
    lower: float
    upper: float
    zeta: float
    text: str = ""
    state: str | None = None


@dataclass
class ParametricProblem:
    """Everything the fitness needs, independent of the problem-file layer.

    ``model`` may be a Sundman form (clock state ``time``); ``y0`` then includes the
    clock's initial 0. Final states in ``terminals``/``objective`` are the model's state
    symbols; decision variables are symbols named like ``variables`` (and ``tf``).
    Variables whose name is a model parameter override it per particle.
    """

    model: Model
    y0: np.ndarray
    parameters: dict[str, float]
    layout: ControlLayout
    coeff_lower: np.ndarray
    coeff_upper: np.ndarray
    tf_bounds: tuple[float, float]           # equal bounds: fixed tf
    variables: list[Variable]
    terminals: list[Terminal]
    objective: sp.Expr = field(default_factory=lambda: sp.Symbol("tf", real=True))
    rtol: float = 1e-8
    atol: float = 1e-10
    max_steps: int = 200_000
    failure_fitness: float = 1e6
    threads: bool = True
    guards: list = field(default_factory=list)   # terminal Events ending hopeless runs (failure)

    # ---- decision vector --------------------------------------------------------
    @property
    def tf_free(self) -> bool:
        return self.tf_bounds[0] != self.tf_bounds[1]

    def bounds(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        lo = [v.lower for v in self.variables]
        hi = [v.upper for v in self.variables]
        it = [v.integer for v in self.variables]
        if self.tf_free:
            lo.append(self.tf_bounds[0])
            hi.append(self.tf_bounds[1])
            it.append(False)
        lo += list(self.coeff_lower)
        hi += list(self.coeff_upper)
        it += [False] * len(self.coeff_lower)
        return np.array(lo, float), np.array(hi, float), np.array(it, bool)

    def names(self) -> list[str]:
        out = [v.name for v in self.variables] + (["tf"] if self.tf_free else [])
        for name, kind, order in zip(self._control_names(), self.layout.kinds, self.layout.orders):
            if kind == "fourier":
                out += [f"{name}_a{k}" for k in range(order + 1)] + [f"{name}_b{k}" for k in range(1, order + 1)]
            elif kind == "polynomial":
                out += [f"{name}_c{k}" for k in range(order + 1)]
            else:
                out += [f"{name}_c0"]
        return out

    def _control_names(self) -> list[str]:
        return [c.name for c in self.model.controls]

    def decode(self, X: np.ndarray) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray]:
        """(variables by name, tf (B,), coefficients (B, n_coeffs))."""
        X = np.atleast_2d(X)
        nv = len(self.variables)
        var = {v.name: X[:, i] for i, v in enumerate(self.variables)}
        if self.tf_free:
            tf = X[:, nv]
            c0 = nv + 1
        else:
            tf = np.full(len(X), self.tf_bounds[0])
            c0 = nv
        return var, tf, X[:, c0:]

    # ---- compiled pieces (rebuilt after unpickling) -----------------------------
    def __getstate__(self):
        d = dict(self.__dict__)
        for k in ("_cm", "_fns"):
            d.pop(k, None)
        return d

    def _ensure(self):
        if getattr(self, "_cm", None) is None:
            self._cm = compile_model(self.model)
            states = list(self.model.states)
            vsyms = [sp.Symbol(v.name, real=True) for v in self.variables] + [sp.Symbol("tf", real=True)]
            exprs = [t.expr for t in self.terminals] + [self.objective]
            args = states + vsyms
            free = set().union(*(sp.sympify(e).free_symbols for e in exprs)) - set(args)
            if free:
                raise ValueError(f"terminal constraints/objective use unknown symbols {sorted(map(str, free))}")
            self._fns = [sp.lambdify(args, e, "numpy") for e in exprs]
        return self._cm

    @property
    def compiled(self):
        return self._ensure()

    def _P(self, var: dict[str, np.ndarray], B: int) -> np.ndarray:
        cm = self._ensure()
        # the problem's constants hold the file's top-level ones too (a target `x(tf) == xf`),
        # which the model's right-hand side does not take (unseen50 F2: KeyError on every run)
        P = np.tile(cm.params({k: v for k, v in self.parameters.items() if k in cm.parameter_names}), (B, 1))
        for name, vals in var.items():
            if name in cm.parameter_names:
                P[:, cm.parameter_names.index(name)] = vals
        return P

    def final(self, X: np.ndarray, parallel: bool | None = None):
        cm = self._ensure()
        var, tf, CD = self.decode(X)
        B = len(tf)
        Yf, status, steps = final_states(cm, self.y0, tf, self._P(var, B), self.layout, CD,
                                         rtol=self.rtol, atol=self.atol, max_steps=self.max_steps,
                                         parallel=self.threads if parallel is None else parallel,
                                         events=self.guards)
        return Yf, status, steps, var, tf

    def errors(self, Yf, var, tf) -> tuple[np.ndarray, np.ndarray]:
        """Terminal errors (B, n_terminal) (signed for equalities) and objective (B,)."""
        self._ensure()
        args = [Yf[:, i] for i in range(Yf.shape[1])] + [var[v.name] for v in self.variables] + [tf]
        B = len(tf)
        E = np.empty((B, len(self.terminals)))
        for j, (t, fn) in enumerate(zip(self.terminals, self._fns)):
            val = np.broadcast_to(np.asarray(fn(*args), float), (B,))
            if t.lower == t.upper:
                E[:, j] = val - t.lower
            else:
                E[:, j] = np.maximum(np.maximum(val - t.upper, t.lower - val), 0.0)
        obj = np.broadcast_to(np.asarray(self._fns[-1](*args), float), (B,)).copy()
        return E, obj

    def fitness(self, X: np.ndarray) -> np.ndarray:
        """The paper's normalised-penalty fitness of a batch of decision vectors."""
        Yf, status, _, var, tf = self.final(X)
        E, obj = self.errors(Yf, var, tf)
        zeta = np.array([t.zeta for t in self.terminals])
        pen = np.maximum((np.abs(E) - zeta) / zeta, 0.0).sum(axis=1) if len(zeta) else 0.0
        J = obj + pen
        bad = (status < 0) | (status == 2) | ~np.isfinite(J)
        return np.where(bad, self.failure_fitness, J)

    __call__ = fitness

    def details(self, x: np.ndarray) -> dict:
        """Final state, terminal errors, error/zeta, objective of one decision vector."""
        Yf, status, steps, var, tf = self.final(np.atleast_2d(x), parallel=False)
        E, obj = self.errors(Yf, var, tf)
        zeta = np.array([t.zeta for t in self.terminals])
        return {"final": Yf[0], "status": int(status[0]), "steps": int(steps[0]),
                "errors": E[0], "ratio": np.abs(E[0]) / zeta if len(zeta) else np.zeros(0),
                "objective": float(obj[0]), "tf": float(tf[0]),
                "variables": {k: float(v[0]) for k, v in var.items()},
                "fitness": float(self.fitness(np.atleast_2d(x))[0])}

    def trajectory(self, x: np.ndarray, n_dense: int = 3, rtol: float | None = None):
        """Recorded trajectory and controls of one decision vector (for the run folder)."""
        cm = self._ensure()
        var, tf, CD = self.decode(np.atleast_2d(x))
        P = self._P(var, 1)[0]
        tr = simulate(cm, self.y0, float(tf[0]), P, self.layout, CD[0],
                      rtol=self.rtol if rtol is None else rtol, atol=self.atol,
                      record=True, n_dense=n_dense, max_steps=self.max_steps)
        U = evaluate_controls(self.layout, CD[0], tr.t, float(tf[0]))
        return tr, U


def penalty(errors: np.ndarray, zeta: np.ndarray) -> np.ndarray:
    """sum_i max((|e_i| - zeta_i)/zeta_i, 0) (digest eq. 32, first relation, w_i = 1)."""
    return np.maximum((np.abs(errors) - zeta) / zeta, 0.0).sum(axis=-1)


def fourier_series(coeffs: np.ndarray, order: int, t: np.ndarray, tf: float) -> np.ndarray:
    """a0/2 + sum_{n=1}^{N} a_n cos(n pi t/tf) + b_n sin(n pi t/tf) (digest eq. 24)."""
    return evaluate_controls(ControlLayout(("fourier",), (order,)), np.asarray(coeffs, float),
                             t, tf)[:, 0]
