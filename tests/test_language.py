"""Problem-language conveniences: YAML merge keys and the `definitions:` home for anchors,
the `==` hint, and models added by other packages through the `ocdsl.models` entry points."""
import sys

import pytest

from conftest import write
from ocdsl.spec.compile import load
from ocdsl.spec.errors import SpecError

BASE = """
name: merge
definitions:
  common: &common
    time: {t0: 0, tf: free}
    objective: minimize tf
  unit_box: &box [-1 <= u <= 1]
model:
  states: [x, v]
  controls: [u]
  dynamics: {x: v, v: u}
problem:
  <<: *common
  constraints: [-1 <= u <= 1, x(t0) == 1, v(t0) == 0, x(tf) == 0, v(tf) == 0, 0.1 <= tf <= 10]
"""


def test_merge_key_and_definitions(tmp_path):
    f = load(write(tmp_path, BASE))
    ph = f.problem.phases[0]
    assert ph.tf is None and f.problem.objective.sense == "minimize"


def test_keys_written_beside_a_merge_win(tmp_path):
    text = BASE.replace("  <<: *common\n", "  <<: *common\n  objective: maximize tf\n")
    assert load(write(tmp_path, text)).problem.objective.sense == "maximize"


def test_error_in_merged_text_points_at_the_anchor_line(tmp_path):
    text = BASE.replace("objective: minimize tf", "objective: minimize tff")
    with pytest.raises(SpecError) as e:
        load(write(tmp_path, text))
    issue = e.value.issues[0]
    assert issue.line == 6 and "tff" in issue.message


def test_merge_of_a_non_mapping_is_one_clear_error(tmp_path):
    text = BASE.replace("  <<: *common\n", "  <<: *box\n")
    with pytest.raises(SpecError, match="merge key"):
        load(write(tmp_path, text))


def test_single_equals_gets_a_hint(tmp_path):
    with pytest.raises(SpecError, match=r"written with ==") as e:
        load(write(tmp_path, BASE.replace("x(t0) == 1", "x(t0) = 1")))
    assert e.value.issues[0].line == 14


@pytest.mark.parametrize("wrong, right", [("=>", ">="), ("=<", "<=")])
def test_a_reversed_inequality_sign_is_named(tmp_path, wrong, right):
    """unseen48 F5: `x(tf) => 0` was told "an equality is written with ==" (the user meant >=)."""
    with pytest.raises(SpecError, match=f"`{wrong}` is written `{right}`") as e:
        load(write(tmp_path, BASE.replace("x(t0) == 1", f"x(t0) {wrong} 1")))
    assert e.value.issues[0].line == 14


def test_third_party_models_through_entry_points(tmp_path, monkeypatch):
    from ocdsl.symbolic import registry

    (tmp_path / "acme_models.py").write_text(
        "from ocdsl.symbolic.model import Model, syms\n"
        "from ocdsl.symbolic.registry import register\n"
        "@register('acme_integrator', description='x'' = u')\n"
        "def build(options):\n"
        "    x, u = syms('x u')\n"
        "    return Model('acme_integrator', (x,), (u,), {x: u})\n")
    info = tmp_path / "acme-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: acme\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text("[ocdsl.models]\nacme = acme_models\n")
    registry.model_names()     # the project's own first: their modules register only once
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(registry, "_LOADED", False)
    monkeypatch.setattr(registry, "_REGISTRY", dict(registry._REGISTRY))
    try:
        assert "acme_integrator" in registry.model_names()
        assert registry.build_model("acme_integrator").states[0].name == "x"
        text = BASE.replace("  states: [x, v]\n  controls: [u]\n  dynamics: {x: v, v: u}\n",
                            "  use: acme_integrator\n")
        text = text.replace(", v(t0) == 0, x(tf) == 0, v(tf) == 0", ", x(tf) == 0")
        assert load(write(tmp_path, text)).problem.phases[0].states[0].name == "x"
    finally:
        sys.modules.pop("acme_models", None)


def test_the_project_models_load_as_ocdsl_models_not_a_top_level_package():
    from ocdsl.symbolic import registry

    registry.model_names()
    assert "ocdsl.models.classic" in sys.modules
    assert "models" not in sys.modules and "models.classic" not in sys.modules


# ---- phases: one model, per-phase values, one-line continuity, vectors, E(tf) ---------------
TWO_PHASE = (__import__("pathlib").Path(__file__).parent / "data" / "two_phase_language.yaml").read_text()


def test_continuity_line_expands_to_time_and_every_shared_state(tmp_path):
    f = load(write(tmp_path, TWO_PHASE))
    texts = [c.text.split("   (")[0] for c in f.problem.boundary if "continuous" in c.text]
    assert texts == ["accelerate.tf == brake.t0", "accelerate.x(tf) == brake.x(t0)",
                     "accelerate.v(tf) == brake.v(t0)"]


def test_continuity_of_chosen_states_and_vectors(tmp_path):
    f = load(write(tmp_path, TWO_PHASE.replace("continuous(accelerate, brake)", "'continuous(accelerate, brake, [v])'")))
    assert [c.text.split("   (")[0] for c in f.problem.boundary if "continuous" in c.text] == \
        ["accelerate.tf == brake.t0", "accelerate.v(tf) == brake.v(t0)"]
    f = load(write(tmp_path, TWO_PHASE.replace("continuous(accelerate, brake)", "'continuous(accelerate, brake, [s])'")))
    assert sum("continuous" in c.text for c in f.problem.boundary) == 3


@pytest.mark.parametrize("link,fragment", [
    ("continuous(accelerate, brakes)", "unknown phase 'brakes'"),
    ('"continuous(accelerate, brake, [w])"', "'w' is not a state of both"),
    ("continuous(accelerate)", "at least two phases"),
])
def test_continuity_errors_name_the_line(tmp_path, link, fragment):
    with pytest.raises(SpecError, match=fragment) as e:
        load(write(tmp_path, TWO_PHASE.replace("continuous(accelerate, brake)", link)))
    assert e.value.issues[0].line == 20


def test_per_phase_parameter_values_and_their_errors(tmp_path):
    text = TWO_PHASE.replace("  brake:\n    parameters: {a: 1.0}", "  brake:\n    parameters: {a: 2.0}")
    f = load(write(tmp_path, text))
    rhs = {ph.name: ph.rhs()[1] for ph in f.problem.phases}
    assert str(rhs["accelerate"]) == "1.0*u" and str(rhs["brake"]) == "2.0*u"
    assert f.parameters["brake.a"] == 2.0
    f = load(write(tmp_path, text), parameters={"brake.a": 3.0})
    assert str(f.problem.phases[1].rhs()[1]) == "3.0*u"
    with pytest.raises(SpecError, match="did you mean 'a'"):
        load(write(tmp_path, text.replace("{a: 2.0}", "{aa: 2.0}")))


def test_top_level_constants_in_links_are_resolved_at_check_time(tmp_path):
    f = load(write(tmp_path, TWO_PHASE))
    gap = [c for c in f.problem.boundary if "gap" in c.text][0]
    assert gap.lower == 0.01 and not {s.name for s in gap.expr.free_symbols} & {"gap"}


def test_named_expression_at_a_boundary(tmp_path):
    f = load(write(tmp_path, TWO_PHASE))
    e = [c for c in f.problem.boundary if c.text == "E(tf) == 0"][0]
    assert {s.name for s in e.expr.free_symbols} == {"brake.v(tf)", "brake.x(tf)"}
    with pytest.raises(SpecError, match="uses the control u"):
        load(write(tmp_path, TWO_PHASE.replace("E: v + a*x", "E: v + a*u")))


@pytest.mark.parametrize("old,new,fragment", [
    ("E: v + a*x", "E: v + a*s", "adds a vector and a number"),
    ('"[v, a*u]"', '"[v, a*u, u]"', "has 2 components but its right-hand side has 3"),
    ("x(tf) == 0, E(tf)", "norm(x) <= 1, E(tf)", "takes vectors"),
    ("x(tf) == 0, E(tf)", "'s[2] == 0', E(tf)", "index 2 outside the 2 components"),
    ("vectors: {s: [x, v]}", "vectors: {s: [x, w]}", "unknown: w"),
])
def test_vector_errors(tmp_path, old, new, fragment):
    assert old in TWO_PHASE
    with pytest.raises(SpecError, match=fragment):
        load(write(tmp_path, TWO_PHASE.replace(old, new)))


def test_vector_helpers_build_the_expected_scalars(tmp_path):
    text = TWO_PHASE.replace("E: v + a*x", "E: 'dot(s, [1, 2]) + norm(s) + cross([x, v, 0], [1, 0, 0])[2]'")
    e = load(write(tmp_path, text)).problem.phases[0].model.expressions
    import sympy as sp

    x, v = sp.symbols("x v", real=True)
    assert sp.simplify(list(e.values())[0] - (x + 2 * v + sp.sqrt(x**2 + v**2) - v)) == 0


@pytest.mark.ipopt
def test_two_phase_file_with_the_new_constructs_solves(tmp_path):
    import ocdsl

    res = ocdsl.load(write(tmp_path, TWO_PHASE)).solve()
    assert res.ok, (res.status, res.expect)
    assert res.tf["brake"] == pytest.approx(2.0, rel=1e-8)


ROCKET_CAR = """
name: Rocket car minimum time
model:
  states: [x, v]
  controls: [u]
  dynamics: {x: v, v: u}
problem:
  time: {t0: 0, tf: free}
  constraints: [-1 <= u <= 1, x(t0) == 0, v(t0) == 0, x(tf) == 1, v(tf) == 0]
  objective: minimize tf
"""


def test_free_final_time_is_bounded_below_by_a_fixed_start(tmp_path):
    """Time runs forward: with t0 fixed and no bound on tf, minimum time used to run to
    tf = -1e20 (backwards in time the car reaches x = 1 ever "sooner")."""
    import ocdsl
    from ocdsl.spec.errors import SpecError

    loaded = ocdsl.load(write(tmp_path, ROCKET_CAR))
    assert loaded.file.problem.phases[0].tf_bounds == (0.0, float("inf"))
    res = loaded.solve()
    assert res.status == "optimal" and res.verified and abs(res.tf - 2.0) < 1e-6
    later = ROCKET_CAR.replace("time: {t0: 0, tf: free}", "time: {t0: free, tf: 3}").replace(
        "x(t0) == 0,", "x(t0) == 0, t0 >= 5,")
    with pytest.raises(SpecError, match=r"t0 <= tf = 3 \(time runs forward\)"):
        ocdsl.load(write(tmp_path, later, "later.yaml"))


def test_a_phase_with_both_ends_free_runs_forward(tmp_path):
    """With t0 and tf both free neither end bounds the other: `minimize tf - t0` flew the
    phase backwards to a duration of -10 and Ipopt called it optimal."""
    import ocdsl

    both = ROCKET_CAR.replace("time: {t0: 0, tf: free}", "time: {t0: free, tf: free}").replace(
        "x(tf) == 1,", "x(tf) == 1, 0 <= t0 <= 10, 0 <= tf <= 10,").replace(
        "minimize tf", "minimize tf - t0")
    loaded = ocdsl.load(write(tmp_path, both))
    forward = [c for c in loaded.file.problem.boundary if "time runs forward" in c.text]
    assert len(forward) == 1 and forward[0].lower == 0.0
    res = loaded.solve()
    assert res.status == "optimal" and res.verified
    assert res.objective == pytest.approx(2.0, rel=1e-6)


def test_tf_in_the_dynamics_says_what_to_write_instead(tmp_path):
    """unseen21 U4: `x: u/tf` said "unknown name 'tf' (did you mean 't'?)" although the docs list
    tf among the names; it now says where tf is not a name and what to write there."""
    text = """name: tf in the dynamics
model:
  states: [x]
  controls: [u]
  dynamics: {x: u/tf}
problem:
  time: {t0: 0, tf: free}
  constraints: [x(t0) == 0, x(tf) == 1, -1 <= u <= 1, 0.5 <= tf <= 5]
  objective: minimize integral(u**2)
"""
    with pytest.raises(SpecError) as e:
        load(write(tmp_path, text))
    issue = e.value.issues[0]
    assert issue.line == 5 and "final time is not a name in a model's dynamics" in str(issue)
    assert "did you mean" not in str(issue) and "free parameter T" in str(issue)
