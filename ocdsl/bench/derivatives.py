"""Derivative generation time against model size (``python -m ocdsl.bench.derivatives``).

What the direct NLP route (``ocdsl.transcribe.direct_nlp``) does once per phase on a cold
cache: the dynamics times the duration, differentiated (nonzero first and lower-triangle
second derivatives in states, controls, t0, tf) and their common subexpressions eliminated by
SymEngine where it can, else SymPy (``ocdsl.symbolic.engine``), then printed by SymPy as NumPy
source, and as C when the sources are long
(``direct_nlp.native``). Models: the ``configs/`` dynamics, seed 0's
6-DOF rendezvous, and ``k`` independent copies of it (12 k states, 6 k controls), so that
the size grows without changing the kind of expression. Size = nodes of the dynamics'
expression DAG (distinct subexpressions, ``sympy.cse``'s view), and Hessian entries.
CPU seconds (``time.process_time``) in this process, the cache off; the exponent is the
slope of log(time) against log(nodes) over the rows of at least 100 nodes.
"""
from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np
import sympy as sp

FILES = ["double_integrator", "brachistochrone", "goddard", "moon_landing", "seed0_rendezvous",
         "seed0_exact_euler"]


def _dag_nodes(exprs) -> int:
    seen = set()
    stack = list(exprs)
    while stack:
        e = stack.pop()
        if e in seen or not e.args:
            continue
        seen.add(e)
        stack.extend(e.args)
    return len(seen)


def dynamics_family(path: Path, copies: int = 1):
    """(label, exprs, dvars, S, states, controls) of the first phase of ``path``, ``copies``
    times with renamed states and controls (t0 and tf shared)."""
    from ..api import compile_file
    from ..symbolic.model import TIME

    file = compile_file(path)
    ph = file.problem.phases[0]
    T0, TF, S = sp.Symbol("t0_"), sp.Symbol("tf_"), sp.Symbol("s_")
    base = [(TF - T0) * sp.sympify(e).subs({TIME: T0 + (TF - T0) * S}) for e in ph.rhs()]
    own = list(ph.states) + list(ph.controls)
    exprs, dvars = [], []
    for c in range(copies):
        ren = {s: sp.Symbol(f"{s.name}_{c}", **s.assumptions0) for s in own} if copies > 1 else {}
        exprs += [e.xreplace(ren) for e in base]
        dvars += [ren.get(s, s) for s in own]
    label = path.stem if copies == 1 else f"{path.stem} x{copies}"
    return label, exprs, dvars + [T0, TF], S, len(ph.states) * copies, len(ph.controls) * copies


def measure(label, exprs, dvars, S, nx, nu) -> dict:
    from ..transcribe import direct_nlp

    import resource

    from ..transcribe.direct_nlp import native

    os.environ["OCDSL_NO_CACHE"] = "1"
    t = time.process_time()
    g = direct_nlp._generated(exprs, dvars, [S], native=True)
    gen = time.process_time() - t
    t = time.process_time()
    for k in ("values", "first", "second"):
        direct_nlp._function(g[k])
    load = time.process_time() - t
    cc = None
    if g.get("c"):      # the compiler runs as a child process: its CPU is the children's
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t = time.process_time()
        fns, why = native.load(g["c"])
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        if fns is not None:
            cc = time.process_time() - t + (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    return {"model": label, "states": nx, "controls": nu, "nodes": _dag_nodes(exprs),
            "jacobian": len(g["jac"]), "hessian": len(g["hess"]),
            "source_lines": sum((g[k] or "").count("\n") for k in ("values", "first", "second")),
            "generate": gen, "compile": load, "c_compile": cc}


def table(rows: list[dict]) -> tuple[str, float | None]:
    lines = ["| model | states | controls | DAG nodes | Jacobian entries | Hessian entries | source lines | "
             "generate CPU s | compile CPU s | C compile CPU s |", "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['model']} | {r['states']} | {r['controls']} | {r['nodes']} | {r['jacobian']} | "
                     f"{r['hessian']} | {r['source_lines']} | {r['generate']:.3f} | {r['compile']:.3f} | "
                     f"{'-' if r['c_compile'] is None else format(r['c_compile'], '.3f')} |")
    big = [r for r in rows if r["nodes"] >= 100]
    p = None
    if len(big) >= 2:
        p = float(np.polyfit(np.log([r["nodes"] for r in big]), np.log([r["generate"] for r in big]), 1)[0])
    return "\n".join(lines), p


def main(argv: list[str] | None = None) -> str:
    from .core import machine

    argv = sys.argv[1:] if argv is None else argv
    configs = Path(argv[0]) if argv else Path("configs")
    rows = []
    for name in FILES:
        rows.append(measure(*dynamics_family(configs / f"{name}.yaml")))
        print(f"  {rows[-1]['model']}: {rows[-1]['generate']:.3f} s", file=sys.stderr)
    for k in (2, 4):
        rows.append(measure(*dynamics_family(configs / "seed0_rendezvous.yaml", k)))
        print(f"  {rows[-1]['model']}: {rows[-1]['generate']:.3f} s", file=sys.stderr)
    text, p = table(rows)
    doc = " ".join(__doc__.split("\n\n")[1].split())
    out = ("# Derivative generation time against model size\n\n"
           f"{machine()}, {time.strftime('%Y-%m-%d %H:%M')}. "
           f"Made by `python -m ocdsl.bench.derivatives` (`make bench-peers`). {doc}\n\n"
           "compile = `exec` of the three sources: what a run on a warm cache (ocdsl/cache.py) "
           "pays instead of generate, besides reading the JSON entry. C compile = the C compiler "
           "on the C source (its child process's CPU included), paid once per content on a cold "
           "cache; - where the family stays NumPy (shorter sources).\n\n" + text + "\n\n"
           + (f"Fitted exponent, generate CPU ~ nodes^p over rows of >= 100 nodes: p = {p:.2f}\n" if p else ""))
    return out


if __name__ == "__main__":
    print(main())
