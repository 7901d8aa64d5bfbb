"""The next mesh of a phase from its error estimate and located features."""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from .estimate import SegmentError
from .locate import corners_to_place, misplaced


def _place(segs: list[list], f: float, snap: float, keep: list[float], tol: float) -> None:
    """Put a breakpoint on f in the segment list [[a, b, N], ...] (in place).

    A breakpoint within ``snap`` of the segment's width from f is moved onto f (no sliver
    segment is left next to the feature) unless it is 0, 1 or holds another feature (within
    ``tol`` of one in ``keep``); otherwise the segment is split at f.
    """
    k = next((q for q, (a, b, _) in enumerate(segs) if a <= f <= b), None)
    if k is None:
        return
    a, b, N = segs[k]
    if min(abs(f - a), abs(b - f)) <= tol:
        return
    held = lambda x: any(abs(x - g) <= tol for g in keep if g != f)  # noqa: E731
    w = b - a
    if f - a <= snap * w and k > 0 and not held(a):
        segs[k - 1][1] = f
        segs[k][0] = f
        return
    if b - f <= snap * w and k < len(segs) - 1 and not held(b):
        segs[k][1] = f
        segs[k + 1][0] = f
        return
    segs[k:k + 1] = [[a, f, N], [f, b, N]]


# a segment narrower than this share of corner_tolerance is a sliver: its rows all stand at
# one time, and a control off its bound there was flown over the segment before it (two-link
# arm: a segment of 2.2e-9 at a switch moved beside a cut, the verification 1.9e-3 off on an
# answer right to 1e-9, unseen48 F1)
SLIVER = 1e-2


def _without_slivers(segs: list[list], featured, width: float) -> list[list]:
    """[[a, b, N], ...] with each segment narrower than ``width`` merged into a neighbour:
    its end goes (into the next segment) unless that end is a located feature, then its
    start (into the previous one); the merged segment keeps the larger degree."""
    held = lambda x: any(abs(x - f) <= width for f in featured)  # noqa: E731
    out = [list(sg) for sg in segs]
    i = 0
    while len(out) > 1 and i < len(out):
        a, b, N = out[i]
        if b - a >= width:
            i += 1
        elif i + 1 < len(out) and (i == 0 or not held(b)):
            out[i + 1] = [a, out[i + 1][1], max(N, out[i + 1][2])]
            del out[i]
        else:
            out[i - 1] = [out[i - 1][0], b, max(N, out[i - 1][2])]
            del out[i]
    return out


def _arc_mesh_moves(mesh, errors, spec, features, todo) -> dict[int, float]:
    """On an arc mesh (every interior breakpoint within corner_tolerance of a located feature,
    as ``coarsen`` builds it): breakpoint index -> feature, for the breakpoints that are not
    exactly on their feature and have a segment above tolerance next to them. ``refine`` moves
    them onto the features and leaves those segments as they are: on such a stiff mesh the
    error next to a junction is that of the junction's position (Bryson-Denham (3, 1, 3):
    0.18 d for a junction off by d), which a higher degree would only paper over."""
    bps = np.asarray(mesh.breakpoints)
    inner = bps[1:-1]
    feats = [f for f in features if f not in todo]
    if not len(inner) or not feats or not all(min(abs(b - f) for f in feats) <= spec.corner_tolerance
                                               for b in inner):
        return {}
    moves = {}
    for f in feats:
        q = 1 + int(np.argmin(np.abs(inner - f)))
        if (abs(bps[q] - f) > 1e-14 and bps[q - 1] < f < bps[q + 1]
                and max(errors[q - 1].error, errors[q].error) > spec.tolerance):
            moves[q] = float(f)
    return moves


def _switch_moves(mesh, spec, features, switches, memory: dict) -> dict[int, float]:
    """Breakpoint index -> bound-to-bound switch (``locate_switches``) within corner_tolerance
    of that breakpoint but not on it, where ``features`` holds the switch or the breakpoint
    itself (``switches.move_switches`` replaces a switch by the breakpoint when moving it would
    not change J, and by a target when it moves it: left to that). ``refine`` (called only
    while the tolerance is unmet) moves those breakpoints onto their switches and leaves the
    segments next to them as they are: the error there is that of the switch's position,
    which neither a higher degree nor a split removes. Measured on
    configs/mesh_bang_off_bang.yaml: the breakpoint 4.6e-7 after the switch (within
    corner_tolerance 1e-5) left x(tf) missed by 2e-6 flown from x(t0); refining the segments
    around it split the smeared switch into slivers whose corners (0.12531, 0.12528, ...
    against 0.127322) were chased for 17 iterations. The quadrature estimate is accurate to
    about active_tol times the segment width (there 0.1273220053 against 0.1273220037).

    With a free final time the estimate is a fixed-point map b -> f(b) of slope about 1/2 (the
    NLP moves t_f with the breakpoint; configs/mesh_tumour.yaml: 0.167181, 0.167178,
    0.1671763, ... against 0.1671743): with the previous (b, f) of the same switch in
    ``memory`` the breakpoint goes to the secant root of f(b) - b instead, when the map's
    slope is below 0.95 (as ``locate_junctions`` does for arc ends)."""
    bps = np.asarray(mesh.breakpoints, float)
    inner = bps[1:-1]
    moves: dict[int, float] = {}
    maps = memory.setdefault("map", {})
    seen = {}
    if not len(inner):
        memory["map"] = seen
        return moves
    for order, f in enumerate(sorted(switches)):
        q = 1 + int(np.argmin(np.abs(inner - f)))
        b = float(bps[q])
        if not any(abs(f - g) <= 1e-15 or abs(b - g) <= 1e-15 for g in features):
            continue    # moved to a target by switches.move_switches, or dropped
        d = abs(b - f)
        if not (1e-14 < d <= spec.corner_tolerance and bps[q - 1] < f < bps[q + 1]) or q in moves:
            continue
        seen[order] = (b, float(f))
        g = float(f)
        prev = maps.get(order)
        if prev is not None and abs(prev[0] - b) > 1e-15:
            F0, F1 = prev[1] - prev[0], f - b
            rho = 1.0 + (F1 - F0) / (b - prev[0])      # slope of the map b -> f(b)
            if F1 != F0 and -1.0 < rho < 0.95:
                cand = b - F1 * (b - prev[0]) / (F1 - F0)
                if bps[q - 1] < cand < bps[q + 1] and abs(cand - b) <= 10.0 * d:
                    g = float(cand)
        moves[q] = g
    memory["map"] = seen
    return moves


def refine(mesh, errors: list[SegmentError], spec, controls=None, features=None, switches=(),
           nudged: dict | None = None) -> Any:
    """The next mesh of one phase (see the module docstring).

    ``features``: located switches and corners (normalised time); each one not already on a
    breakpoint becomes one (moving a close breakpoint, or splitting), and the segment that
    held it is otherwise left to the next iteration's estimate. ``controls`` (per segment,
    s -> control polynomial) is used to locate corners when ``features`` is not given.
    """
    from ...transcribe.mesh import Mesh

    tol, nmin, nmax = spec.tolerance, spec.min_degree, spec.max_degree
    pieces = spec.bracket_pieces
    if features is None:
        features = corners_to_place(mesh, errors, spec, controls)
    todo = misplaced(mesh, features, spec)
    moves = _arc_mesh_moves(mesh, errors, spec, features, todo)
    still = {k for q in moves for k in (q - 1, q)}
    # a switch moved onto last time as well: its neighbours are refined as usual this time (a
    # located switch that still moves by a little must not hold them back forever)
    memory = nudged if nudged is not None else {}
    before = list(memory.get("last", []))
    nudges = _switch_moves(mesh, spec, features, switches, memory)
    for q, f in nudges.items():
        if q in moves:
            continue
        moves[q] = f
        if not any(abs(f - p) <= spec.corner_tolerance for p in before):
            still |= {q - 1, q}
    memory["last"] = list(nudges.values())
    proposals: list[list[list]] = []
    within = not any(e.error > tol for e in errors)
    for e in errors:
        k = e.segment
        a, b = float(mesh.breakpoints[k]), float(mesh.breakpoints[k + 1])
        N = mesh.degrees[k]
        holds = [f for f in todo if a < f < b]
        if within and e.inner_junction and not holds:
            # every segment meets the tolerance but this one holds a junction between two of its
            # nodes (``SegmentError.inner_junctions``): cut at its bracket
            proposals.append(_cut(a, b, N, e.inner_junctions, pieces, nmin))
            continue
        if not (e.error > tol) or holds or k in still:
            proposals.append([[a, b, N]])
            continue
        if e.nonsmooth and not e.smoothed:
            width = b - a
            merged = []
            for c in _bracket_cuts(a, b, e.switches, pieces):   # drop slivers far below the bracket scale
                if not merged or c - merged[-1] > 1e-6 * width:
                    merged.append(c)
            if merged:
                edges = [a, *merged, b]
                # a segment whose only brackets are a state's or a path constraint's and hold
                # one of its ends (the change is between its first node and the segment
                # before, or its last and the next): the rest of it is refined as a smooth
                # segment too. Cutting only the bracket left it at its degree, and where its
                # own error was the larger the same segment lost a sliver per iteration
                # (configs/mesh_goddard.yaml: the speed sagging 1e-7 below its bound at a
                # breakpoint of the boundary arc bracketed the first node; the error, halved
                # each time, took seven meshes). A control's switch there is left to the
                # switch moves: its segments' error is the switch's position.
                at_ends = not e.control_switch and all(
                    lo <= a + 1e-12 * width or hi >= b - 1e-12 * width for lo, hi in e.switches)
                prop = []
                for x, y in zip(edges, edges[1:]):
                    bulk = at_ends and y - x >= 0.5 * width
                    prop.extend(_smooth_proposal(x, y, N, e.error, spec) if bulk else [[x, y, nmin]])
                proposals.append(prop)
                continue
        # smooth (or a switch that cannot be bracketed more finely): p, then h
        proposals.append(_smooth_proposal(a, b, N, e.error, spec))
    # at most growth x the segments: the largest errors are split first; a split that does not
    # fit the remaining budget is cut down to it (``_within_budget``), and a segment that gets
    # no new segment at all waits. (It used to be left as it was even when it came first:
    # Bryson-Denham with LG on 2 x 3 touches x <= l at two Gauss points of each segment, so
    # each segment's brackets asked for 5 cuts against a budget of 4 and the 2 x 3 mesh was
    # solved again until max_iterations.)
    budget = max(1, int(spec.growth * mesh.segments) - mesh.segments)
    for k in sorted(range(len(errors)), key=lambda q: -errors[q].error):
        extra = len(proposals[k]) - 1
        if extra <= 0:
            continue
        if extra > budget:
            proposals[k] = _within_budget(proposals[k], budget, mesh.degrees[k])
            extra = len(proposals[k]) - 1
        budget -= extra
    segs = [sg for prop in proposals for sg in prop]
    for q, f in moves.items():   # the segments next to a moved breakpoint were kept: edges exact
        b = float(mesh.breakpoints[q])
        for sg in segs:
            sg[0] = f if sg[0] == b else sg[0]
            sg[1] = f if sg[1] == b else sg[1]
    for f in todo:
        _place(segs, f, spec.snap, features, spec.corner_tolerance)
    segs = _without_slivers([sg for sg in segs if sg[1] > sg[0]], [*features, *moves.values()],
                            SLIVER * spec.corner_tolerance)
    bps = [0.0] + [sg[1] for sg in segs]
    bps[-1] = 1.0
    new = Mesh(mesh.scheme_name, np.array(bps), tuple(int(sg[2]) for sg in segs))
    if same_mesh(new, mesh) and (todo or any(e.error > tol for e in errors)):
        # never the same mesh again while the tolerance is unmet: the worst segment is
        # refined regardless of the rules above, or the refinement stops (MeshStalled)
        new = _forced_refinement(mesh, errors, spec, todo)
    return new


def _bracket_cuts(a: float, b: float, brackets, pieces: int) -> list[float]:
    """The points that cut each bracket (s, s') into ``pieces``, strictly inside [a, b], sorted."""
    width = b - a
    cuts = {lo + (hi - lo) * q / pieces for lo, hi in brackets for q in range(pieces + 1)}
    return sorted(c for c in cuts if a + 1e-9 * width < c < b - 1e-9 * width)


def _cut(a: float, b: float, N: int, brackets, pieces: int, nmin: int) -> list[list]:
    """[a, b] cut into ``pieces`` across each bracket (s, s'), the pieces at the lowest degree
    and the rest of the segment at its own."""
    edges = [a, *_bracket_cuts(a, b, brackets, pieces), b]
    inside = lambda x, y: any(lo <= x and y <= hi for lo, hi in brackets)  # noqa: E731
    return [[x, y, nmin if inside(x, y) else N] for x, y in zip(edges, edges[1:])]


def _smooth_proposal(a: float, b: float, N: int, error: float, spec) -> list[list]:
    """A smooth segment [a, b] of degree N and estimated ``error``: its degree raised by as
    many as the error needs (p), else split into segments of min_degree (h)."""
    ratio = error / spec.tolerance if math.isfinite(error) else 1e6
    P = max(1, math.ceil(math.log(ratio) / math.log(max(N, 2))))
    if N + P <= spec.max_degree:
        return [[a, b, N + P]]
    B = max(math.ceil((N + P) / spec.min_degree), 2)
    edges = [a + (b - a) * q / B for q in range(B + 1)]
    return [[x, y, spec.min_degree] for x, y in zip(edges, edges[1:])]


class MeshStalled(RuntimeError):
    """``refine`` cannot produce a mesh different from the current one although the
    tolerance is unmet; ``solve_adaptive`` ends with ``mesh_not_converged`` and this message."""


def same_mesh(a, b) -> bool:
    return (a.scheme_name == b.scheme_name and tuple(a.degrees) == tuple(b.degrees)
            and np.array_equal(np.asarray(a.breakpoints), np.asarray(b.breakpoints)))


def _within_budget(prop: list[list], budget: int, degree: int) -> list[list]:
    """A segment's proposal [[a, b, N], ...] cut down to at most ``budget`` new segments:
    ``budget`` of its interior edges, evenly spread over them (a bracketed switch keeps edges on
    either side of it), each piece with the proposal's largest degree; with no budget left,
    the segment unchanged (it waits for the next iteration)."""
    a, b = prop[0][0], prop[-1][1]
    if budget <= 0:
        return [[a, b, degree]]
    inner = [sg[1] for sg in prop[:-1]]
    pick = sorted({inner[min(len(inner) - 1, round((q + 1) * (len(inner) + 1) / (budget + 1)) - 1)]
                   for q in range(budget)})
    N = max(sg[2] for sg in prop)
    edges = [a, *pick, b]
    return [[x, y, N] for x, y in zip(edges, edges[1:])]


def _forced_refinement(mesh, errors, spec, todo):
    """The mesh with its worst segment (largest error) refined: degree raised by one up to
    max_degree, else bisected. Raises MeshStalled when neither is possible."""
    from ...transcribe.mesh import Mesh

    bps = np.asarray(mesh.breakpoints, float)
    worst = max(errors, key=lambda e: e.error) if errors else None
    if worst is None or not (worst.error > spec.tolerance):
        raise MeshStalled(f"located switches/corners {todo} could not be put on breakpoints of mesh "
                          f"{mesh.describe()}")
    k = worst.segment
    degrees = list(mesh.degrees)
    if degrees[k] < spec.max_degree:
        degrees[k] += 1
        return Mesh(mesh.scheme_name, bps.copy(), tuple(degrees))
    a, b = bps[k], bps[k + 1]
    mid = 0.5 * (a + b)
    if not (a < mid < b) or b - a < 1e-12:
        raise MeshStalled(f"segment {k} (s in [{a:.6g}, {b:.6g}]) has error {worst.error:.3e} above "
                          f"tolerance {spec.tolerance:.1e} at max_degree {spec.max_degree} and is too "
                          "short to split")
    degrees[k:k + 1] = [spec.min_degree, spec.min_degree]
    return Mesh(mesh.scheme_name, np.concatenate([bps[:k + 1], [mid], bps[k + 1:]]), tuple(degrees))
