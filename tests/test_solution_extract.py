"""Controls on the state nodes (transcribe/solution.py), checked against each segment's own
interpolating polynomial, on meshes with mixed degrees and every scheme."""
import numpy as np
import pytest

from ocdsl.api import compile_file
from ocdsl.transcribe.guess import make_guess
from ocdsl.transcribe.mesh import Mesh
from ocdsl.transcribe.pseudospectral import build
from ocdsl.transcribe.solution import control_on_state_nodes, extract, later_owns_breakpoint


@pytest.mark.parametrize("scheme", ["LG", "LGR", "LGL", "LGR-start"])
def test_controls_on_state_nodes_are_each_segments_polynomial(configs, scheme):
    file = compile_file(configs / "moon_landing.yaml")
    ph = file.problem.phases[0]
    degrees = (3, 5, 2, 4, 3) if scheme == "LGL" else (3, 5, 1, 4, 3)
    mesh = Mesh(scheme, np.array([0.0, 0.1, 0.35, 0.5, 0.8, 1.0]), degrees)
    tr = build(file.problem, {ph.name: mesh}, {ph.name: make_guess(file.problem, ph, None)})
    pb = tr.phases[0]
    lay = pb.layout
    U = np.random.default_rng(1).normal(size=(lay.n_colloc, 2))
    got = control_on_state_nodes(pb, U)
    assert not np.isnan(got).any()
    for k in range(mesh.segments):
        a, b = mesh.breakpoints[k], mesh.breakpoints[k + 1]
        s_c = lay.s_colloc[lay.colloc[k]]
        nodes = list(lay.support[k]) + [lay.end[k]]
        # a shared start is the previous segment's end, unless only this segment collocates
        # there (LGR-start): then it is this one's own node, and not the previous one's end
        first = 0 if k == 0 or later_owns_breakpoint(mesh, k) else 1
        if k + 1 < mesh.segments and later_owns_breakpoint(mesh, k + 1):
            nodes = [n for n in nodes if n != lay.end[k]]
        for n in nodes[first:]:
            for j in range(U.shape[1]):
                poly = np.polynomial.Polynomial.fit(s_c, U[lay.colloc[k], j], len(s_c) - 1, domain=[a, b])
                assert got[n, j] == pytest.approx(poly(lay.s_state[n]), abs=1e-9), (k, n, j)
    # where a state node is a collocation node, the value is the control there exactly
    for k in range(mesh.segments):
        own = k == 0 or later_owns_breakpoint(mesh, k)
        assert np.array_equal(got[lay.colloc_state[k] if own else lay.colloc_state[k][1:]],
                              U[lay.colloc[k] if own else lay.colloc[k][1:]])


def test_extract_reads_the_variables(configs):
    file = compile_file(configs / "brachistochrone.yaml")
    ph = file.problem.phases[0]
    tr = build(file.problem, {ph.name: Mesh.uniform("LGR", 4, 3)}, {ph.name: make_guess(file.problem, ph, None)})
    b = tr.phases[0].block
    for n, j in b.X:
        b.X[n, j].set_value(10 * n + j)
    traj = extract(tr)[0]
    for j, s in enumerate(ph.states):
        assert traj.states[s.name].tolist() == [10.0 * n + j for n in range(len(traj.time))]


@pytest.mark.parametrize("scheme", ["LG", "LGR", "LGL"])
def test_built_variables_start_at_the_guess(configs, scheme):
    """The state and control variables are set from the guess arrays in index order."""
    file = compile_file(configs / "moon_landing.yaml")
    ph = file.problem.phases[0]
    guess = make_guess(file.problem, ph, None, seed=3)     # random controls: every value differs
    seen = {}
    for name in ("states_at", "controls_at"):
        def recording(s, _f=getattr(guess, name), _name=name):
            seen[_name] = _f(s)
            return seen[_name]
        object.__setattr__(guess, name, recording)
    tr = build(file.problem, {ph.name: Mesh.uniform(scheme, 6, 3)}, {ph.name: guess})
    b, lay = tr.phases[0].block, tr.phases[0].layout
    xg, ug = seen["states_at"], seen["controls_at"]
    assert len(set(ug.ravel().tolist())) == ug.size > 1
    assert all(b.X[n, j].value == xg[n, j] for n in range(lay.n_state_nodes) for j in range(len(ph.states)))
    assert all(b.U[i, j].value == ug[i, j] for i in range(lay.n_colloc) for j in range(len(ph.controls)))


def test_angles_that_enter_only_through_sin_and_cos_are_exported_on_one_branch(tmp_path):
    """A heading that the dynamics see only through sin/cos may take any branch at each
    node; exported, it is one continuous branch starting in (-pi, pi]."""
    import yaml

    from ocdsl.api import compile_file
    from ocdsl.transcribe.solution import periodic_controls, unwrap_angles

    spec = {"name": "heading", "model": {"states": ["x", "y"], "controls": ["beta", "w"],
                                        "dynamics": {"x": "cos(beta) + w", "y": "sin(beta)"}},
            "problem": {"time": {"t0": 0, "tf": 1}, "constraints": ["x(t0) == 0", "y(t0) == 0", "0 <= w <= 1"],
                        "objective": "maximize y(tf)"}}
    p = tmp_path / "h.yaml"
    p.write_text(yaml.safe_dump(spec))
    ph = compile_file(p).problem.phases[0]
    assert periodic_controls(ph) == [0]          # beta; w enters linearly (and is bounded)
    U = np.column_stack([np.array([np.nan, 0.1, 0.2 + 2 * np.pi, 0.3 - 4 * np.pi, 0.4]) + 6 * np.pi,
                         np.zeros(5)])
    out = unwrap_angles(U, [0], [(-np.inf, np.inf), (0, 1)])
    assert np.isnan(out[0, 0])
    assert np.allclose(out[1:, 0], [0.1, 0.2, 0.3, 0.4])
    # bounds that the moved values would leave: left as they are
    kept = unwrap_angles(U, [0], [(15.0, 40.0), (0, 1)])
    assert np.array_equal(kept, U, equal_nan=True)
