"""The server: load ocdsl's modules once, then run each command in a fork of this process.

``start`` detaches a server (a new session, standard streams on a log file beside the
socket) and returns once it listens; servers of other code fingerprints in the same folder
are stopped first (their code is no longer on disk). The server exits after ``idle``
seconds without a command, on ``ocdsl serve stop``, or on SIGTERM, and removes its socket.

The server itself runs nothing: it imports and listens. Each accepted connection is
forked at once, so commands run side by side (a study's points, two terminals) and each
starts from the same loaded, untouched state. The worker takes the client's standard
streams (passed over the socket), working folder, environment, umask and command line,
reseeds Python's and NumPy's global random generators (a fresh process would not share
them), restores the default signal handlers, and runs the console script's command. Its
exit code and CPU seconds go back to the client.
"""
from __future__ import annotations

import atexit
import io
import json
import os
import random
import resource
import signal
import socket
import struct
import sys
import time
import traceback
from pathlib import Path

from . import address

# what `ocdsl run` and `ocdsl check` import on their way; not what only some files need
# (SciPy, Matplotlib): a worker imports those itself, as a fresh process would
PRELOAD = ("ocdsl.cli", "ocdsl.api", "ocdsl.run", "ocdsl.spec.compile", "ocdsl.spec.schema",
           "ocdsl.transcribe.pseudospectral", "ocdsl.transcribe.direct_nlp",
           "ocdsl.transcribe.flat_bspline", "ocdsl.solve.ipopt", "ocdsl.solve.certify",
           "ocdsl.solve.costates", "ocdsl.solve.mesh", "ocdsl.verify", "ocdsl.result",
           "ocdsl.run_folder")


class ServeError(Exception):
    """A server that cannot be started or reached (the message says why)."""


def _pid_of(key: str) -> int | None:
    try:
        return int(address.pid_path(key).read_text().strip())
    except (OSError, ValueError):
        return None


def _alive(pid: int | None) -> bool:
    """A running ocdsl server has this pid: a pid file outlives its server, and the number may
    since belong to another process, which must never be signalled (its command line is
    read from /proc; another user's process or a vanished one is not ours)."""
    if pid is None or pid <= 0:
        return False
    try:
        cmdline = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
    except OSError:
        return False
    return any(part.endswith(b"ocdsl") for part in cmdline) and b"serve" in cmdline


def status() -> dict:
    """This code's server (pid, socket) if one runs, and the servers of other code."""
    key = address.code_key()
    pid = _pid_of(key)
    others = []
    for p in address.folder().glob("*.pid"):
        other = _pid_of(p.stem)
        if p.stem != key and _alive(other):
            others.append({"key": p.stem, "pid": other})
    return {"key": key, "pid": pid if _alive(pid) else None,
            "socket": str(address.socket_path(key)), "folder": str(address.folder()),
            "other_servers": others}


def stop(every: bool = False) -> list[int]:
    """Stop this code's server (``every``: every server in the folder); the pids stopped."""
    key = address.code_key()
    return _stop([p.stem for p in address.folder().glob("*.pid")] if every else [key])


def _stop(keys: list[str]) -> list[int]:
    """SIGTERM the live servers of ``keys``, remove their files, wait for them to exit."""
    stopped = []
    for k in keys:
        pid = _pid_of(k)
        if _alive(pid):
            os.kill(pid, signal.SIGTERM)
            stopped.append(pid)
        _remove(k)
    for pid in stopped:             # a server removes its files itself; wait for that
        for _ in range(200):
            if not _alive(pid):
                break
            time.sleep(0.01)
    return stopped


def _remove(key: str) -> None:
    for p in (address.socket_path(key), address.pid_path(key)):
        try:
            p.unlink()
        except FileNotFoundError:
            pass


def start(idle: float) -> dict:
    """Start this code's server unless it runs; return ``status()`` once it listens."""
    key = address.code_key()
    if _alive(_pid_of(key)):
        return status()
    _stop([p.stem for p in address.folder().glob("*.pid") if p.stem != key])   # code no longer on disk
    _remove(key)
    sock_path = address.socket_path(key)
    if len(os.fsencode(str(sock_path))) > 100:
        raise ServeError(f"socket path too long for AF_UNIX: {sock_path} "
                         f"(set {address.ENV_DIR} to a shorter folder)")
    ready_r, ready_w = os.pipe()
    pid = os.fork()
    if pid == 0:                           # first child: a new session, then the server
        os.close(ready_r)
        os.setsid()
        if os.fork() != 0:
            os._exit(0)
        try:
            _serve(key, idle, ready_w)
        except BaseException:
            traceback.print_exc()
        finally:
            os._exit(0)
    os.close(ready_w)
    os.waitpid(pid, 0)
    with os.fdopen(ready_r, "rb") as f:
        word = f.read()
    if word != b"ready":
        log = address.folder() / f"{key}.log"
        raise ServeError(f"the server did not start: {word.decode(errors='replace') or 'no reason given'}"
                         f" (log: {log})")
    return status()


def _serve(key: str, idle: float, ready_w: int) -> None:
    log = os.open(address.folder() / f"{key}.log", os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    null = os.open(os.devnull, os.O_RDONLY)
    os.dup2(null, 0)
    os.dup2(log, 1)
    os.dup2(log, 2)
    os.close(null)
    os.close(log)
    try:
        import importlib

        import ocdsl.startup

        ocdsl.startup.one_command_process()      # each worker is one command
        for name in PRELOAD:
            try:
                importlib.import_module(name)
            except ImportError as e:
                print(f"preload {name}: {e}", flush=True)
        from ocdsl.solve import ipopt_c
        from ocdsl.solve.ipopt import import_cyipopt

        import_cyipopt()         # without its SciPy front end, as a run imports it
        ipopt_c.available()      # loads the library the direct NLP calls (OCDSL_IPOPT_LIBRARY's, if set)
        import gc

        gc.collect()
        gc.freeze()          # the workers' collections then leave the loaded modules' pages alone
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        sock.bind(str(address.socket_path(key)))
        os.chmod(address.socket_path(key), 0o600)
        sock.listen(16)
        address.pid_path(key).write_text(str(os.getpid()))
    except BaseException as e:
        os.write(ready_w, f"{type(e).__name__}: {e}".encode())
        os.close(ready_w)
        raise
    os.write(ready_w, b"ready")
    os.close(ready_w)
    print(f"ocdsl serve: pid {os.getpid()} listening on {address.socket_path(key)}, "
          f"idle limit {idle:g} s", flush=True)

    def terminate(_signum, _frame):
        raise SystemExit(0)

    signal.signal(signal.SIGTERM, terminate)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGHUP, signal.SIG_IGN)
    signal.signal(signal.SIGCHLD, signal.SIG_IGN)    # workers are reaped by the kernel
    sock.settimeout(idle)
    try:
        while True:
            try:
                conn, _ = sock.accept()
            except socket.timeout:
                print("ocdsl serve: idle limit reached", flush=True)
                break
            except InterruptedError:
                continue
            if not _same_user(conn):
                conn.close()
                continue
            if os.fork() == 0:
                sock.close()
                _worker(conn)            # never returns
            conn.close()
    finally:
        if _pid_of(key) == os.getpid():
            _remove(key)


def _same_user(conn: socket.socket) -> bool:
    creds = conn.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED, struct.calcsize("3i"))
    _pid, uid, _gid = struct.unpack("3i", creds)
    return uid == os.getuid()


def _recv_exact(conn: socket.socket, n: int) -> bytes:
    buf = bytearray()
    while len(buf) < n:
        chunk = conn.recv(n - len(buf))
        if not chunk:
            raise EOFError("client closed the connection")
        buf += chunk
    return bytes(buf)


def _take_streams(fds: list[int]) -> None:
    for target, fd in enumerate(fds):
        os.dup2(fd, target)
        os.close(fd)
    # what CPython does at start-up for these descriptors: stdout line-buffered on a terminal
    sys.stdin = io.TextIOWrapper(io.open(0, "rb", closefd=False), errors="strict")
    sys.stdout = io.TextIOWrapper(io.open(1, "wb", closefd=False), line_buffering=os.isatty(1),
                                  write_through=False)
    sys.stderr = io.TextIOWrapper(io.open(2, "wb", closefd=False), line_buffering=True,
                                  errors="backslashreplace")
    sys.__stdin__, sys.__stdout__, sys.__stderr__ = sys.stdin, sys.stdout, sys.stderr


def _worker(conn: socket.socket) -> None:
    rc = 1
    started = False
    try:
        for s in (signal.SIGTERM, signal.SIGHUP, signal.SIGCHLD):
            signal.signal(s, signal.SIG_DFL)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        _msg, fds, _flags, _addr = socket.recv_fds(conn, 1, 3)
        if len(fds) != 3:
            raise EOFError("the client sent no standard streams")
        size = int.from_bytes(_recv_exact(conn, 8), "little")
        req = json.loads(_recv_exact(conn, size).decode("utf-8", "surrogateescape"))
        _take_streams(fds)
        os.chdir(req["cwd"])
        os.environ.clear()
        os.environ.update(req["env"])
        os.umask(int(req["umask"]))
        sys.argv = list(req["argv"])
        random.seed()
        if "numpy" in sys.modules:
            sys.modules["numpy"].random.seed(int.from_bytes(os.urandom(4), "little"))
        conn.sendall(json.dumps({"pid": os.getpid()}).encode() + b"\n")
        started = True
        rc = _run_command()
    except BaseException:
        if started:
            traceback.print_exc()
    finally:
        if started:
            for f in (sys.stdout, sys.stderr):
                try:
                    f.flush()
                except Exception:
                    pass
            me = resource.getrusage(resource.RUSAGE_SELF)
            kids = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu = me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime
            # peak resident memory as Linux counts it for a fork: the server's pages included
            rss = max(me.ru_maxrss, kids.ru_maxrss) / 1024.0
            try:
                conn.sendall(json.dumps({"rc": rc, "cpu_s": cpu, "rss_mb": rss}).encode() + b"\n")
            except OSError:
                pass
        os._exit(rc if 0 <= rc < 256 else 1)


def _run_command() -> int:
    """The console script's command in this process, with its exit code as CPython would
    give it (SystemExit's code; 130 after an uncaught Ctrl-C; 1 after a traceback)."""
    from ocdsl.cli import entry

    try:
        entry()
        rc = 0
    except SystemExit as e:
        if e.code is None:
            rc = 0
        elif isinstance(e.code, int):
            rc = e.code
        else:
            print(e.code, file=sys.stderr)
            rc = 1
    except KeyboardInterrupt:
        traceback.print_exc()
        rc = 130
    except BaseException:
        traceback.print_exc()
        rc = 1
    atexit._run_exitfuncs()
    return rc
