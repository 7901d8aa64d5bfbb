"""The report reads only the run folder: what it draws (Hamiltonian, switching functions,
re-integration) is written by the run, and an older folder without it gets a note, never a
re-computation (issue 25)."""
from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ocdsl.result import Result, read_csv

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.ipopt


@pytest.fixture(scope="module")
def brach(tmp_path_factory) -> Path:
    from ocdsl.api import run_file

    out = tmp_path_factory.mktemp("rf") / "brach"
    run_file(ROOT / "configs" / "brachistochrone.yaml", out)
    return out


def test_run_writes_hamiltonian_and_reintegration(brach):
    cols = read_csv(brach / "trajectory.csv")
    assert "hamiltonian" in cols and "dH_dtheta" in cols
    col = cols["collocated"] > 0
    # minimum time with free t_f: H = -1 at the collocated rows
    assert np.nanmax(np.abs(cols["hamiltonian"][col] + 1.0)) < 1e-4
    assert np.all(np.isnan(cols["hamiltonian"][~col]))
    reint = read_csv(brach / "tables" / "reintegration_main.csv")
    assert {"t", "x", "y", "v"} <= set(reint)
    assert reint["t"][0] == pytest.approx(0.0) and reint["t"][-1] == pytest.approx(cols["t"][-1])


def test_report_imports_no_solver_and_no_problem_compiler(brach, tmp_path):
    """Building the report in a fresh interpreter loads neither ocdsl.solve nor the problem
    compiler (ocdsl.spec / ocdsl.symbolic): it reads files."""
    code = ("import sys; from ocdsl.report.build import build_run_html; "
            f"html = build_run_html({str(brach)!r}); "
            "bad = sorted(m for m in sys.modules if m.startswith(('ocdsl.solve', 'ocdsl.spec', "
            "'ocdsl.symbolic', 'ocdsl.transcribe', 'ocdsl.verify', 'pyomo'))); "
            "print('BAD', bad); assert not bad, bad; assert 'Hamiltonian' in html")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_older_folder_gets_a_note_not_a_recomputation(brach, tmp_path):
    from ocdsl.report.build import build_run_html

    old = tmp_path / "old"
    shutil.copytree(brach, old)
    cols = read_csv(old / "trajectory.csv")
    for k in ("hamiltonian", "dH_dtheta"):
        cols.pop(k)
    from ocdsl.result import _write_csv
    _write_csv(old / "trajectory.csv", cols)
    shutil.rmtree(old / "tables")
    data = json.loads((old / "result.json").read_text())
    data["tables"] = []
    data.pop("verification", None)
    (old / "result.json").write_text(json.dumps(data))
    # an older ocdsl recorded no digests (a folder edited after ocdsl wrote it is refused)
    from ocdsl import run_folder

    marker = run_folder.read_marker(old)
    run_folder.write_marker(old, marker["kind"], marker["entries"], digests={})
    html = build_run_html(old)
    assert "not the Hamiltonian" in html and "Re-run the problem file" in html
    assert "no independent verification" in html
    assert "Figure" in html and "Hamiltonian H along" not in html
    res = Result.read(old)
    assert "hamiltonian" not in res.phases[0].extra
