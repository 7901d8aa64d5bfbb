"""Controls collocated at phase junctions (and, LGL, at located switches) tied to the
one-sided limit of their segment's interior control polynomial."""
from __future__ import annotations

import numpy as np


def jumping_ends(tr) -> dict[str, set]:
    """Per phase, the ends (``"end"``: the last segment's tau = +1, ``"start"``: the first
    segment's tau = -1) whose collocated control jumps off its segment's other nodes
    (``verify.checks.end_jump``) in the solved model ``tr``."""
    from ...verify.checks import end_jump
    from .segments import solution_arrays

    out: dict[str, set] = {}
    for pb in tr.phases:
        lay = pb.layout
        if not pb.phase.controls:
            continue
        _X, U, _t0, _tf = solution_arrays(pb)
        size = np.maximum(np.ptp(U, axis=0), 1e-9)
        for which, k, tau in (("end", lay.mesh.segments - 1, 1.0), ("start", 0, -1.0)):
            col = np.asarray(lay.mesh.scheme(k).colloc, float)
            at = np.flatnonzero(np.abs(col - tau) < 1e-12)
            if not len(at) or len(col) < 3:
                continue
            nodes = np.asarray(lay.colloc[k])
            others = [q for q in range(len(col)) if q != at[0]]
            jumps, _ = end_jump(tau, col[others], U[nodes[at[0]]], U[nodes[others]], size)
            if jumps.any():
                out.setdefault(pb.phase.name, set()).add(which)
    return out


def limit_junction_controls(tr, features: dict | None = None, tol: float = 0.0,
                            outer: dict | None = None, junctions: bool = True) -> int:
    """At every phase junction, constrain a control collocated at the phase's end point to the
    one-sided limit of its segment's interior control polynomial (``junction_control: limit``).

    Which points: tau = +1 of the last segment of a phase that another phase follows (LGR, LGL)
    and tau = -1 of the first segment of a phase that follows another (LGR-start, LGL); the
    phases are taken in their order in the problem. The constraint is u_end = sum_i l_i(+-1) u_i
    over the segment's other collocation points (Lagrange basis l_i through them); segments with
    no other collocation point are left free. Why (measured, docs/mesh-refinement.md "Two
    phases"): in the continuous problem the control at a phase junction acts on a single
    instant, where it generally jumps; in the NLP it acts through its quadrature weight w_N h/2,
    and on the two-phase double integrator (LGR) the NLP drives it to the other bound, so that
    the segment's control polynomial overshoots the bound between the nodes (1.2 on 2 x 3) and
    the collocated state goes faster than any admissible control allows (tf = 1.99918 < 2). The
    error estimate rightly sees that (1.7e-2), but it only falls with the width of the phase's
    end segment, so refinement does not reach 1e-8 in 8 iterations. With the end control tied
    to its interior limit, the discrete solution is the exact one.

    ``features`` (per phase, normalised times of located switches/corners, as
    ``locate_features`` returns them) with ``tol``: for LGL also at every interior breakpoint
    within ``tol`` of one, both controls there (tau = +1 of the segment before, tau = -1 of the
    segment after: two control values at one instant, each collocated) are tied to their own
    segment's interior limit. Measured on the single-phase double integrator (LGL, 2 x 3): the
    NLP puts u = 0 at both copies of the breakpoint t = 1 (u = (1, 1, 0 | 0, -1, -1)), the
    control polynomials overshoot to 1.12 between the nodes, and the estimate (3.0e-2, then
    falling only with the width of the two segments) never reached 1e-9. LGR and LGR-start
    collocate one control at such a breakpoint and converged there without it, so they are
    left as they were. ``outer``: per phase, the problem's own ends (``"end"``, ``"start"``)
    tied as well (``jumping_ends``); ``junctions=False``: those alone, no junction (a fixed
    mesh's run, fixed_mesh.tie_jumping_end_controls). Returns the number of constraints added."""
    import pyomo.core as pyo

    from ...transcribe.nodes import lagrange_matrix

    added = 0
    n_ph = len(tr.phases)
    for i, pb in enumerate(tr.phases):
        lay, b = pb.layout, pb.block
        nu = len(pb.phase.controls)
        ends = []
        tied_outer = (outer or {}).get(pb.phase.name, ())
        if (junctions and i < n_ph - 1) or "end" in tied_outer:
            ends.append(("end", lay.mesh.segments - 1, 1.0))
        if (junctions and i > 0) or "start" in tied_outer:
            ends.append(("start", 0, -1.0))
        if lay.mesh.scheme_name == "LGL" and features:
            bps = np.asarray(lay.mesh.breakpoints)
            for q in range(1, len(bps) - 1):
                if any(abs(bps[q] - f) <= tol for f in features.get(pb.phase.name, [])):
                    ends.append((f"end_{q - 1}", q - 1, 1.0))
                    ends.append((f"start_{q}", q, -1.0))
        for which, k, tau in ends:
            col = np.asarray(lay.mesh.scheme(k).colloc, float)
            at = np.flatnonzero(np.abs(col - tau) < 1e-12)
            if not len(at) or len(col) < 2:
                continue
            others = [q for q in range(len(col)) if q != at[0]]
            coef = lagrange_matrix(col[others], np.array([tau]))[0]
            nodes = np.asarray(lay.colloc[k])
            cl = pyo.ConstraintList()
            b.add_component(f"mesh_junction_control_{which}", cl)
            pb.control_ties.append((k, int(at[0]), others, np.asarray(coef, float)))
            for j in range(nu):
                cl.add(b.U[int(nodes[at[0]]), j]
                       == sum(float(c) * b.U[int(nodes[q]), j] for c, q in zip(coef, others)))
                added += 1
    return added
