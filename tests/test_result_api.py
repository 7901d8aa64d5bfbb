"""The notebook API: ocdsl.read, Result.sample / to_pandas / plot / summary / repr, and the
docstring examples of ocdsl/result_views.py run as doctests."""
import doctest
import os

import numpy as np
import pytest

import ocdsl
from conftest import ROOT
from ocdsl import result_views
from ocdsl.result import PhaseTrajectory, Result


def _two_segment_phase():
    # two segments [0, 1], [1, 2]; rows at 0, 0.5, 1, 1.5, 2; control collocated except at t = 0
    t = np.array([0.0, 0.5, 1.0, 1.5, 2.0])
    return PhaseTrajectory("main", t, states={"x": t**2},
                           controls={"u": np.array([99.0, 1.0, 2.0, 5.0, 7.0])},
                           extra={"collocated": np.array([0.0, 1.0, 1.0, 1.0, 1.0])})


def test_sample_lagrange_segments_uses_collocated_rows_of_each_segment():
    res = Result("demo", "optimal", phases=[_two_segment_phase()],
                 method={"meshes": {"main": {"breakpoints": [0.0, 0.5, 1.0]}}})
    out = res.sample([0.25, 0.75, 1.25, 1.75])
    # the verification's contract (ocdsl/verify/interpolate.py): a row on an interior boundary
    # ends the segment before it. Segment 1: line through (0.5, 1), (1, 2); segment 2: line
    # through (1.5, 5), (2, 7) (the row at t = 1 is not also the start of segment 2)
    assert out["u"][:2] == pytest.approx([0.5, 1.5])
    assert out["u"][2:] == pytest.approx([4.0, 6.0])
    # the state is the polynomial through each segment's rows: x = t^2 exactly
    assert out["x"] == pytest.approx(np.array([0.25, 0.75, 1.25, 1.75]) ** 2)


def test_sample_controls_are_the_verifications_interpolant():
    from ocdsl.verify.interpolate import control_interpolant, declared_interpolation

    res = Result("demo", "optimal", phases=[_two_segment_phase()],
                 method={"meshes": {"main": {"breakpoints": [0.0, 0.5, 1.0]}}})
    tt = np.linspace(0.0, 2.0, 17)
    traj = res.phase()
    ref = control_interpolant(traj, ["u"], [(-np.inf, np.inf)], declared_interpolation(traj, res.method)).at(tt)
    assert res.sample(tt)["u"] == pytest.approx(ref[:, 0])


def test_sample_clips_controls_to_their_bounds_and_follows_recorded_kind():
    ph = _two_segment_phase()
    ph.control_interpolation = {"kind": "previous"}
    res = Result("demo", "optimal", phases=[ph],
                 problem={"phases": {"main": {"bounds": {"u": [None, 6.0]}}}})
    out = res.sample([0.6, 1.9, 2.0])
    assert out["u"] == pytest.approx([1.0, 5.0, 6.0])   # hold, hold, clipped 7 -> 6


def test_repr_is_short_and_summary_reports_relative_error():
    res = Result("demo", "max_iter", message="Maximum iterations exceeded", objective=1.5,
                 tables={"big": {"a": np.zeros(10000)}},
                 expect=[{"name": "tf", "value": 1.1, "reference": 1.0, "rtol": 1e-3, "atol": None,
                          "error": 0.1, "relative_error": 0.1, "passed": False}])
    text = repr(res)
    assert text.startswith("<Result 'demo': max_iter") and len(text) < 200
    s = res.summary()
    assert "relative error 1.00e-01" in s and "FAIL" in s and "Maximum iterations" in s


def test_to_pandas_multi_phase_has_phase_column_and_units():
    pytest.importorskip("pandas")
    a = PhaseTrajectory("a", np.array([0.0, 1.0]), states={"x": np.array([0.0, 1.0])})
    b = PhaseTrajectory("b", np.array([1.0, 2.0]), states={"x": np.array([1.0, 3.0])})
    res = Result("demo", "optimal", phases=[a, b], problem={"units": {"x": "km"}})
    df = res.to_pandas()
    assert list(df["phase"]) == ["a", "a", "b", "b"] and df.attrs["units"] == {"x": "km"}
    assert list(res.to_pandas("b")["x"]) == [1.0, 3.0]


def test_to_pandas_without_pandas_says_how_to_install(monkeypatch):
    import builtins

    real = builtins.__import__

    def no_pandas(name, *args, **kwargs):
        if name == "pandas":
            raise ImportError("no pandas")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_pandas)
    with pytest.raises(ImportError, match=r"ocdsl\[notebook\]"):
        Result("demo", "optimal", phases=[_two_segment_phase()]).to_pandas()


def test_plot_returns_a_figure_with_one_axis_per_variable():
    fig = Result("demo", "optimal", phases=[_two_segment_phase()]).plot()
    assert [ax.get_title() for ax in fig.axes] == ["x", "u"]


def test_read_gives_back_the_written_result(tmp_path):
    res = Result("demo", "optimal", objective=2.0, tf=2.0, phases=[_two_segment_phase()],
                 problem={"phases": {"main": {"states": ["x"], "controls": ["u"]}}})
    back = ocdsl.read(res.write(tmp_path / "run"))
    assert repr(back) == repr(res)
    assert back.sample(0.75)["u"] == pytest.approx(res.sample(0.75)["u"])


def test_a_table_of_counts_is_written_as_integers_and_reads_back(tmp_path):
    """mesh_history.csv said "iteration 1.0, segments 10.0": counts are written as counts."""
    res = Result("demo", "optimal", objective=2.0, tf=2.0, phases=[_two_segment_phase()],
                 tables={"mesh_history": {"iteration": np.array([1, 2]), "segments": np.array([10, 14]),
                                          "max_error": np.array([2.5e-2, 1e-7])}})
    folder = res.write(tmp_path / "run")
    lines = (folder / "tables" / "mesh_history.csv").read_text().splitlines()
    assert lines == ["iteration,segments,max_error", "1,10,0.025", "2,14,1e-07"]
    back = ocdsl.read(folder).tables["mesh_history"]
    assert back["segments"].tolist() == [10.0, 14.0] and back["max_error"].tolist() == [2.5e-2, 1e-7]


@pytest.mark.ipopt
def test_docstring_examples(tmp_path):
    pytest.importorskip("pandas")
    cwd = os.getcwd()
    os.chdir(ROOT)
    try:
        failures, tried = doctest.testmod(result_views, extraglobs={"tmp": tmp_path},
                                          optionflags=doctest.ELLIPSIS)
    finally:
        os.chdir(cwd)
    assert tried >= 10 and failures == 0


def test_sample_does_not_extrapolate_and_names_the_phase_that_holds_the_time():
    """unseen52 F1: sample(2) of the first phase of a two-phase run (span [0, 1]) gave the
    polynomial's extrapolation (x = 1, v = 2 for 0, 0), and the brachistochrone at t = 5 put
    x at 183 m on a 10 m track."""
    import numpy as np

    from ocdsl.result import PhaseTrajectory, Result

    a = PhaseTrajectory("accelerate", np.array([0.0, 0.5, 1.0]), states={"x": np.array([0.0, 0.25, 1.0])})
    b = PhaseTrajectory("brake", np.array([1.0, 1.5, 2.0]), states={"x": np.array([1.0, 1.75, 2.0])})
    res = Result("two", "optimal", phases=[a, b])
    assert res.sample(0.5)["x"] == pytest.approx([0.25])
    with pytest.raises(ValueError, match=r"t = 2 is outside phase 'accelerate'.*phase 'brake' holds it"):
        res.sample(2.0)
    assert res.sample(2.0, phase="brake")["x"] == pytest.approx([2.0])
    with pytest.raises(ValueError, match="t = 5 is outside phase 'brake'"):
        res.sample([1.5, 5.0], phase="brake")


def test_the_api_takes_parameters_as_the_command_line_does_and_refuses_clearly(configs, tmp_path):
    """unseen52 F7, F8: `parameters={"l": "1/9"}` was a bare "could not convert string to
    float" (the command line takes `--param l=1/9`), and a warm start from a missing folder a
    raw FileNotFoundError naming the result.json inside it."""
    import ocdsl

    bd = configs / "brachistochrone.yaml"
    assert ocdsl.load(bd, {"g": "98/10"}).file.parameters == ocdsl.load(bd, {"g": 9.8}).file.parameters
    with pytest.raises(ValueError, match=r"parameters\['g'\] = '1/9x' is not a finite number"):
        ocdsl.load(bd, {"g": "1/9x"})
    with pytest.raises(ValueError, match=r"parameters\['g'\] = inf"):
        ocdsl.load(bd).solve(parameters={"g": float("inf")})
    with pytest.raises(ValueError, match="not a run folder \\(no result.json\\)"):
        ocdsl.load(bd).solve(warm_start=tmp_path / "nowhere")
    from ocdsl.api import run_file

    with pytest.raises(ValueError, match="not a run folder"):
        run_file(bd, None, warm_start=tmp_path / "nowhere")


def test_solves_from_threads_run_one_at_a_time_and_leave_the_streams_alone(configs):
    """unseen52 F5: four solves from four threads all ended `error` (each `optimal` alone),
    and the process's stdout stayed redirected afterwards."""
    import os
    from concurrent.futures import ThreadPoolExecutor

    import ocdsl

    before = os.readlink("/proc/self/fd/1") if os.path.exists("/proc/self/fd/1") else None
    files = [configs / "brachistochrone.yaml", configs / "double_integrator.yaml", configs / "brachistochrone.yaml"]
    with ThreadPoolExecutor(3) as ex:
        results = list(ex.map(lambda p: ocdsl.load(p).solve(), files))
    assert [r.status for r in results] == ["optimal"] * 3, [r.message for r in results]
    assert results[0].objective == pytest.approx(results[2].objective, rel=1e-12)
    if before is not None:
        assert os.readlink("/proc/self/fd/1") == before
