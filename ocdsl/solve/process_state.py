"""What a solve keeps of the process around Ipopt's and the ASL's library calls: the
floating-point environment (restored) and glibc's heap top pad (set once)."""
from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import functools


@contextlib.contextmanager
def floating_point_environment_kept():
    """Restore the floating-point environment (x87 control word, MXCSR) on exit.

    The ASL sets the x87 unit to 53-bit precision whenever it reads an NL file (its
    ``fpinit``), and leaves it so for the whole process. NumPy's LAPACK then rounds
    differently: the same least-squares start of the seed 2 lander came out 3e-14 apart
    before and after the first PyNumero solve in a process, and Ipopt went from there to a
    different local optimum (t_f 1036.873 against 1037.454 s). With the environment
    restored, a run does not depend on what ran before it in the process
    (tests/test_fp_environment.py)."""
    libm = _libm()
    if libm is None:
        yield
        return
    saved = ctypes.create_string_buffer(64)  # fenv_t is 32 bytes on x86-64 glibc
    libm.fegetenv(saved)
    try:
        yield
    finally:
        libm.fesetenv(saved)


@functools.cache
def _libm():
    # the interpreter's own symbols hold libm on Linux; find_library (a subprocess) otherwise
    for name in (None, ctypes.util.find_library("m")):
        try:
            lib = ctypes.CDLL(name)
        except (OSError, TypeError):
            continue
        if hasattr(lib, "fegetenv") and hasattr(lib, "fesetenv"):
            return lib
    return None


# M_TOP_PAD (glibc mallopt): bytes kept at the top of the heap when it grows and when it is
# trimmed. Ipopt's MUMPS allocates and frees its factorisation workspace at every iteration;
# with glibc's default pad (128 KiB) the freed top is handed back to the kernel each time and
# faulted in again at the next factorisation. Seed 0 (8 starts, 742 iterations): 1.1-1.3 s of
# system CPU per run, against 0.3-0.4 s with a 64 MiB pad and the same user CPU (peak RSS
# +2 MB); CasADi's Ipopt showed 0.02 s of system CPU per start against 0.12 s here
# (reports/bench/seed0.md). The dynamic mmap threshold stays as it is, so large blocks still
# go back to the kernel when freed.
_HEAP_TOP_PAD = 64 << 20
_M_TOP_PAD = -2


@functools.cache
def heap_kept() -> bool:
    """Set glibc's heap top pad for the rest of the process (once); False where there is no
    glibc ``mallopt`` (macOS, musl), which changes nothing there."""
    try:
        libc = ctypes.CDLL(None)
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return bool(mallopt(_M_TOP_PAD, _HEAP_TOP_PAD))
