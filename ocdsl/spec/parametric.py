"""``method: {transcription: parametric, ...}``: controls as series, global search (PSO).

Example (seed 1, 10 N)::

    method:
      transcription: parametric
      controls:
        delta: {series: fourier, order: 5, bounds: [-1.0, 1.0], a0: [-3.2, 3.2]}
        phi:   {series: fourier, order: 8, bounds: [-0.5, 0.5], a0: [2.6, 3.7]}
      parameters:
        N_rev: {integer: true, bounds: [3, 8]}
      tolerances: {r: 1.0e-3, theta: 1.0e-3, z: 1.0e-3, rdot: 1.0e-3, thetadot: 1.0e-3, zdot: 1.0e-3}
      integrator: {rtol: 1.0e-8, atol: 1.0e-10, sundman_k: 1.5}
      optimizer:
        name: pso
        particles: 64
        iterations: 500
        inertia: [0.9, 0.4]
        c1: 2.0
        c2: 2.0
        velocity_limit: 0.2
        discrete: jin
        stall_iterations: 150
        seed: 1

``tolerances`` are the zeta_i of the paper's normalised penalty, keyed by the state whose
final value a terminal equality constraint fixes (``default`` for the others); the fitness
is tf + sum max((|error_i| - zeta_i)/zeta_i, 0) (digest eqs. 32-35).
"""
from __future__ import annotations

import math

from typing import Literal, Optional

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class SeriesSpec(_Strict):
    """One control written as a series over [0, tf] (tau = t/tf for polynomials)."""

    series: Literal["fourier", "polynomial", "constant"] = "fourier"
    order: int = Field(0, description="Fourier order N (a0, a1..aN, b1..bN) or polynomial degree")
    bounds: tuple[float, float] = Field((-1.0, 1.0), description="search box of the coefficients")
    a0: Optional[tuple[float, float]] = Field(None, description="search box of the constant term (default: bounds)")
    decay: float = Field(0.0, ge=0.0, le=4.0, description="box of the order-n coefficients scaled by n**-decay")

    @field_validator("order")
    @classmethod
    def _order(cls, v):
        if v < 0:
            raise ValueError(f"series order must be >= 0, got {v}")
        if v > 200:
            raise ValueError(f"series order {v} is unreasonably large (max 200)")
        return v

    @model_validator(mode="after")
    def _check(self):
        for name, b in (("bounds", self.bounds), ("a0", self.a0)):
            if b is not None and not b[0] < b[1]:
                raise ValueError(f"{name} must be [lower, upper] with lower < upper, got {list(b)}")
        return self


class SearchParameter(_Strict):
    """A decision parameter of the search (continuous, or integer with ``integer: true``)."""

    integer: bool = False
    bounds: Optional[tuple[float, float]] = None

    @model_validator(mode="after")
    def _check(self):
        if self.bounds is None:
            kind = "an integer parameter" if self.integer else "a search parameter"
            raise ValueError(f"{kind} needs bounds: [lower, upper]")
        if not self.bounds[0] <= self.bounds[1]:
            raise ValueError(f"bounds reversed: {list(self.bounds)}")
        # an infinite bound ended in OverflowError (int(inf)), a traceback from `check` (fuzzing)
        if self.integer and any(not math.isfinite(float(b)) or float(b) != int(b) for b in self.bounds):
            raise ValueError(f"integer parameter bounds must be finite integers, got {list(self.bounds)}")
        return self


class PSOSpec(_Strict):
    """Particle swarm settings (defaults are the digest's suggestions, §7 item 13)."""

    name: Literal["pso"] = "pso"
    particles: int = Field(64, ge=2, le=100_000)
    iterations: int = Field(500, ge=1, le=10_000_000)
    inertia: tuple[float, float] = Field((0.9, 0.4), description="linear schedule [start, end]")
    c1: float = Field(2.0, ge=0.0, le=4.0, description="cognitive coefficient")
    c2: float = Field(2.0, ge=0.0, le=4.0, description="social coefficient")
    velocity_limit: float = Field(0.2, gt=0.0, le=1.0, description="max |v| as a fraction of each box width")
    discrete: Literal["jin", "round"] = Field("jin", description="integer coordinates: lattice moves (jin) or rounding at evaluation")
    stall_iterations: int = Field(0, ge=0, description="stop after this many iterations without improvement (0: never)")
    tolerance: float = Field(0.0, ge=0.0, description="improvement below this counts as none")
    target: Optional[float] = Field(None, description="stop when the best fitness is at or below this")
    seed: int = 0
    chunks: int = Field(0, ge=0, description="batches per iteration given to the executor (0: one per worker)")
    restarts: int = Field(1, ge=1, le=1000, description="independent swarms (seeds seed, seed+1, ...); the lowest best fitness is kept")
    topology: Literal["global", "ring"] = Field("global", description="social attractor: swarm best (global) or best of i-1, i, i+1 (ring)")

    @field_validator("inertia")
    @classmethod
    def _inertia(cls, v):
        for w in v:
            if not 0.0 <= w <= 1.2:
                raise ValueError(f"inertia weights must lie in [0, 1.2], got {list(v)}")
        return v

    @model_validator(mode="after")
    def _check(self):
        if self.c1 + self.c2 <= 0:
            raise ValueError("c1 + c2 must be positive")
        return self


class IntegratorSpec(_Strict):
    rtol: float = Field(1e-8, gt=0.0, le=1e-2)
    atol: float = Field(1e-10, gt=0.0, le=1e-2)
    sundman_k: Optional[float] = Field(None, description="Sundman exponent (model must offer the option)")
    sundman_c: float = Field(1.0, gt=0.0)
    sundman_distance: Optional[str] = Field(None, description="state or named expression R (default R_SE, then r)")
    max_steps: int = Field(200_000, ge=10)


class PolishSpec(_Strict):
    """Optional local polish of the best particle (not in the seed paper; reported apart).

    ``least_squares``: with the integers and tf fixed at the swarm's best, SciPy's
    trust-region least squares drives the terminal errors / zeta to zero over the
    continuous coefficients (Jacobian by forward differences, evaluated as one batch).
    """

    method: Literal["none", "least_squares"] = "none"
    max_iterations: int = Field(50, ge=1, le=10_000)
    fd_step: float = Field(1e-6, gt=0.0, le=1e-2, description="forward-difference step, fraction of each box width")
    free_tf: bool = Field(False, description="let the polish move tf too (default: tf stays at the swarm's value)")


class ContinuationSpec(_Strict):
    """Optional continuation in tf after the polish (not in the seed paper; reported apart).

    The swarm's fitness tf + sum of normalised penalties is dominated by the penalties, so
    the swarm's tf is only loosely determined. From the polished best (inside the zeta
    box), with the integers fixed, tf is lowered by ``step`` (fraction of tf) and the
    least-squares polish restores every |error|/zeta <= ``target_ratio`` from the previous
    coefficients (the series are in t/tf, so the same coefficients give the same angle
    history in normalised time); a success keeps the point and multiplies the step by
    ``grow``, a failure halves it; it stops below ``min_step`` or after ``max_steps``
    polishes. Each polish may use ``evaluations_per_step`` integrations. When the polish
    with tf fixed left the swarm's best outside the box, one polish with tf free (either
    direction) is tried first (``extra.continuation.restored_with_free_tf``).
    """

    enabled: bool = False
    step: float = Field(0.02, gt=0.0, le=0.5, description="first decrease of tf, fraction of tf")
    min_step: float = Field(1e-3, gt=0.0, le=0.5, description="stop when the step falls below this fraction of tf")
    grow: float = Field(1.5, ge=1.0, le=4.0)
    target_ratio: float = Field(0.5, gt=0.0, le=1.0, description="each polish stops once every |error|/zeta is at or below this")
    max_steps: int = Field(40, ge=1, le=10_000)
    evaluations_per_step: int = Field(2000, ge=10, le=10_000_000)

    @model_validator(mode="after")
    def _check(self):
        if self.min_step > self.step:
            raise ValueError(f"min_step {self.min_step} exceeds step {self.step}")
        return self


class RefineSpec(_Strict):
    """Optional constrained local minimisation of the objective (tf in the seed paper) after
    the continuation (not in the seed paper; reported apart in ``extra.refine``).

    ``slsqp``: with the integers fixed, SciPy's SLSQP minimises the objective subject to
    ``|error_i| / zeta_i <= target_ratio`` for every terminal constraint, over tf and the
    continuous coefficients (Jacobians by forward differences, one batch per iteration).
    Unlike the continuation, which only moves tf while restoring feasibility, it trades tf
    against the terminal errors at once, i.e. it converges to a local minimum of the
    paper's problem (min tf inside the zeta box). ``box_scale`` widens the coefficient box
    about its centre for this stage only (the swarm's box is a search range, not a
    constraint of the problem; 1 keeps it). When SLSQP stops with its last iterate outside
    the zeta box at a lower tf than the best so far, that iterate is restored: least squares
    over the coefficients (tf fixed, at most ``restore_iterations`` evaluations) drives its
    errors back inside the box. When SLSQP stopped on a failed line search, or a restoration
    succeeded, it is restarted, up to ``restarts`` times, from the fastest point inside the
    zeta box. A result outside the box or with a larger tf than its start is rejected.
    """

    method: Literal["none", "slsqp"] = "none"
    max_iterations: int = Field(300, ge=1, le=100_000)
    target_ratio: float = Field(0.9, gt=0.0, le=1.0, description="bound on every |error|/zeta")
    box_scale: float = Field(1.0, ge=1.0, le=100.0, description="coefficient box widened about its centre by this factor")
    fd_step: float = Field(1e-6, gt=0.0, le=1e-2, description="forward-difference step, fraction of each box width")
    restarts: int = Field(3, ge=0, le=100, description="SLSQP restarts from the fastest point inside the box after a failed line search or a restoration")
    restore_iterations: int = Field(300, ge=1, le=100_000, description="least-squares evaluations to bring an iterate outside the zeta box back inside at its tf")


class ParametricSpec(_Strict):
    transcription: Literal["parametric"] = "parametric"
    controls: dict[str, SeriesSpec]
    parameters: dict[str, SearchParameter] = Field(default_factory=dict)
    tolerances: dict[str, float] = Field(default_factory=dict, description="zeta per terminal state ('default' for the rest)")
    penalty: Literal["normalized"] = "normalized"
    guards: dict[str, tuple[float, float]] = Field(default_factory=dict, description="state -> [min, max]; leaving it ends the run as a failure")
    failure_fitness: float = Field(1e6, description="fitness of a run whose integration failed")
    integrator: IntegratorSpec = Field(default_factory=IntegratorSpec)
    optimizer: PSOSpec = Field(default_factory=PSOSpec)
    polish: PolishSpec = Field(default_factory=PolishSpec)
    continuation: ContinuationSpec = Field(default_factory=ContinuationSpec)
    refine: RefineSpec = Field(default_factory=RefineSpec)
    output_points: int = Field(2000, ge=10)
    threads: bool = Field(True, description="in-process evaluation over all cores (threads running the compiled batch)")

    @field_validator("tolerances")
    @classmethod
    def _zeta(cls, v):
        for k, z in v.items():
            if not (z > 0):
                raise ValueError(f"tolerance zeta for {k!r} must be > 0, got {z}")
        return v

    @field_validator("guards")
    @classmethod
    def _guards(cls, v):
        for k, b in v.items():
            if not b[0] < b[1]:
                raise ValueError(f"guard for {k!r} must be [min, max] with min < max, got {list(b)}")
        return v

    @field_validator("controls")
    @classmethod
    def _controls(cls, v):
        if not v:
            raise ValueError("at least one control must be given as a series")
        return v

    @model_validator(mode="after")
    def _continuation_needs_polish(self):
        if self.continuation.enabled and self.polish.method == "none":
            raise ValueError("continuation in tf needs polish: {method: least_squares}")
        return self

    def problems_with(self, problem) -> list[tuple[tuple, str]]:
        """What this block names that the problem does not have, as (key path under
        ``method``, message): checked when the file is compiled (``ocdsl check``), not when
        the search starts (unseen9 F4: `thetta` passed the check, the run ended with a
        traceback in its message)."""
        from ..hints import did_you_mean

        ph = problem.phases[0]
        controls = [c.name for c in ph.controls]
        states = [s.name for s in ph.states]
        out = []
        for name in self.controls:
            if name not in controls:
                out.append((("controls", name), f"'{name}' is not a control of the model"
                            + did_you_mean(name, controls) + f"; controls: {', '.join(controls)}"))
        missing = [c for c in controls if c not in self.controls]
        if missing:
            out.append((("controls",), f"no series for the control(s) {', '.join(missing)}: "
                                       "give one for every control of the model"))
        for key in ("tolerances", "guards"):
            for name in getattr(self, key):
                if name not in states and not (key == "tolerances" and name == "default"):
                    out.append(((key, name), f"'{name}' is not a state of the model"
                                + did_you_mean(name, states) + f"; states: {', '.join(states)}"))
        bounded = [f"{lo:g} <= {s.name} <= {hi:g}" if math.isfinite(lo) and math.isfinite(hi)
                   else f"{s.name} <= {hi:g}" if math.isfinite(hi) else f"{s.name} >= {lo:g}"
                   for s, (lo, hi) in ph.state_bounds.items() if math.isfinite(lo) or math.isfinite(hi)]
        if bounded or ph.path:
            # the search sees the terminal errors only: a state bound was broken by 3.3 % while
            # the run said `feasible` (unseen22 FC4: a brachistochrone under y <= 1)
            said = bounded + [c.text for c in ph.path]
            out.append(((), "the parametric method imposes conditions at t0 and tf only, not along the "
                            f"trajectory: {'; '.join(said)} would be ignored by the search. Give a state's "
                            "range as `guards: {state: [min, max]}` (a flight that leaves it fails), or use "
                            "a pseudospectral method"))
        if problem.integrals:
            # the shooting kernel integrates the states only (unseen19: `ocdsl check` said ok,
            # the run ended "unknown symbols ['integral1_main']")
            out.append(((), "the parametric method integrates the model's states only: integral(...) in the "
                            "objective or the constraints is not supported; add the integrand as a state "
                            "(q' = u**2, q(t0) == 0, minimize q(tf)), or use a pseudospectral method"))
        return out


try:  # register with the lead's method registry when it is there
    from ocdsl.methods import register_method

    register_method("parametric", ParametricSpec)
except ImportError:  # pragma: no cover
    pass
