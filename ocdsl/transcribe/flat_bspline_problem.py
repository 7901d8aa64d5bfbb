"""Runner of ``method: {transcription: flat-bspline}``: a compiled symbolic
:class:`~ocdsl.symbolic.problem.Problem` -> flat B-spline NLP -> :class:`~ocdsl.result.Result`.

What is mapped, phase by phase
------------------------------
* the model (with the phase's constants) is reduced by
  :func:`ocdsl.symbolic.flatness.flatten` with the method's ``flat_outputs`` (or the
  automatic search) and the phase's box bounds (which choose solution branches);
* box bounds on the original states/controls: on a flat output they bound the control
  points (convex hull), on anything else they are inequalities at the collocation points
  through the flat map; path constraints likewise;
* time: the flat back end measures each phase from its start (``t = t0 + d tau``, the
  duration ``d`` free or fixed); ``t0`` of a phase is a number or an NLP variable;
  bounds on ``tf`` become bounds on the duration when ``t0`` is fixed, and a boundary
  constraint ``lo <= tf - t0 <= hi`` becomes the duration's bounds;
* boundary constraints and links (any relation in boundary values ``x(t0)``, ``x(tf)``,
  phase times, integrals and free parameters), and the objective, are lambdified into
  Pyomo with every boundary value rewritten through the flat map; boundary equalities of
  a single boundary value (``x(t0) == 3``) also shape the guess and fix integration
  constants (the lander's ``m(t0)``);
* integrals: composite Gauss-Legendre quadrature over the knot spans (degree + 1 points
  per span) of the flat expression of the integrand;
* guess: the core's :func:`ocdsl.transcribe.guess.make_guess` (the file's ``guess:``,
  linear between fixed boundary values, mid-bounds), fitted by least squares.

Not supported (a clear error): free parameters inside the dynamics or path constraints,
and explicitly time-dependent dynamics in a phase whose start is not fixed at 0.
"""
from __future__ import annotations

import math
import time as _time

import numpy as np
import sympy as sp

from ..pyomo_logs import evaluation_unlogged
from .bspline import clamped_knots
from ..result import PhaseTrajectory, Result
from ..symbolic.flatness import FlatnessError, flatten
from ..symbolic.model import TIME

INF = float("inf")

#: Ipopt options of the flat back end (under the file's own ``solver: options``).
FLAT_SOLVER_DEFAULTS = {"mu_strategy": "monotone", "tol": 1e-9}


class FlatProblemError(ValueError):
    """The problem cannot be mapped onto the flat B-spline back end."""


def _is_boundary_symbol(problem, s) -> bool:
    return s in problem.boundary_values


def _phase_flatmap(problem, ph, method):
    outputs = method.outputs_for(ph.name)
    bounds = {s.name: b for s, b in {**ph.state_bounds, **ph.control_bounds}.items()}
    rhs_syms = set().union(*(e.free_symbols for e in ph.rhs()))
    free_in_dyn = rhs_syms & set(problem.free_parameters)
    if free_in_dyn:
        raise FlatProblemError(f"phase {ph.name!r}: free parameter(s) {sorted(s.name for s in free_in_dyn)} "
                               "in the dynamics are not supported by flat-bspline")
    if TIME in rhs_syms and ph.t0 != 0.0:
        raise FlatProblemError(f"phase {ph.name!r}: time-dependent dynamics need t0 fixed at 0 "
                               "with flat-bspline (its phases are measured from their start)")
    try:
        return flatten(ph.model, outputs, bounds=bounds, parameter_values=dict(ph.constants))
    except FlatnessError as e:
        raise FlatnessError(f"phase {ph.name!r}: {e}") from None


def _guess_tables(problem, ph):
    from .guess import make_guess

    return make_guess(problem, ph)


class _Mapped:
    """The flat phases built from a Problem, plus the bookkeeping of times and symbols."""

    def __init__(self, file):
        from .flat_bspline import FlatBSplineOptions, FlatPhase

        problem, method = file.problem, file.method
        self.file, self.problem, self.method = file, problem, method
        self.opts = FlatBSplineOptions(method.degree, method.control_points, method.collocation_points,
                                       method.collocation, method.residual, method.quadrature)
        simple: dict[str, dict] = {ph.name: {} for ph in problem.phases}
        self.consumed: set[int] = set()
        self.duration_bounds: dict[str, list[float]] = {}
        for i, c in enumerate(problem.boundary):
            if c.is_equality and isinstance(c.expr, sp.Symbol) and c.expr in problem.boundary_values:
                bv = problem.boundary_values[c.expr]
                simple[bv.phase][(bv.var.name, bv.which)] = float(c.lower)
                self.consumed.add(i)
        for ph in problem.phases:
            d = [0.0, INF]
            if ph.t0 is not None:
                lo, hi = ph.tf_bounds
                d = [max(0.0, lo - ph.t0), hi - ph.t0]
            for i, c in enumerate(problem.boundary):
                if sp.expand(c.expr - (ph.tf_symbol - ph.t0_symbol)) == 0:
                    d = [max(d[0], c.lower), min(d[1], c.upper)]
                    self.consumed.add(i)
            if ph.tf is not None and ph.t0 is not None:
                d = [ph.tf - ph.t0, ph.tf - ph.t0]
            self.duration_bounds[ph.name] = d
        # time guesses, phase after phase: a free start follows the phase before
        self.t0_guess, self.dur_guess = {}, {}
        prev_end = 0.0
        self.phases = []
        self.flatmaps = {}
        for ph in problem.phases:
            g = _guess_tables(problem, ph)
            # make_guess's start (the file's t0, its guess, or the middle of finite bounds);
            # an unbounded free start without a guess follows the phase before
            given = ph.t0 is not None or ph.guess.get("t0") is not None or all(map(math.isfinite, ph.t0_bounds))
            t0g = g.t0 if given else prev_end
            tfg = ph.tf if ph.tf is not None else ph.guess.get("tf")
            lo, hi = self.duration_bounds[ph.name]
            if tfg is not None and float(tfg) > t0g:
                dur = float(tfg) - t0g
            elif math.isfinite(hi):
                dur = 0.5 * (lo + hi) if lo > 0 else 0.5 * hi
            else:
                dur = max(2 * lo, 1.0)
            self.t0_guess[ph.name], self.dur_guess[ph.name] = t0g, dur
            prev_end = t0g + dur
            fm = _phase_flatmap(problem, ph, method)
            self.flatmaps[ph.name] = fm
            guess = {}
            for y in fm.functions:
                j = g.state_names.index(y.name)
                guess[y.name] = (lambda tau, j=j, g=g: float(g.states_at(np.array([tau]))[0, j]))
            for c, x in fm.constants.items():
                guess[f"{x.name}_t0"] = float(g.states_at(np.array([0.0]))[0, g.state_names.index(x.name)])
            bounds = {s.name: b for s, b in {**ph.state_bounds, **ph.control_bounds}.items()}
            self.phases.append(FlatPhase(ph.name, ph.model, simple[ph.name], (lo, hi), dur, None,
                                         bounds, guess, {}, self.opts, flatmap=fm))

    def with_options(self, opts) -> "_Mapped":
        """The same mapping (flat maps, guesses, times) with other spline options."""
        import copy
        from dataclasses import replace

        other = copy.copy(self)
        other.opts = opts
        other.phases = [replace(ph, options=opts) for ph in self.phases]
        return other

    def warm_from(self, coarse: "_Mapped") -> None:
        """Start this (built) mapping's NLP at the solution of ``coarse``'s: every function's
        scaled spline refitted by least squares on a fine grid (exact when the knots are
        nested), durations, integration constants, start times and free parameters copied."""
        import pyomo.core as pyo

        from .bspline import basis_matrix

        n = 8 * (self.opts.n_ctrl - self.opts.degree) + 1
        tau = np.linspace(0.0, 1.0, n)
        A = basis_matrix(self.opts.degree, self.opts.n_ctrl, tau)
        Ac = basis_matrix(coarse.opts.degree, coarse.opts.n_ctrl, tau)
        for name, p in self.nlp.phases.items():
            q = coarse.nlp.phases[name]
            for j in range(len(p.functions)):
                zc = np.array([pyo.value(q.block.z[j, i]) for i in range(coarse.opts.n_ctrl)])
                z, *_ = np.linalg.lstsq(A, Ac @ zc, rcond=None)
                for i in range(self.opts.n_ctrl):
                    v = p.block.z[j, i]
                    v.set_value(float(np.clip(z[i], v.lb if v.lb is not None else -INF,
                                              v.ub if v.ub is not None else INF)))
            p.block.s.set_value(pyo.value(q.block.s))
            for k in p.block.k:
                if not p.block.k[k].fixed:
                    p.block.k[k].set_value(pyo.value(q.block.k[k]))
        for k in self.nlp.model.t0:
            if not self.nlp.model.t0[k].fixed:
                self.nlp.model.t0[k].set_value(pyo.value(coarse.nlp.model.t0[k]))
        for s, v in self.free.items():
            v.set_value(pyo.value(coarse.free[s]))

    def build(self):
        """The Pyomo model: the flat back end's phases, then times, general boundary
        constraints, links, path constraints and the objective of the Problem."""
        import pyomo.core as pyo

        from .flat_bspline import build_flat_bspline

        t = _time.perf_counter()
        nlp = build_flat_bspline(self.phases, (), objective="tf")
        m = nlp.model
        m.del_component(m.obj)
        problem = self.problem
        self.nlp = nlp
        # phase start times
        m.t0 = pyo.Var([ph.name for ph in problem.phases])
        self.t0 = {}
        for ph in problem.phases:
            if ph.t0 is not None:
                self.t0[ph.name] = float(ph.t0)
                m.t0[ph.name].fix(float(ph.t0))
            else:
                v = m.t0[ph.name]
                v.set_value(self.t0_guess[ph.name])
                lo, hi = ph.t0_bounds
                v.setlb(lo if math.isfinite(lo) else None)
                v.setub(hi if math.isfinite(hi) else None)
                self.t0[ph.name] = v
        m.times = pyo.ConstraintList()
        for ph in problem.phases:
            if ph.t0 is None:   # a fixed tf, or tf bounds, on t0 + duration
                lo, hi = (ph.tf, ph.tf) if ph.tf is not None else ph.tf_bounds
                tf = self.t0[ph.name] + nlp.phases[ph.name].tf
                if lo == hi:
                    m.times.add(tf == lo)
                    continue
                if math.isfinite(lo):
                    m.times.add(tf >= lo)
                if math.isfinite(hi):
                    m.times.add(tf <= hi)
        # free parameters
        self.free = {}
        if problem.free_parameters:
            m.p = pyo.Var([s.name for s in problem.free_parameters])
            for s, fp in problem.free_parameters.items():
                v = m.p[s.name]
                v.set_value(fp.guess)
                v.setlb(fp.lower if math.isfinite(fp.lower) else None)
                v.setub(fp.upper if math.isfinite(fp.upper) else None)
                self.free[s] = v
        # path constraints (general relations in states/controls/t)
        from .flat_bspline import PYOMO_FUNCTIONS

        for ph in problem.phases:
            p = nlp.phases[ph.name]
            fm = self.flatmaps[ph.name]
            sub = {**fm.states, **fm.controls}
            blk = p.block
            blk.general_path = pyo.ConstraintList()
            for c in ph.path:
                if c.expr.free_symbols & set(problem.free_parameters):
                    raise FlatProblemError(f"path constraint {c.text!r}: free parameters in path "
                                           "constraints are not supported by flat-bspline")
                # TIME in the flat map is the time since the phase start
                start = sp.Symbol("__phase_t0")
                e = c.expr.xreplace({TIME: TIME + start}).xreplace(sub)
                f = sp.lambdify(p.args + [start], e, modules=[PYOMO_FUNCTIONS])
                for tau in self.opts.points():
                    _add(blk.general_path, f(*p.values_at(float(tau)), self.t0[ph.name]), c.lower, c.upper)
        # integrals
        self.integral_expr = {}
        for s, (phase_name, integrand) in problem.integrals.items():
            self.integral_expr[s] = self._quadrature(phase_name, integrand)
        # boundary constraints and links
        m.general_boundary = pyo.ConstraintList()
        for i, c in enumerate(problem.boundary):
            if i in self.consumed:
                continue
            _add(m.general_boundary, self.scalar(c.expr), c.lower, c.upper)
        obj = self.scalar(problem.objective.expr)
        sense = pyo.minimize if problem.objective.sense == "minimize" else pyo.maximize
        m.obj = pyo.Objective(expr=obj, sense=sense)
        nlp.build_time_s = _time.perf_counter() - t
        return nlp

    def _quadrature(self, phase_name, integrand):
        from .flat_bspline import PYOMO_FUNCTIONS

        p = self.nlp.phases[phase_name]
        fm = self.flatmaps[phase_name]
        # TIME in the flat map is the time since the phase start: an integrand of t in a phase
        # from t0 = 5 was integrated as if it started at 0 (J 269.50 for 163.46, unseen32)
        start = sp.Symbol("__phase_t0")
        e = integrand.xreplace({TIME: TIME + start}).xreplace({**fm.states, **fm.controls})
        if e.free_symbols & set(self.problem.free_parameters):
            raise FlatProblemError("free parameters inside an integral are not supported by flat-bspline")
        n = self.opts.degree + 1
        x, w = np.polynomial.legendre.leggauss(n)
        knots = np.linspace(0.0, 1.0, self.opts.n_ctrl - self.opts.degree + 1)
        f = sp.lambdify(p.args + [start], e, modules=[PYOMO_FUNCTIONS])
        total = 0
        for a, b in zip(knots[:-1], knots[1:]):
            for xi, wi in zip(x, w):
                tau = 0.5 * (a + b) + 0.5 * (b - a) * xi
                total = total + float(0.5 * (b - a) * wi) * f(*p.values_at(float(tau)), self.t0[phase_name])
        return total * p.tf

    def pyomo_of(self, s):
        """Pyomo expression (or number) of a scalar symbol of the Problem."""
        problem = self.problem
        if s in problem.boundary_values:
            bv = problem.boundary_values[s]
            return self.nlp.phases[bv.phase].end_value(bv.var.name, bv.which)
        for ph in problem.phases:
            if s == ph.t0_symbol:
                return self.t0[ph.name]
            if s == ph.tf_symbol:
                return self.t0[ph.name] + self.nlp.phases[ph.name].tf
        if s in self.free:
            return self.free[s]
        if s in self.integral_expr:
            return self.integral_expr[s]
        if s.name in self.file.parameters:
            return float(self.file.parameters[s.name])
        raise FlatProblemError(f"'{s}' in a boundary constraint or the objective is not a boundary value, "
                               "phase time, integral or parameter")

    def scalar(self, expr: sp.Expr):
        from .flat_bspline import PYOMO_FUNCTIONS

        syms = sorted(expr.free_symbols, key=lambda s: s.name)
        if not syms:
            return float(expr)
        return sp.lambdify(syms, expr, modules=[PYOMO_FUNCTIONS])(*[self.pyomo_of(s) for s in syms])


def _add(clist, e, lo: float, hi: float) -> None:
    if lo == hi:
        clist.add(e == lo)
        return
    if math.isfinite(lo):
        clist.add(e >= lo)
    if math.isfinite(hi):
        clist.add(e <= hi)


def build_from_problem(file):
    """(mapping, Pyomo NLP) of a compiled problem file whose method is flat-bspline."""
    mp = _Mapped(file)
    return mp, mp.build()


def run_flat_file(file, timer, *, seed=None, warm_start=None, verbose=False, progress=False) -> Result:
    """``fn(file, timer, ...) -> Result`` of :func:`ocdsl.methods.register_runner`.

    With the method's ``tolerance``, the result of the file's setting is verified
    (:mod:`ocdsl.verify`) and, until a level passes or ``refinements`` are spent, the pieces
    are doubled (with ``refine_residual``, warm start from the level before): see
    :func:`ocdsl.transcribe.flat_bspline_refine.refine`. The Result is the last level that converged, with every level in
    ``extra["refinement"]``."""
    from ..solve import ipopt

    ipopt.check_available()
    problem, method = file.problem, file.method
    if problem is None:
        raise FlatProblemError("flat-bspline needs a `problem:` or `phases:` block")
    if warm_start is not None:
        raise FlatProblemError("flat-bspline does not take a warm start yet")
    with timer.measure("symbolic"):
        mp = _Mapped(file)
    with timer.measure("build"):
        nlp = mp.build()
    with timer.measure("solve"):
        # monotone barrier by default: with the core's adaptive strategy Ipopt reached poor
        # local optima of the seed-2 flat NLPs (e.g. 112.4 kg instead of 150.39 kg on the
        # 2 km strategy-3 row, depending on round-off); the file's options still win
        options = {**FLAT_SOLVER_DEFAULTS, **file.spec.solver.options}
        info, records = _solve_starts(nlp, method, options, problem.objective.sense,
                                      method.seed if seed is None else seed, verbose, progress,
                                      flies=lambda info: _flies(file, mp, nlp, info))
    with timer.measure("post"):
        try:
            with evaluation_unlogged():
                try:
                    result = solved_result(file, mp, nlp, info)
                except (ZeroDivisionError, OverflowError) as e:
                    # an end value on the map's singularity (a loop from the straight-line guess:
                    # the heading at t0 is 0/0) was a bare ZeroDivisionError after Pyomo printed
                    # the whole expression (unseen49 F1)
                    raise FlatSingularError(f"the flat map cannot be evaluated at the solver's last point "
                                            f"({type(e).__name__}: {e})") from None
        except FlatSingularError as e:
            # the planar quadrotor's outputs (x, th) divide by sin(th), 0 in hover (unseen32)
            # the key is `flat_outputs:` (unseen49 F4: the advice named `outputs:`, refused)
            hint = singularity_hint(mp, problem)
            raise FlatSingularError(f"{e}. {hint + '; or c' if hint else 'C'}hoose other flat outputs "
                                    "(`flat_outputs:`), give a guess along which the outputs move as the "
                                    "solution should (`guess:`: a loop's straight-line guess stands still), "
                                    "or a pseudospectral transcription (`transcription: LGR`)") from None
        result.extra["starts"] = records
    if method.tolerance is not None:
        from .flat_bspline_refine import refine

        with timer.measure("refine"):
            result = refine(file, mp, result, options, verbose, sum(timer.breakdown().values()))
    else:
        from .flat_bspline_refine import confirm_objective

        with timer.measure("bisection"):
            result = confirm_objective(file, mp, result, options, verbose)
    if result.status not in ("optimal", "acceptable", "mesh_not_converged"):
        hint = singularity_hint(mp, problem)
        if hint:
            result.message = f"{result.message.rstrip('.')}. {hint}"
    result.wall_time_s = timer.breakdown()
    return result


def _flies(file, mp: "_Mapped", nlp, info) -> bool:
    """Whether the solution in the model passes the file's verification."""
    from ..verify import VerifySettings, attach_verification

    try:
        res = solved_result(file, mp, nlp, info)
    except FlatSingularError:
        return False
    attach_verification(file.problem, res, VerifySettings.of(file.spec.verify))
    return res.verification.get("status") == "verified"


def singularity_hint(mp: "_Mapped", problem) -> str:
    """Where the flat map divides by an expression in the outputs' derivatives, the NLP is
    singular where it vanishes (a unicycle's x'^2 + y'^2, its speed squared): a failed solve
    says which, and that bounding the quantity away from zero keeps the solver off it
    (unseen22 f13: 'unrecoverable error ... search direction', no word why; with 0.1 <= v the
    same file solves)."""
    out, branches = [], []
    for ph in problem.phases:
        fm = mp.flatmaps[ph.name]
        bounds = {**getattr(ph, "state_bounds", {}), **getattr(ph, "control_bounds", {})}
        for group in (fm.states, fm.controls):
            for name, expr in group.items():
                den = sp.denom(sp.together(expr))
                if den.free_symbols and str(den) not in out:
                    out.append(str(den))
                for p in sp.sympify(expr).atoms(sp.Pow):
                    if p.exp.is_Rational and p.exp.q == 2 and p.base.free_symbols and str(p.base) not in out:
                        out.append(str(p.base))
                branch = _root_branch(expr)
                lo, hi = bounds.get(name, (-math.inf, math.inf))
                # a bound on the branch's side is the file's choice of it: nothing to say
                if branch is not None and not (lo >= 0 if branch[0] == "+" else hi <= 0):
                    branches.append((name, *branch, [str(y) for y in getattr(fm, "outputs", ())]))
    said = []
    for ph in problem.phases:
        fm = mp.flatmaps[ph.name]
        path = getattr(ph, "path", None) or []
        in_path = set().union(*(c.expr.free_symbols for c in path)) if path else set()
        for x, expr in fm.states.items():
            if isinstance(expr, sp.atan2) and (x in getattr(ph, "state_bounds", {}) or x in in_path):
                # a bound on an atan2 state is imposed on its principal value: a 270-degree turn
                # "infeasible" under `th >= -0.5`, which the turn never meets (unseen49 F2)
                said.append(f"{x} is atan2 of the outputs' derivatives, and its bounds and path constraints "
                            f"see its principal value in (-pi, pi]: a {x} that turns past pi meets them there "
                            f"though {x} itself never does. Bound {x} with `transcription: LGR`, which sees {x}")
    if out:
        said.append(f"The flat map is singular where {' or '.join(f'`{d}`' for d in out[:3])} vanishes (its "
                    "division or square root): the solver may have run into it. Bounding the state or control "
                    "that measures it away from zero (for a speed, `0.1 <= v`) keeps the outputs off it")
    for name, sign, base, outputs in branches[:2]:
        # unseen37 F1: x3 = +sqrt(x1' - x2) from the outputs [x1, x2], while x2(t0) = x2(tf) = 0
        # and x2' = x3 make x3 change sign: no trajectory of the problem is on that branch
        said.append(f"With the outputs {outputs} the map takes {name} = {sign}sqrt({base}), so {name} "
                    f"{'>=' if sign == '+' else '<='} 0 throughout: a solution in which {name} changes sign is not "
                    f"on it. A bound on {name} chooses the branch (`{name} <= 0` the other one), or other "
                    "`flat_outputs` may avoid the root")
    return ". ".join(said)


def _root_branch(expr) -> tuple[str, sp.Expr] | None:
    """('+' or '-', base) where ``expr`` is a square root or its negative, else None."""
    e = sp.sympify(expr)
    sign = "+"
    if e.could_extract_minus_sign():
        e, sign = -e, "-"
    if e.is_Pow and e.exp == sp.Rational(1, 2) and e.base.free_symbols:
        return sign, e.base
    return None


class FlatSingularError(FlatProblemError):
    """The flat map cannot be evaluated at the solution (it divides by zero there)."""


def _value(expr, what: str) -> float:
    """The number of a Pyomo expression of the flat map at the solution. The kinematic
    bicycle's heading from rest is 2 atan(y' / (|(x', y')| + x')) with x' = y' = 0 at t0: Pyomo
    logged the expression and the run ended "ZeroDivisionError: float division by zero"
    (unseen32)."""
    import pyomo.core as pyo

    try:
        return float(pyo.value(expr, exception=False))
    except (ZeroDivisionError, ValueError, OverflowError, TypeError) as e:
        raise FlatSingularError(f"the flat map cannot be evaluated at the solution: {what} ({e})") from None


def solved_result(file, mp: "_Mapped", nlp, info) -> Result:
    """The Result of a solved flat NLP: every state and control on ``dense_points`` per
    phase (at least 8 per knot span, so that the cubic per knot span through the rows that
    the run folder declares follows the spline), residuals, boundary values, expect checks."""
    import pyomo.core as pyo

    from ..run import check_expectations

    problem, method, opts = file.problem, file.method, mp.opts
    tau = np.linspace(0.0, 1.0, max(method.dense_points, 8 * (opts.n_ctrl - opts.degree) + 1))
    knots = np.unique(clamped_knots(opts.degree, opts.n_ctrl))
    phases, dense = [], {}
    for ph in problem.phases:
        p = nlp.phases[ph.name]
        with np.errstate(all="ignore"):       # a singular flat map's inf or nan: the verification's
            num = p.numeric(tau)
        t0 = float(pyo.value(mp.t0[ph.name]))
        # the controls are smooth inside knot spans, only continuous at the knots
        spans = {"kind": "cubic", "breakpoints": (t0 + np.interp(knots, tau, num["t"])).tolist()}
        traj = PhaseTrajectory(ph.name, num["t"] + t0,
                               {s.name: num[s.name] for s in ph.states},
                               {c.name: _unwrapped(ph, c, num[c.name], mp.flatmaps[ph.name].controls.get(c))
                                for c in ph.controls},
                               extra={k: v for k, v in num.items() if k.startswith("residual_")},
                               control_interpolation=spans)
        dense[ph.name] = max([float(np.max(np.abs(v))) for v in traj.extra.values()] or [0.0])
        phases.append(traj)
    values: dict[sp.Symbol, float] = {}
    for s in problem.boundary_values:
        values[s] = _value(mp.pyomo_of(s), s.name)
    tf = {}
    for ph in problem.phases:
        values[ph.t0_symbol] = float(pyo.value(mp.t0[ph.name]))
        values[ph.tf_symbol] = tf[ph.name] = float(pyo.value(mp.pyomo_of(ph.tf_symbol)))
    for s, v in mp.free.items():
        values[s] = float(pyo.value(v))
    for s, e in mp.integral_expr.items():
        values[s] = _value(e, f"integral({problem.integrals[s][1]})")
    for name, v in file.parameters.items():
        values.setdefault(sp.Symbol(name, real=True), float(v))
    reduction = {}
    for ph in problem.phases:
        fm = mp.flatmaps[ph.name]
        n_bc = sum(1 for c in problem.boundary if any(
            problem.boundary_values.get(s) is not None and problem.boundary_values[s].phase == ph.name
            for s in c.expr.free_symbols))
        n_bc -= sum(1 for v in nlp.phases[ph.name].block.k.values() if v.fixed)
        red = fm.reduction(opts.n_ctrl, opts.n_col, n_bc, free_tf=ph.tf is None or ph.t0 is None)
        reduction[ph.name] = {**red.as_dict(), "outputs": [y.name for y in fm.outputs],
                              "functions": [y.name for y in fm.functions],
                              "residuals": [str(r.expr) for r in fm.residuals]}
    reduction["total"] = {k: sum(reduction[ph.name][k] for ph in problem.phases)
                          for k in ("variables_flat", "constraints_flat", "variables_full",
                                    "constraints_full")}
    objective = info.objective
    result = Result(
        name=file.spec.name, status=info.status, message=info.message, objective=objective,
        tf=tf["main"] if len(tf) == 1 and "main" in tf else tf,
        iterations=info.iterations, nlp=info.nlp,
        method={**method.model_dump(), "control_points": opts.n_ctrl, "collocation_points": opts.n_col,
                "residual": opts.residual},
        parameters={**file.parameters, **{s.name: values[s] for s in problem.free_parameters}},
        phases=phases, problem=problem.description)
    result.extra["flat_reduction"] = reduction
    result.extra["flat_map"] = {ph.name: mp.flatmaps[ph.name].summary() for ph in problem.phases}
    result.extra["max_residual_dense"] = dense
    result.extra["ipopt_history"] = [list(h) for h in info.history[-200:]]
    result.expect = check_expectations(file, values, objective)
    return result


def _unwrapped(ph, control, values: np.ndarray, expr) -> np.ndarray:
    """An angle from the flat map's atan2 jumps by 2 pi where it crosses the branch cut;
    the exported control is made continuous (the cubic through the rows must not cross the
    jump), shifted by a multiple of 2 pi into the control's bounds, or, unbounded, so that
    most of it lies in [-pi, pi] (atan2's range). Only such a control (``expr``, its flat
    map, has an atan2): the fourth derivative of a flat output stepping by more than pi
    between rows was "unwrapped" into a wrong column, and a right answer failed its
    verification (unseen22 FA1)."""
    values = np.asarray(values, float)
    if expr is None or not sp.sympify(expr).has(sp.atan2):
        return values
    if len(values) < 2 or not np.all(np.isfinite(values)) or np.max(np.abs(np.diff(values))) < np.pi:
        return values
    out = np.unwrap(values)
    lo, hi = ph.control_bounds.get(control, (-INF, INF))
    shifts = [out + 2 * np.pi * k for k in (0, -1, 1, -2, 2)]
    for shifted in shifts if math.isfinite(lo) or math.isfinite(hi) else ():
        if np.all(shifted >= lo - 1e-12) and np.all(shifted <= hi + 1e-12):
            return shifted
    return min(shifts, key=lambda a: int(np.sum(np.abs(a) > np.pi)))


def _solve_starts(nlp, method, options, sense: str, seed: int, verbose: bool, progress: bool, flies=None):
    """Solve from the built guess, then (``method.starts`` > 1) from copies of it whose free
    scaled control points are moved by normal noise of standard deviation ``method.spread``
    (start i draws from ``seed + i``) and clipped to their bounds; the model is left at the
    best solution. The flat NLPs have several local optima close together (seed 2, strategy
    1: final masses 149.851, 149.871 and 149.935 kg, each reached from nearby starts), so a
    single start lands on one of them by the accidents of its path. With several starts,
    ``flies(info)`` (the model at that start's solution) says whether its trajectory passes
    the verification, and one that does beats one that does not whatever their objectives:
    a start through the flat map's singularity reached 1.618 with the dynamics off by 2.98,
    below the optimum 1.8807 another start had found (unseen22b f17). Returns (the best
    SolveInfo, one record per start)."""
    import pyomo.core as pyo

    from ..run import _better, _start_record
    from ..solve import ipopt

    variables = [v for v in nlp.model.component_data_objects(pyo.Var) if not v.fixed]
    guess = [v.value for v in variables]
    control_points = {id(v) for ph in nlp.phases.values() for v in ph.block.z.values()}
    best = best_values = best_rank = None
    records = []
    for i in range(method.starts):
        rng = np.random.default_rng(seed + i) if i else None
        for v, x in zip(variables, guess):
            if rng is not None and id(v) in control_points and x is not None:
                x = x + method.spread * rng.normal()
                x = max(x, v.lb) if v.lb is not None else x
                x = min(x, v.ub) if v.ub is not None else x
            v.set_value(x, skip_validation=True)
        label = f"[{i + 1}/{method.starts}]" if method.starts > 1 else ""
        info = ipopt.solve(nlp.model, options, verbose=verbose, progress=ipopt.Progress(progress, label))
        records.append(_start_record(i, seed + i if i else None, info))
        converged = info.status in ("optimal", "acceptable")
        valid = False
        if flies is not None and method.starts > 1 and converged:
            valid = records[-1]["verified"] = bool(flies(info))
        rank = (converged, valid)
        if best is None or rank > best_rank or (rank == best_rank and _better(info, best, sense)):
            best, best_values, best_rank = info, [v.value for v in variables], rank
    for v, x in zip(variables, best_values):
        v.set_value(x, skip_validation=True)
    return best, records
