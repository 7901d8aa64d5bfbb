"""A single solve whose state bound binds says that its J is the fixed mesh's optimum
(unseen5): on 3 LG segments the speed-limited transfer is feasible, verified and passes the
certificate at J = 12.24, while the problem's optimum is 12.1956; nothing said so."""
from __future__ import annotations

from ocdsl.api import run_file

SPEED_LIMIT = """name: speed limit
model:
  states: [x, v]
  controls: [u]
  dynamics: {x: v, v: u}
problem:
  time: {t0: 0, tf: 1}
  constraints: [LIMIT, x(t0) == 0, v(t0) == 0, x(tf) == 1, v(tf) == 0]
  objective: minimize integral(u**2)
method: {transcription: LG, segments: 3, degree: 3}
"""


def _notes(tmp_path, limit: str) -> tuple[object, list[str]]:
    p = tmp_path / "s.yaml"
    p.write_text(SPEED_LIMIT.replace("LIMIT", limit))
    res = run_file(p, None)
    return res, [n for n in res.extra.get("notes", []) if "fixed mesh" in n]


def test_a_binding_state_bound_on_a_fixed_mesh_is_said_to_leave_j_the_meshs(tmp_path):
    res, notes = _notes(tmp_path, "v <= 1.4")
    # exact optimum: 8 (1.4)^2 / (3 t1), t1 = 1.5 (1 - 1/1.4)
    exact = 8 * 1.4 ** 2 / (3 * 1.5 * (1 - 1 / 1.4))
    assert res.status == "optimal" and res.objective - exact > 1e-3 * exact       # the mesh's optimum
    assert res.verification["status"] == "verified"
    assert len(notes) == 1 and "`v <= 1.4`" in notes[0] and "mesh:" in notes[0], res.extra.get("notes")


def test_a_bound_that_never_binds_and_a_state_leaving_its_bound_from_rest_are_not_named(tmp_path):
    res, notes = _notes(tmp_path, "v <= 5")          # the unconstrained peak speed is 1.5
    assert res.status == "optimal" and notes == []
    res, notes = _notes(tmp_path, "x >= 0")          # x(t0) = 0 on the bound, then leaving it
    assert res.status == "optimal" and notes == [], notes
