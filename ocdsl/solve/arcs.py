"""Arcs of state and path constraints on a fixed mesh: what the verification cannot judge.

Where a state bound or an inequality path constraint starts or stops binding, the optimal
state has a kink (and the control often a jump) at a junction time that the problem fixes.
On a mesh chosen without it the NLP's optimum is a feasible trajectory, flown exactly by the
verification, whose J is the optimum *of that mesh*: a speed-limited minimum-energy transfer
gave J = 12.24 on 3 LG segments and 12.1957 on 7 against the exact 12.1956, verified, with a
passing certificate (unseen5). Whether a junction sits inside a segment or the NLP moved it
onto a wrong breakpoint (the 7-segment case: the arc began at the breakpoint 2/7, the exact
junction is 0.3), the nodes alone do not tell. So a single solve names the arcs it found and
says what its J is; adaptive refinement (``mesh:``) places the junctions and checks J.
"""
from __future__ import annotations

import math

import numpy as np

# relative to 1 + |bound|: Ipopt leaves an active bound within about 1e-8; a state leaving its
# bound from rest (Goddard's r >= 1 from r(t0) = 1) is 7e-7 above it at the first node
ACTIVE_TOL = 1e-7


def constrained_arcs(tr) -> list[str]:
    """One note per phase of a solved pseudospectral transcription ``tr`` whose state bounds
    or inequality path constraints bind at a node inside the phase (not only at its ends,
    where boundary conditions hold states at bounds; a touch point counts: the 3-segment
    speed limit touched at one node): which, and over what times."""
    import pyomo.core as pyo

    from ..transcribe.solution import node_values, phase_times
    from .mesh.segments import activity

    notes = []
    for pb in tr.phases:
        ph, lay = pb.phase, pb.layout
        X, _ = node_values(pb)
        t0, tf = phase_times(pb)
        rows = []         # (constraint text, values at nodes, their normalised times, lo, hi)
        for j, s in enumerate(ph.states):
            lo, hi = ph.bounds_of(s)
            if math.isfinite(lo) or math.isfinite(hi):
                rows.append((_bound_text(s.name, lo, hi), X[:, j], lay.s_state, lo, hi))
        npath = len(ph.path)
        path_rows = getattr(pb.block, "path", None)
        if npath and path_rows is not None and len(path_rows) == lay.n_colloc * npath:
            G = np.array([[_value(pyo.value(path_rows[cn * npath + q].body, exception=False))
                           for q in range(npath)] for cn in range(lay.n_colloc)], float)
            for q, c in enumerate(ph.path):
                if not c.is_equality:
                    rows.append((c.text or str(c.expr), G[:, q], lay.s_colloc, c.lower, c.upper))
        arcs = []
        for text, values, s_nodes, lo, hi in rows:
            s_nodes = np.asarray(s_nodes, float)
            inner = (s_nodes > 1e-12) & (s_nodes < 1 - 1e-12)
            on = activity(np.asarray(values, float), lo, hi, ACTIVE_TOL) != 0
            # a state held at its bound by a boundary condition and leaving it (arriving at
            # it) is at the bound at the end node and, within the tolerance, at the next one:
            # no arc (the brachistochrone's x >= 0 from x(t0) = 0)
            for end, nxt in ((0, 1), (len(on) - 1, len(on) - 2)):
                if len(on) > 2 and on[end] and on[nxt] and not on[nxt + (nxt - end)]:
                    on[nxt] = False
            on &= inner
            n_on = int(np.count_nonzero(on))
            if n_on == 1:
                arcs.append(f"`{text}` (at its bound at one node, t = {t0 + (tf - t0) * s_nodes[on][0]:.6g})")
            elif n_on:
                a, b = s_nodes[on].min(), s_nodes[on].max()
                arcs.append(f"`{text}` (at its bound at {n_on} nodes in t in "
                            f"[{t0 + (tf - t0) * a:.6g}, {t0 + (tf - t0) * b:.6g}])")
        if arcs:
            phase = f"phase '{ph.name}': " if len(tr.phases) > 1 else ""
            notes.append(f"{phase}{'; '.join(arcs)} {'binds' if len(arcs) == 1 else 'bind'} on this fixed mesh: J is the optimum of "
                         "this mesh, which differs from the problem's where the mesh misses the arc's "
                         "junctions; the verification checks that the trajectory is feasible, not that J is "
                         "optimal. `mesh:` places the junctions and refines until the error estimate meets "
                         "its tolerance (docs/mesh.md)")
    return notes


def _value(v) -> float:
    return math.nan if v is None else float(v)


def _bound_text(name: str, lo: float, hi: float) -> str:
    if math.isfinite(lo) and math.isfinite(hi):
        return f"{lo:g} <= {name} <= {hi:g}"
    return f"{name} >= {lo:g}" if math.isfinite(lo) else f"{name} <= {hi:g}"
