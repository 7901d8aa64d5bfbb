"""``ocdsl serve`` (ocdsl/serve): commands run by a forked worker of a loaded server give what
the same command gives in a process of its own, and a server never serves other code.

Each test talks to a real server through the console script, in a folder of its own."""
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from ocdsl.serve import address

ROOT = Path(__file__).resolve().parent.parent
OCDSL = Path(sys.executable).with_name("ocdsl")
DI = ROOT / "configs" / "double_integrator.yaml"

pytestmark = pytest.mark.skipif(not OCDSL.exists(), reason="no console script in this environment")


def _env(folder: Path, **extra) -> dict:
    env = dict(os.environ)
    env.pop(address.ENV_OFF, None)
    env[address.ENV_DIR] = str(folder)
    env[address.ENV_LOG] = str(folder / "served.jsonl")
    env.update(extra)
    return env


def _ocdsl(env, *args, cwd=None, timeout=300):
    return subprocess.run([str(OCDSL), *args], env=env, cwd=cwd, capture_output=True, text=True,
                          timeout=timeout)


def _served(folder: Path) -> list[dict]:
    log = folder / "served.jsonl"
    return [json.loads(x) for x in log.read_text().splitlines()] if log.exists() else []


@pytest.fixture(scope="module")
def server():
    folder = Path(tempfile.mkdtemp(prefix="osv", dir="/tmp"))   # AF_UNIX paths are short
    env = _env(folder)
    p = _ocdsl(env, "serve", "start", "--idle", "600")
    assert p.returncode == 0, p.stderr
    yield folder, env
    _ocdsl(env, "serve", "stop", "--all")
    shutil.rmtree(folder, ignore_errors=True)


def _comparable(run: Path) -> dict:
    """result.json without what differs between two runs of one file (times, paths)."""
    def strip(x):
        if isinstance(x, dict):
            return {k: strip(v) for k, v in x.items()
                    if not any(w in k for w in ("time", "wall", "seconds", "cpu", "path", "created",
                                                "host", "folder", "evaluation"))}
        if isinstance(x, list):
            return [strip(v) for v in x]
        return x
    return strip(json.loads((run / "result.json").read_text()))


def test_status_names_the_running_server(server):
    folder, env = server
    p = _ocdsl(env, "serve", "status")
    assert p.returncode == 0 and "running" in p.stdout


def test_a_served_run_equals_a_run_of_its_own(server, tmp_path):
    folder, env = server
    before = len(_served(folder))
    own = _ocdsl({**env, address.ENV_OFF: "1"}, "run", str(DI), "--out", str(tmp_path / "own"))
    srv = _ocdsl(env, "run", str(DI), "--out", str(tmp_path / "srv"))
    assert own.returncode == srv.returncode == 0, srv.stderr
    log = _served(folder)
    assert len(log) == before + 1 and log[-1]["rc"] == 0 and log[-1]["worker_cpu_s"] > 0
    assert _comparable(tmp_path / "own") == _comparable(tmp_path / "srv")
    assert (tmp_path / "own" / "trajectory.csv").read_text() == (tmp_path / "srv" / "trajectory.csv").read_text()
    # the summary reaches the client's standard output, with the run's own lines
    assert "optimality certificate" in srv.stdout and "expect tf" in srv.stdout


def test_relative_paths_and_errors_are_the_clients(server, tmp_path):
    folder, env = server
    bad = tmp_path / "bad.yaml"
    bad.write_text(DI.read_text().replace("minimize tf", "minimize tf +* 2"))
    shutil.copy(DI, tmp_path / "di.yaml")
    before = len(_served(folder))
    p = _ocdsl(env, "run", "bad.yaml", cwd=tmp_path)
    assert p.returncode == 2 and "bad.yaml" in p.stderr and "Traceback" not in p.stderr
    assert not (tmp_path / "runs" / "bad").exists()
    ok = _ocdsl(env, "run", "di.yaml", "-q", cwd=tmp_path)      # default folder runs/di, relative
    assert ok.returncode == 0 and (tmp_path / "runs" / "di" / "result.json").exists()
    assert [r["rc"] for r in _served(folder)[before:]] == [2, 0]


def test_two_commands_at_once(server, tmp_path):
    folder, env = server
    before = len(_served(folder))
    procs = [subprocess.Popen([str(OCDSL), "run", str(DI), "--out", str(tmp_path / f"r{i}"), "-q"],
                              env=env) for i in range(2)]
    assert [p.wait(timeout=300) for p in procs] == [0, 0]
    new = _served(folder)[before:]
    assert len(new) == 2 and len({r["worker_pid"] for r in new}) == 2
    a, b = (json.loads((tmp_path / f"r{i}" / "result.json").read_text()) for i in range(2))
    assert a["status"] == b["status"] == "optimal" and a["objective"] == b["objective"]


def test_other_environment_or_code_is_not_served(server, tmp_path):
    folder, env = server
    before = len(_served(folder))
    # an import-time variable differs: this client's modules would load differently
    p = _ocdsl({**env, "OMP_NUM_THREADS": "1"}, "run", str(DI), "--out", str(tmp_path / "a"), "-q")
    assert p.returncode == 0 and len(_served(folder)) == before


def test_the_fingerprint_follows_the_package_files(tmp_path, monkeypatch):
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "sub" / "m.py").write_text("x = 1\n")
    monkeypatch.setattr(address, "PACKAGE", pkg)
    k0 = address.code_key()
    assert address.code_key() == k0
    (pkg / "sub" / "__pycache__").mkdir()              # bytecode is not code
    (pkg / "sub" / "__pycache__" / "m.cpython-311.pyc").write_bytes(b"\0")
    assert address.code_key() == k0
    (pkg / "sub" / "m.py").write_text("x = 22\n")
    k1 = address.code_key()
    assert k1 != k0
    (pkg / "new.py").write_text("")
    assert address.code_key() != k1
    monkeypatch.setenv("PYOMO_CONFIG_DIR", "/elsewhere")
    assert address.code_key() not in (k0, k1)


def test_a_dead_server_falls_back_to_this_process(tmp_path):
    folder = Path(tempfile.mkdtemp(prefix="osd", dir="/tmp"))
    try:
        env = _env(folder)
        st = _ocdsl(env, "serve", "status")
        assert st.returncode == 1
        sock_path = st.stdout.split("(socket ", 1)[1].split(")")[0]
        # a socket file nobody listens on (a server the OS killed)
        import socket
        s = socket.socket(socket.AF_UNIX)
        s.bind(sock_path)
        s.close()
        run = _ocdsl(env, "run", str(DI), "--out", str(tmp_path / "r"), "-q")
        assert run.returncode == 0 and not _served(folder)
        assert json.loads((tmp_path / "r" / "result.json").read_text())["status"] == "optimal"
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def test_ctrl_c_reaches_the_worker(server, tmp_path):
    folder, env = server
    big = tmp_path / "big.yaml"
    big.write_text(DI.read_text().replace("segments: 10, degree: 5", "segments: 3000, degree: 6"))
    p = subprocess.Popen([str(OCDSL), "run", str(big), "--out", str(tmp_path / "big"), "-q"], env=env,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # well inside the command (the solve of 54,000 variables takes seconds; a Ctrl-C after
    # it, in the verification, is ignored by design: ocdsl/solve/ipopt.py interruptible)
    time.sleep(1.0)
    p.send_signal(signal.SIGINT)
    out, err = p.communicate(timeout=120)
    assert p.returncode == 130, err[-2000:]
    if (tmp_path / "big" / "result.json").exists():
        assert json.loads((tmp_path / "big" / "result.json").read_text())["status"] == "interrupted"


def test_a_server_that_does_not_answer_is_not_waited_for_nor_run_twice(server, tmp_path, monkeypatch, capfd):
    """A stopped server (SIGSTOP): the client gives up after its timeout with exit 1 and a
    message, and does not also run the command itself; the request left behind is not run
    when the server resumes (the worker's hello meets a closed socket)."""
    from ocdsl.serve import client

    folder, env = server
    (pid_file,) = folder.glob("*.pid")
    pid = int(pid_file.read_text())
    monkeypatch.setattr(address, "code_key", lambda: pid_file.stem)
    monkeypatch.setattr(client, "HELLO_TIMEOUT", 1.0)
    monkeypatch.setenv(address.ENV_DIR, str(folder))
    out = tmp_path / "never"
    os.kill(pid, signal.SIGSTOP)
    try:
        rc = client.served(["ocdsl", "run", str(DI), "--out", str(out), "-q"])
    finally:
        os.kill(pid, signal.SIGCONT)
    assert rc == 1 and "did not answer" in capfd.readouterr().err
    time.sleep(3.0)
    assert not out.exists()
    # and the server still serves
    ok = _ocdsl(env, "run", str(DI), "--out", str(tmp_path / "after"), "-q")
    # by its arguments, not as the log's last line: under load another client's line can
    # come after it (a flake seen in a full run on two busy cores)
    after = [e for e in _served(folder) if str(tmp_path / "after") in e["argv"]]
    assert ok.returncode == 0 and [e["rc"] for e in after] == [0]
    assert not any(str(out) in e["argv"] and e["rc"] == 0 for e in _served(folder))


def test_a_stale_pid_file_never_signals_another_process(tmp_path):
    """A server's pid file outlives a server the OS killed, and its number may be reused:
    `serve stop --all` and `serve status` must not take that process for a server, nor
    signal it."""
    folder = Path(tempfile.mkdtemp(prefix="osp", dir="/tmp"))
    other = subprocess.Popen(["sleep", "60"])
    try:
        (folder / "0123456789abcdef0123.pid").write_text(str(other.pid))
        env = _env(folder)
        p = _ocdsl(env, "serve", "stop", "--all")
        assert p.returncode == 0 and "stopped nothing" in p.stdout, p.stdout
        time.sleep(0.2)
        assert other.poll() is None              # still running: it was not signalled
        assert not (folder / "0123456789abcdef0123.pid").exists()   # ocdsl's own stale file is gone
        assert _ocdsl(env, "serve", "status").returncode == 1
    finally:
        other.kill()
        shutil.rmtree(folder, ignore_errors=True)
