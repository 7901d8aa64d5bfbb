"""The ASL sets the x87 unit to 53-bit precision whenever it reads an NL file, for the rest of
the process. ocdsl's solves restore the floating-point environment, so that a run gives the
same numbers whatever was solved before it in the same process (a study, a test worker)."""
import numpy as np
import pytest

from ocdsl.solve.process_state import floating_point_environment_kept

pytestmark = pytest.mark.ipopt

X87_EXTENDED = np.finfo(np.longdouble).nmant >= 63  # 80-bit long double: x86


def _x87_extended_precision() -> bool:
    # 1 + 2^-60 is representable in the 64-bit mantissa, not in a 53-bit one
    return bool(np.longdouble(1) + np.longdouble(2.0) ** -60 != 1)


def _lander():
    from ocdsl.models.lunar_lander import seed_problem
    from ocdsl.transcribe.flat_bspline import build_flat_bspline

    phases, links = seed_problem(100.0, None)
    return build_flat_bspline(phases, links)


def _read_by_asl(model):
    from ocdsl.solve.ipopt import pynumero_nlp

    pynumero_nlp(model)


@pytest.mark.skipif(not X87_EXTENDED, reason="no x87 extended precision on this platform")
def test_the_asl_changes_the_environment_and_the_guard_restores_it():
    assert _x87_extended_precision()
    with floating_point_environment_kept():
        _read_by_asl(_lander().model)
        assert not _x87_extended_precision()   # what the guard is for: the ASL's fpinit
    assert _x87_extended_precision()


@pytest.mark.skipif(not X87_EXTENDED, reason="no x87 extended precision on this platform")
def test_a_pynumero_solve_leaves_the_environment_as_it_found_it():
    from ocdsl.solve import ipopt

    nlp = _lander()   # the flat B-spline model takes the PyNumero route
    info = ipopt.solve(nlp.model, {"tol": 1e-9})
    assert info.status == "optimal" and info.nlp["evaluation"].startswith("PyNumero")
    assert _x87_extended_precision()


def test_the_same_solve_gives_the_same_numbers_after_another_solve():
    """Seed 2 strategy 1 (flat lander, h = 100 km): before the guard, its least-squares start
    moved by 3e-14 after the first PyNumero solve in a process, and Ipopt went from there to a
    different local optimum (t_f 1036.8729 s the first time, 1037.4543 s every later time)."""
    from ocdsl.transcribe.flat_bspline import solve_flat

    from ocdsl.solve import ipopt

    first = solve_flat(_lander()).tf["main"]
    assert ipopt.solve(_lander().model, {"tol": 1e-9}).status == "optimal"
    again = solve_flat(_lander()).tf["main"]
    assert again == first
