"""Limit the BLAS thread pool for small-matrix controller loops (no extra dependency).

The controllers work on 9x9 matrices; a multithreaded OpenBLAS only adds
synchronisation there, and on a loaded machine (``pytest -n 2`` on 2 cores) its spinning
threads slow every Riccati solve by an order of magnitude. :func:`blas_threads` sets the
thread count of every OpenBLAS loaded in the process (NumPy's and SciPy's copies) through
their exported ``*_set_num_threads`` / ``*_get_num_threads`` functions and restores it
afterwards; it does nothing when no OpenBLAS is found.
"""
from __future__ import annotations

import contextlib
import ctypes

_SET = ("scipy_openblas_set_num_threads64_", "scipy_openblas_set_num_threads",
        "openblas_set_num_threads64_", "openblas_set_num_threads")
_GET = ("scipy_openblas_get_num_threads64_", "scipy_openblas_get_num_threads",
        "openblas_get_num_threads64_", "openblas_get_num_threads")


def _libraries():
    import numpy  # noqa: F401  (load the libraries)
    import scipy.linalg  # noqa: F401

    paths = set()
    try:
        with open("/proc/self/maps") as fh:
            for line in fh:
                p = line.split()[-1]
                if "openblas" in p.lower() and p.endswith(".so") or ".so." in p and "openblas" in p.lower():
                    paths.add(p)
    except OSError:
        return []
    out = []
    for p in sorted(paths):
        try:
            lib = ctypes.CDLL(p)
        except OSError:
            continue
        setf = next((getattr(lib, s) for s in _SET if hasattr(lib, s)), None)
        getf = next((getattr(lib, s) for s in _GET if hasattr(lib, s)), None)
        if setf is not None and getf is not None:
            setf.argtypes, setf.restype, getf.restype = [ctypes.c_int], None, ctypes.c_int
            out.append((setf, getf))
    return out


@contextlib.contextmanager
def blas_threads(n: int = 1):
    """Run the block with at most ``n`` BLAS threads."""
    libs = _libraries()
    old = [g() for _, g in libs]
    for s, _ in libs:
        s(n)
    try:
        yield len(libs)
    finally:
        for (s, _), o in zip(libs, old):
            s(o)
