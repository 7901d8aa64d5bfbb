"""Generate a stand-alone CasADi script from a symbolic Problem, with ocdsl's transcription.

The script is what a user who knows CasADi would write by hand for the same problem: SX
symbols for the state nodes, controls, free t0/tf and free parameters; the dynamics,
path constraints, integrands, boundary constraints and objective as CasADi expressions
(SymPy -> Python source through ``sympy.lambdify`` with CasADi function names and common
subexpressions); the collocation equations ``D @ X = scale * F`` per segment with ocdsl's
nodes and matrices; box bounds as variable bounds and boundary values fixed by an
equality as fixed variables (``lbx == ubx``, which Ipopt removes); ocdsl's initial guess;
and ocdsl's Ipopt options. Every number is embedded in the script, so running it imports
only CasADi and NumPy.

CasADi is installed with ocdsl (ocdsl's direct NLP calls its build of Ipopt); this module does not import it. The
generated script prints one JSON line: stage times, NLP size, status, objective.
"""
from __future__ import annotations

import inspect
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import sympy as sp
from sympy.printing.pycode import PythonCodePrinter

from ..symbolic.model import TIME
from ..symbolic.problem import Problem

# names the printed code uses -> CasADi (imported in the script's header)
CASADI_HEADER = (
    "from casadi import (sin, cos, tan, asin, acos, atan, atan2, sinh, cosh, tanh, asinh, acosh,\n"
    "                    atanh, exp, log, sqrt, fabs, sign, fmin, fmax, floor, ceil)\n"
    "from math import pi, e, inf\n"
    "Abs = fabs\n"
)


class _CasadiPrinter(PythonCodePrinter):
    """Python code with bare function names (``sin``, ``sqrt``...), resolved to CasADi's."""

    def __init__(self):
        super().__init__({"fully_qualified_modules": False, "inline": True, "allow_unknown_functions": True})

    def _print_Abs(self, expr):
        return f"fabs({self._print(expr.args[0])})"

    def _nested(self, fn, expr):
        """fn(fn(a, b), c) ...: CasADi's fmax/fmin take two arguments."""
        args = [self._print(a) for a in expr.args]
        out = args[0]
        for a in args[1:]:
            out = f"{fn}({out}, {a})"
        return out

    def _print_Max(self, expr):
        return self._nested("fmax", expr)

    def _print_Min(self, expr):
        return self._nested("fmin", expr)


def function_source(name: str, args, exprs) -> str:
    """Python source of ``def name(*args): return [exprs]`` in CasADi names, with CSE."""
    exprs = [sp.sympify(e) for e in exprs]
    fn = sp.lambdify(list(args), exprs, modules=[{}], printer=_CasadiPrinter(), cse=True, docstring_limit=0)
    src = inspect.getsource(fn)
    return src.replace("def _lambdifygenerated(", f"def {name}(", 1)


def _f(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


def problem_data(problem: Problem, meshes: dict, guesses: dict | list[dict]) -> tuple[dict, str]:
    """The numbers and the function sources of the script, from the same pieces ocdsl builds.

    ``guesses`` is one dict phase name -> PhaseGuess, or a list of them (one per start, as
    ``method.starts`` does in ocdsl: the script keeps the best converged start).
    """
    starts = guesses if isinstance(guesses, list) else [guesses]
    guesses = starts[0]
    from ..transcribe.mesh import Layout
    from ..transcribe.nodes import lobatto_integration_matrix

    free = sorted(problem.free_parameters, key=str)
    funcs: list[str] = []
    data: dict[str, Any] = {"name": problem.name, "sense": problem.objective.sense,
                            "free": [{"name": s.name, "lb": _f(fp.lower), "ub": _f(fp.upper),
                                      "guess": float(fp.guess)} for s, fp in
                                     ((s, problem.free_parameters[s]) for s in free)],
                            "phases": []}
    scalar_of: dict[sp.Symbol, tuple] = {s: ("param", i) for i, s in enumerate(free)}
    for p, ph in enumerate(problem.phases):
        mesh = meshes[ph.name]
        lay = Layout.of(mesh)
        args = list(ph.states) + list(ph.controls) + [TIME] + free
        tag = f"p{p}"
        funcs.append(function_source(f"{tag}_f", args, list(ph.rhs())))
        if ph.path:
            funcs.append(function_source(f"{tag}_g", args, [c.expr for c in ph.path]))
        if ph.integrals:
            funcs.append(function_source(f"{tag}_L", args, list(ph.integrals.values())))
        segs = []
        for k in range(mesh.segments):
            sc = mesh.scheme(k)
            seg = {"sup": lay.support[k].tolist(), "cs": lay.colloc_state[k].tolist(),
                   "cu": lay.colloc[k].tolist(), "half_h": (mesh.breakpoints[k + 1] - mesh.breakpoints[k]) / 2.0,
                   "scheme": sc.name, "degree": sc.degree}
            if sc.name == "LGL":
                seg["A"] = np.asarray(lobatto_integration_matrix(sc.degree)).tolist()
            else:
                seg["D"] = np.asarray(sc.D).tolist()
            if not sc.end_from_support:
                seg["end"] = int(lay.end[k])
                seg["w"] = np.asarray(sc.weights).tolist()
            segs.append(seg)
        wq = np.zeros(lay.n_colloc)
        for k in range(mesh.segments):
            sc = mesh.scheme(k)
            half_h = (mesh.breakpoints[k + 1] - mesh.breakpoints[k]) / 2.0
            wq[lay.colloc[k]] = np.asarray(sc.weights) * half_h
        per_start = []
        for gs in starts:
            gp = gs[ph.name]
            per_start.append({"xg": gp.states_at(lay.s_state).tolist(), "ug": gp.controls_at(lay.s_colloc).tolist(),
                              "t0_guess": gp.t0, "tf_guess": gp.tf})
        sb = [[_f(v) for v in ph.state_bounds.get(s, (-math.inf, math.inf))] for s in ph.states]
        cb = [[_f(v) for v in ph.control_bounds.get(c, (-math.inf, math.inf))] for c in ph.controls]
        data["phases"].append({
            "name": ph.name, "nx": len(ph.states), "nu": len(ph.controls), "N": lay.n_state_nodes,
            "C": lay.n_colloc, "cs_all": np.concatenate(lay.colloc_state).tolist(), "s_colloc": lay.s_colloc.tolist(), "segments": segs, "wq": wq.tolist(),
            "state_bounds": sb, "control_bounds": cb, "starts": per_start,
            "t0": ph.t0, "tf": ph.tf, "t0_bounds": [_f(v) for v in ph.t0_bounds],
            "tf_bounds": [_f(v) for v in ph.tf_bounds],
            "path": [[_f(c.lower), _f(c.upper)] for c in ph.path], "n_integrals": len(ph.integrals)})
        scalar_of[ph.t0_symbol] = ("t0", p) if ph.t0 is None else ("const", float(ph.t0))
        scalar_of[ph.tf_symbol] = ("tf", p) if ph.tf is None else ("const", float(ph.tf))
        for q, s in enumerate(ph.integrals):
            scalar_of[s] = ("integral", p, q)
    for s, bv in problem.boundary_values.items():
        p = next(i for i, ph in enumerate(problem.phases) if ph.name == bv.phase)
        ph = problem.phases[p]
        n = 0 if bv.which == "t0" else data["phases"][p]["N"] - 1
        scalar_of[s] = ("X", p, n, ph.states.index(bv.var))
    # boundary constraints on one variable become bounds, as in ocdsl's build()
    tighten, general = [], []
    for c in problem.boundary:
        ref = scalar_of.get(c.expr) if isinstance(c.expr, sp.Symbol) else None
        if ref is not None and ref[0] in ("X", "t0", "tf", "param"):
            tighten.append({"ref": list(ref), "lo": _f(c.lower), "hi": _f(c.upper), "eq": c.lower == c.upper})
        else:
            general.append(c)
    data["tighten"] = tighten
    syms = sorted(set().union(*[c.expr.free_symbols for c in general]), key=str) if general else []
    if general:
        funcs.append(function_source("boundary", syms, [c.expr for c in general]))
    data["boundary_args"] = [list(scalar_of[s]) for s in syms]
    data["boundary"] = [[_f(c.lower), _f(c.upper)] for c in general]
    osyms = sorted(problem.objective.expr.free_symbols, key=str)
    funcs.append(function_source("objective", osyms, [problem.objective.expr]))
    data["objective_args"] = [list(scalar_of[s]) for s in osyms]
    return data, "\n".join(funcs)


_BODY = r'''
def _col(v, n):
    """A lambdified output as an (n, 1) column (constants are broadcast)."""
    if isinstance(v, (int, float)):
        return DM.ones(n, 1) * float(v)
    return v if v.shape[0] == n else v * DM.ones(n, 1)


def _b(v, default):
    return default if v is None else v


def build(start=0):
    xs, lbx, ubx, x0 = [], [], [], []
    g, lbg, ubg = [], [], []
    phases = []

    def var(name, n, lb, ub, guess):
        v = SX.sym(name, n)
        xs.append(v)
        lbx.extend(lb)
        ubx.extend(ub)
        x0.extend(guess)
        return v, len(lbx) - n

    params, params_at = [], []
    for fp in DATA["free"]:
        v, at = var(fp["name"], 1, [_b(fp["lb"], -inf)], [_b(fp["ub"], inf)], [fp["guess"]])
        params.append(v)
        params_at.append(at)
    for p, ph in enumerate(DATA["phases"]):
        nx, nu, N, C = ph["nx"], ph["nu"], ph["N"], ph["C"]
        lb = [_b(ph["state_bounds"][j][0], -inf) for j in range(nx) for n in range(N)]
        ub = [_b(ph["state_bounds"][j][1], inf) for j in range(nx) for n in range(N)]
        gs = ph["starts"][start]
        xg = [gs["xg"][n][j] for j in range(nx) for n in range(N)]
        Xv, x_at = var(f"X{p}", N * nx, lb, ub, xg)
        X = reshape(Xv, N, nx)
        lb = [_b(ph["control_bounds"][j][0], -inf) for j in range(nu) for n in range(C)]
        ub = [_b(ph["control_bounds"][j][1], inf) for j in range(nu) for n in range(C)]
        ug = [gs["ug"][n][j] for j in range(nu) for n in range(C)]
        Uv, u_at = var(f"U{p}", C * nu, lb, ub, ug)
        U = reshape(Uv, C, nu) if nu else SX(C, 0)
        info = {"x_at": x_at, "N": N, "X": X}
        if ph["t0"] is None:
            t0, info["t0_at"] = var(f"t0_{p}", 1, [_b(ph["t0_bounds"][0], -inf)], [_b(ph["t0_bounds"][1], inf)],
                                    [gs["t0_guess"]])
        else:
            t0 = ph["t0"]
        if ph["tf"] is None:
            tf, info["tf_at"] = var(f"tf_{p}", 1, [_b(ph["tf_bounds"][0], -inf)], [_b(ph["tf_bounds"][1], inf)],
                                    [gs["tf_guess"]])
        else:
            tf = ph["tf"]
        info["t0"], info["tf"] = t0, tf
        duration = tf - t0
        t = t0 + duration * DM(ph["s_colloc"])
        fns = FUNCS[p]
        # the dynamics at every collocation node at once (elementwise SX operations)
        cols = [X[ph["cs_all"], j] for j in range(nx)]
        cols += [U[:, j] for j in range(nu)]
        F = horzcat(*[_col(v, C) for v in fns["f"](*cols, t, *params)])
        for seg in ph["segments"]:
            sup, cu = seg["sup"], seg["cu"]
            scale = duration * seg["half_h"]
            Fk = F[cu, :]
            Xs = X[sup, :]
            if "A" in seg:
                A = DM(seg["A"])
                d = Xs[1:, :] - repmat(Xs[0, :], len(sup) - 1, 1) - scale * mtimes(A[1:, :], Fk)
            else:
                d = mtimes(DM(seg["D"]), Xs) - scale * Fk
            g.append(vec(d))
            lbg.extend([0.0] * d.numel())
            ubg.extend([0.0] * d.numel())
            if "end" in seg:
                d = X[seg["end"], :] - Xs[0, :] - scale * mtimes(DM(seg["w"]).T, Fk)
                g.append(d.T)
                lbg.extend([0.0] * nx)
                ubg.extend([0.0] * nx)
        if ph["path"]:
            for (lo, hi), v in zip(ph["path"], fns["g"](*cols, t, *params)):
                g.append(_col(v, C))
                lbg.extend([_b(lo, -inf)] * C)
                ubg.extend([_b(hi, inf)] * C)
        info["integrals"] = []
        if ph["n_integrals"]:
            wq = DM(ph["wq"])
            info["integrals"] = [duration * dot(wq, _col(v, C)) for v in fns["L"](*cols, t, *params)]
        phases.append(info)

    def scalar(ref):
        kind = ref[0]
        if kind == "param":
            return params[ref[1]]
        if kind == "const":
            return ref[1]
        if kind in ("t0", "tf"):
            return phases[ref[1]][kind]
        if kind == "integral":
            return phases[ref[1]]["integrals"][ref[2]]
        return phases[ref[1]]["X"][ref[2], ref[3]]

    def index(ref):
        kind = ref[0]
        if kind == "param":
            return params_at[ref[1]]
        if kind in ("t0", "tf"):
            return phases[ref[1]][kind + "_at"]
        ph = phases[ref[1]]
        return ph["x_at"] + ref[3] * ph["N"] + ref[2]

    global _INDEX
    _INDEX = index
    for c in DATA["tighten"]:
        i = index(c["ref"])
        if c["eq"]:
            lbx[i] = ubx[i] = x0[i] = c["lo"]
            continue
        if c["lo"] is not None:
            lbx[i] = max(lbx[i], c["lo"])
        if c["hi"] is not None:
            ubx[i] = min(ubx[i], c["hi"])
    if DATA["boundary"]:
        vals = boundary(*[scalar(r) for r in DATA["boundary_args"]])
        for (lo, hi), v in zip(DATA["boundary"], vals):
            g.append(v)
            lbg.append(_b(lo, -inf))
            ubg.append(_b(hi, inf))
    J = objective(*[scalar(r) for r in DATA["objective_args"]])[0]
    if DATA["sense"] == "maximize":
        J = -J
    nlp = {"x": vertcat(*xs), "f": J, "g": vertcat(*g)}
    return nlp, lbx, ubx, x0, lbg, ubg


def initial_guess(start):
    """x0 of another start (same variable order as build())."""
    x0 = [fp["guess"] for fp in DATA["free"]]
    for ph in DATA["phases"]:
        gs, nx, nu, N, C = ph["starts"][start], ph["nx"], ph["nu"], ph["N"], ph["C"]
        x0 += [gs["xg"][n][j] for j in range(nx) for n in range(N)]
        x0 += [gs["ug"][n][j] for j in range(nu) for n in range(C)]
        if ph["t0"] is None:
            x0.append(gs["t0_guess"])
        if ph["tf"] is None:
            x0.append(gs["tf_guess"])
    for c in DATA["tighten"]:
        if c["eq"]:
            x0[_INDEX(c["ref"])] = c["lo"]
    return x0


_INDEX = None


def main():
    import argparse
    import json
    import resource
    import time as _time

    ap = argparse.ArgumentParser()
    ap.add_argument("--no-solve", action="store_true")
    ap.add_argument("--repeat", type=int, default=1, help="build + nlpsol this many times (CPU medians)")
    a = ap.parse_args()
    out = {"import": _T_IMPORT}
    cpu_b, cpu_h = [], []
    for _ in range(max(1, a.repeat)):
        t, c = _time.perf_counter(), _time.process_time()
        nlp, lbx, ubx, x0, lbg, ubg = build()
        out["build"] = _time.perf_counter() - t
        cpu_b.append(_time.process_time() - c)
        t, c = _time.perf_counter(), _time.process_time()
        solver = nlpsol("solver", "ipopt", nlp, {"ipopt": OPTIONS, "print_time": False})
        out["handover"] = _time.perf_counter() - t
        cpu_h.append(_time.process_time() - c)
    out["build_cpu"] = sorted(cpu_b)[len(cpu_b) // 2]
    out["handover_cpu"] = sorted(cpu_h)[len(cpu_h) // 2]
    out["variables"], out["constraints"] = nlp["x"].numel(), nlp["g"].numel()
    if not a.no_solve:
        t = _time.perf_counter()
        best = None
        for start in range(len(DATA["phases"][0]["starts"])):
            if start:
                x0 = initial_guess(start)
            sol = solver(x0=x0, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
            st = solver.stats()
            f = float(sol["f"])
            ok = st["return_status"] in ("Solve_Succeeded", "Solved_To_Acceptable_Level")
            if best is None or (ok and (not best[0] or f < best[1])):
                best = (ok, f, st["return_status"], st["iter_count"])
        out["solve"] = _time.perf_counter() - t
        out["starts"] = len(DATA["phases"][0]["starts"])
        out["status"], out["iterations"] = best[2], best[3]
        out["objective"] = -best[1] if DATA["sense"] == "maximize" else best[1]
    out["peak_rss_kb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print("CASADI_RESULT " + json.dumps(out))


if __name__ == "__main__":
    main()
'''


def generate(problem: Problem, meshes: dict, guesses: dict, options: dict[str, Any]) -> str:
    """Source of the CasADi script of ``problem`` on ``meshes`` from ``guesses`` with Ipopt ``options``."""
    data, funcs = problem_data(problem, meshes, guesses)
    per_phase = []
    for p, ph in enumerate(problem.phases):
        names = {"f": f"p{p}_f"}
        if ph.path:
            names["g"] = f"p{p}_g"
        if ph.integrals:
            names["L"] = f"p{p}_L"
        per_phase.append("{" + ", ".join(f"{k!r}: {v}" for k, v in names.items()) + "}")
    return "\n".join([
        f'"""CasADi script generated by ocdsl from problem {problem.name!r}: same transcription,',
        'mesh, bounds, guess and Ipopt options as `ocdsl run`. Prints one JSON line."""',
        "import time as _t",
        "_T0 = _t.perf_counter()",
        "from casadi import (DM, SX, dot, horzcat, mtimes, nlpsol, repmat, reshape, vec, vertcat)",
        CASADI_HEADER,
        "_T_IMPORT = _t.perf_counter() - _T0",
        "",
        f"DATA = __import__('json').loads({json.dumps(data)!r})",
        f"OPTIONS = __import__('json').loads({json.dumps(options)!r})",
        "",
        funcs,
        f"FUNCS = [{', '.join(per_phase)}]",
        _BODY,
    ])


def ipopt_options(file_options: dict[str, Any]) -> dict[str, Any]:
    """ocdsl's Ipopt options for a file (what ``ocdsl.solve.ipopt.solve`` passes, not verbose)."""
    from ..solve.ipopt import DEFAULT_OPTIONS

    opts = {**DEFAULT_OPTIONS, **(file_options or {})}
    opts.setdefault("print_level", 0)
    opts.setdefault("sb", "yes")
    return opts


def write_script(path: str | Path, file, segments: int | None = None,
                 extra_options: dict[str, Any] | None = None) -> Path:
    """Write the CasADi script of a compiled problem file (``ocdsl.api.compile_file``)."""
    from ..transcribe.guess import start_guesses
    from ..transcribe.mesh import Mesh

    problem, method = file.problem, file.method
    segs = segments if segments is not None else method.segments
    meshes = {ph.name: Mesh.uniform(method.transcription, segs, method.degree) for ph in problem.phases}
    starts = getattr(method, "starts", 1)
    guesses = [start_guesses(problem, {}, i, None, method.seed) for i in range(starts)]   # as ocdsl.run does
    opts = {**ipopt_options(file.spec.solver.options), **(extra_options or {})}
    path = Path(path)
    path.write_text(generate(problem, meshes, guesses, opts))
    return path
