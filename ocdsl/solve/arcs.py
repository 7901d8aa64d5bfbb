"""Arcs of state and path constraints on a fixed mesh: what the verification cannot judge.

Where a state bound or an inequality path constraint starts or stops binding, the optimal
state has a kink (and the control often a jump) at a junction time that the problem fixes.
On a mesh chosen without it the NLP's optimum is a feasible trajectory, flown exactly by the
verification, whose J is the optimum *of that mesh*: a speed-limited minimum-energy transfer
gave J = 12.24 on 3 LG segments and 12.1957 on 7 against the exact 12.1956, verified, with a
passing certificate (unseen5). Whether a junction sits inside a segment or the NLP moved it
onto a wrong breakpoint (the 7-segment case: the arc began at the breakpoint 2/7, the exact
junction is 0.3), the nodes alone do not tell. So a single solve whose inequalities bind
inside a phase is solved once more with every segment bisected (``fixed_mesh.bisection_check``),
and J must agree to a quarter of the verification's tolerance; else the run is ``mesh_not_converged``
(the status of an adaptive mesh that misses its tolerance) and says where the arcs are.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..verify.objective_size import own_size

# relative to 1 + |bound|: Ipopt leaves an active bound within about 1e-8; a state leaving its
# bound from rest (Goddard's r >= 1 from r(t0) = 1) is 7e-7 above it at the first node
ACTIVE_TOL = 1e-7

# The bisected mesh keeps every breakpoint, so an arc the NLP pinned to a breakpoint stays
# there and J moves slowly: 13.890625 -> 13.890165 on 7 -> 14 LG segments of degree 3 (errors
# 1.25e-4 -> 9.2e-5 against the exact 13.888889, a 1.36x cut). With J's errors e and e/r on
# the two meshes, a difference d means e = d r / (r - 1): d <= tol / 4 keeps e <= tol
# wherever a bisection cuts the error at least 4/3 times, and d > tol means e > tol wherever
# it cuts it at all. Between the two the mesh is bisected once more and r measured
# (Richardson): Goddard's speed-limited uniform mesh has d = 3.9e-6 and e = 8.1e-6.
AGREEMENT_SHARE = 0.25


@dataclass(frozen=True)
class PhaseArcs:
    phase: str
    arcs: list[str]         # "`v <= 1.4` (at its bound at one node, t = 0.5)"


@dataclass(frozen=True)
class Level:
    """One solve of the bisection check."""
    objective: float | None         # None: the solve did not converge
    status: str
    variables: int
    iterations: int
    final_times: dict = field(default_factory=dict)   # the free final times of that solve



#: how Bisection.describe begins (``qualified_notes`` finds the notes that quote it)
BISECTED = "with every segment bisected"

@dataclass(frozen=True)
class Bisection:
    """J on the file's mesh against J with every segment bisected, and bisected again where
    the first difference alone does not decide (``fixed_mesh.bisection_check``)."""
    objective: float
    levels: tuple[Level, ...]
    tolerance: float
    floor: float                    # an absolute difference this small is the NLP's own accuracy
    constant: float = 0.0           # J's constant part (verify/objective_size.py): not J's size

    def _objectives(self) -> list[float]:
        out = [self.objective]
        for lv in self.levels:
            if lv.objective is None or not math.isfinite(lv.objective):
                break
            out.append(lv.objective)
        return out

    def differences(self, judged: bool = True) -> list[float]:
        """Relative differences of successive objectives; ``judged``: an absolute one below the
        floor counted as 0 (what the verdict uses; the messages print the measured ones)."""
        js = self._objectives()
        return [0.0 if judged and abs(b - a) <= self.floor
                else abs(b - a) / max(own_size(a, self.constant), own_size(b, self.constant), 1e-300)
                for a, b in zip(js, js[1:])]

    @property
    def needs_second(self) -> bool:
        d = self.differences()
        return len(self.levels) == 1 and len(d) == 1 and AGREEMENT_SHARE * self.tolerance < d[0] <= self.tolerance

    @property
    def error(self) -> float | None:
        """This mesh's relative error in J as the check estimates it (None: not judged)."""
        d = self.differences()
        if not d:
            return None
        if d[0] <= AGREEMENT_SHARE * self.tolerance or d[0] > self.tolerance:
            return d[0]
        if len(d) < 2:
            return None
        return math.inf if d[1] >= d[0] else d[0] ** 2 / (d[0] - d[1])

    @property
    def agrees(self) -> bool | None:
        """True/False: J did/did not survive the bisection; None: not judged."""
        e = self.error
        if e is None:
            return None
        d = self.differences()[0]
        return bool(d <= AGREEMENT_SHARE * self.tolerance or e <= self.tolerance and d <= self.tolerance)

    def record(self) -> dict:
        d = self.differences(judged=False)
        return {"objective": self.objective,
                "levels": [{"objective": lv.objective, "status": lv.status, "variables": lv.variables,
                            "iterations": lv.iterations, "final_times": lv.final_times} for lv in self.levels],
                "relative_differences": d, "estimated_error": self.error,
                "tolerance": self.tolerance, "agrees": self.agrees}

    def shown(self, j: float) -> str:
        """``j`` with ten digits of J less its constant part (as many more as the constant takes)."""
        extra = 0
        if 0.0 < own_size(j, self.constant) < abs(j):
            extra = math.ceil(math.log10(abs(j) / own_size(j, self.constant)))
        return f"{j:.{min(10 + extra, 17)}g}"

    def describe(self) -> str:
        """What the solves gave: "with every segment bisected (N variables) J = ..."."""
        first = self.levels[0]
        d, measured = self.differences(), self.differences(judged=False)
        text = f"{BISECTED} ({first.variables} variables) "
        if first.objective is None:
            return text + f"Ipopt ended {first.status}"
        of = (f" of J less its constant part {self.constant:g}"
              if own_size(first.objective, self.constant) < abs(first.objective) else "")
        text += f"J = {self.shown(first.objective)} (relative difference{of} {measured[0]:.1e}"
        if len(self.levels) < 2:
            if d[0] > self.tolerance:
                return text + f", more than the verification's tolerance {self.tolerance:g})"
            if measured[0] > AGREEMENT_SHARE * self.tolerance:
                return text + f"; |dJ| within Ipopt's accuracy {self.floor:g})"
            return text + f", within a quarter of the verification's tolerance {self.tolerance:g})"
        second = self.levels[1]
        text += f"), and bisected again ({second.variables} variables) "
        if second.objective is None:
            return text + f"Ipopt ended {second.status}"
        text += f"J = {self.shown(second.objective)} (relative difference {measured[1]:.1e}): "
        if self.error == math.inf:
            return text + "the differences do not shrink"
        return text + f"this mesh's error is about {self.error:.1e} (Richardson), against the verification's tolerance {self.tolerance:g}"


def _binding_rows(tr, controls: bool = False):
    """Per phase of a solved transcription ``tr``: (phase block, [(constraint text, normalised
    times of the nodes inside the phase where it binds)]), see :func:`binding_arcs`; with
    ``controls``, the control bounds too."""
    import pyomo.core as pyo

    from ..transcribe.solution import node_values
    from .mesh.segments import activity

    for pb in tr.phases:
        ph, lay = pb.phase, pb.layout
        X, U = node_values(pb)
        rows = []         # (constraint text, values at nodes, their normalised times, lo, hi)
        for j, s in enumerate(ph.states):
            lo, hi = ph.bounds_of(s)
            if math.isfinite(lo) or math.isfinite(hi):
                rows.append((_bound_text(s.name, lo, hi), X[:, j], lay.s_state, lo, hi))
        for j, c in enumerate(ph.controls if controls else ()):
            lo, hi = ph.bounds_of(c)
            if math.isfinite(lo) or math.isfinite(hi):
                rows.append((_bound_text(c.name, lo, hi), U[:, j], lay.s_colloc, lo, hi))
        npath = len(ph.path)
        path_rows = getattr(pb.block, "path", None)
        if npath and path_rows is not None and len(path_rows) == lay.n_colloc * npath:
            G = np.array([[_value(pyo.value(path_rows[cn * npath + q].body, exception=False))
                           for q in range(npath)] for cn in range(lay.n_colloc)], float)
            for q, c in enumerate(ph.path):
                if not c.is_equality:
                    rows.append((c.text or str(c.expr), G[:, q], lay.s_colloc, c.lower, c.upper))
        out = []
        for text, values, s_nodes, lo, hi in rows:
            s_nodes = np.asarray(s_nodes, float)
            inner = (s_nodes > 1e-12) & (s_nodes < 1 - 1e-12)
            values = np.asarray(values, float)
            on = activity(values, lo, hi, ACTIVE_TOL, span=float(np.ptp(values)) if len(values) else None) != 0
            # a state held at its bound by a boundary condition and leaving it (arriving at
            # it) is at the bound at the end node and, within the tolerance, at the next one:
            # no arc (the brachistochrone's x >= 0 from x(t0) = 0)
            for end, nxt in ((0, 1), (len(on) - 1, len(on) - 2)):
                if len(on) > 2 and on[end] and on[nxt] and not on[nxt + (nxt - end)]:
                    on[nxt] = False
            on &= inner
            if on.any():
                out.append((text, s_nodes[on]))
        yield pb, out


def binding_arcs(tr, controls: bool = False) -> list[PhaseArcs]:
    """The phases of a solved pseudospectral transcription ``tr`` whose state bounds or
    inequality path constraints (with ``controls``, control bounds too) bind at a node inside
    the phase (not only at its ends, where boundary conditions hold states at bounds; a touch
    point counts: the 3-segment speed limit touched at one node): which, and over what times."""
    from ..transcribe.solution import phase_times

    found = []
    for pb, rows in _binding_rows(tr, controls):
        t0, tf = phase_times(pb)
        arcs = []
        for text, s_on in rows:
            if len(s_on) == 1:
                arcs.append(f"`{text}` (at its bound at one node, t = {t0 + (tf - t0) * s_on[0]:.6g})")
            else:
                a, b = s_on.min(), s_on.max()
                arcs.append(f"`{text}` (at its bound at {len(s_on)} nodes in t in "
                            f"[{t0 + (tf - t0) * a:.6g}, {t0 + (tf - t0) * b:.6g}])")
        if arcs:
            found.append(PhaseArcs(pb.phase.name, arcs))
    return found


def unchanged_binding_segments(tr, meshes_of: list[dict]) -> list[str]:
    """The constraints of ``tr`` that bind inside a segment every mesh of ``meshes_of``
    (phase -> Mesh each) holds unchanged, same ends and degree: those meshes agreeing in J
    says nothing of that segment (unseen16: LGL kept Bryson-Denham's [0.4, 0.6] at degree 3
    through every mesh, its polynomial unable to follow the arc x = l, J 1.6e-3 high on all)."""
    out = []
    for pb, rows in _binding_rows(tr):
        meshes = [m.get(pb.phase.name) for m in meshes_of]
        if len(meshes) < 2 or any(m is None for m in meshes):
            continue
        for text, s_on in rows:
            for s in s_on:
                segs = set()
                for m in meshes:
                    bps = np.asarray(m.breakpoints, float)
                    k = int(np.clip(np.searchsorted(bps, s, side="right") - 1, 0, len(bps) - 2))
                    segs.add((round(float(bps[k]), 12), round(float(bps[k + 1]), 12), m.degrees[k]))
                if len(segs) == 1:
                    a, b, _ = segs.pop()
                    out.append(f"`{text}` in [{a:.6g}, {b:.6g}] (normalised time)")
                    break
    return out


def free_final_times(tr) -> dict[str, float]:
    """Phase name -> the solved final time of each phase whose final time is free."""
    import pyomo.core as pyo

    return {pb.phase.name: float(pyo.value(pb.block.tf)) for pb in tr.phases if pb.phase.tf is None}


#: how the notes of final_time_spread begin, and where their reading of the spread starts
#: (``qualified_notes`` rewrites that reading)
WEAK_TF, FLAT_IN_TF = "the final time is weakly determined:", ": J is flat in t_f"


def final_time_spread(solutions: list[tuple[float, dict]], tolerance: float) -> str | None:
    """A note when solutions whose J agree within ``tolerance`` (the run's, on other meshes)
    put a free final time far further apart than that: J is flat in t_f near the optimum, and
    the reported t_f is known only to that spread (unseen10 F7: Hotelling's exhaustion time
    2.3e-4 off with J right to 6e-12, verified, nothing said). ``solutions``: (J, final times)."""
    good = [(j, t) for j, t in solutions if j is not None and math.isfinite(j) and t]
    if len(good) < 2:
        return None
    js = [j for j, _ in good]
    spread_j = (max(js) - min(js)) / max(max(abs(j) for j in js), 1e-300)
    if spread_j > tolerance:
        return None
    parts = []
    for name in good[0][1]:
        ts = [t[name] for _, t in good if name in t]
        spread = (max(ts) - min(ts)) / max(max(abs(x) for x in ts), 1e-300)
        if len(ts) >= 2 and spread > max(10 * tolerance, 1e-6) and spread > 100 * spread_j:
            parts.append(f"{'' if name == 'main' else f'phase {name!r}: '}t_f from {min(ts):.10g} to "
                         f"{max(ts):.10g} (relative spread {spread:.1e})")
    if not parts:
        return None
    return (f"{WEAK_TF} solutions on other meshes whose J agree to {spread_j:.1e} give {'; '.join(parts)}"
            f"{FLAT_IN_TF} near the optimum, so t_f is less certain than J (its error may well exceed that "
            "spread; J is not affected)")


#: what a fixed mesh's run is checked against when nothing binds and no flight judged J
UNJUDGED = ("no flight of the minimum principle's control judged J on this fixed mesh (it is not made "
            "for several phases, path constraints, a control that H does not hold quadratically, or J of a "
            "fixed t_f and parameters alone)")


def describe(found: list[PhaseArcs], multi_phase: bool, unjudged: str | None = None) -> str:
    """What binds, or why no flight judged J: the flight's own reason where it ran (the list
    of cases it is not made for was printed for single-phase problems with none of them,
    where the flight had run and judged nothing, unseen48 F4)."""
    if not found:
        return f"the flight of the minimum principle's control judged no J on this fixed mesh ({unjudged})" \
            if unjudged else UNJUDGED
    parts = [(f"phase '{p.phase}': " if multi_phase else "") + "; ".join(p.arcs) for p in found]
    n = sum(len(p.arcs) for p in found)
    return f"{'; '.join(parts)} {'binds' if n == 1 else 'bind'} inside the phase on this fixed mesh"


def note(found: list[PhaseArcs], multi_phase: bool, check: Bisection | None, unjudged: str | None = None) -> str:
    """The run's note on its arcs and, when made, on the bisection check."""
    what = describe(found, multi_phase, unjudged)
    if check is None:
        return (f"{what}: J is the optimum of this mesh, which differs from the problem's where the mesh "
                "misses the arcs' junctions; the verification checks that the trajectory is feasible, not "
                "that J is optimal (the bisection check is off: verify: {bisection_check: false}). `mesh:` "
                "places the junctions and refines until the error estimate meets its tolerance (docs/mesh.md)")
    if check.agrees is None:
        return (f"{what}; {check.describe()}, so J is unchecked: it is the optimum of this mesh, which "
                "differs from the problem's where the mesh misses the arcs' junctions. `mesh:` places the "
                "junctions and refines until the error estimate meets its tolerance (docs/mesh.md)")
    if check.agrees:
        return f"{what}; {check.describe()}"
    return ""       # a disagreement is the run's message (mismatch_message)


def mismatch_message(found: list[PhaseArcs], multi_phase: bool, check: Bisection, unjudged: str | None = None) -> str:
    why = ("the mesh misses these arcs' junctions or the controls' switches" if found
           else "the mesh is too coarse for the optimum")
    return (f"J = {check.shown(check.objective)} on this mesh but {check.describe()}: "
            f"{describe(found, multi_phase, unjudged)}, "
            f"and J is this mesh's optimum, not the problem's ({why}). "
            "`mesh:` places the junctions and refines until the error estimate meets its tolerance "
            "(docs/mesh.md); or a finer uniform mesh")


def _value(v) -> float:
    return math.nan if v is None else float(v)


def _bound_text(name: str, lo: float, hi: float) -> str:
    def shown(b: float) -> str:     # the shortest that reads back (1e+07 was 10000000.111, unseen59 F5)
        return next(t for t in (f"{b:.{d}g}" for d in (6, 10, 15, 17)) if float(t) == b)

    if math.isfinite(lo) and math.isfinite(hi):
        return f"{shown(lo)} <= {name} <= {shown(hi)}"
    return f"{name} >= {shown(lo)}" if math.isfinite(lo) else f"{name} <= {shown(hi)}"


def qualified_notes(notes: list[str], bisection_agrees: bool) -> list[str]:
    """``notes`` of a run whose trajectory does not fly (a dynamics check of the verification
    failed): an agreeing bisection and a weakly determined t_f speak of the NLP's J, which is no
    trajectory's then, and say so (unseen47 F4: x' = u - x, max x(tf), tf unbounded: J = 1.19
    above the supremum 1, dynamics 0.139 off, and the notes "with every segment bisected ... J =
    1.191199352 (within a quarter of the verification's tolerance)" and "t_f is less certain
    than J (... J is not affected)")."""
    out = []
    for n in notes:
        if bisection_agrees and BISECTED in n:
            n += ("; both are the NLP's J, and the trajectory does not satisfy the dynamics (the verification "
                  "failed), so the agreement says nothing of the problem's J")
        elif n.startswith(WEAK_TF) and FLAT_IN_TF in n:
            n = (n.split(FLAT_IN_TF)[0] + ": the trajectory does not satisfy the dynamics (the verification "
                 "failed), so this is no optimum's t_f and J is not established either; a t_f that moves this "
                 "far between meshes may be running away (a bound on t_f shows it)")
        out.append(n)
    return out
