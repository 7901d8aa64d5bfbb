"""Optional regularisation of chattering (singular) arcs: w * int (du/ds)^2 ds added to the
objective where the control zigzagged from node to node."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...verify.objective_size import own_size
from .segments import solution_arrays, zigzag


def chattering_segments(pb) -> list[tuple[float, float]]:
    """Segments (normalised time) on which a control zigzags from node to node (``zigzag`` on
    the segment's collocation points and the nearest one on either side): the discrete
    solution of a singular arc, where the control is weakly determined and the NLP chatters."""
    lay = pb.layout
    U = solution_arrays(pb)[1]
    bps = lay.mesh.breakpoints
    # steps below 1e-3 of the control's range are solver noise (a bang arc 1e-8 inside its bound)
    span = []
    for j, c in enumerate(pb.phase.controls):
        lo, hi = pb.phase.bounds_of(c)
        span.append(1e-3 * ((hi - lo) if math.isfinite(hi - lo) else 1.0 + np.max(np.abs(U[:, j]))))
    out = []
    for k in range(lay.mesh.segments):
        nodes = list(lay.colloc[k])
        if k > 0:
            nodes = [lay.colloc[k - 1][-1]] + nodes
        if k + 1 < lay.mesh.segments:
            nodes = nodes + [lay.colloc[k + 1][0]]
        if len(nodes) >= 4 and any(zigzag(U[nodes, j], span[j]) for j in range(U.shape[1])):
            out.append((float(bps[k]), float(bps[k + 1])))
    return out


def merge_intervals(old: list, new: list) -> list:
    out = []
    for a, b in sorted([tuple(x) for x in old] + [tuple(x) for x in new]):
        if out and a <= out[-1][1] + 1e-12:
            out[-1] = (out[-1][0], max(out[-1][1], b))
        else:
            out.append((a, b))
    return out


def regularise(tr, regions: dict, weight: float):
    """Add weight * sum over consecutive collocation points inside ``regions`` (per phase,
    normalised-time intervals) of (u_{i+1} - u_i)^2 / (s_{i+1} - s_i) -- a quadrature of
    weight * int (du/ds)^2 ds over the detected chattering arcs -- to the objective (with the
    sign that penalises it). Returns the Pyomo expression of the added term, or None.
    The solved objective is reported without it (``solve_adaptive``)."""
    import pyomo.core as pyo

    if not weight or not any(regions.values()):
        return None
    pairs = []                  # (ds, u_{i+1}, u_i)
    for pb in tr.phases:
        iv = regions.get(pb.phase.name) or []
        lay, b = pb.layout, pb.block
        sc = lay.s_colloc
        inside = [any(a <= x <= c for a, c in iv) for x in sc]
        nu = len(pb.phase.controls)
        for i in range(lay.n_colloc - 1):
            if inside[i] and inside[i + 1] and sc[i + 1] > sc[i]:
                for j in range(nu):
                    pairs.append((float(sc[i + 1] - sc[i]), b.U[i + 1, j], b.U[i, j]))
    if not pairs:
        return None
    m = tr.model
    m.mesh_regularisation = pyo.Expression(expr=weight * sum((a - b) ** 2 / ds for ds, a, b in pairs))
    sign = 1.0 if m.objective.sense == pyo.minimize else -1.0
    m.objective.expr = m.objective.expr + sign * m.mesh_regularisation
    # the same term as data, for the NumPy evaluation of the NLP (transcribe/direct_nlp): the
    # PyNumero route it otherwise takes writes and loads each mesh's NL file
    tr.penalty = (m.objective.expr, [(weight / ds, a, b) for ds, a, b in pairs])
    return m.mesh_regularisation


SKIPPED = "not solved (the term is within the tolerance)"


@dataclass(frozen=True)
class Unregularised:
    """The refinement's J (the problem's objective at the regularised optimum) against the
    same final mesh solved without the term (``check_unregularised``). The term moves the
    optimum itself, not only the reported value: Jackson's reactor with w = 1.5e-7 converged
    at J 1.1e-5 below the maximum, verified (the trajectory is feasible) and certified (unseen6).

    Neither number alone bounds that bias. Without the term a singular arc chatters and the
    mesh's J can pass the problem's: COPS Goddard's unregularised J is 2.1e-5 above the
    published 1.01283 (the regularised one 5.9e-6 above it). And the term's own size w R(u_w)
    bounds the bias only where R grows slowly as w falls. So the J is refused where both say
    so: the unregularised J differs by more than the tolerance *and* the term is above it
    (Jackson 1.5e-7: 1.08e-5 and 3.2e-5; w = 1e-7: 8.0e-6 and 2.4e-5, bias 8.0e-6, kept;
    COPS Goddard: 1.5e-5 and 2.2e-6, kept)."""
    weight: float
    objective: float
    term: float                        # w R(u_w): the regularisation's value at the reported solution
    plain_objective: float | None      # None: the solve without the term did not converge
    plain_status: str
    tolerance: float
    size: float                        # J's resolved size (verify/objective_size.py): both are relative to it
    constant: float = 0.0              # J's constant part (verify/objective_size.py)

    @property
    def difference(self) -> float:
        if self.plain_objective is None:
            return math.nan
        return abs(self.plain_objective - self.objective) / max(self.size, own_size(self.plain_objective, self.constant))

    @property
    def relative_term(self) -> float:
        return abs(self.term) / self.size

    @property
    def agrees(self) -> bool | None:
        if self.relative_term <= self.tolerance:
            return True
        return None if self.plain_objective is None else bool(self.difference <= self.tolerance)

    def record(self) -> dict:
        return {"weight": self.weight, "objective": self.objective, "term": self.term,
                "relative_term": self.relative_term, "unregularised_objective": self.plain_objective,
                "unregularised_status": self.plain_status,
                "relative_difference": None if self.plain_objective is None else self.difference,
                "tolerance": self.tolerance, "agrees": self.agrees}

    def describe(self) -> str:
        term = (f"the regularisation (w = {self.weight:g}) is {self.relative_term:.1e} of J, "
                f"{'within' if self.relative_term <= self.tolerance else 'more than'} the verification's "
                f"tolerance {self.tolerance:g}")
        if self.plain_status == SKIPPED:
            return term
        if self.plain_objective is None:
            return f"{term}; the final mesh solved without it ended {self.plain_status}"
        return (f"{term}; the final mesh solved without it gives J = {self.plain_objective:.10g} against "
                f"{self.objective:.10g} (relative difference {self.difference:.1e})")


def check_unregularised(tr, objective: float, weight: float, build_plain, solve, tolerance: float,
                        objective_scale: float | None = None) -> Unregularised:
    """Solve the mesh of ``tr`` without the regularisation, from ``tr``'s solution:
    ``build_plain(guesses)`` is the model without the term, ``solve(model_tr)`` its SolveInfo
    (not where the term is within the tolerance: then it is not judged to move J past it).
    Both are relative to J, but not below what the NLP resolves of it (``resolved_size``): a J
    of 1e-10 at an optimum of 0 (Aly and Chan) had a term of 5e-11 "half of J" (unseen41 F1)."""
    import pyomo.core as pyo

    from ...transcribe.guess import solved_guesses
    from ...verify.objective_size import resolved_size

    term = float(pyo.value(tr.model.mesh_regularisation))
    constant = tr.problem.objective_constant
    size = resolved_size(objective, objective_scale, constant)
    skipped = Unregularised(weight, float(objective), term, None, SKIPPED, tolerance, size, constant)
    if skipped.relative_term <= tolerance:
        return skipped
    info = solve(build_plain(solved_guesses(tr.problem, tr)))
    good = info.status in ("optimal", "acceptable") and info.objective is not None
    return Unregularised(weight, float(objective), term, float(info.objective) if good else None, info.status,
                         tolerance, size, constant)
