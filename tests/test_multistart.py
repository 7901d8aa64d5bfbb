"""Several starts solve one model (ocdsl/run.py, solve/reuse.py ``restart``).

Each start must begin exactly where a fresh build of its guess begins (every variable's
value, bounds and fixed flag), so every start's Ipopt run, and the best start's result,
are those of solving each start on its own model.
"""
import numpy as np
import pytest

import ocdsl
from ocdsl.api import compile_file
from ocdsl.solve.reuse import SolvedState, restart
from ocdsl.transcribe.guess import start_guesses
from ocdsl.transcribe.mesh import Mesh
from ocdsl.transcribe.pseudospectral import build


def _file(configs, tmp_path, starts):
    p = tmp_path / f"brach_{starts}.yaml"
    p.write_text((configs / "brachistochrone.yaml").read_text().replace(
        "method: {transcription: LGR, segments: 8, degree: 5}",
        f"method: {{transcription: LGR, segments: 8, degree: 5, starts: {starts}, seed: 0}}"))
    return p


def _vars(tr):
    import pyomo.core as pyo

    return [(v.name, v.value, v.lb, v.ub, v.fixed) for v in tr.model.component_data_objects(pyo.Var)]


def test_restart_gives_a_fresh_builds_values(configs, tmp_path):
    file = compile_file(_file(configs, tmp_path, 3))
    problem = file.problem
    meshes = {ph.name: Mesh.uniform("LGR", 8, 5) for ph in problem.phases}
    # perturbed starts (states, controls and the free tf moved): transcribe/guess.py start_guesses
    guess = lambda s: start_guesses(problem, {}, s, None, 0)  # noqa: E731
    tr = build(problem, meshes, guess(1))
    first = _vars(tr)
    for v in tr.model.component_data_objects(__import__("pyomo.core", fromlist=["Var"]).Var):
        if not v.fixed:
            v.set_value(123.0, skip_validation=True)          # what a solve leaves behind
    state = SolvedState(tr.model)
    restart(tr, guess(2), problem)
    assert _vars(tr) == _vars(build(problem, meshes, guess(2)))
    assert _vars(tr) != first
    state.restore()
    assert all(v[1] == 123.0 for v in _vars(tr) if not v[4])


@pytest.mark.ipopt
def test_starts_on_one_model_match_separate_solves(configs, tmp_path):
    from ocdsl.solve import ipopt
    from ocdsl.transcribe.solution import extract

    multi = ocdsl.load(_file(configs, tmp_path, 3)).solve()
    rows = multi.extra["starts"]
    assert [r["seed"] for r in rows] == [None, 1, 2]       # start 0: the file's guess
    file = compile_file(_file(configs, tmp_path, 3))
    problem = file.problem
    meshes = {ph.name: Mesh.uniform("LGR", 8, 5) for ph in problem.phases}
    singles = []
    for i in range(3):          # each start on its own, freshly built model
        tr = build(problem, meshes, start_guesses(problem, {}, i, None, 0))
        singles.append((ipopt.solve(tr.model, file.spec.solver.options, transcription=tr), extract(tr)))
    for r, (info, _) in zip(rows, singles):
        assert r["status"] == info.status and r["iterations"] == info.iterations
        assert r["objective"] == info.objective
    best = min(range(3), key=lambda i: singles[i][0].objective)
    assert multi.objective == singles[best][0].objective
    for name, values in singles[best][1][0].states.items():
        np.testing.assert_array_equal(multi.phase().states[name], values)
    # start 0 is the single start, bit for bit
    one = ocdsl.load(_file(configs, tmp_path, 1)).solve()
    assert rows[0]["objective"] == one.objective and rows[0]["iterations"] == one.iterations
