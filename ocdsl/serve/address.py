"""Where the server of this exact code listens (standard library only: the client imports it).

A server is named by a fingerprint of everything its loaded modules came from: the Python
executable and version, every file of the ``ocdsl`` package (path, size, modification
time), the folders on ``sys.path`` (installing or upgrading a package changes its folder's
modification time), and the environment variables that modules read when they are
imported. A client whose code or environment differs computes another name, finds no
server and runs the command itself: an edited ocdsl never reaches a server holding the old
one.

The folder is ``$OCDSL_SERVE_DIR``, else ``$XDG_RUNTIME_DIR/ocdsl-serve``, else
``~/.cache/ocdsl/serve``; it is made readable by its owner only, and the server also
refuses a peer of another user.
"""
from __future__ import annotations

import hashlib
import os
import sys
from pathlib import Path

ENV_DIR = "OCDSL_SERVE_DIR"
ENV_OFF = "OCDSL_NO_SERVE"
ENV_LOG = "OCDSL_SERVE_LOG"
# read when a module is imported (or, OCDSL_IPOPT_LIBRARY, when the server loads Ipopt), so a
# server loaded under other values would behave differently from a fresh process
IMPORT_TIME_ENV = ("PYOMO_CONFIG_DIR", "OCDSL_IPOPT_LIBRARY", "PYTHONPATH", "PYTHONHASHSEED", "PYTHONWARNINGS",
                   "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "MPLBACKEND",
                   "NUMBA_DISABLE_JIT", "NUMBA_CACHE_DIR", "SYMPY_USE_CACHE", "SYMPY_GROUND_TYPES")
PACKAGE = Path(__file__).resolve().parent.parent


def folder() -> Path:
    if os.environ.get(ENV_DIR):
        d = Path(os.environ[ENV_DIR])
    elif os.environ.get("XDG_RUNTIME_DIR"):
        d = Path(os.environ["XDG_RUNTIME_DIR"]) / "ocdsl-serve"
    else:
        d = Path.home() / ".cache" / "ocdsl" / "serve"
    d.mkdir(parents=True, exist_ok=True, mode=0o700)
    return d


def _package_files(root: Path):
    stack = [root]
    while stack:
        d = stack.pop()
        with os.scandir(d) as it:
            for e in it:
                if e.is_dir(follow_symlinks=False):
                    if e.name != "__pycache__":
                        stack.append(Path(e.path))
                elif not e.name.endswith((".pyc", ".pyo")):
                    st = e.stat()
                    yield f"{os.path.relpath(e.path, root)}:{st.st_size}:{st.st_mtime_ns}"


def code_key() -> str:
    h = hashlib.sha256()
    parts = [sys.executable, sys.version]
    for p in sys.path:
        try:
            parts.append(f"{p}:{os.stat(p or '.').st_mtime_ns}")
        except OSError:
            parts.append(p)
    parts += sorted(_package_files(PACKAGE))
    parts += [f"{k}={os.environ.get(k, '')}" for k in IMPORT_TIME_ENV]
    for p in parts:
        h.update(p.encode("utf-8", "surrogateescape"))
        h.update(b"\0")
    return h.hexdigest()[:20]


def socket_path(key: str) -> Path:
    return folder() / f"{key}.sock"


def pid_path(key: str) -> Path:
    return folder() / f"{key}.pid"
