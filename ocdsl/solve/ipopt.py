"""Ipopt through Pyomo's cyipopt interface: availability check, options, progress, status."""
from __future__ import annotations

import contextlib
import contextvars
import os
import signal
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from .process_state import floating_point_environment_kept, heap_kept
from .start_options import adapted

SQUARE = "Feasible point for square problem found."
STATUS_MAP = {
    # Ipopt's status messages (cyipopt) -> ocdsl statuses
    "Algorithm terminated successfully at a locally optimal point, satisfying the convergence tolerances (can be specified by options).": "optimal",
    "Algorithm stopped at a point that was converged, not to \"desired\" tolerances, but to \"acceptable\" tolerances (see the acceptable-... options).": "acceptable",
    "Maximum number of iterations exceeded (can be specified by an option).": "max_iter",
    "Maximum CPU time exceeded.": "time_limit",
    "Maximum wallclock time exceeded.": "time_limit",
    "It seems that the iterates diverge.": "diverged",
    "The user call-back function intermediate_callback (see Section 3.3.4 in the documentation) returned "
    "false, i.e., the user code requested a premature termination of the optimization.": "interrupted",
    "Problem may be infeasible.": "infeasible",
    "Algorithm converged to a point of local infeasibility. Problem may be infeasible.": "infeasible",
    # as many equations as free unknowns and no inequalities: Ipopt solves the equations and
    # its one feasible point, within the bounds, is the NLP's optimum (a quaternion slew on a
    # first mesh of 2 x 3 with every end state fixed, unseen21 U1: it had ended the refinement)
    SQUARE: "optimal",
}
# Ipopt's STOP_AT_TINY_STEP: its steps became too small to change the iterate. At a point
# feasible to ``tol`` that is Ipopt at the end of its precision (the minimum-energy quadruple
# integrator's flat NLP: J = 100800 exact at iteration 4, its dual infeasibility held at
# rounding level on one machine, "optimal" on another): accepted as `acceptable`, which the
# verification and the certificate then judge like any other; elsewhere an error
TINY_STEP = "Algorithm proceeds with very little progress."
# Ipopt's message when the equality constraints outnumber the free unknowns (it does not start)
TOO_FEW_FREEDOMS = "Problem has too few degrees of freedom"
TOO_FEW_HINT = (": the NLP has more equality constraints than free unknowns; a mesh this coarse cannot meet "
                "the boundary conditions (more segments or a higher degree)")

# mumps_permuting_scaling 0 (MUMPS ICNTL(6) = 0, no maximum-weight matching): with Ipopt's
# default (7, automatic) MUMPS computes its scaling once, in the analysis phase (ICNTL(8)
# effectively -2), from the KKT matrix at the starting point, and Ipopt analyses only once
# because the structure never changes. With the bundled MUMPS 5.5.1 (cyipopt-wheels) that
# stale scaling gave wrong-looking inertia: on the brachistochrone at 16 segments, for the
# same KKT matrix (iterates equal to 7 digits with CasADi's Ipopt 3.14.19 / MUMPS 5.8.2),
# MUMPS 5.5.1 counted 242 negative pivots where 5.8.2 counted 240 (= constraints), and from
# then on Ipopt regularised the Hessian at almost every iteration (221 of 230 at 64 segments).
# With 0, MUMPS scales each factorisation afresh (ICNTL(8) = 7); measured (CPU, brachistochrone
# LGR degree 5; reports/bench/levers.md section 8): 16/64/100/500 segments 56/229/231/251 ->
# 21/29/24/23 iterations (CasADi: 19/32/33/41), Ipopt CPU per iteration at 500 segments
# 0.05 s (CasADi 0.04 s); the configs/ examples take the same iterations as before and every
# optimum is unchanged (tests/test_examples.py, test_costates.py, test_fast_paths.py).
# User options still override it.
# bound_relax_factor 1e-9 (Ipopt's default 1e-8): a state held at its bound through a phase (mass
# at its dry value while coasting) ends on the relaxed bound, 1e-8 * |b| outside. Ipopt 3.14
# counts that as constraint violation, one rounding above tol = 1e-8, so it never reports
# "desired" (three-phase Goddard: 36 iterations, acceptable), and ocdsl/verify measures a
# constant state against 1e-3 of its size, which makes it 1e-5: exactly the default verify
# tolerance. At 1e-9 the same run is optimal and verified, 1.25e-9 from the published value.
# option_file_name "": Ipopt reads no ipopt.opt from the working folder (a stray one there
# silently cut every solve to its max_iter 1: unseen24); the file's `solver: options` can
# still name one
DEFAULT_OPTIONS = {"mu_strategy": "adaptive", "max_iter": 3000, "tol": 1e-8, "mumps_permuting_scaling": 0,
                   "bound_relax_factor": 1e-9, "option_file_name": ""}
# Ipopt's ApplicationReturnStatus codes that cyipopt's messages lack ("Unknown status")
STATUS_CODES = {-4: "time_limit", -5: "time_limit", 5: "interrupted"}

_INTERRUPTED = threading.Event()
_BY: list[str] = ["Ctrl-C"]
_SIGNALS = {signal.SIGINT: "Ctrl-C", signal.SIGTERM: "SIGTERM"}


@contextlib.contextmanager
def interruptible():
    """Inside, Ctrl-C (SIGINT) or SIGTERM (what `timeout`, systemd and batch schedulers send)
    stops the running solve at its next iteration, which returns its last iterate with
    status ``interrupted``, and later solves do not start; a second signal raises
    KeyboardInterrupt. Before, SIGTERM ended the process with no run folder (unseen24). Only
    in the main thread (signals go there)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _INTERRUPTED.clear()

    def handler(signum, frame):
        if _INTERRUPTED.is_set():
            raise KeyboardInterrupt
        _BY[0] = _SIGNALS.get(signum, "a signal")
        _INTERRUPTED.set()

    previous = {sig: signal.signal(sig, handler) for sig in _SIGNALS}
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)
        _INTERRUPTED.clear()      # what was interrupted has said so; the next command starts afresh


def interrupted() -> bool:
    return _INTERRUPTED.is_set()


def interrupted_by() -> str:
    """What interrupted the run: "Ctrl-C" or "SIGTERM"."""
    return _BY[0]

# the run's wall-clock deadline (time.monotonic()), set by ``time_limit``; every solve
# gets the time left as Ipopt's max_wall_time
_DEADLINE: "contextvars.ContextVar[tuple[float, float] | None]" = contextvars.ContextVar("deadline", default=None)


# the solves of the current time limit that it cut or refused (``time_limit``), so that a run
# whose later starts or checks it cut does not end as if it had done them (unseen42 F3)
_CUT: "contextvars.ContextVar[list | None]" = contextvars.ContextVar("cut", default=None)


def solves_cut() -> int:
    """How many solves under the current ``time_limit`` ended or were refused by it."""
    cut = _CUT.get()
    return 0 if cut is None else len(cut)


def _count_cut(status: str) -> None:
    cut = _CUT.get()
    if cut is not None and status == "time_limit":
        cut.append(1)


def seconds_left() -> float | None:
    """Wall-clock seconds left of the run's time limit (None without one)."""
    deadline = _DEADLINE.get()
    return None if deadline is None else deadline[0] - time.monotonic()


@contextlib.contextmanager
def time_limit(seconds: float | None):
    """Solves inside share ``seconds`` of wall-clock time (a run's mesh iterations and starts)."""
    token = _DEADLINE.set(None if seconds is None else (time.monotonic() + float(seconds), float(seconds)))
    cut = _CUT.set([])
    try:
        yield
    finally:
        _DEADLINE.reset(token)
        _CUT.reset(cut)


class SolverUnavailable(RuntimeError):
    """Ipopt or PyNumero's ASL library is missing; the message says how to fix it."""


def _light_scipy() -> None:
    """Let Pyomo's first scipy import load only scipy.sparse, not scipy.stats.

    Pyomo registers a callback that, on the first import of scipy anywhere (cyipopt imports
    it), also imports scipy.stats, spatial and integrate: about 1 s of start-up that the NLP
    never uses (PyNumero needs scipy.sparse only; SciPy loads other submodules lazily on
    attribute access). Replaces that callback while it has not run yet; does nothing
    otherwise or if Pyomo's internals differ.
    """
    if "scipy.stats" in sys.modules:
        return
    try:
        from pyomo.common import dependencies as deps

        ind = deps.scipy_available
        if getattr(ind, "_callback", None) is deps._finalize_scipy:
            ind._callback = _finalize_scipy_sparse
    except Exception:  # pragma: no cover - a Pyomo without this hook
        pass


def _finalize_scipy_sparse(module, available) -> None:
    if available:
        import scipy.sparse  # noqa: F401


def import_cyipopt():
    """cyipopt, imported without its SciPy front end when SciPy is not loaded yet.

    ``cyipopt/__init__`` imports ``scipy_interface`` (``minimize_ipopt``, which ocdsl does
    not use), and that imports scipy.optimize and scipy.sparse: 0.5 s of CPU, a third of a
    small run. The module guards the import (``try: import scipy except ImportError``), so
    while cyipopt loads ``scipy`` is marked absent; the mark is removed at once, so any
    later ``import scipy`` works as usual. ``cyipopt.Problem`` is unaffected."""
    if "cyipopt" in sys.modules or "scipy" in sys.modules:
        import cyipopt
        return cyipopt
    sys.modules["scipy"] = None          # `import scipy` raises ImportError while set
    try:
        import cyipopt
    finally:
        del sys.modules["scipy"]
    return cyipopt


def check_available() -> None:
    """Fail early with a fix, instead of Pyomo's opaque AttributeError on AmplInterface."""
    _light_scipy()
    try:
        import_cyipopt()
    except ImportError as e:
        raise SolverUnavailable(f"cyipopt is not importable ({e}); install the project with `make setup` "
                                "(it installs the cyipopt-wheels package, which bundles Ipopt)") from None
    from pyomo.contrib.pynumero.asl import AmplInterface

    if not AmplInterface.available():
        where = os.environ.get("PYOMO_CONFIG_DIR", "<not set>")
        raise SolverUnavailable(
            "PyNumero's ASL library (libpynumero_ASL) was not found, so Pyomo cannot hand the NLP to "
            f"Ipopt. PYOMO_CONFIG_DIR={where}. Fix: run `make setup` (builds it into "
            ".venv/share/pyomo), or set PYOMO_CONFIG_DIR to the folder that holds lib/libpynumero_ASL.so.")


@dataclass
class SolveInfo:
    status: str
    message: str
    iterations: int
    objective: float | None
    solve_time: float
    nlp: dict[str, int] = field(default_factory=dict)
    history: list[tuple[int, float, float, float]] = field(default_factory=list)  # iter, obj, inf_pr, inf_du
    log: str = ""


class Progress:
    """A one-line live display written straight to the terminal's file descriptor.

    Pyomo captures stdout/stderr during the solve, so the line goes to a duplicate of
    the original stderr descriptor taken before the solve starts.
    """

    def __init__(self, enabled: bool, label: str = ""):
        self.enabled = enabled and sys.stderr.isatty()
        self.label = label
        self.fd = os.dup(sys.stderr.fileno()) if self.enabled else None
        self.last = 0.0

    def update(self, it: int, obj: float, inf_pr: float, inf_du: float) -> None:
        now = time.perf_counter()
        if self.fd is None or now - self.last < 0.1:
            return
        self.last = now
        line = f"\r{self.label} iter {it:4d}  objective {obj: .8e}  infeasibility {inf_pr:.2e}  dual {inf_du:.2e} "
        os.write(self.fd, line.encode())

    def close(self) -> None:
        if self.fd is not None:
            os.write(self.fd, b"\r\x1b[K")
            os.close(self.fd)
            self.fd = None


# Ipopt options of a solve started from given multipliers (``solve(..., multipliers=...)``),
# the caller's options override them. warm_start_init_point makes Ipopt use the lambda, z_L,
# z_U passed to cyipopt instead of its least-squares / unit estimates; the pushes keep the
# start (and the bound multipliers) within 1e-9 of where they are instead of Ipopt's default
# 1e-3 push into the interior, and a small mu_init does not move the (nearly optimal) point
# back onto the central path of mu = 0.1 (measured in docs/mesh-refinement.md, "Warm start").
WARM_START_OPTIONS = {"warm_start_init_point": "yes", "warm_start_bound_push": 1e-9,
                      "warm_start_bound_frac": 1e-9, "warm_start_slack_bound_push": 1e-9,
                      "warm_start_slack_bound_frac": 1e-9, "warm_start_mult_bound_push": 1e-9,
                      "mu_init": 1e-6}


@dataclass
class Multipliers:
    """Starting multipliers for ``solve``, keyed by Pyomo component data.

    ``constraints``: ConstraintData -> multiplier in Pyomo's ``dual`` suffix convention
    (Ipopt's lambda, ``L = f + lambda^T g``); ``lower`` / ``upper``: VarData -> Ipopt's
    z_L / z_U (>= 0). Missing entries start at 0 (Ipopt pushes bound multipliers up to
    ``warm_start_mult_bound_push``)."""

    constraints: Any = field(default_factory=lambda: _component_map())
    lower: Any = field(default_factory=lambda: _component_map())
    upper: Any = field(default_factory=lambda: _component_map())


def _component_map():
    """A dict keyed by Pyomo component data (VarData is not hashable)."""
    from pyomo.common.collections import ComponentMap

    return ComponentMap()


_SOLVES_WITH_OUTPUT_FILE = [0]


def _numbered_output_file(options: dict[str, Any]) -> dict[str, Any]:
    """The options with Ipopt's ``output_file`` kept for the process's first solve and
    numbered for the later ones (``ipopt.txt``, ``ipopt.2.txt``, ...): Ipopt truncates the
    file per solve (this build has no ``file_append``), so a run's later solves (the
    bisection check, the certificate's, a mesh's next iterations) overwrote the first one's
    log; the bench read the bisected mesh's sizes and iterations as the run's (Goddard: 2,560
    variables against its 644)."""
    name = options.get("output_file")
    if not name:
        return options
    _SOLVES_WITH_OUTPUT_FILE[0] += 1
    n = _SOLVES_WITH_OUTPUT_FILE[0]
    if n == 1:
        return options
    path = Path(str(name))
    return {**options, "output_file": str(path.with_name(f"{path.stem}.{n}{path.suffix}"))}


def solve(model, options: dict[str, Any] | None = None, verbose: bool = False,
          progress: Progress | None = None, on_iteration: Callable | None = None,
          multipliers: Multipliers | None = None, transcription=None,
          multipliers_max_iter: int | None = None) -> SolveInfo:
    """Solve a Pyomo model with Ipopt; never raises for a failed solve (status 'error').

    With ``multipliers`` the solve starts from them as well as from the variables' values
    (Pyomo's ``SolverFactory('cyipopt')`` cannot pass them), with
    ``WARM_START_OPTIONS`` under the caller's options; if that solve does not end optimal or
    acceptable, the variables are reset to their starting values and the model is solved
    again without the multipliers (the message says so, the iterations of both count); the
    attempt with them stops at ``multipliers_max_iter`` when given. Bound
    multipliers are loaded into the model's ``ipopt_zL_out`` / ``ipopt_zU_out`` suffixes when
    it has them (both paths).

    ``transcription``: the pseudospectral Transcription that built ``model``; Ipopt then
    evaluates the NLP through ``transcribe.direct_nlp`` where it covers the model (the
    message of ``SolveInfo.nlp["evaluation"]`` says which route was taken)."""
    import pyomo.core as pyo

    from .. import pyomo_logs

    check_available()
    heap_kept()
    pyomo_logs.quiet()

    def options_with(*layers):
        out = {k: v for layer in layers for k, v in layer.items()}
        if not verbose:
            out.setdefault("print_level", 0)
        out.setdefault("sb", "yes")
        return out

    if interrupted():
        return SolveInfo("interrupted", f"interrupted ({interrupted_by()}) before this solve", 0, None, 0.0)
    deadline = _DEADLINE.get()
    if deadline is not None and deadline[0] - time.monotonic() <= 0:
        _count_cut("time_limit")
        return SolveInfo("time_limit", f"the run's time limit of {deadline[1]:g} s was reached before "
                         "this solve (solver: time_limit, or ocdsl run --time-limit)", 0, None, 0.0)

    def limited(out):
        """``out`` with the run's time left now as Ipopt's max_wall_time (every attempt's
        options: the warm-started one lost it, and a mesh's solve ran 75 s past a 100 s limit,
        unseen10 F1; a retry after it gets what is left then)."""
        if deadline is not None:
            left = max(deadline[0] - time.monotonic(), 1e-3)
            out["max_wall_time"] = min(float(out.get("max_wall_time", left)), left)
        return out

    options = _numbered_output_file(options or {})
    given = frozenset(options)         # the caller's own options (start_options.adapted)
    opts = limited(options_with(DEFAULT_OPTIONS, options))
    try:
        if multipliers is None:
            return _attempt(model, opts, verbose, progress, on_iteration, None, transcription, given)
        start = [(v, v.value) for v in model.component_data_objects(pyo.Var) if not v.fixed]
        warm_options = options_with(DEFAULT_OPTIONS, WARM_START_OPTIONS, options or {})
        if multipliers_max_iter is not None:
            warm_options["max_iter"] = min(int(warm_options["max_iter"]), int(multipliers_max_iter))
        warm = _attempt(model, limited(warm_options), verbose, progress, on_iteration, multipliers, transcription,
                        given)
        if warm.status in ("optimal", "acceptable", "time_limit", "interrupted"):
            return warm
        # never worse than without the multipliers: the same primal start, Ipopt's own duals
        for v, x in start:
            v.set_value(x, skip_validation=True)
        info = _attempt(model, limited(opts), verbose, progress, on_iteration, None, transcription, given)
        info.message = (f"{info.message} (started from the given multipliers Ipopt ended '{warm.status}' "
                        f"after {warm.iterations} iterations; solved again without them, iterations "
                        "counted together)")
        info.iterations += warm.iterations
        info.solve_time += warm.solve_time
        info.history = warm.history + info.history
        return info
    finally:
        if progress:
            progress.close()


def _attempt(model, opts, verbose, progress, on_iteration, multipliers, transcription=None,
             given: frozenset = frozenset()) -> SolveInfo:
    import pyomo.core as pyo

    from ..transcribe import pseudospectral
    from . import ipopt_c

    history: list[tuple[int, float, float, float]] = []

    def callback(*args):
        # 12- or 13-argument form: (nlp?, alg_mod, iter, obj, inf_pr, inf_du, mu, d_norm, ...)
        vals = args[-11:]
        it, obj, inf_pr, inf_du = int(vals[1]), float(vals[2]), float(vals[3]), float(vals[4])
        history.append((it, obj, inf_pr, inf_du))
        if progress:
            progress.update(it, obj, inf_pr, inf_du)
        if on_iteration:
            on_iteration(it, obj, inf_pr, inf_du)
        return not _INTERRUPTED.is_set()       # False: Ipopt stops, keeping this iterate

    if getattr(model, "scaling_factor", None) is not None:
        opts = {**opts, "nlp_scaling_method": "user-scaling"}     # ocdsl/solve/scaling.py
    t = time.perf_counter()
    code = None
    try:
        # gc_frozen: the hand-over's full collections do not walk the built model again
        # (reports/bench/levers.md section 11); the environment: the ASL's x87 precision
        with pseudospectral.gc_frozen(), floating_point_environment_kept():
            direct, why = direct_nlp(transcription)
            if direct is not None:
                msg, nlp_info, code = _solve_direct_nlp(direct, opts, verbose, callback, multipliers,
                                                        transcription, given)
            elif transcription is not None and (root := _root_of_zero(transcription)):
                raise _BadStart("the initial guess puts a root at 0, where its derivative is infinite "
                                f"(the NLP evaluator would stop the process): {root}. Ipopt was not started")
            else:
                msg, nlp, code, scaled = _solve_pynumero(model, opts, verbose, callback, multipliers, given)
            if direct is None:
                nlp_info = {"variables": int(nlp.n_primals()), "constraints": int(nlp.n_constraints()),
                            "nonzeros": int(nlp.nnz_jacobian()),
                            "hessian_nonzeros": int(nlp.nnz_hessian_lag()),
                            "equality_constraints": int(nlp.n_eq_constraints()),
                            "inequality_constraints": int(nlp.n_ineq_constraints()),
                            "evaluation": f"PyNumero (ASL): {why}", "ipopt": ipopt_c.cyipopt_name(), **scaled}
    except _BadStart as e:
        return SolveInfo("error", str(e), 0, None, time.perf_counter() - t)
    except Exception as e:  # evaluation errors, bad options...
        return SolveInfo("error", f"{type(e).__name__}: {e}", len(history) and history[-1][0],
                         None, time.perf_counter() - t, history=history)
    elapsed = time.perf_counter() - t
    msg = msg.decode() if isinstance(msg, bytes) else str(msg)
    # Ipopt's message, possibly followed by a diagnosis (an infeasible end's unmet constraints)
    status = next((v for k, v in STATUS_MAP.items() if msg.startswith(k)), None) or STATUS_CODES.get(code, "error")
    if msg.startswith(TINY_STEP) and history and history[-1][2] <= float(opts.get("tol", DEFAULT_OPTIONS["tol"])):
        status = "acceptable"
        msg += (f" At a point feasible to {history[-1][2]:.1e}, where its steps no longer change the iterate: "
                "accepted at Ipopt's acceptable level")
    if msg.startswith(TOO_FEW_FREEDOMS) and TOO_FEW_HINT not in msg:
        msg = msg.rstrip(".") + TOO_FEW_HINT
    elif msg.startswith(SQUARE):
        msg += " (as many equations as free unknowns: its one feasible point is the NLP's optimum)"
    if interrupted() and status in ("interrupted", "error"):
        status = "interrupted"
        msg = (f"interrupted ({interrupted_by()}) at iteration {history[-1][0] if history else 0}; "
               "the last iterate is written")
    if status == "time_limit":
        wall = opts.get("max_wall_time")
        given = f" (this solve had {float(wall):.3g} s: the run's solver: time_limit, or max_wall_time)" if wall else ""
        said = "" if msg == "Unknown status" else f" (Ipopt: {msg})"     # cyipopt has no words for -5
        msg = f"a time limit was reached{given}; the last iterate is written{said}"
    if status in ("max_iter", "diverged", "time_limit", "error"):
        from .diagnose import diverging

        objective = next(model.component_data_objects(pyo.Objective, active=True), None)
        # Ipopt minimises: a maximisation's history is the negated objective, not the user's
        msg += diverging(history, -1.0 if objective is not None and objective.sense == pyo.maximize else 1.0)
    obj = None
    try:
        obj = float(pyo.value(next(model.component_data_objects(pyo.Objective, active=True))))
    except Exception:
        pass
    iterations = history[-1][0] if history else 0
    _count_cut(status)
    return SolveInfo(status, msg, iterations, obj, elapsed, nlp_info, history)


def direct_nlp(transcription):
    """(the DirectNLP of ``transcription``, "") where the solve evaluates through NumPy, or
    (None, why it takes the PyNumero route)."""
    from ..transcribe import pseudospectral

    if transcription is None:
        return None, "no transcription given"
    if not pseudospectral.FAST["direct_nlp"]:
        return None, "direct evaluation turned off"
    from ..transcribe.direct_nlp import DirectNLP

    return DirectNLP.of(transcription)


def _start_multipliers(multipliers: Multipliers, constraints, variables, lower, upper) -> dict:
    """cyipopt's ``lagrange``, ``zl`` and ``zu`` from ``multipliers`` for these rows and
    variables (bounds ``lower``/``upper``): missing entries 0, bound multipliers >= 0."""
    import numpy as np

    lam = np.array([float(multipliers.constraints.get(c, 0.0)) for c in constraints], float)
    zl = np.array([max(0.0, float(multipliers.lower.get(v, 0.0))) for v in variables], float)
    zu = np.array([max(0.0, float(multipliers.upper.get(v, 0.0))) for v in variables], float)
    # no bound, no multiplier (Ipopt ignores them there; keep them clean anyway)
    zl[~np.isfinite(lower) | (lower <= -1e19)] = 0.0
    zu[~np.isfinite(upper) | (upper >= 1e19)] = 0.0
    return {"lagrange": lam, "zl": zl, "zu": zu}


def _root_of_zero(transcription) -> str | None:
    from . import diagnose

    try:
        return diagnose.root_of_zero_at_guess(transcription)
    except Exception:  # noqa: BLE001  (a check that fails must not stop a solve it cannot judge)
        return None


class _BadStart(Exception):
    """The NLP is not finite at its starting point; the message names where."""


def _solve_direct_nlp(nlp, opts: dict[str, Any], verbose: bool, callback: Callable,
                      multipliers: Multipliers | None, transcription=None, given: frozenset = frozenset()):
    """Ipopt on a ``DirectNLP`` (cyipopt.Problem), starting from the model's values and, when
    given, the multipliers; the solution, duals and bound multipliers are loaded into the
    model as ``_solve_pynumero`` does. Returns (Ipopt's status message, the
    NLP's sizes, Ipopt's status code); a start where the NLP is not finite is refused with
    :class:`_BadStart` before Ipopt runs, and an infeasible end names the constraints left
    unmet (ocdsl/solve/diagnose.py)."""
    import cyipopt
    from pyomo.common.tee import capture_output

    from . import diagnose

    if transcription is not None:
        bad = diagnose.nonfinite_at_start(transcription, nlp)
        if bad:
            raise _BadStart(bad)
    from . import ipopt_c

    nlp.intermediate = callback
    if ipopt_c.available():      # Ipopt without cyipopt's element-wise copies (ipopt_c.py)
        problem = ipopt_c.Problem(nlp)
    else:
        problem = cyipopt.Problem(n=nlp.n, m=nlp.m, problem_obj=nlp, lb=nlp.xl, ub=nlp.xu, cl=nlp.gl, cu=nlp.gu)
    library = ipopt_c.name()
    model = transcription.model if transcription is not None else None
    sf = getattr(model, "scaling_factor", None)
    opts, changed = adapted(opts, given, nlp.gradient, nlp.x0, nlp.xl, nlp.xu, sf is not None)
    for k, v in opts.items():
        problem.add_option(k, v)
    if sf is not None:     # the model's scaling suffix, in this NLP's variable and row order
        import numpy as np
        import pyomo.core as pyo

        obj = next(model.component_data_objects(pyo.Objective, active=True))
        problem.set_problem_scaling(float(sf.get(obj, 1.0)), np.array([sf.get(v, 1.0) for v in nlp.variables]),
                                    np.array([sf.get(c, 1.0) for c in nlp.rows]))
    kwargs = {} if multipliers is None else _start_multipliers(multipliers, nlp.rows, nlp.variables,
                                                                 nlp.xl, nlp.xu)
    try:
        with capture_output(sys.stdout if verbose else None, capture_fd=True):
            x, info = problem.solve(nlp.x0, **kwargs)
        nlp.load(x, info["mult_g"], info["mult_x_L"], info["mult_x_U"])
    finally:
        problem.close()
    msg = info["status_msg"]
    msg = msg.decode() if isinstance(msg, bytes) else str(msg)
    if transcription is not None and STATUS_MAP.get(msg) == "infeasible":
        msg += diagnose.infeasibility_message(transcription, nlp, x)
    return msg, {**nlp.info(), "ipopt": library, **changed}, info.get("status")


def pynumero_nlp(model):
    """PyNumero's PyomoNLP of a model (NL writer + ASL). ocdsl's own modules import only
    ``pyomo.core`` (0.2 s less start-up than ``pyomo.environ``); the NL writer is one of
    the plugins ``pyomo.environ`` registers, so it is imported here, where it is needed."""
    import pyomo.environ  # noqa: F401
    from pyomo.common.env import CtypesEnviron
    from pyomo.contrib.pynumero.interfaces.pyomo_nlp import PyomoNLP

    if os.name != "nt":
        # PyomoNLP sets AMPLFUNC through CtypesEnviron, which first probes eleven Windows C
        # runtimes with ctypes.util.find_library, a subprocess each (0.14 s per process,
        # half of a small PyNumero solve); off Windows none exists and os.environ is the C
        # library's own environment, so there is nothing to probe
        CtypesEnviron.DLLs = []

    return PyomoNLP(model)


def _solve_pynumero(model, opts: dict[str, Any], verbose: bool, callback: Callable,
                    multipliers: Multipliers | None = None, given: frozenset = frozenset()):
    """What Pyomo's cyipopt solver does (pynumero ``algorithms/solvers/cyipopt_solver.py``,
    ``PyomoCyIpoptSolver.solve``: PyomoNLP -> CyIpoptNLP -> options -> solve -> load the
    primals, duals and bound multipliers into the model), except that cyipopt's ``solve``
    gets ``lagrange``, ``zl`` and ``zu`` besides ``x0`` when ``multipliers`` are given, and
    that every Ipopt return code comes back: Pyomo's solver raised ``KeyError: b'Unknown
    status'`` on a solve that ran out of the run's wall-clock time (Ipopt's -5, which
    cyipopt has no message for), so a time limit read as an error and its iterate was lost
    (unseen19 f4). Returns (Ipopt's status message, the PyomoNLP, Ipopt's return code, what
    ``start_options.adapted`` changed). Models with grey-box blocks are not handled here."""
    from pyomo.common.tee import capture_output
    from pyomo.contrib.pynumero.interfaces.cyipopt_interface import CyIpoptNLP
    nlp = pynumero_nlp(model)
    problem = CyIpoptNLP(nlp, intermediate_callback=callback)
    obj, xs, gs = problem.scaling_factors()
    if any(f is not None for f in (obj, xs, gs)):       # ocdsl/solve/scaling.py
        import numpy as np

        problem.set_problem_scaling(1.0 if obj is None else obj,
                                    np.ones(len(problem.x_lb())) if xs is None else xs,
                                    np.ones(len(problem.g_lb())) if gs is None else gs)
    opts, changed = adapted(opts, given, problem.gradient, problem.x_init(), problem.x_lb(), problem.x_ub(),
                            any(f is not None for f in (obj, xs, gs)))
    for k, v in opts.items():
        problem.add_option(k, v)
    start = {} if multipliers is None else _start_multipliers(
        multipliers, nlp.get_pyomo_constraints(), nlp.get_pyomo_variables(), problem.x_lb(), problem.x_ub())
    try:
        with capture_output(sys.stdout if verbose else None, capture_fd=True):
            x, info = problem.solve(problem.x_init(), **start)
        nlp.set_primals(x)
        nlp.set_duals(info["mult_g"])
        nlp.load_state_into_pyomo(bound_multipliers=(info["mult_x_L"], info["mult_x_U"]))
    finally:
        problem.close()
    return info["status_msg"], nlp, info["status"], changed
