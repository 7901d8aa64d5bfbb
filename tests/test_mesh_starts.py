"""``starts:`` with ``mesh:`` (unseen finding #32: the starts were silently dropped): the
starts are solved on the first mesh, all recorded, and the refinement goes on from the best."""
from __future__ import annotations

import math

from ocdsl.api import run_file

BROCKETT = """name: brockett
model:
  states: [x, y, z]
  controls: [u1, u2]
  dynamics: {x: u1, y: u2, z: x*u2 - y*u1}
problem:
  time: {t0: 0, tf: 1}
  constraints: [x(t0) == 0, y(t0) == 0, z(t0) == 0, x(tf) == 0, y(tf) == 0, z(tf) == 1]
  objective: minimize integral(u1**2 + u2**2)
method: {transcription: LGR, segments: 6, degree: 4, starts: 3, seed: 1,
         mesh: {tolerance: 1.0e-6, max_iterations: 6}}
"""


def test_starts_with_mesh_are_solved_on_the_first_mesh_and_recorded(tmp_path):
    p = tmp_path / "b.yaml"
    p.write_text(BROCKETT)
    res = run_file(p, None)
    starts = res.extra.get("starts")
    # start 0 is the file's guess (no seed), starts 1 and 2 perturbed copies from seed + i
    assert starts is not None and [r["seed"] for r in starts][:3] == [None, 2, 3], starts
    good = [r["objective"] for r in starts if r["status"] == "optimal"]
    assert good, starts
    first = res.extra["mesh_history"][0]
    # the refinement went on from the best start of the first mesh
    assert math.isclose(first["objective"], min(good), rel_tol=1e-12), (first, starts)
    assert res.status == "optimal" and abs(res.objective - 2 * math.pi) < 1e-5 * 2 * math.pi, res.message
