"""Ipopt's C interface through ctypes, for the direct NLP (``transcribe.direct_nlp.DirectNLP``).

Why not ``cyipopt.Problem``: its callbacks copy every returned array into Ipopt's element by
element through an untyped NumPy object (``values[i] = np_jac_g[i]`` in ipopt_wrapper.pyx),
about 55 ns an element: 0.6-0.7 ms per Jacobian of seed 0 (11,400 nonzeros) or the orbit
raising problem (12,670), more than the whole Jacobian evaluation, and about half of what Ipopt
counted as function evaluations (reports/bench/seed0.md). Here each callback is one
``memmove``. It is the C interface that cyipopt calls, on the library ``library_choice`` picks
(CasADi's newer build of Ipopt and MUMPS where installed, else cyipopt's own), with cyipopt's semantics:
options by Python type, the warm-start multipliers in and out of ``IpoptSolve``, an
evaluation that raises ``cyipopt.CyIpoptEvaluationError`` reports an evaluation error to Ipopt
(which cuts its step back), any other exception stops the solve and is raised after it, and
cyipopt's status messages.
"""
from __future__ import annotations

import contextlib
import ctypes
import functools
import os
import sys

import numpy as np

_D = ctypes.POINTER(ctypes.c_double)
_I = ctypes.POINTER(ctypes.c_int)
_VP = ctypes.c_void_p
_INT, _DBL = ctypes.c_int, ctypes.c_double
# Ipopt's callbacks; its Bool is cyipopt's ``ctypedef int Bool`` (new_x / new_lambda unused)
_EVAL_F = ctypes.CFUNCTYPE(_INT, _INT, _VP, _INT, _D, _VP)
_EVAL_G = ctypes.CFUNCTYPE(_INT, _INT, _VP, _INT, _INT, _VP, _VP)
_EVAL_GRAD = ctypes.CFUNCTYPE(_INT, _INT, _VP, _INT, _VP, _VP)
_EVAL_JAC = ctypes.CFUNCTYPE(_INT, _INT, _VP, _INT, _INT, _INT, _VP, _VP, _VP, _VP)
_EVAL_H = ctypes.CFUNCTYPE(_INT, _INT, _VP, _INT, _DBL, _INT, _VP, _INT, _INT, _VP, _VP, _VP, _VP)
_INTERMEDIATE = ctypes.CFUNCTYPE(_INT, _INT, _INT, _DBL, _DBL, _DBL, _DBL, _DBL, _DBL, _DBL, _DBL, _INT, _VP)


# Which libipopt: $OCDSL_IPOPT_LIBRARY (a path) if set, else CasADi's build where the casadi
# package is installed (a dependency: Ipopt 3.14.19 with MUMPS 5.8.2 and METIS), else cyipopt's
# (Ipopt 3.14.11, MUMPS 5.5.1). Why CasADi's first: on the same NLP and options its MUMPS
# takes half the time per iteration (brachistochrone, 100 segments, 1,999 variables: Ipopt
# without function evaluations 0.225 -> 0.106 s CPU for the same 27 iterations; section 21 of
# reports/bench/levers.md), which sections 6, 8 and 12 there traced to MUMPS 5.5.1 against
# 5.8.2 (not the BLAS, the ordering or the NLP).
LIBRARY_ENV = "OCDSL_IPOPT_LIBRARY"


def _casadi_library() -> str | None:
    """CasADi's bundled libipopt, found without importing casadi (0.1 s we do not need)."""
    import importlib.util
    from pathlib import Path

    try:
        spec = importlib.util.find_spec("casadi")
    except (ImportError, ValueError):
        return None
    for folder in (spec.submodule_search_locations or []) if spec else []:
        for name in ("libipopt.so.3", "libipopt.so", "libipopt.dylib"):
            if (Path(folder) / name).is_file():
                return str(Path(folder) / name)
    return None


@functools.cache
def _cyipopt_library() -> str | None:
    """cyipopt's libipopt, as loaded into this process by ``import cyipopt``."""
    from .ipopt import import_cyipopt

    import_cyipopt()     # loads the library and its MUMPS / BLAS
    paths = set()
    try:
        with open("/proc/self/maps") as fh:
            for line in fh:
                p = line.split()[-1]
                if "libipopt" in p and ".so" in p:
                    paths.add(p)
    except OSError:
        return None
    others = {os.path.realpath(p) for p in (_casadi_library(), os.environ.get(LIBRARY_ENV)) if p}
    paths = {p for p in paths if os.path.realpath(p) not in others}     # loaded too, maybe
    return paths.pop() if len(paths) == 1 else None


def library_choice() -> tuple[str | None, str]:
    """(the path of the libipopt the direct NLP calls, where it comes from: "OCDSL_IPOPT_LIBRARY",
    "casadi" or "cyipopt"); the path is None where none is found (cyipopt.Problem then)."""
    given = os.environ.get(LIBRARY_ENV)
    if given:
        return given, LIBRARY_ENV
    path = _casadi_library()
    if path is not None:
        return path, "casadi"
    return _cyipopt_library(), "cyipopt"


@functools.cache
def _library(path: str | None = None):
    """The loaded libipopt at ``path`` (default: ``library_choice()``); None if not found.
    A path given in OCDSL_IPOPT_LIBRARY that does not load is an error, not a fallback."""
    if path is None:
        path, source = library_choice()
        if path is None:
            return None
    else:
        source = "cyipopt" if path == _cyipopt_library() else "given"
    try:
        with _one_blas_thread():
            lib = ctypes.CDLL(path)
        lib.IpoptSolve      # noqa: B018  (a library without Ipopt's C interface is refused here)
    except (OSError, AttributeError) as e:
        if source == LIBRARY_ENV:
            raise OSError(f"{LIBRARY_ENV}={path} does not load as Ipopt's library: {e}") from None
        return None
    lib.CreateIpoptProblem.restype = _VP
    lib.CreateIpoptProblem.argtypes = [_INT, _D, _D, _INT, _D, _D, _INT, _INT, _INT,
                                       _EVAL_F, _EVAL_G, _EVAL_GRAD, _EVAL_JAC, _EVAL_H]
    lib.FreeIpoptProblem.argtypes, lib.FreeIpoptProblem.restype = [_VP], None
    lib.AddIpoptStrOption.argtypes, lib.AddIpoptStrOption.restype = [_VP, ctypes.c_char_p, ctypes.c_char_p], _INT
    lib.AddIpoptNumOption.argtypes, lib.AddIpoptNumOption.restype = [_VP, ctypes.c_char_p, _DBL], _INT
    lib.AddIpoptIntOption.argtypes, lib.AddIpoptIntOption.restype = [_VP, ctypes.c_char_p, _INT], _INT
    lib.SetIpoptProblemScaling.argtypes, lib.SetIpoptProblemScaling.restype = [_VP, _DBL, _D, _D], _INT
    lib.SetIntermediateCallback.argtypes, lib.SetIntermediateCallback.restype = [_VP, _INTERMEDIATE], _INT
    lib.IpoptSolve.argtypes = [_VP, _D, _D, _D, _D, _D, _D, _VP]
    lib.IpoptSolve.restype = _INT
    version = _version(lib) or (".".join(map(str, sys.modules["cyipopt"].IPOPT_VERSION)) if source == "cyipopt" else "")
    lib.ocdsl_name = f"Ipopt {version} ({source})" if version else f"Ipopt ({source})"
    return lib


@contextlib.contextmanager
def _one_blas_thread():
    """Load the library with one OpenBLAS thread for its MUMPS unless the user set a count:
    CasADi's OpenBLAS starts one per core, and on these KKT systems (small dense fronts) the
    second only costs CPU (brachistochrone, 100 segments: process CPU 1.19 -> 0.96 s, the
    same wall; the CasADi script's own Ipopt CPU is twice its wall time on the small examples
    of reports/bench/peers.md). OpenBLAS reads the count when it loads (openblas_set_num_threads
    afterwards leaves its second thread spinning), so it is set for the load only."""
    from ..serve.client import BLAS_THREADS

    if any(os.environ.get(k) for k in BLAS_THREADS):
        yield
        return
    os.environ["OPENBLAS_NUM_THREADS"] = "1"
    try:
        yield
    finally:
        os.environ.pop("OPENBLAS_NUM_THREADS", None)


def _version(lib) -> str:
    """"3.14.19" (GetIpoptVersion), or "" where the library lacks it (cyipopt's 3.14.11 does)."""
    getter = getattr(lib, "GetIpoptVersion", None)
    if getter is None:
        return ""
    parts = [_INT() for _ in range(3)]
    getter.argtypes, getter.restype = [_I, _I, _I], None
    getter(*(ctypes.byref(p) for p in parts))
    return ".".join(str(p.value) for p in parts)


def name(path: str | None = None) -> str:
    """The version and source of the library at ``path`` (default: the one the direct NLP
    calls), as result.json's nlp records it: "Ipopt 3.14.19 (casadi)"."""
    lib = _library(path)
    return lib.ocdsl_name if lib is not None else "Ipopt (cyipopt)"


def cyipopt_name() -> str:
    """What the PyNumero route solves with: cyipopt's own library."""
    path = _cyipopt_library()
    return name(path) if path else "Ipopt (cyipopt)"


def available() -> bool:
    return _library() is not None


def _ptr(a: np.ndarray):
    return a.ctypes.data_as(_D)


class Problem:
    """cyipopt.Problem's interface as ``_solve_direct_nlp`` uses it: ``add_option``,
    ``set_problem_scaling``, ``solve(x0, lagrange=, zl=, zu=)`` -> (x, info), ``close``."""

    def __init__(self, nlp, library: str | None = None):
        from cyipopt import CyIpoptEvaluationError

        self.lib = lib = _library(library)
        self.nlp = nlp
        n, m = nlp.n, nlp.m
        jr, jc = (np.ascontiguousarray(a, np.int32) for a in nlp.jacobianstructure())
        hr, hc = (np.ascontiguousarray(a, np.int32) for a in nlp.hessianstructure())
        self._keep = [np.ascontiguousarray(a, float) for a in (nlp.xl, nlp.xu, nlp.gl, nlp.gu)]
        self.exception = None
        xs = ctypes.c_double * n
        lams = ctypes.c_double * max(m, 1)

        def x_of(p):
            return np.frombuffer(xs.from_address(p), float)

        def put(p, values, k):
            v = np.ascontiguousarray(values, float)
            if v.size != k:
                raise ValueError(f"a callback returned {v.size} values where Ipopt expects {k}")
            ctypes.memmove(p, v.ctypes.data, 8 * k)

        def guarded(body):
            def cb(*args):
                if self.exception is not None:
                    return 0
                try:
                    return 1 if body(*args) is not False else 0
                except CyIpoptEvaluationError:
                    return 0
                except BaseException:
                    self.exception = sys.exc_info()[1]
                    return 0
            return cb

        def f(n_, x, new_x, obj, user):
            obj[0] = float(nlp.objective(x_of(x)))

        def g(n_, x, new_x, m_, out, user):
            put(out, nlp.constraints(x_of(x)), m)

        def grad(n_, x, new_x, out, user):
            put(out, nlp.gradient(x_of(x)), n)

        def jac(n_, x, new_x, m_, nele, irow, jcol, values, user):
            if not values:
                ctypes.memmove(irow, jr.ctypes.data, 4 * len(jr))
                ctypes.memmove(jcol, jc.ctypes.data, 4 * len(jc))
            else:
                put(values, nlp.jacobian(x_of(x)), len(jr))

        def hess(n_, x, new_x, obj_factor, m_, lam, new_lam, nele, irow, jcol, values, user):
            if not values:
                ctypes.memmove(irow, hr.ctypes.data, 4 * len(hr))
                ctypes.memmove(jcol, hc.ctypes.data, 4 * len(hc))
            else:
                lagrange = np.frombuffer(lams.from_address(lam), float)[:m] if m else np.zeros(0)
                put(values, nlp.hessian(x_of(x), lagrange, obj_factor), len(hr))

        def intermediate(alg_mod, it, obj, inf_pr, inf_du, mu, d_norm, reg, alpha_du, alpha_pr, ls, user):
            return nlp.intermediate(alg_mod, it, obj, inf_pr, inf_du, mu, d_norm, reg, alpha_du, alpha_pr, ls)

        # the ctypes function objects must outlive the problem: kept on it
        self._cbs = (_EVAL_F(guarded(f)), _EVAL_G(guarded(g)), _EVAL_GRAD(guarded(grad)),
                     _EVAL_JAC(guarded(jac)), _EVAL_H(guarded(hess)))
        self._intermediate = _INTERMEDIATE(guarded(intermediate))
        xl, xu, gl, gu = self._keep
        self.handle = lib.CreateIpoptProblem(n, _ptr(xl), _ptr(xu), m, _ptr(gl), _ptr(gu), len(jr), len(hr), 0,
                                             *self._cbs)
        if not self.handle:
            raise ValueError("Ipopt refused the problem (CreateIpoptProblem)")
        lib.SetIntermediateCallback(self.handle, self._intermediate)

    def add_option(self, key, value) -> None:
        k = str(key).encode()
        if isinstance(value, bytes):
            ok = self.lib.AddIpoptStrOption(self.handle, k, value)
        elif isinstance(value, str):
            ok = self.lib.AddIpoptStrOption(self.handle, k, value.encode())
        elif isinstance(value, (bool, int, np.integer)):
            ok = self.lib.AddIpoptIntOption(self.handle, k, int(value))
        else:
            ok = self.lib.AddIpoptNumOption(self.handle, k, float(value))
        if not ok:
            raise TypeError(f"Error while assigning an option {key!r} = {value!r}")   # cyipopt's message

    def set_problem_scaling(self, obj_scaling, x_scaling, g_scaling) -> None:
        xs, gs = np.ascontiguousarray(x_scaling, float), np.ascontiguousarray(g_scaling, float)
        self._keep += [xs, gs]
        self.lib.SetIpoptProblemScaling(self.handle, float(obj_scaling), _ptr(xs), _ptr(gs))

    def solve(self, x0, lagrange=None, zl=None, zu=None):
        from ipopt_wrapper import STATUS_MESSAGES

        n, m = self.nlp.n, self.nlp.m
        x = np.array(x0, float)
        g = np.zeros(m)
        mult_g = np.zeros(m) if lagrange is None else np.array(lagrange, float)
        mult_l = np.zeros(n) if zl is None else np.array(zl, float)
        mult_u = np.zeros(n) if zu is None else np.array(zu, float)
        obj = ctypes.c_double(0.0)
        self.exception = None
        status = self.lib.IpoptSolve(self.handle, _ptr(x), _ptr(g), ctypes.byref(obj), _ptr(mult_g), _ptr(mult_l),
                                     _ptr(mult_u), None)
        if self.exception is not None:
            raise self.exception
        return x, {"x": x, "g": g, "obj_val": obj.value, "mult_g": mult_g, "mult_x_L": mult_l, "mult_x_U": mult_u,
                   "status": status, "status_msg": STATUS_MESSAGES.get(status, b"Unknown status")}

    def close(self) -> None:
        if self.handle:
            self.lib.FreeIpoptProblem(self.handle)
            self.handle = None
