"""The console script: hand the command to a server of this exact code, else run it here.

Standard library only, and nothing of ocdsl but ``serve.address``: with a server running,
the command's own process costs a Python start-up and a few milliseconds. Without one (no
server, another code fingerprint, ``OCDSL_NO_SERVE=1``, a standard stream closed, or a
server that does not answer) the command runs in this process, as it always did. ``ocdsl
serve ...`` itself always runs here.

Ctrl-C, SIGTERM and SIGHUP received here are passed on to the worker, which handles them
as the command does in a process of its own (an interrupted solve still writes its run
folder). With ``OCDSL_SERVE_LOG`` set, one JSON line per served command (exit code, the
worker's CPU seconds and wall time) is appended to that file: the command's CPU is this
process's plus the worker's.
"""
from __future__ import annotations

import json
import os
import signal
import socket
import sys
import time

from . import address

# the worker forwards these to the command as it would arrive at a process of its own
FORWARDED = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
HELLO_TIMEOUT = 20.0


# the thread counts of the BLAS libraries; one thread unless the user chose a count
BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")


def one_blas_thread() -> None:
    """NumPy's OpenBLAS starts a thread per core when it loads; on ocdsl's small dense
    products the second only spins (whole processes, the same wall: brachistochrone CPU
    0.85 -> 0.80 s, Goddard 1.53 -> 1.31 s). Set before anything imports NumPy, and before
    the server's name is computed (address.IMPORT_TIME_ENV), so that a served and a local
    command see the same count."""
    if not any(os.environ.get(k) for k in BLAS_THREADS):
        os.environ["OPENBLAS_NUM_THREADS"] = "1"


def entry() -> None:
    one_blas_thread()
    argv = list(sys.argv)
    if len(argv) < 2 or argv[1] != "serve":
        rc = served(argv)
        if rc is not None:
            sys.exit(rc)
    from ..cli import entry as run_here

    run_here()


def _streams_open() -> bool:
    try:
        for fd in (0, 1, 2):
            os.fstat(fd)
    except OSError:
        return False
    return True


def _read_line(sock: socket.socket) -> bytes:
    buf = bytearray()
    while not buf.endswith(b"\n"):
        try:
            chunk = sock.recv(1)
        except InterruptedError:
            continue
        if not chunk:
            return bytes(buf)
        buf += chunk
    return bytes(buf)


def served(argv: list[str]) -> int | None:
    """The command's exit code from the server, or None when it is to run here."""
    if os.environ.get(address.ENV_OFF, "").strip().lower() not in ("", "0", "false", "no"):
        return None
    try:
        path = address.socket_path(address.code_key())
        if not path.exists() or not _streams_open():
            return None
        cwd = os.getcwd()
    except OSError:
        return None
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    t0 = time.perf_counter()
    # the server forks at once and the worker answers within milliseconds; a stopped
    # (SIGSTOP) or swamped server is not waited for
    sock.settimeout(HELLO_TIMEOUT)
    try:
        sock.connect(str(path))
        umask = os.umask(0)
        os.umask(umask)
        request = json.dumps({"argv": argv, "cwd": cwd, "env": dict(os.environ),
                              "umask": umask}).encode("utf-8", "surrogateescape")
        socket.send_fds(sock, [b"F"], [0, 1, 2])
        sock.sendall(len(request).to_bytes(8, "little") + request)
        hello = _read_line(sock)
    except socket.timeout:
        # the request may still reach a worker later: running the command here too could run
        # it twice, so say so and stop
        sock.close()
        print(f"ocdsl: the server at {path} did not answer within {HELLO_TIMEOUT:g} s; "
              f"run `ocdsl serve stop`, or set {address.ENV_OFF}=1 to run without it",
              file=sys.stderr)
        return 1
    except OSError:
        sock.close()
        return None
    if not hello:           # the worker never started the command: run it here
        sock.close()
        return None
    sock.settimeout(None)   # the command itself takes as long as it takes
    pid = json.loads(hello)["pid"]

    def forward(signum, _frame):
        try:
            os.kill(pid, signum)
        except ProcessLookupError:
            pass

    for s in FORWARDED:
        signal.signal(s, forward)
    line = _read_line(sock)
    sock.close()
    if not line:
        print(f"ocdsl: the server's worker (pid {pid}) ended without an exit status",
              file=sys.stderr)
        return 1
    status = json.loads(line)
    log = os.environ.get(address.ENV_LOG)
    if log:
        with open(log, "a") as f:
            f.write(json.dumps({"argv": argv[1:], "rc": status["rc"], "worker_pid": pid,
                                "worker_cpu_s": status["cpu_s"], "worker_rss_mb": status["rss_mb"],
                                "wall_s": time.perf_counter() - t0}) + "\n")
    return int(status["rc"])
