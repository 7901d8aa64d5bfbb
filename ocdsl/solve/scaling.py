"""Automatic scaling of a built pseudospectral NLP (``scaling: {mode: auto}``).

Why: Ipopt's default gradient-based scaling scales constraints and the objective but not
the variables; a problem written in SI units mixes positions of 1e7 m, speeds of 1e3 m/s
and masses of 1e5 kg, and its iterates then move in a badly conditioned space (GPOPS-II's
four-phase launch vehicle in SI units hit max_iter). Here each variable gets a typical
magnitude and Ipopt solves in ``x / magnitude`` (``nlp_scaling_method: user-scaling``):

* a state or control: the file's ``scaling.variables`` value, else the larger magnitude of
  its finite bounds, else the largest magnitude of its starting values, else 1;
* a phase's free ``t0`` / ``tf``: ``scaling.time``, else its bounds, else its start;
* a collocation defect of state x: x's magnitude (the defect is a difference of x values);
* a path or boundary constraint: the larger magnitude of its finite bounds when not zero,
  else the largest magnitude of the variables in it;
* the objective: ``scaling.objective``, else its magnitude at the start (at least 1e-8).

Each factor is 1/magnitude in the model's ``scaling_factor`` suffix, which both Ipopt
routes read (ocdsl/solve/ipopt.py). Ipopt reports solutions and multipliers of the
unscaled problem, so nothing downstream changes.
"""
from __future__ import annotations

import math
from typing import Any


def _magnitude(*values) -> float | None:
    finite = [abs(float(v)) for v in values if v is not None and math.isfinite(float(v)) and v != 0]
    return max(finite) if finite else None


def _phase_magnitudes(tr, given: dict, time: float | None, default: float | None = 1.0):
    """Per phase: ({state, control, free t0/tf: its typical magnitude}, {name: its Pyomo
    variables}), by the rules of the module's docstring; ``default`` where none is found."""
    import pyomo.core as pyo

    out = []
    for pb in tr.phases:
        ph, b = pb.phase, pb.block
        info: dict[str, float] = {}
        datas: dict[str, list] = {}
        for group, var in (("states", b.X), ("controls", b.U)):
            names = [s.name for s in (ph.states if group == "states" else ph.controls)]
            for j, name in enumerate(names):
                datas[name] = [var[i, j] for i in sorted({k[0] for k in var.keys()})]
                s = given.get(f"{ph.name}.{name}", given.get(name))
                if s is None:
                    s = _magnitude(datas[name][0].lb, datas[name][0].ub) or \
                        _magnitude(*[d.value for d in datas[name]]) or default
                info[name] = s
        for which in ("t0", "tf"):
            comp = getattr(b, which)
            if isinstance(comp, pyo.Var):
                info[which] = time or _magnitude(comp.lb, comp.ub) or _magnitude(comp.value) or default
                datas[which] = [comp]
        out.append((info, datas))
    return out


def sizeless(tr, given: dict) -> list[str]:
    """The states and controls whose magnitude auto scaling could not find (no value given in
    ``scaling.variables``, no finite bound, every starting value 0): they take 1."""
    out = []
    for pb, (info, _) in zip(tr.phases, _phase_magnitudes(tr, given, None, default=None)):
        out += [x.name if len(tr.phases) == 1 else f"{pb.phase.name}.{x.name}"
                for x in (*pb.phase.states, *pb.phase.controls) if info[x.name] is None]
    return out


def spread(tr) -> tuple[float, str, str]:
    """(largest / smallest typical magnitude, the name of the largest, of the smallest), over
    the states, controls and free times of every phase, at the built model's start."""
    multi = len(tr.phases) > 1
    mags = {(f"{pb.phase.name}.{k}" if multi else k): v
            for pb, (info, _) in zip(tr.phases, _phase_magnitudes(tr, {}, None)) for k, v in info.items()}
    if not mags:
        return 1.0, "", ""
    hi, lo = max(mags, key=mags.get), min(mags, key=mags.get)
    return mags[hi] / mags[lo], hi, lo


def apply(tr, spec) -> dict[str, Any]:
    """Attach ``scaling_factor`` to ``tr.model`` from ``spec`` (a ScalingSpec); returns the
    magnitudes used, per phase and variable (result.json ``extra.scaling``)."""
    import pyomo.core as pyo
    from pyomo.core.expr.visitor import identify_variables

    m = tr.model
    if hasattr(m, "scaling_factor"):
        m.del_component("scaling_factor")
    m.scaling_factor = sf = pyo.Suffix(direction=pyo.Suffix.EXPORT)
    given = dict(spec.variables)
    used: dict[str, Any] = {}
    var_scale: dict[int, float] = {}

    def set_var(v, s):
        var_scale[id(v)] = s
        if not v.fixed:          # a fixed variable is not in the NLP
            sf[v] = 1.0 / s

    for pb, (info, datas) in zip(tr.phases, _phase_magnitudes(tr, given, spec.time)):
        ph = pb.phase
        for name, s in info.items():
            for d in datas[name]:
                set_var(d, s)
        for (_, _, j), c in pb.defects.items():
            sf[c] = 1.0 / info[ph.states[j].name]
        for (_, j), c in pb.ends.items():
            sf[c] = 1.0 / info[ph.states[j].name]
        used[ph.name] = info
    for v in m.component_data_objects(pyo.Var, active=True):
        if id(v) not in var_scale and not v.fixed:
            set_var(v, spec.variables.get(v.name) or _magnitude(v.lb, v.ub) or _magnitude(v.value) or 1.0)
    for c in m.component_data_objects(pyo.Constraint, active=True):
        if c in sf:
            continue
        s = _magnitude(pyo.value(c.lower) if c.has_lb() else None, pyo.value(c.upper) if c.has_ub() else None)
        if s is None:
            s = max((var_scale.get(id(v), 1.0) for v in identify_variables(c.body)), default=1.0)
        sf[c] = 1.0 / s
    for obj in m.component_data_objects(pyo.Objective, active=True):
        s = spec.objective or _magnitude(pyo.value(obj.expr, exception=False)) or \
            max((var_scale.get(id(v), 1.0) for v in identify_variables(obj.expr)), default=1.0)
        sf[obj] = 1.0 / s
        used["objective"] = s
    return used
