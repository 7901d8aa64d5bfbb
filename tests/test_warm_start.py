"""Multiplier warm start across meshes (issue 12): ocdsl/solve/warm_start.py and the direct
cyipopt path of ocdsl/solve/ipopt.py (``solve(..., multipliers=...)``)."""
from pathlib import Path

import numpy as np
import pytest

import ocdsl
from ocdsl.api import compile_file
from ocdsl.solve import ipopt
from ocdsl.solve import warm_start as ws
from ocdsl.solve.costates import colloc_costates, path_scale
from ocdsl.transcribe.guess import make_guess
from ocdsl.transcribe.mesh import Mesh
from ocdsl.transcribe.pseudospectral import build

pytestmark = pytest.mark.ipopt

DATA = Path(__file__).parent / "data"


def _solve_on(f, mesh, snapshot=None, use_multipliers=True):
    """Build ``f`` on ``mesh``; with ``snapshot`` start from it (primal always, multipliers
    when ``use_multipliers``)."""
    guesses = {ph.name: make_guess(f.problem, ph) for ph in f.problem.phases}
    tr = build(f.problem, {ph.name: mesh for ph in f.problem.phases}, guesses)
    ws.prepare(tr.model)
    mult = ws.apply(snapshot, tr) if snapshot is not None else None
    opts = {**f.spec.solver.options, "tol": 1e-10}
    info = ipopt.solve(tr.model, opts, multipliers=mult if use_multipliers else None)
    assert info.status == "optimal", info.message
    return tr, info


def _mapped(tr, snapshot):
    """Costates and path multiplier densities that the mapped multipliers give on ``tr``."""
    m = tr.model
    saved = list(m.dual.items())
    mult = ws.apply(snapshot, tr, primal=False)
    m.dual.clear()
    for c, v in mult.constraints.items():
        m.dual[c] = v
    pb = tr.phases[0]
    lam = colloc_costates(m, pb)
    scale = path_scale(pb, 3.0)
    mu = np.array([m.dual[pb.block.path[i]] for i in range(pb.layout.n_colloc)]) / scale
    m.dual.clear()
    m.dual.update(saved)
    return lam, mu


@pytest.mark.parametrize("scheme", ["LGR", "LG", "LGL"])
def test_mapped_multipliers_reproduce_costates_on_new_mesh(scheme):
    """The LQ problem with a path constraint active on [0, 0.965] (tests/data/
    path_multiplier_lq.yaml): solved on a uniform 6 x 4 mesh, its multipliers mapped onto an
    unrelated non-uniform mesh give there the costate and the path multiplier mu that the
    solve on that mesh gives, to the interpolation error across the kink at t1: measured
    max |delta lambda| 5.4e-4 LGR, 1.8e-4 LG, 2.0e-3 LGL (max |lambda| = 1.22) and
    max |delta mu| 9.2e-3, 2.0e-4, 7.1e-3 (max mu = 0.72). A wrong sign, a missing weight or
    a missing (tf - t0) h/2 would be off by O(1)."""
    f = compile_file(DATA / "path_multiplier_lq.yaml")
    old = Mesh.uniform(scheme, 6, 4)
    new = Mesh(scheme, np.array([0, .07, .2, .31, .45, .5, .66, .8, .93, 1.]), (5, 3, 6, 4, 5, 4, 6, 5, 4))
    tr_old, _ = _solve_on(f, old)
    snap = ws.take(tr_old)
    tr_new, _ = _solve_on(f, new)                       # cold: its own multipliers
    pb = tr_new.phases[0]
    lam_solved = colloc_costates(tr_new.model, pb)
    mu_solved = np.array([tr_new.model.dual[pb.block.path[i]] for i in range(pb.layout.n_colloc)]) \
        / path_scale(pb, 3.0)
    lam_map, mu_map = _mapped(tr_new, snap)
    assert np.max(np.abs(lam_solved)) > 1.0 and np.max(mu_solved) > 0.5     # both matter
    assert np.max(np.abs(lam_map - lam_solved)) < 3e-3
    assert np.max(np.abs(mu_map - mu_solved)) < 1.5e-2


def test_mapped_costates_exact_on_a_smooth_problem():
    """Brachistochrone (smooth, tf free): mapped from 8 x 5 onto 9 other segments, the
    costates agree with the new mesh's own to 1e-6 of their size, and the warm-started
    solve on the new mesh takes at most 3 Ipopt iterations (measured 1; cold 40)."""
    f = compile_file(Path(__file__).parents[1] / "configs" / "brachistochrone.yaml")
    old = Mesh.uniform("LGR", 8, 5)
    new = Mesh("LGR", np.array([0, .07, .2, .31, .45, .5, .66, .8, .93, 1.]), (5, 3, 6, 4, 5, 4, 6, 5, 4))
    tr_old, _ = _solve_on(f, old)
    snap = ws.take(tr_old)
    tr_new, info_warm = _solve_on(f, new, snap)
    lam_solved = colloc_costates(tr_new.model, tr_new.phases[0])
    mult = ws.apply(snap, tr_new, primal=False)
    m = tr_new.model
    m.dual.clear()
    m.dual.update(mult.constraints.items())
    lam_map = colloc_costates(m, tr_new.phases[0])
    scale = np.max(np.abs(lam_solved), axis=0)
    assert np.all(np.max(np.abs(lam_map - lam_solved), axis=0) <= 2e-5 * scale)
    assert info_warm.iterations <= 3


@pytest.mark.parametrize("config", ["mesh_bryson_denham.yaml", "mesh_moon_landing.yaml"])
def test_resolve_same_mesh_takes_few_iterations_with_multipliers(configs, config):
    """Re-solving a mesh from its own solution: with the multipliers Ipopt stops within 3
    iterations (measured 1-2); from the same exact primal point without them it needs more
    (its default duals and bound push move it off the optimum)."""
    f = compile_file(configs / config)
    mesh = Mesh.uniform("LGR", 6, 4)
    tr, info = _solve_on(f, mesh)
    snap = ws.take(tr)
    tr_m, info_m = _solve_on(f, mesh, snap)
    tr_p, info_p = _solve_on(f, mesh, snap, use_multipliers=False)
    assert info_m.iterations <= 3
    assert info_p.iterations > info_m.iterations + 2
    for i in (info_m, info_p):
        assert abs(i.objective - info.objective) <= 1e-9 * abs(info.objective)
    # the direct path reads everything back like Pyomo's: duals (costates) and bounds' z
    # (the duals of a degenerate optimum move a little between solves: measured 1.7e-5 of
    # max |lambda| on Bryson-Denham, 3.5e-4 on the moon landing's lambda_m with Ipopt's
    # bound_relax_factor 1e-8 and 1.4e-3 with ocdsl's 1e-9 (the first two nodes only, where
    # the thrust leaves its bound; every other node agrees to 2e-12); 4e-3 without the
    # multipliers. A wrong read-back is off by O(1).)
    lam, lam_m = colloc_costates(tr.model, tr.phases[0]), colloc_costates(tr_m.model, tr_m.phases[0])
    assert np.all(np.abs(lam_m - lam) <= 2e-3 * np.max(np.abs(lam), axis=0))
    assert len(tr_m.model.ipopt_zL_out) == len(tr.model.ipopt_zL_out) > 0


def test_failed_warm_start_falls_back_to_a_plain_solve(configs, monkeypatch):
    """A start from multipliers that does not end optimal is solved again without them from
    the same primal point; the message says so and the iterations of both count."""
    f = compile_file(configs / "mesh_moon_landing.yaml")
    mesh = Mesh.uniform("LGR", 6, 4)
    tr, info = _solve_on(f, mesh)
    snap = ws.take(tr)
    monkeypatch.setitem(ipopt.WARM_START_OPTIONS, "max_iter", 0)    # the warm attempt must stop
    tr2, info2 = _solve_on(f, mesh, snap)
    assert "solved again without them" in info2.message
    assert abs(info2.objective - info.objective) <= 1e-9 * abs(info.objective)


def test_mesh_refinement_multipliers_fewer_iterations_same_result(configs):
    """Moon landing: the multiplier warm start (default) and the primal-only one end with the
    same J (1e-8 relative), the former in fewer Ipopt iterations in total (measured 49
    against 96, both on the same final mesh). The meshes are not compared here: which
    breakpoints the locators choose reacts to 1e-10 differences of the solutions (see
    docs/mesh-refinement.md, "Warm start")."""
    runs = {}
    for mode in ("multipliers", "primal"):
        loaded = ocdsl.load(configs / "mesh_moon_landing.yaml")
        loaded.file.method.mesh.warm_start = mode
        runs[mode] = loaded.solve()
    m, p = runs["multipliers"], runs["primal"]
    assert m.status == p.status == "optimal"
    assert abs(m.objective - p.objective) <= 1e-8 * abs(p.objective)
    hm, hp = m.extra["mesh_history"], p.extra["mesh_history"]
    assert [h["warm_start"] for h in hm] == ["none"] + ["multipliers"] * (len(hm) - 1)
    assert [h["warm_start"] for h in hp] == ["none"] + ["primal"] * (len(hp) - 1)
    assert sum(h["ipopt_iterations"] for h in hm) < sum(h["ipopt_iterations"] for h in hp)


def test_a_warm_start_from_another_problem_is_named_in_a_note(configs, tmp_path):
    """--warm-start from a brachistochrone run (states x, y, v; control theta) into the double
    integrator (x, v; u): the shared names are used and the mismatch is said, on the plain and
    the adaptive-mesh route (it was silent); a warm start from the same problem has no note."""
    from ocdsl.api import run_file

    source = run_file(configs / "brachistochrone.yaml", tmp_path / "brach")
    assert source.status == "optimal"
    for name in ("double_integrator.yaml", "mesh_double_integrator.yaml"):
        res = run_file(configs / name, tmp_path / name, warm_start=tmp_path / "brach")
        # (the fixed mesh's bisection check has its own note)
        notes = [n for n in res.extra.get("notes", []) if "warm start" in n]
        assert len(notes) == 1, notes
        assert "it has no u" in notes[0] and "its y, theta are not in this problem" in notes[0], notes
        same = run_file(configs / name, tmp_path / f"again_{name}", warm_start=tmp_path / name)
        assert not [n for n in same.extra.get("notes", []) if "warm start" in n], same.extra.get("notes")


def test_a_start_from_multipliers_stops_at_its_own_cap():
    """``multipliers_max_iter`` stops the attempt from the mesh before's multipliers, and the
    same point is solved again without them (the mesh refinement's multiplier_cap; unseen48
    F2: 5,100 iterations with them, 281 without)."""
    f = compile_file(DATA / "path_multiplier_lq.yaml")
    tr_old, _ = _solve_on(f, Mesh.uniform("LGR", 6, 4))
    snap = ws.take(tr_old)
    guesses = {ph.name: make_guess(f.problem, ph) for ph in f.problem.phases}
    tr = build(f.problem, {ph.name: Mesh.uniform("LGR", 11, 5) for ph in f.problem.phases}, guesses)
    ws.prepare(tr.model)
    mult = ws.apply(snap, tr)
    info = ipopt.solve(tr.model, {**f.spec.solver.options, "tol": 1e-12}, multipliers=mult, multipliers_max_iter=1)
    assert info.status == "optimal"
    assert "Ipopt ended 'max_iter' after 1 iterations; solved again without them" in info.message
