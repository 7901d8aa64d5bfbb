"""``method: {transcription: flat-bspline, ...}``: flat outputs + B-spline collocation.

Example (seed 2, the lunar lander)::

    method:
      transcription: flat-bspline
      flat_outputs: [r, theta]      # or per phase {braking: [r, theta], descent: [r]};
                                    # omitted: ocdsl searches small sets of states
      degree: 5                     # spline degree (order 6)
      control_points: 15            # per unknown function (10 pieces + degree)
      collocation_points: 15        # where the residual equations are enforced
      collocation: uniform          # or interior (ends excluded)
      starts: 8                     # the guess, then 7 perturbed copies; best kept
      seed: 0                       # start i perturbs with seed + i
      spread: 0.02                  # std. dev. of the perturbation of the scaled control points

Registered with :mod:`ocdsl.methods`; the runner lives in
:mod:`ocdsl.transcribe.flat_bspline_problem` (imported only when a file is solved, so
that ``ocdsl check`` stays free of Pyomo). See docs/flatness.md.
"""
from __future__ import annotations

from typing import Literal, Union

from pydantic import BaseModel, ConfigDict, Field, model_validator

from ..methods import register_method, register_runner


class FlatBSplineMethod(BaseModel):
    model_config = ConfigDict(extra="forbid")

    transcription: Literal["flat-bspline"] = "flat-bspline"
    degree: int = Field(5, ge=1, le=15, description="B-spline degree p (order p + 1)")
    control_points: int = Field(15, ge=2, le=2000, description="control points per unknown function")
    collocation_points: int = Field(15, ge=1, le=20000, description="collocation points of the residuals")
    collocation: Literal["uniform", "interior"] = Field(
        "uniform", description="uniform points with both ends, or uniform interior points")
    flat_outputs: Union[list[str], dict[str, list[str]], None] = Field(
        None, description="flat outputs (state names): one list for every phase, or per phase; "
                          "omitted: searched automatically")
    residual: Literal["collocation", "galerkin"] = Field(
        "galerkin", description="galerkin: each residual's weighted mean against every one of "
        "collocation_points test B-splines == 0 (it cannot be spent between points); collocation: each "
        "residual == 0 at the collocation points (the seed's method; the residual between them is free, "
        "and grows as points are added)")
    quadrature: int = Field(0, ge=0, le=50, description="Gauss-Legendre points per span of the Galerkin "
                            "integrals (0: degree + 2)")
    tolerance: Union[float, None] = Field(
        None, gt=0, lt=1, description="verify the result at this tolerance (ocdsl/verify) and, while it "
        "fails, double the knot spans and solve again from the previous level")
    refinements: int = Field(5, ge=0, le=12, description="doublings at most (with tolerance)")
    refine_residual: Literal["collocation", "galerkin"] = Field(
        "galerkin", description="the residual of the refined levels; a first level with another residual "
        "is first solved again with this one at the same size")
    dense_points: int = Field(201, ge=2, le=100000,
                              description="points per phase of the reconstructed trajectory")
    starts: int = Field(1, ge=1, le=1000, description="solves from the guess and from perturbed copies of "
                        "it; the best is kept")
    seed: int = Field(0, description="seed of the perturbations (start i uses seed + i)")
    spread: float = Field(0.02, gt=0, le=0.5, description="standard deviation of the perturbation of every "
                          "scaled control point (each flat output is scaled to [0, 1] by its bounds)")

    @model_validator(mode="after")
    def _check(self):
        if self.control_points < self.degree + 1:
            raise ValueError(f"control_points = {self.control_points} must be at least degree + 1 = "
                             f"{self.degree + 1}")
        if self.residual == "galerkin" and self.collocation_points < self.degree + 1:
            raise ValueError(f"residual: galerkin needs collocation_points (test functions) >= degree + 1 = "
                             f"{self.degree + 1}")
        if isinstance(self.flat_outputs, list) and not self.flat_outputs:
            raise ValueError("flat_outputs: give at least one state (or omit it for the search)")
        return self

    def problems_with(self, problem) -> list[tuple[tuple, str]]:
        """Flat outputs that are not states of their phase, and phases the mapping names
        that the problem does not have, as (key path under ``method``, message): at compile
        time (``ocdsl check``), not in the run (unseen9 F4)."""
        from ..hints import did_you_mean

        phases = {ph.name: ph for ph in problem.phases}
        out = []
        if isinstance(self.flat_outputs, dict):
            for name in self.flat_outputs:
                if name not in phases:
                    out.append((("flat_outputs", name), f"'{name}' is not a phase" + did_you_mean(name, list(phases))))
        for name, ph in phases.items():
            states = [s.name for s in ph.states]
            unknown = [o for o in self.outputs_for(name) or [] if o not in states]
            if unknown:
                where = ("flat_outputs", name) if isinstance(self.flat_outputs, dict) else ("flat_outputs",)
                out.append((where, f"flat output(s) {', '.join(unknown)} not states of "
                                   + (f"phase '{name}'" if len(phases) > 1 else "the model")
                                   + did_you_mean(unknown[0], states) + f"; states: {', '.join(states)}"))
        return out

    def outputs_for(self, phase: str) -> list[str] | None:
        if self.flat_outputs is None or isinstance(self.flat_outputs, list):
            return self.flat_outputs
        return self.flat_outputs.get(phase)


def _run(file, timer, *, seed=None, warm_start=None, verbose=False, progress=False):
    from .flat_bspline_problem import run_flat_file

    return run_flat_file(file, timer, seed=seed, warm_start=warm_start, verbose=verbose,
                         progress=progress)


register_method("flat-bspline", FlatBSplineMethod)
register_runner("flat-bspline", _run)
