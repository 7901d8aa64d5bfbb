"""Breakpoints held by bang-bang switches, moved to where the objective is stationary in them.

A switch on a breakpoint is pinned there: with the control at one bound on every node before
it and at the other bound after it, the next solve shows no interior control value, and the
quadrature locator (``locate.locate_switches``) sees the switch exactly on the breakpoint
whether or not it belongs there. Where a free final time or an integral constraint can absorb
the misplacement, the discrete optimum then sits with the switch pinned and t_f off
(configs/mesh_tumour.yaml: dose window fixed at s_b t_f, t_f 2.2e-3 off the exact bang-off
solution with every error estimate within 1e-7).

For a breakpoint s_b the derivative of the discrete optimum J*(s_b) is, by the envelope
theorem, the partial derivative of the Lagrangian at the solution: with the primal values and
multipliers fixed, dJ*/ds_b = dJ/ds_b + sum_c y_c d(body_c)/ds_b, y_c the multipliers as
``ipopt.solve`` loads them into the ``dual`` suffix (checked against re-solves on the tumour
mesh [0, 0.16687, 1], degrees (4, 8): envelope 24.99, finite difference of J* 24.77).
Minimisation only (a maximised objective is left to the quadrature locator), and phases with a
free initial or final time only (see ``move_switches``). The partial derivatives are forward
differences with the breakpoint moved by ``DELTA`` (same nodes, same variables, same
constraints: only the node times and segment widths change), evaluated by the solved model's
NumPy NLP and its copy on the moved mesh (``DirectNLP.with_breakpoints``); a model on the
PyNumero route is rebuilt on the moved mesh instead. The stationary breakpoint is then found by a secant on
s_b -> dJ*/ds_b across mesh iterations (``memory``) where two records bracket a minimum (a
positive slope); a pinned switch without one (J* is kinked there, and a record from the
other side of the kink gives no slope) moves, by a fixed fraction of its neighbouring
segments, only where a warm-started trial solve of a small step found J lower. A record of the memory is paired with the switch
whose breakpoint it belongs to (``_pair_records``), not with the switch's order among those located:
a locator that misses one switch, or finds a spurious one, would pair one switch's derivative with
another's breakpoint and make the secant's target meaningless.
"""
from __future__ import annotations

import math

import numpy as np

DELTA = 1e-7          # normalised-time step of the finite difference
FIRST_STEP = 0.05     # a move without a known slope (after a trial lowered J), fraction of the smaller neighbour


def _values(model):
    import pyomo.core as pyo

    vars_ = list(model.component_data_objects(pyo.Var, descend_into=True))
    cons = list(model.component_data_objects(pyo.Constraint, active=True, descend_into=True))
    return vars_, cons


def breakpoint_gradient(tr, rebuild, phase: str, q: int) -> float:
    """dJ*/ds at breakpoint ``q`` of phase ``phase`` of the solved transcription ``tr``
    (see the module doc); ``rebuild(meshes)`` builds the model on other meshes exactly as
    ``tr`` was built. NaN when the two models do not match."""
    import pyomo.core as pyo

    fast = _direct_difference(tr, phase, q)
    if fast is not None:
        return fast / DELTA
    other = rebuild(_moved(tr, phase, q, DELTA))
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
    return total / DELTA


def _direct_difference(tr, phase: str, q: int):
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
    n1 = n0.with_breakpoints(index, _moved(tr, phase, q, DELTA)[phase])
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


def _pair_records(records: list, points) -> list:
    """For each breakpoint in ``points`` (one per switch located this iteration), the index in
    ``records`` of the previous record of the same switch, or None. A record is
    ``(breakpoint, dJ*/ds, lo, hi)``, lo and hi the neighbouring breakpoints when it was
    written (the outer ends of its two segments). Criterion: a record can belong to a breakpoint only when the breakpoint lies
    strictly inside the record's (lo, hi) -- ``move_switches`` clamps every move within those two
    segments, and ``refine`` puts the breakpoint on the moved target, so the same switch is found
    there next iteration whatever refinement did to the segments around it, while a switch beyond
    a neighbouring breakpoint of the record is another one. Among those candidates the nearest
    pairs first, and each record serves one switch at most (two located switches never share
    one, and a spurious switch between two real ones gets a record only a real one left)."""
    pts = [float(b) for b in points]
    cand = sorted((abs(r[0] - b), i, j) for i, b in enumerate(pts) for j, r in enumerate(records)
                  if r[2] < b < r[3])
    out: list = [None] * len(pts)
    used = set()
    for _, i, j in cand:
        if out[i] is None and j not in used:
            out[i] = j
            used.add(j)
    return out


def move_switches(tr, rebuild, resolve, features: dict, switches: dict, spec, memory: dict,
                  objective: float) -> dict:
    """Per phase: the features with those on breakpoint-pinned switches replaced by the
    breakpoint the secant on dJ*/ds predicts (left as they are when that is within
    ``corner_tolerance`` or the derivative is insignificant). ``switches``: per phase, the
    bound-to-bound switches located this iteration; ``memory``: per phase, the list of previous
    records (breakpoint, derivative, lo, hi) of the switches (``_pair_records``), replaced by this
    iteration's: a record no located switch is paired with is dropped, one whose switch is
    located but not moved this time is kept. ``resolve(meshes)``: the objective of a
    warm-started solve on other meshes (None when it fails)."""
    import pyomo.core as pyo

    out = dict(features)
    obj = next(tr.model.component_data_objects(pyo.Objective, active=True))
    if obj.sense == pyo.maximize:
        return out
    j_model = float(pyo.value(obj.expr))   # as solved (a regularisation term included)
    tol = spec.corner_tolerance
    for pb in tr.phases:
        name = pb.phase.name
        if pb.phase.tf is not None and pb.phase.t0 is not None:
            # fixed times: the quadrature locator's switches converge by themselves, and the
            # secant made configs/mesh_bang_off_bang.yaml oscillate (terminal error 1e-6 ->
            # 8.6e-3 -> 2.8e-3 ... in 20 iterations, against 1.4e-7 without it)
            continue
        bps = np.asarray(pb.layout.mesh.breakpoints, float)
        feats = list(features.get(name, []))
        located = sorted(switches.get(name, []))
        qs = [int(np.argmin(np.abs(bps - f))) for f in located]
        records = list(memory.get(name, []))
        pairing = _pair_records(records, [bps[q] for q in qs])
        # the switches located this time keep their records until replaced below; the records
        # of switches not located this time (missed, or never real) are dropped
        mem = {k: records[j] for k, j in enumerate(pairing) if j is not None}   # by order, this time
        for order, f in enumerate(located):
            q = qs[order]
            if not (0 < q < len(bps) - 1):
                continue
            width = min(bps[q] - bps[q - 1], bps[q + 1] - bps[q])
            pinned = abs(bps[q] - f) <= tol
            # a switch off its breakpoint but near it: the breakpoint is on its way there (the
            # quadrature estimate f is a fixed-point map that only halves the distance per
            # iteration, tumour: 0.200237, 0.200129, 0.20007, ...): the secant on dJ*/ds takes over
            if not pinned and abs(bps[q] - f) > spec.snap * width:
                continue
            g = breakpoint_gradient(tr, rebuild, name, q)
            if not math.isfinite(g):
                continue
            prev = mem.get(order)
            mem[order] = (float(bps[q]), g, float(bps[q - 1]), float(bps[q + 1]))
            # insignificant: moving the breakpoint by corner_tolerance changes J by far less
            # than the tolerance asks of it
            if pinned and abs(g) * tol <= 1e-2 * spec.tolerance * (1.0 + abs(objective)):
                continue
            slope = None
            if prev is not None and abs(prev[0] - bps[q]) > 1e-15 and (g - prev[1]) != 0:
                slope = (g - prev[1]) / (bps[q] - prev[0])
            target = None
            if pinned and not (slope is not None and slope > 0):
                # a switch exactly on its breakpoint makes J*(s_b) kinked there (moving it
                # either way forces interior control values: double integrator, switch at 1),
                # and the multipliers give one subgradient only; a secant across the kink
                # (a record from the other side) has no meaning either. A small move is tried
                # by a warm-started solve first, and the breakpoint moves only if it lowers J
                # (before, a negative secant slope moved it untried: the COPS robot arm ended
                # mesh_not_converged at 1,084 variables, now optimal at 283; the harmonic
                # oscillator's meshes disagreed in J, now it converges)
                step = min(10 * tol, 0.01 * width)
                d = -math.copysign(step, g)
                j_trial = resolve(_moved(tr, name, q, d))
                if j_trial is None or not (j_trial < j_model - 0.25 * abs(g) * step):
                    mem.pop(order, None)
                    continue
                target = bps[q] + math.copysign(FIRST_STEP * width, d)
            elif slope is not None and slope > 0:     # a minimum of J*(s_b) (what the NLP minimises)
                target = bps[q] - g / slope
                # the move would gain far less than the tolerance: the breakpoint is where
                # the objective needs it (J* can be flat in it: tumour, p(tf) at its minimum)
                if g * g / (2.0 * slope) <= 1e-2 * spec.tolerance * (1.0 + abs(objective)):
                    target = float(bps[q])
            else:
                target = f
            # within the two neighbouring segments
            target = float(min(max(target, bps[q - 1] + 0.1 * (bps[q] - bps[q - 1])),
                               bps[q + 1] - 0.1 * (bps[q + 1] - bps[q])))
            if abs(target - bps[q]) > tol:
                feats = [target if abs(x - f) <= tol else x for x in feats]
            elif not pinned:
                # the secant says the breakpoint is where it belongs: the switch counts as on it
                feats = [float(bps[q]) if abs(x - f) <= tol else x for x in feats]
        memory[name] = [mem[k] for k in sorted(mem)]
        out[name] = sorted(feats)
    return out
