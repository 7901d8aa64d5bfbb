"""Angles unwrapped along time where some rows are empty (NaN: a control the transcription
has no value for at that node, e.g. LGR's phase start). ``np.unwrap`` spreads one NaN over
every later row."""
from __future__ import annotations

import numpy as np


def unwrap_finite(values, period: float = 2 * np.pi) -> np.ndarray:
    """``values`` unwrapped over its finite rows; NaN rows stay NaN."""
    out = np.array(values, dtype=float)
    ok = np.isfinite(out)
    if ok.any():
        out[ok] = np.unwrap(out[ok], period=period)
    return out
