"""Bang-bang switch times as unknowns of the NLP (``build(free_breakpoints=...)``).

A switch on a breakpoint is pinned there: with the control at one bound on every node before
it and at the other after it, the next solve shows no interior control value, and the
quadrature locator (``locate.locate_switches``) sees the switch exactly on the breakpoint
whether or not it belongs there. Where a free final time or an integral constraint can absorb
the misplacement, the discrete optimum then sits with the switch pinned and t_f off
(configs/mesh_tumour.yaml: dose window fixed at s_b t_f, t_f 2.2e-3 off the exact bang-off
solution with every error estimate within 1e-7).

``solve_switch_times``: each switch located on or near a breakpoint whose move would change J
(dJ*/ds_b by the envelope theorem, ``breakpoint_gradient``: the Lagrangian's partial
derivative at the solution, from the direct NLP on the moved mesh) gets that breakpoint as an
unknown, the bang controls of its two segments held at their bounds, all switches of the
problem in one solve with t_f; the next mesh puts its breakpoints there exactly. It replaced
a secant on s_b -> dJ*/ds_b across mesh iterations, under which two switches with a free
final time disturbed each other through t_f for 12-30 meshes (docs/mesh.md).

``with_switch_costates``: the converged mesh solved once more the same way, for its
multipliers. Minimisation only, and phases with a free initial or final time only (on the
fixed-time bang-off-bang problem breakpoint moves made the terminal error oscillate).
"""
from __future__ import annotations

import math

import numpy as np

from ...verify.objective_size import own_size

DELTA = 1e-7          # normalised-time step of the finite difference


def _values(model):
    import pyomo.core as pyo

    vars_ = list(model.component_data_objects(pyo.Var, descend_into=True))
    cons = list(model.component_data_objects(pyo.Constraint, active=True, descend_into=True))
    return vars_, cons


def breakpoint_gradient(tr, rebuild, phase: str, q: int, step: float = DELTA) -> float:
    """dJ*/ds at breakpoint ``q`` of phase ``phase`` of the solved transcription ``tr``
    (see the module doc), by a difference over ``step`` (negative: the one-sided derivative
    from below); ``rebuild(meshes)`` builds the model on other meshes exactly as ``tr`` was
    built. NaN when the two models do not match."""
    import pyomo.core as pyo

    fast = _direct_difference(tr, phase, q, step)
    if fast is not None:
        return fast / step
    other = rebuild(_moved(tr, phase, q, step))
    v0, c0 = _values(tr.model)
    v1, c1 = _values(other.model)
    if len(v0) != len(v1) or len(c0) != len(c1):
        return math.nan
    for a, b in zip(v0, v1):
        b.set_value(a.value, skip_validation=True)
    dual = tr.model.dual
    total = 0.0
    for a, b in zip(c0, c1):
        y = dual.get(a)
        if not y:
            continue
        total += y * (pyo.value(b.body) - pyo.value(a.body))
    obj0 = next(tr.model.component_data_objects(pyo.Objective, active=True))
    obj1 = next(other.model.component_data_objects(pyo.Objective, active=True))
    total += pyo.value(obj1.expr) - pyo.value(obj0.expr)
    return total / step


def _direct_difference(tr, phase: str, q: int, step: float = DELTA):
    """L - L(tr) at tr's primal values and multipliers, L that of tr with breakpoint ``q`` of
    ``phase`` moved by DELTA, evaluated by tr's NumPy NLP and its copy on the moved mesh
    (``DirectNLP.with_breakpoints``: every row at once, nothing rebuilt; the Pyomo model
    rebuilt for each breakpoint was most of a robot-arm mesh iteration, and its expression
    walk 0.2-0.3 s per derivative at 2,000 variables before that). None where the model takes
    the PyNumero route (a regularised objective): the caller rebuilds it then."""
    from .. import ipopt

    n0, _ = ipopt.direct_nlp(tr)
    if n0 is None:
        return None
    index = next(i for i, p in enumerate(tr.phases) if p.phase.name == phase)
    n1 = n0.with_breakpoints(index, _moved(tr, phase, q, step)[phase])
    x = n0.x0                 # tr's values, in the variable order the copy shares
    dual = tr.model.dual
    y = np.array([dual.get(r) or 0.0 for r in n0.rows], float)
    with np.errstate(all="ignore"):
        d = float(y @ (n1.constraints(x) - n0.constraints(x)) + n1.objective(x) - n0.objective(x))
    return d if math.isfinite(d) else None


def _moved(tr, phase: str, q: int, step: float) -> dict:
    """The meshes of ``tr`` with breakpoint ``q`` of ``phase`` moved by ``step``."""
    from ...transcribe.mesh import Mesh

    meshes = {p.phase.name: p.layout.mesh for p in tr.phases}
    m = meshes[phase]
    bps = np.asarray(m.breakpoints, float).copy()
    bps[q] += step
    meshes[phase] = Mesh(m.scheme_name, bps, tuple(m.degrees))
    return meshes


def solve_switch_times(tr, rebuild, solve, features: dict, switches: dict, spec, objective: float,
                       times: str = "free"):
    """(features, meshes): per phase, the features with those on or near breakpoint-held
    switches replaced by the breakpoints an NLP with those breakpoints as unknowns puts them
    at (``build(free_breakpoints=)``, every switch of the problem at once, with t_f and the
    rest), and the meshes of the phases whose breakpoints so moved, exactly there (not through
    the features, which count anything within corner_tolerance as on a breakpoint).
    ``rebuild(meshes, free_breakpoints=None)`` builds as ``tr`` was built, from its solution;
    ``solve(model)`` is the SolveInfo of a solve of it. ``times``: the phases with a free
    initial or final time (``"free"``, at every mesh), or those with both fixed (``"fixed"``:
    the mesh drive's check of a mesh within tolerance; a switch pinned on a breakpoint is
    not always where the quadrature locator would move it: unseen13 F1, J 2.3e-4 low with
    the switch on t = 1.978 for 2, called converged)."""
    out = dict(features)
    tol = spec.corner_tolerance
    size = 1.0 + own_size(objective, tr.problem.objective_constant)
    free: dict = {}
    plan: dict = {}       # phase -> [(switch located, breakpoint index)]
    for pb in tr.phases:
        name = pb.phase.name
        fixed_times = pb.phase.tf is not None and pb.phase.t0 is not None
        if fixed_times != (times == "fixed"):
            continue
        bps = np.asarray(pb.layout.mesh.breakpoints, float)
        for f in sorted(switches.get(name, [])):
            q = int(np.argmin(np.abs(bps - f)))
            if not (0 < q < len(bps) - 1):
                continue
            width = min(bps[q] - bps[q - 1], bps[q + 1] - bps[q])
            pinned = abs(bps[q] - f) <= tol
            if not pinned and abs(bps[q] - f) > spec.snap * width:
                continue
            g = breakpoint_gradient(tr, rebuild, name, q)
            # insignificant: moving the breakpoint by corner_tolerance changes J by far less
            # than the tolerance asks of it
            if not math.isfinite(g) or (pinned and abs(g) * tol <= 1e-2 * spec.tolerance * size):
                continue
            plan.setdefault(name, []).append((f, q))
            free.setdefault(name, set()).add(q)
    if not free:
        return out, {}
    model, _ = _switch_model(tr, rebuild, {k: sorted(v) for k, v in free.items()}, tol)
    info = solve(model)
    if info.status not in ("optimal", "acceptable") or info.objective is None:
        return out, {}
    meshes = solved_meshes(model)
    before = {p.phase.name: np.asarray(p.layout.mesh.breakpoints, float) for p in tr.phases}
    for name, pairs in plan.items():
        bps = before[name]
        feats = list(features.get(name, []))
        for f, q in pairs:
            target = float(meshes[name].breakpoints[q])
            feats = [target if abs(x - f) <= tol or abs(x - bps[q]) <= tol else x for x in feats]
        out[name] = sorted(feats)
    return out, meshes


def with_free_switches(tr, rebuild, solve, free: dict, tol: float):
    """(objective, meshes) of ``tr``'s problem solved with the breakpoints ``free`` (phase ->
    indices) as unknowns and the bang controls of their segments held (``_switch_model``), or
    None when no control is held or the solve does not converge: where the switches go when
    the mesh does not hold them (``fixed_mesh.pinned_switches``)."""
    model, held = _switch_model(tr, rebuild, free, tol)
    if not held:
        return None
    info = solve(model)
    if info.status not in ("optimal", "acceptable") or info.objective is None:
        return None
    return float(info.objective), solved_meshes(model)


def _switch_model(tr, rebuild, free: dict, tol: float):
    """(model, controls held): ``tr``'s problem on its meshes with the breakpoints ``free``
    (phase -> indices) as unknowns and the bang controls of their two segments held."""
    model = rebuild({p.phase.name: p.layout.mesh for p in tr.phases}, free_breakpoints=free)
    held = sum(_hold_bang_controls(old, new, q, tol)
               for old, new in zip(tr.phases, model.phases) for q in free.get(new.phase.name, ()))
    return model, held


def solved_meshes(model) -> dict:
    """Phase -> its mesh with the breakpoints the solve of ``model`` put its unknown ones at
    (phases with such breakpoints only)."""
    import pyomo.core as pyo

    from ...transcribe.mesh import Mesh

    out = {}
    for pb in model.phases:
        if pb.free_breakpoints:
            mesh = pb.layout.mesh
            bps = np.asarray(mesh.breakpoints, float).copy()
            for q, var in pb.free_breakpoints.items():
                bps[q] = float(pyo.value(var))
            out[pb.phase.name] = Mesh(mesh.scheme_name, bps, tuple(mesh.degrees))
    return out


def _hold_bang_controls(solved, pb, q: int, tol: float) -> int:
    """In the model ``pb`` (breakpoint ``q`` an unknown), each control that ``solved`` has at
    one bound on the first node of segment q - 1 and at the other on the last node of segment
    q (a switch between them) is fixed to those bounds on the two segments: the breakpoint is
    then the switch's time (without, the NLP moves the switch into a segment, where the
    collocation's error lowers J). Returns how many controls were held."""
    import pyomo.core as pyo

    lay = solved.layout
    left, right = lay.colloc[q - 1], lay.colloc[q]
    held = 0
    for j, u in enumerate(solved.phase.controls):
        lo, hi = solved.phase.control_bounds.get(u, (-math.inf, math.inf))
        if not (math.isfinite(lo) and math.isfinite(hi)):
            continue

        def at(nodes, v, j=j, span=max(1.0, hi - lo)):
            return all(abs(pyo.value(solved.block.U[i, j]) - v) <= tol * span for i in nodes)

        for a, b in ((lo, hi), (hi, lo)):
            if at(left[:1], a) and at(right[-1:], b):
                for i in left:
                    pb.block.U[i, j].fix(a)
                for i in right:
                    pb.block.U[i, j].fix(b)
                held += 1
    return held


def _state_at_bound(pb, nodes) -> bool:
    """Whether a state of the solved phase ``pb`` sits on one of its bounds at one of the
    state ``nodes`` (``segments.activity``, as the estimate judges it)."""
    from ...transcribe.solution import node_values
    from .segments import activity

    X, _ = node_values(pb)
    idx = np.asarray(nodes, int)
    return any(activity(X[idx, j], *pb.phase.bounds_of(x)[:2], 1e-6).any() for j, x in enumerate(pb.phase.states))


def with_switch_costates(tr, rebuild, solve, switches: dict, spec, objective: float):
    """The converged ``tr`` solved once more with its switch breakpoints as unknowns and the
    bang controls on their two segments held (``solve_switch_times``' model), returned as
    (transcription of the moved mesh, layouts updated; its SolveInfo), or None when that does
    not hold.

    Why: on a mesh whose breakpoints carry the switches, every control node sits on a bound,
    and the fixed NLP's multipliers are a family (the terminal multipliers are free but for
    t_f's stationarity); Ipopt returns one whose H jumps at the switches (harmonic
    oscillator: H from -1.10 to -0.95 against -1, certificate failed on an exact tf). With the
    breakpoints unknowns, their stationarity is H's continuity there: the multipliers are
    the PMP costates. The primal moves by the breakpoint's error only (it must stay within
    corner_tolerance and J within the tolerance)."""
    from ...transcribe.mesh import Layout

    tol = spec.corner_tolerance
    free = {}
    for pb in tr.phases:
        bps = np.asarray(pb.layout.mesh.breakpoints, float)
        qs = {int(np.argmin(np.abs(bps - f))) for f in switches.get(pb.phase.name, [])}
        qs = sorted(q for q in qs if 0 < q < len(bps) - 1
                    and min(abs(bps[q] - f) for f in switches[pb.phase.name]) <= tol)
        # a state resting on its bound beside the switch (the moon lander's m <= 1 while it
        # coasts from m(t0) = 1) has a bound multiplier that only the signs of the controls,
        # once held, would pin: Ipopt gave it a share, the costates shifted, and the switching
        # function came out with the wrong sign on the whole coast arc (certificate failed with
        # J right to 1e-11). The fixed mesh's costates keep the signs KKT gives them.
        lay = pb.layout
        qs = [q for q in qs if not _state_at_bound(pb, [*lay.support[q - 1], *lay.support[q], lay.end[q]])]
        if qs:
            free[pb.phase.name] = qs
    if not free:
        return None
    model, held = _switch_model(tr, rebuild, free, tol)
    if not held:
        return None
    info = solve(model)
    size = 1.0 + own_size(objective, tr.problem.objective_constant)
    if info.status != "optimal" or info.objective is None or abs(info.objective - objective) > spec.tolerance * size:
        return None
    meshes = solved_meshes(model)
    for pb in model.phases:
        if pb.phase.name in meshes:
            if np.max(np.abs(meshes[pb.phase.name].breakpoints - pb.layout.mesh.breakpoints)) > tol:
                return None
            pb.layout = Layout.of(meshes[pb.phase.name])
    return model, info
