"""Flat-output B-spline collocation (seed 002): a Pyomo NLP from a :class:`FlatMap`.

Each function of the flat map (the flat outputs, plus any state that could not be
eliminated) is a clamped B-spline in normalised time ``tau = t / tf`` in [0, 1]; its
control points are the NLP variables, with ``tf`` of each phase. The residual equations
of the flat map are collocated at ``n_col`` points; boundary conditions, links and path
bounds are written on the ORIGINAL states/controls and rewritten through the flat map.
Derivatives: ``d^k y / dt^k = (B^(k)(tau) c) / tf^k``.

Inputs (kept simple; the problem-file front end maps onto them)
---------------------------------------------------------------
:class:`FlatPhase`:
    ``name``; ``model`` (a :class:`~ocdsl.symbolic.model.Model`); ``outputs`` (state names,
    or None for the automatic search); ``boundary`` ``{(state, "t0"|"tf"): value}``;
    ``path_bounds`` ``{name: (lo, hi)}`` on states or controls (for a flat output these
    bound its control points, which by the convex-hull property bounds the curve; for
    any other quantity they are inequalities at the collocation points; they also choose
    solution branches in the flat map); ``tf_bounds``, ``tf_guess``; ``guess``
    ``{function: callable(tau) -> value | (start, end)}``; ``parameters`` (numbers
    overriding the model's defaults); ``options`` (:class:`FlatBSplineOptions`).
``links``: ``[((phase_a, state, "tf"), (phase_b, state, "t0")), ...]`` equalities.
``objective``: ``"tf"`` (total duration, all phases) or a callable ``f(nlp) -> Pyomo
expression``.

Variables are scaled: an output with finite bounds (lo, hi) is ``lo + (hi - lo) z`` with
``z`` in [0, 1] the NLP variable (the seed scales to [0, 1] as well); ``tf`` is
``tf_guess * s``.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

import numpy as np
import pyomo.core as pyo
import sympy as sp

from ocdsl.symbolic.flatness import FlatMap, derivative_symbol, flatten
from ocdsl.symbolic.model import TIME, Model

from .bspline import basis_matrix, clamped_knots
from .flat_angles import angle_states, branch_at, quadrature_rule, unwrap_from

__all__ = ["FlatBSplineOptions", "FlatPhase", "FlatNLP", "build_flat_bspline", "solve_flat",
           "PYOMO_FUNCTIONS"]


def _atan2(y, x):
    # half-angle form, exact except on the negative x axis
    return 2 * pyo.atan(y / (pyo.sqrt(x ** 2 + y ** 2) + x))


#: SymPy function names -> Pyomo functions for ``sympy.lambdify``.
PYOMO_FUNCTIONS = {"sin": pyo.sin, "cos": pyo.cos, "tan": pyo.tan, "asin": pyo.asin,
                   "acos": pyo.acos, "atan": pyo.atan, "atan2": _atan2, "sqrt": pyo.sqrt,
                   "exp": pyo.exp, "log": pyo.log, "sinh": pyo.sinh, "cosh": pyo.cosh,
                   "tanh": pyo.tanh, "Abs": abs, "pi": np.pi, "E": np.e}


@dataclass(frozen=True)
class FlatBSplineOptions:
    """Options of the flat B-spline transcription.

    degree : spline degree p (order p + 1); the seed uses order 6, i.e. degree 5.
    n_ctrl : control points per function (seed: 15 = 10 pieces + 5).
    n_col : residual equations per residual (seed: 15): collocation points, or test functions
        of the Galerkin residual.
    collocation : "uniform" (both ends included) or "interior" (uniform, ends excluded).
    residual : "collocation" (the seed: each residual == 0 at the ``n_col`` points) or
        "galerkin" (each residual's weighted mean against every one of ``n_col`` clamped
        B-splines of the same degree is 0, integrated by Gauss-Legendre on every span).
        Collocation leaves the residual free between the points, and the optimiser spends
        that freedom (seed 2: more thrust than the engine has between points, worse as
        points are added); a zero local mean leaves it only oscillations orthogonal to the
        test splines, which buy the objective nothing to first order.
    quadrature : Gauss-Legendre points per span of the Galerkin integrals (0: degree + 2).
    """

    degree: int = 5
    n_ctrl: int = 15
    n_col: int = 15
    collocation: str = "uniform"
    residual: str = "collocation"
    quadrature: int = 0

    def __post_init__(self) -> None:
        if self.collocation not in ("uniform", "interior"):
            raise ValueError(f"collocation must be 'uniform' or 'interior', not {self.collocation!r}")
        if self.residual not in ("collocation", "galerkin"):
            raise ValueError(f"residual must be 'collocation' or 'galerkin', not {self.residual!r}")
        if self.residual == "galerkin" and self.n_col < self.degree + 1:
            raise ValueError(f"a Galerkin residual needs n_col >= degree + 1 = {self.degree + 1} test "
                             f"functions, not {self.n_col}")
        if self.n_ctrl < self.degree + 1:
            raise ValueError(f"n_ctrl = {self.n_ctrl} < degree + 1 = {self.degree + 1}")
        if self.n_col < 1:
            raise ValueError("n_col must be >= 1")

    def points(self) -> np.ndarray:
        if self.collocation == "uniform":
            return np.linspace(0.0, 1.0, self.n_col)
        return (np.arange(self.n_col) + 0.5) / self.n_col

    def galerkin_rule(self) -> tuple[np.ndarray, np.ndarray]:
        """(nodes, W): Gauss-Legendre nodes on every span of the trial and test knots, and
        ``W[j, i] = w_j phi_i(x_j) / integral(phi_i)``, so that ``W.T @ r(nodes)`` are the
        residual's weighted means against the ``n_col`` test B-splines."""
        breaks = np.unique(np.concatenate([clamped_knots(self.degree, self.n_ctrl),
                                           clamped_knots(self.degree, self.n_col)]))
        x, w = np.polynomial.legendre.leggauss(self.quadrature or self.degree + 2)
        a, b = breaks[:-1, None], breaks[1:, None]
        nodes = (0.5 * (a + b) + 0.5 * (b - a) * x).ravel()
        weights = (0.5 * (b - a) * w).ravel()
        W = basis_matrix(self.degree, self.n_col, nodes) * weights[:, None]
        return nodes, W / W.sum(axis=0)


@dataclass
class FlatPhase:
    """One phase of a flat B-spline problem (see the module docstring)."""

    name: str
    model: Model
    boundary: Mapping[tuple[str, str], float]
    tf_bounds: tuple[float, float]
    tf_guess: float
    outputs: Sequence[str] | None = None
    path_bounds: Mapping[str, tuple[float | None, float | None]] = field(default_factory=dict)
    guess: Mapping[str, Any] = field(default_factory=dict)
    parameters: Mapping[str, float] = field(default_factory=dict)
    options: FlatBSplineOptions = field(default_factory=FlatBSplineOptions)
    flatmap: FlatMap | None = None


class _PhaseNLP:
    """The Pyomo pieces of one phase, and evaluation of flat expressions in it."""

    def __init__(self, m: pyo.ConcreteModel, ph: FlatPhase):
        self.ph = ph
        self.fm = ph.flatmap or flatten(ph.model, ph.outputs, bounds=ph.path_bounds,
                                        parameter_values=dict(ph.parameters))
        fm, opt = self.fm, ph.options
        self.functions = list(fm.functions)
        self.max_order = max(fm.orders.values())
        self.block = b = pyo.Block()
        m.add_component(ph.name, b)
        nf, nc = len(self.functions), opt.n_ctrl
        b.I = pyo.RangeSet(0, nc - 1)
        self.offset, self.scale = {}, {}
        for y in self.functions:
            lo, hi = ph.path_bounds.get(y.name, (None, None))
            if lo is not None and hi is not None and np.isfinite(lo) and np.isfinite(hi):
                self.offset[y], self.scale[y] = float(lo), float(hi - lo)
            else:
                self.offset[y], self.scale[y] = 0.0, 1.0
        b.z = pyo.Var(range(nf), b.I, initialize=0.5)
        for j, y in enumerate(self.functions):
            lo, hi = ph.path_bounds.get(y.name, (None, None))
            for i in range(nc):
                if lo is not None and np.isfinite(lo):
                    b.z[j, i].setlb((lo - self.offset[y]) / self.scale[y])
                if hi is not None and np.isfinite(hi):
                    b.z[j, i].setub((hi - self.offset[y]) / self.scale[y])
        tf_lo, tf_hi = ph.tf_bounds
        self.tf_ref = float(ph.tf_guess)
        if not (np.isfinite(self.tf_ref) and self.tf_ref > 0):
            raise ValueError(f"phase {ph.name!r}: the duration guess must be positive, got {ph.tf_guess}")
        # the duration stays positive (derivatives are divided by its powers)
        s_lo = max(tf_lo / self.tf_ref, 1e-8) if tf_lo is not None and np.isfinite(tf_lo) else 1e-8
        s_hi = tf_hi / self.tf_ref if tf_hi is not None and np.isfinite(tf_hi) else None
        b.s = pyo.Var(bounds=(s_lo, s_hi), initialize=1.0)
        if s_hi is not None and s_hi == s_lo:
            b.s.fix(s_lo)
        self.tf = self.tf_ref * b.s
        # integration constants (quadrature states): fixed when a boundary value gives them
        b.k = pyo.Var(range(len(fm.constants)), initialize=0.0)
        self.constants = list(fm.constants)
        for q, c in enumerate(self.constants):
            x = fm.constants[c]
            at0 = sp.expand(fm.states[x].xreplace({TIME: 0}))
            if (x.name, "t0") in ph.boundary and at0 == c:
                b.k[q].fix(float(ph.boundary[(x.name, "t0")]))
        self.args = [derivative_symbol(y, k) for y in self.functions
                     for k in range(self.max_order + 1)] + self.constants + [TIME]
        self._fns: dict[sp.Expr, Callable] = {}
        self._values: dict[float, list] = {}
        self.angles = angle_states(fm, ph.model)
        self._ends: dict[tuple[str, str], Any] = {}
        self._initial_guess()

    # -- evaluation ---------------------------------------------------------------
    def coeff(self, y) -> list:
        j = self.functions.index(y)
        return [self.offset[y] + self.scale[y] * self.block.z[j, i] for i in range(self.ph.options.n_ctrl)]

    def values_at(self, tau: float) -> list:
        """Pyomo expressions for all lambdify arguments at normalised time tau (made once per
        tau: every constraint and quadrature term at a point shares them)."""
        tau = float(tau)
        if tau in self._values:
            return self._values[tau]
        opt = self.ph.options
        out = []
        for y in self.functions:
            c = self.coeff(y)
            for k in range(self.max_order + 1):
                row = basis_matrix(opt.degree, opt.n_ctrl, [tau], k)[0]
                expr = sum(float(row[i]) * c[i] for i in range(opt.n_ctrl) if row[i] != 0.0)
                out.append(expr / self.tf ** k if k else expr)
        out += [self.block.k[q] for q in range(len(self.constants))]
        out.append(self.tf * tau)
        self._values[tau] = out
        return out

    def fn(self, expr: sp.Expr) -> Callable:
        if expr not in self._fns:
            self._fns[expr] = sp.lambdify(self.args, expr, modules=[PYOMO_FUNCTIONS])
        return self._fns[expr]

    def expr_of(self, name: str) -> sp.Expr:
        return self.fm.expression(name)

    def at(self, name_or_expr, tau: float):
        e = self.expr_of(name_or_expr) if isinstance(name_or_expr, str) else name_or_expr
        return self.fn(e)(*self.values_at(tau))

    def end_value(self, name: str, where: str):
        """The state ``name`` at the phase's start (``"t0"``) or end (``"tf"``); an angle of
        the flat map with its winding (``flat_angles``), anything else as ``at``."""
        key = (name, where)
        if key not in self._ends:
            x = self.ph.model.symbol(name)
            if x not in self.angles:
                self._ends[key] = self.at(name, 0.0 if where == "t0" else 1.0)
            else:
                S, C, rate = self.angles[x]
                start = branch_at(float(self.ph.boundary.get((name, "t0"), 0.0)), self.at(S, 0.0),
                                  self.at(C, 0.0), pyo.sin, pyo.cos, _atan2)
                if where == "t0":
                    self._ends[key] = start
                else:
                    nodes, weights = quadrature_rule(self.ph.options.degree, self.ph.options.n_ctrl)
                    turned = self.tf * sum(float(w) * self.at(rate, float(t)) for t, w in zip(nodes, weights))
                    self._ends[key] = branch_at(start + turned, self.at(S, 1.0), self.at(C, 1.0),
                                                pyo.sin, pyo.cos, _atan2)
        return self._ends[key]

    # -- guess --------------------------------------------------------------------
    def _initial_guess(self) -> None:
        opt, ph = self.ph.options, self.ph
        tau = np.linspace(0, 1, max(4 * opt.n_ctrl, 50))
        A = basis_matrix(opt.degree, opt.n_ctrl, tau)
        for j, y in enumerate(self.functions):
            g = ph.guess.get(y.name)
            if g is None:
                a = ph.boundary.get((y.name, "t0"), 0.0)
                b_ = ph.boundary.get((y.name, "tf"), a)
                g = (a, b_)
            vals = (g[0] + (g[1] - g[0]) * tau) if isinstance(g, (tuple, list)) else np.array([g(t) for t in tau])
            c, *_ = np.linalg.lstsq(A, vals, rcond=None)
            for i in range(opt.n_ctrl):
                z = (c[i] - self.offset[y]) / self.scale[y]
                v = self.block.z[j, i]
                if v.lb is not None:
                    z = max(z, v.lb)
                if v.ub is not None:
                    z = min(z, v.ub)
                v.set_value(float(z))
        for q, c in enumerate(self.constants):
            x = self.fm.constants[c]
            if not self.block.k[q].fixed:
                self.block.k[q].set_value(float(ph.guess.get(f"{x.name}_t0", 0.0)))

    # -- numbers after the solve -----------------------------------------------------
    def numeric(self, tau: np.ndarray) -> dict[str, np.ndarray]:
        """States and controls (and residuals) on a grid of tau after the solve."""
        opt = self.ph.options
        tf = pyo.value(self.tf)
        vals: dict[sp.Symbol, np.ndarray] = {}
        for y in self.functions:
            c = np.array([pyo.value(e) for e in self.coeff(y)])
            for k in range(self.max_order + 1):
                vals[derivative_symbol(y, k)] = basis_matrix(opt.degree, opt.n_ctrl, tau, k) @ c / tf ** k
        for q, c in enumerate(self.constants):
            vals[c] = np.full_like(tau, pyo.value(self.block.k[q]))
        vals[TIME] = tf * tau
        argv = [vals[a] for a in self.args]
        out = {"t": tf * tau}
        for group in (self.fm.states, self.fm.controls):
            for s, e in group.items():
                out[s.name] = np.broadcast_to(sp.lambdify(self.args, e, "numpy")(*argv), tau.shape).astype(float)
        for x in self.angles:       # continuous, from the branch its boundary condition took
            out[x.name] = unwrap_from(out[x.name], pyo.value(self.end_value(x.name, "t0")))
        for i, r in enumerate(self.fm.residuals):
            out[f"residual_{i}"] = np.broadcast_to(sp.lambdify(self.args, r.expr, "numpy")(*argv), tau.shape).astype(float)
        return out


@dataclass
class FlatNLP:
    """The built Pyomo model and what is needed to read the solution back."""

    model: pyo.ConcreteModel
    phases: dict[str, _PhaseNLP]
    build_time_s: float

    def size(self) -> dict[str, int]:
        """Active unfixed variables and active equality/inequality constraint rows."""
        nv = sum(1 for v in self.model.component_data_objects(pyo.Var, active=True) if not v.fixed)
        nc = sum(1 for c in self.model.component_data_objects(pyo.Constraint, active=True))
        neq = sum(1 for c in self.model.component_data_objects(pyo.Constraint, active=True) if c.equality)
        return {"variables": nv, "constraints": nc, "equalities": neq}

    def tf(self) -> dict[str, float]:
        return {k: float(pyo.value(p.tf)) for k, p in self.phases.items()}

    def value(self, phase: str, name: str, where: str) -> float:
        """Value of a state or control at ``where`` in {"t0", "tf"} of ``phase``."""
        p = self.phases[phase]
        return float(pyo.value(p.at(name, 0.0 if where == "t0" else 1.0)))


def build_flat_bspline(phases: Sequence[FlatPhase], links: Sequence = (),
                       objective: str | Callable = "tf") -> FlatNLP:
    """Build the Pyomo ConcreteModel of a (multi-phase) flat B-spline problem."""
    t_start = time.perf_counter()
    m = pyo.ConcreteModel(name="flat_bspline")
    nlps: dict[str, _PhaseNLP] = {}
    for ph in phases:
        if ph.name in nlps:
            raise ValueError(f"phase name {ph.name!r} used twice")
        p = nlps[ph.name] = _PhaseNLP(m, ph)
        b, opt = p.block, ph.options
        taus = opt.points()
        _residual_equations(p, opt, taus)
        # boundary conditions through the flat map
        b.boundary = pyo.ConstraintList()
        for (name, where), value in ph.boundary.items():
            if where not in ("t0", "tf"):
                raise ValueError(f"phase {ph.name!r}: boundary key ({name!r}, {where!r}) must use 't0' or 'tf'")
            sym_ = ph.model.symbol(name)
            if sym_ in p.fm.constants.values():
                q = p.constants.index(next(c for c, x in p.fm.constants.items() if x == sym_))
                if where == "t0" and b.k[q].fixed:
                    continue
            b.boundary.add(p.end_value(name, where) == float(value))
        # path bounds on non-function quantities, at collocation points
        b.path = pyo.ConstraintList()
        fnames = {y.name for y in p.functions}
        for name, (lo, hi) in ph.path_bounds.items():
            if name in fnames:
                continue
            for tau in taus:
                e = p.at(name, float(tau))
                if lo is not None and np.isfinite(lo):
                    b.path.add(e >= float(lo))
                if hi is not None and np.isfinite(hi):
                    b.path.add(e <= float(hi))
    m.links = pyo.ConstraintList()
    for (pa, xa, wa), (pb, xb, wb) in links:
        ea = nlps[pa].at(xa, 0.0 if wa == "t0" else 1.0)
        eb = nlps[pb].at(xb, 0.0 if wb == "t0" else 1.0)
        m.links.add(ea == eb)
    if objective == "tf":
        m.obj = pyo.Objective(expr=sum(p.tf for p in nlps.values()), sense=pyo.minimize)
    elif callable(objective):
        m.obj = pyo.Objective(expr=objective(nlps), sense=pyo.minimize)
    else:
        raise ValueError(f"objective must be 'tf' or a callable, not {objective!r}")
    return FlatNLP(m, nlps, time.perf_counter() - t_start)


def _residual_equations(p: _PhaseNLP, opt: FlatBSplineOptions, taus: np.ndarray) -> None:
    """The residuals of the flat map, collocated at ``taus`` or in Galerkin form."""
    b = p.block
    b.residual = pyo.ConstraintList()
    if opt.residual == "collocation":
        for r in p.fm.residuals:
            for tau in taus:
                b.residual.add(p.at(r.expr, float(tau)) == 0)
        return
    nodes, W = opt.galerkin_rule()
    # one named expression per quadrature node: shared by the p + 1 test functions over it
    b.residual_node = pyo.Expression(range(len(p.fm.residuals)), range(len(nodes)))
    for k, r in enumerate(p.fm.residuals):
        for j, tau in enumerate(nodes):
            b.residual_node[k, j] = p.at(r.expr, float(tau))
        for i in range(W.shape[1]):
            b.residual.add(sum(float(W[j, i]) * b.residual_node[k, j] for j in np.flatnonzero(W[:, i])) == 0)


@dataclass
class FlatSolution:
    """Outcome of :func:`solve_flat`."""

    status: str
    termination: str
    objective: float
    tf: dict[str, float]
    size: dict[str, int]
    wall_time_s: dict[str, float]
    trajectories: dict[str, dict[str, np.ndarray]]
    max_residual_dense: float


def solve_flat(nlp: FlatNLP, tee: bool = False, options: Mapping[str, Any] | None = None,
               n_dense: int = 201) -> FlatSolution:
    """Solve with Ipopt through Pyomo's ``cyipopt`` interface; sample the trajectories
    on ``n_dense`` points per phase and report the largest residual between
    collocation points too (``max_residual_dense``)."""
    from pyomo.environ import SolverFactory   # the solver plugins: only this route needs them

    solver = SolverFactory("cyipopt")
    opts = {"tol": 1e-9, "max_iter": 3000, "print_level": 5 if tee else 0}
    opts.update(options or {})
    for k, v in opts.items():
        solver.config.options[k] = v
    from ..solve.process_state import floating_point_environment_kept

    t0 = time.perf_counter()
    with floating_point_environment_kept():
        res = solver.solve(nlp.model, tee=tee, load_solutions=False)
    solve_s = time.perf_counter() - t0
    term = str(res.solver.termination_condition)
    # Pyomo maps Ipopt's Solved_To_Acceptable_Level to "feasible"
    ok = term in ("optimal", "locallyOptimal", "feasible")
    if ok or res.solution:
        try:
            nlp.model.solutions.load_from(res)
        except Exception:  # noqa: BLE001 - no solution to load
            pass
    tau = np.linspace(0, 1, n_dense)
    traj = {k: p.numeric(tau) for k, p in nlp.phases.items()}
    dense = max([float(np.max(np.abs(v))) for tr in traj.values() for k, v in tr.items()
                 if k.startswith("residual_")] or [0.0])
    return FlatSolution(
        status=("acceptable" if term == "feasible" else "optimal") if ok
        else ("max_iter" if "maxIterations" in term else "error"),
        termination=term, objective=float(pyo.value(nlp.model.obj)), tf=nlp.tf(),
        size=nlp.size(), wall_time_s={"build": nlp.build_time_s, "solve": solve_s},
        trajectories=traj, max_residual_dense=dense)
