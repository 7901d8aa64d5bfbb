"""A condition written twice (unseen9 F1): refused at its line, and where a dependence slips
past that check, the certificate's multiplier check fails the run instead of passing a
non-stationary point as optimal."""
import math
from pathlib import Path

import pytest
from scipy.optimize import minimize_scalar

from ocdsl.api import compile_file
from ocdsl.spec.errors import SpecError

REPEATED = Path(__file__).parent / "data" / "two_stage_repeated_time_link.yaml"
TIME_LINK = "  - stage1.tf == stage2.t0\n"


def _staging_optimum():
    """Full throttle in both stages (gravity loss): burnout speed in closed form per split,
    maximised over the split (c = 3, g = 1, F = 3 then 1.5, m0 = 1, MP = 0.8, k = 0.1)."""
    c, g, F1, F2, MP, k = 3.0, 1.0, 3.0, 1.5, 0.8, 0.1

    def v_burnout(mp1):
        m1 = 1.0 - mp1
        v1 = c * math.log(1.0 / m1) - g * mp1 * c / F1
        m2 = m1 - k * mp1
        return v1 + c * math.log(m2 / (m2 - (MP - mp1))) - g * (MP - mp1) * c / F2

    best = minimize_scalar(lambda p: -v_burnout(p), bounds=(0.05, 0.75), method="bounded",
                           options={"xatol": 1e-12})
    return best.x, -best.fun


def test_a_link_that_continuous_adds_is_refused_at_its_line():
    text = REPEATED.read_text()
    line = text[:text.index(TIME_LINK)].count("\n") + 1
    with pytest.raises(SpecError) as e:
        compile_file(REPEATED)
    msg = str(e.value)
    assert f"{REPEATED.name}:{line}: repeats `stage1.tf == stage2.t0`, which `continuous(stage1, stage2, [h, v])` adds" in msg


def test_an_equality_repeated_up_to_a_factor_is_refused_but_a_repeated_value_is_not(tmp_path):
    base = """
name: repeated
model: {states: [x], controls: [u], dynamics: {x: u}}
problem:
  time: {t0: 0, tf: 1}
  constraints: [x(t0) == 0, x(t0) == 0, EXTRA]
  objective: minimize integral(u**2)
"""
    ok = tmp_path / "ok.yaml"
    ok.write_text(base.replace("EXTRA", "x(tf) + x(t0) == 1"))
    compile_file(ok)            # x(t0) == 0 twice fixes one variable twice: no row, no error
    bad = tmp_path / "bad.yaml"
    bad.write_text(base.replace("EXTRA", "x(tf) + x(t0) == 1, 2*x(tf) + 2*x(t0) == 2"))
    with pytest.raises(SpecError, match="repeats `x\\(tf\\) \\+ x\\(t0\\) == 1`"):
        compile_file(bad)


@pytest.mark.ipopt
def test_the_two_stage_split_without_the_repeat_is_the_optimum(tmp_path):
    from ocdsl.api import run_file

    path = tmp_path / "once.yaml"
    path.write_text(REPEATED.read_text().replace(TIME_LINK, ""))
    res = run_file(path, tmp_path / "run")
    split, speed = _staging_optimum()
    assert res.status == "optimal" and res.verified and res.ok
    assert res.objective == pytest.approx(speed, rel=1e-7)
    assert res.parameters["mp1"] == pytest.approx(split, rel=1e-6)


@pytest.mark.ipopt
def test_a_repeat_past_the_file_check_fails_the_certificate_not_optimal(tmp_path, monkeypatch):
    """Without the compile-time check the NLP has two identical rows: Ipopt ends 'optimal'
    with multipliers +-1.4e17 at a split that is not the optimum (J 5e-4 low, start- and
    mesh-dependent); the certificate's multiplier check fails the run."""
    from ocdsl.api import run_file
    from ocdsl.spec.compile.constraints import ConstraintCompiler

    monkeypatch.setattr(ConstraintCompiler, "check_repeated", lambda self, boundary, phases=(): None)
    res = run_file(REPEATED, tmp_path / "run")
    split, speed = _staging_optimum()
    from ocdsl.result import certificate_verdict

    assert certificate_verdict(res.certificate) == "failed" and res.certificate["failed"] == ["multipliers"]
    assert "linearly dependent" in res.certificate["multipliers"]["reason"]
    assert not res.ok
    # the point it stopped at is not the optimum: what the check is for
    assert abs(res.objective - speed) > 1e-5


def test_an_integral_written_twice_is_one_integral_and_its_repeated_bound_is_refused(tmp_path):
    """unseen10 F4: `integral(u**2) <= 1.5` twice made two integrals and two identical rows."""
    text = """
name: repeated integral
model: {states: [x, v], controls: [u], dynamics: {x: v, v: u}}
problem:
  time: {t0: 0, tf: free}
  constraints: [x(t0) == 0, v(t0) == 0, x(tf) == 1, v(tf) == 0, integral(u**2) <= 1.5, 0.1 <= tf <= 10]
  objective: minimize tf + integral(u**2)
"""
    ok = tmp_path / "ok.yaml"
    ok.write_text(text)
    ph = compile_file(ok).problem.phases[0]
    assert len(ph.integrals) == 1            # the objective's and the constraint's are one
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace("integral(u**2) <= 1.5,", "integral(u**2) <= 1.5, integral(u**2) <= 1.5,"))
    with pytest.raises(SpecError, match=r"bad.yaml:6: repeats `integral\(u\*\*2\) <= 1.5`"):
        compile_file(bad)
