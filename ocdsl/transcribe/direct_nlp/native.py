"""Node functions compiled to machine code: the C twin of a family's NumPy source, made by the
system's C compiler once per content and kept in the disk cache beside the JSON entry.

Why: a generated NumPy function pays about 1 us of interpreter and ufunc overhead per
operation, whatever the number of nodes. Seed 0's 6-DOF dynamics have about 1,500 operations in
their second derivatives, so on its 60 nodes a Hessian took 0.8 ms in NumPy and 0.05 ms
compiled, and each of its 8 starts evaluates 55-127 of them (CasADi runs the same expressions
in its SX virtual machine, in C). Families whose NumPy source is shorter than ``MIN_LINES``
stay NumPy: there the overhead is small and a compile (about 0.1 s, once per content) would
only slow the first run. Where no compiler is found
or a compile fails, the family stays NumPy, and ``DirectNLP.info()`` says which it took.

The C function of a list of expressions is ``void NAME(const double *in, double *out, long C)``:
``in[i * C + n]`` is argument i at node n, ``out[r * C + n]`` row r at node n, the same
common subexpressions as the NumPy source, and no floating-point contraction (``a*b + c``
rounds as NumPy rounds it).
"""
from __future__ import annotations

import ctypes
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

# total lines (common subexpressions + rows) of a family's three NumPy sources from which it is
# compiled: seed 0's dynamics have 986, the next largest in configs/ (min_time_to_climb's
# tables) far fewer; reports/bench/seed0.md
MIN_LINES = 400
# -O0: seed 0's 1,059 lines compile in 0.14 s against 0.80 s at -O1 and evaluate in 82 against
# 48 us per point (values, first and second derivatives at 60 nodes): the compile is paid on
# every cold run, the difference in evaluation is 25 ms over seed 0's 742 iterations
FLAGS = ("-O0", "-fPIC", "-shared", "-ffp-contract=off", "-fno-math-errno")
NAMES = ("values", "first", "second")

_PRINTER: list = []
_LOADED: dict[str, object] = {}


def _printer():
    """C99's printer, plus the functions of ocdsl's own that codegen._SMOOTH admits."""
    if not _PRINTER:
        from sympy.printing.c import C99CodePrinter

        class _Printer(C99CodePrinter):
            def _ramp(self, e, power: int) -> str:
                base = f"fmax({self._print(e.args[0])}, 0.0)"
                return base if power == 1 else f"pow({base}, {power}.0)"

            def _print_r1(self, e):
                return self._ramp(e, 1)

            def _print_r2(self, e):
                return self._ramp(e, 2)

            def _print_r3(self, e):
                return self._ramp(e, 3)

            def _print_Heaviside(self, e):     # numpy.heaviside(x, 0.5)
                x = self._print(e.args[0])
                return f"(({x}) > 0.0 ? 1.0 : (({x}) < 0.0 ? 0.0 : 0.5))"

            def _print_safe_exp(self, e):
                return f"exp({self._print(e.args[0])})"

        _PRINTER.append(_Printer())
    return _PRINTER[0]


def function_source(name: str, args, reps, red) -> str:
    """C source of ``name`` computing the rows ``red`` after the common subexpressions ``reps``
    (``sympy.cse``'s output) of the arguments ``args`` at every node."""
    pr = _printer()
    lines = [f"void {name}(const double *in, double *out, long C) {{",
             "  for (long n = 0; n < C; n++) {"]
    lines += [f"    const double {a} = in[{i} * C + n];" for i, a in enumerate(args)]
    lines += [f"    const double {s} = {pr.doprint(e)};" for s, e in reps]
    lines += [f"    out[{i} * C + n] = {pr.doprint(e)};" for i, e in enumerate(red)]
    lines += ["  }", "}"]
    return "\n".join(lines) + "\n"


def module_source(functions: dict[str, str]) -> str:
    return "#include <math.h>\n\n" + "\n".join(functions[k] for k in NAMES if k in functions)


def _compiler() -> str | None:
    return os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")


def _compile(source: str, target: Path, cc: str) -> None:
    """Compile ``source`` into the shared library ``target`` through temporary files in its
    folder and a rename (concurrent runs never load a half-written library)."""
    with tempfile.TemporaryDirectory(dir=target.parent, prefix=".cc-") as tmp:
        c_file, so_file = Path(tmp) / "f.c", Path(tmp) / "f.so"
        c_file.write_text(source)
        subprocess.run([cc, *FLAGS, "-o", str(so_file), str(c_file), "-lm"], check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, timeout=300)
        os.replace(so_file, target)


def load(source: str) -> tuple[dict | None, str]:
    """({name: callable f(*cols, out)}, "") for the functions in ``source``, compiled (or
    found compiled in the cache), or (None, why not)."""
    from ... import cache

    cc = _compiler()
    if cc is None:
        return None, "no C compiler"
    key = cache.fingerprint(source, cc, " ".join(FLAGS))
    lib = _LOADED.get(key)
    if lib is None:
        try:
            if cache.enabled():
                target = cache.folder("nlp") / f"{key}.so"
                if not target.exists():
                    _compile(source, target, cc)
                lib = ctypes.CDLL(str(target))
            else:        # nothing kept: the library lives in memory after dlopen
                with tempfile.TemporaryDirectory(prefix="ocdsl-cc-") as tmp:
                    target = Path(tmp) / f"{key}.so"
                    _compile(source, target, cc)
                    lib = ctypes.CDLL(str(target))
        except (OSError, subprocess.SubprocessError) as e:
            return None, f"C compile failed, {type(e).__name__}"
        _LOADED[key] = lib
    out = {}
    for name in NAMES:
        fn = getattr(lib, name, None)
        if fn is not None:
            fn.argtypes, fn.restype = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_long], None
            out[name] = _caller(fn)
    return out, ""


def _caller(fn):
    """``f(Y, out)`` as _Family calls its functions: ``Y`` the C-ordered float64 (arguments,
    nodes) array, ``out`` a C-ordered (rows, nodes) array (one pointer each: building a
    pointer per argument cost more than the compiled function itself)."""
    def f(Y, out):
        fn(Y.ctypes.data, out.ctypes.data, out.shape[1])
        return out
    return f
