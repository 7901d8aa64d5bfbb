"""Which bound a control sits on at each node, and where it switches."""
from __future__ import annotations

import math
from typing import Mapping

import numpy as np

from ocdsl.symbolic.model import Model

def _f(x) -> float | None:
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


def _bounds(model: Model, control_bounds: Mapping | None) -> list[tuple[float, float]]:
    out = []
    for c in model.controls:
        lo, hi = (control_bounds or {}).get(c.name, (None, None))
        lo = -np.inf if lo is None else float(lo)
        hi = np.inf if hi is None else float(hi)
        if lo > hi:
            raise ValueError(f"certificate: bounds of {c.name} are reversed: {lo} > {hi}")
        out.append((lo, hi))
    return out


def _band(lo: float, hi: float, frac: float) -> float:
    if math.isfinite(lo) and math.isfinite(hi):
        return frac * (hi - lo)
    b = hi if math.isfinite(hi) else lo
    return frac * max(abs(b), 1.0) if math.isfinite(b) else 0.0


SPREAD_SHARE = 10.0    # the band is at most this many times ``frac`` of the control's own spread
# ... and at least this share of the bound range (what the NLP resolves of a weakly active
# bound): 1e-7 left a coast arc's thrust of 2e-4 to 2.4e-3 N against 0 <= T <= 4000 N (6e-7
# of it, Ipopt's interior-point distance where the switching function is small, under `scaling:
# {mode: auto}`) off its bound at 11 of 16 nodes, and stationarity failed a right answer
# (unseen36 F2: J to 2e-9). A node inside the band whose dH/du is near zero counts as weakly
# active, one with the wrong sign still fails the switching check
RESOLUTION = 1e-5


def _side(U, bounds, frac):
    """Per node and control: +1 at the upper bound, -1 at the lower, 0 off the bounds.

    "At" a bound: within ``frac`` of the bound range, but no farther than SPREAD_SHARE x
    ``frac`` of the control's spread over the rows of ``U`` (the phase's nodes), and always
    within RESOLUTION of the range: with `0 <= u <= 1e5` a control near 20 throughout sat "at"
    its lower bound (1 % of the range is 1,000), and the end-arc check called for the upper
    one, a gain of 94 on J = 112 exact (unseen30)."""
    side = np.zeros(U.shape, int)
    with np.errstate(all="ignore"):
        spread = np.nanmax(U, axis=0) - np.nanmin(U, axis=0) if len(U) else np.zeros(U.shape[1])
    for j, (lo, hi) in enumerate(bounds):
        s = float(spread[j]) if np.isfinite(spread[j]) else math.inf
        band = min(_band(lo, hi, frac), max(SPREAD_SHARE * frac * s, RESOLUTION * _band(lo, hi, 1.0)))
        if math.isfinite(hi):
            side[U[:, j] >= hi - band, j] = 1
        if math.isfinite(lo):
            side[(U[:, j] <= lo + band) & (side[:, j] == 0), j] = -1
    return side


def switch_pairs(side_j) -> list[tuple[int, int]]:
    """(a, b): consecutive saturated nodes of one control on opposite bounds, a bang switch
    between them."""
    idx = np.flatnonzero(side_j != 0)
    return [(int(a), int(b)) for a, b in zip(idx[:-1], idx[1:]) if side_j[a] != side_j[b]]


def _switches(t, side_j, S_j):
    """Switches between consecutive saturated nodes on opposite bounds: the switching
    function's first zero between them, or where it is nearest zero when it keeps its sign
    there (a switch on a breakpoint node, whose dH/du is 0 to rounding: the middle of the
    bracket was 0.025 late, unseen45 F2)."""
    idx = np.flatnonzero(side_j != 0)
    times, seq = [], []
    for k in idx:
        s = "+" if side_j[k] > 0 else "-"
        if not seq or seq[-1] != s:
            seq.append(s)
    for a, c in switch_pairs(side_j):
        tz = None
        for k in range(a, c):   # first zero crossing of the switching function
            s0, s1 = S_j[k], S_j[k + 1]
            if s0 == 0:
                tz = t[k]
                break
            if s0 * s1 < 0:
                tz = t[k] + (t[k + 1] - t[k]) * s0 / (s0 - s1)
                break
        if tz is None:
            tz = t[a + int(np.argmin(np.abs(S_j[a:c + 1])))]
        times.append(float(tz))
    return times, seq
