"""Issue 25's figure and table defects, each on a small synthetic run folder: the report
draws what the run folder declares (objectives, swept parameters, physical time), not what
column guessing finds."""
from __future__ import annotations

import base64
import csv
import json
import re
from pathlib import Path

import numpy as np
import pytest

from ocdsl.report import make_comparison_report, make_index, make_report
from ocdsl.report.build import build_comparison_html, build_run_html
from ocdsl.report.build.pareto import pareto_criteria
from ocdsl.result import PhaseTrajectory, Result


def _svgs(html: str) -> list[str]:
    return [base64.b64decode(b).decode() for b in
            re.findall(r'<figure[^>]*>\s*<img src="data:image/svg\+xml;base64,([^"]+)"', html)]


def _captions(html: str) -> list[str]:
    return re.findall(r"<figcaption><b>Figure \d+\.</b> (.*?)</figcaption>", html, re.S)


def _table(html: str, caption_start: str) -> list[list[str]]:
    i = html.index(caption_start)
    body = html[i:html.index("</table>", i)]
    return [re.findall(r"<t[hd][^>]*>(.*?)</t[hd]>", r, re.S) for r in re.findall(r"<tr>(.*?)</tr>", body, re.S)]


# ------------------------------------------------------------------------ Pareto
def test_pareto_axes_are_the_results_objectives(tmp_path):
    """A Pareto run folder's front is drawn in its objectives' plane, whatever columns come
    first in the table (the seed-4 reports plotted family_id against label_major)."""
    n = 6
    tab = {"family_id": np.array([0, 0, 0, 1, 1, 1.0]), "label_major": np.array([1, 1, 1, 2, 2, 2.0]),
           "t_mot": np.linspace(0.5, 1.5, n), "t_sum": np.linspace(40, 20, n), "pareto": np.ones(n)}
    res = Result(name="front", status="optimal", extra={"objectives": ["t_mot", "t_sum"]},
                 tables={"pareto": tab}, problem={"name": "front"})
    assert pareto_criteria([{k: v[0] for k, v in tab.items()}], {}) == ("family_id", "label_major")  # the old guess
    html = build_run_html(res.write(tmp_path / "p"))
    caps = [c for c in _captions(html) if "Pareto front" in c]
    assert caps and "(t_mot, t_sum)" in caps[0]


@pytest.mark.parametrize("senses", [("maximize", "minimize"), ("minimize", "minimize"),
                                    ("minimize", "maximize"), ("maximize", "maximize")])
def test_a_pareto_front_is_joined_through_dominated_corners_only(senses):
    """unseen35 P43: range (maximised) against time (minimised), x(T) = T^2 / 4: the min-min
    staircase joined the points through corners such as (range 1.0, time 1.5), better than
    both neighbours, drawing an unattainable region as the front. Each corner of the drawn
    staircase is now dominated by a point of the set, whatever the senses."""
    from matplotlib.cbook import STEP_LOOKUP_MAP

    from ocdsl.report.figures.pareto import fig_pareto

    better = [1.0 if s == "maximize" else -1.0 for s in senses]
    # a trade-off: improving the first criterion worsens the second
    t = np.linspace(1.0, 3.0, 5)
    a = t ** 2 / 4 * better[0]
    b = -t * better[1]
    rows = [{"a": x, "b": y, "pareto": 1} for x, y in zip(a, b)]
    fig = fig_pareto(rows, ("a", "b"), senses=senses)[0].figure
    line = next(ln for ln in fig.axes[0].get_lines() if ln.get_label() == "Pareto set")
    xs, ys = STEP_LOOKUP_MAP[line.get_drawstyle()](*line.get_data())
    for cx, cy in zip(xs, ys):
        assert any((x - cx) * better[0] >= -1e-12 and (y - cy) * better[1] >= -1e-12 for x, y in zip(a, b)), \
            (senses, cx, cy)


# ------------------------------------------------------------------------ sweeps
def _sweep_folder(folder: Path, swept: dict, rows: list[dict]) -> Path:
    folder.mkdir(parents=True)
    with open(folder / "study.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    (folder / "study.json").write_text(json.dumps({"name": "sweep", "spec": {"sweep": swept},
                                                   "study_file": "/home/someone/private/study.yaml",
                                                   "client_host": "secret-host", "state": "complete"}))
    return folder


def test_one_dimensional_sweep_plots_outputs_against_the_parameter(tmp_path):
    """The `sweep` index column is not a second parameter: a 1-D sweep gets objective and
    t_f against the swept parameter, not histograms; no paths or host names in the report."""
    rows = [{"id": f"p{i}", "E": 2.2 + 0.05 * i, "sweep": i, "seed": "", "status": "optimal",
             "verification": "verified", "objective": 1.37 + 0.01 * i, "tf": 1.37 + 0.004 * i, "iterations": 20,
             "wall_time_s": 1.4, "host": "secret-host", "warm_start": "", "message": "Optimal Solution Found."}
            for i in range(10)]
    folder = _sweep_folder(tmp_path / "s", {"grid": {"E": {"start": 2.2, "stop": 2.65, "num": 10}}}, rows)
    html = make_comparison_report([folder], tmp_path / "out", formats=("html",))[0].read_text()
    caps = _captions(html)
    assert any("against the swept parameter E" in c for c in caps), caps
    assert not any("Distribution" in c for c in caps)
    assert "secret-host" not in html and "/home/someone" not in html and "study.yaml" in html
    study = _table(html, "Study table (study.csv)")
    assert "sweep" not in study[0] and "host" not in study[0] and "message" not in study[0]


def test_zip_sweep_with_per_phase_tf_gets_one_column_per_phase(tmp_path):
    rows = [{"id": f"p{i}", "h_v": float(5 - i), "t_ref": 1000.0 + i, "sweep": i, "status": "optimal",
             "objective": 148.0 + i, "tf": json.dumps({"braking": 950.0 + i, "descent": 1030.0 + i}),
             "message": "ok" if i else "Maximum Number of Iterations Exceeded."} for i in range(5)]
    rows[0]["status"] = "max_iter"
    folder = _sweep_folder(tmp_path / "z", {"zip": {"h_v": [5, 4, 3, 2, 1], "t_ref": [1000, 1001, 1002, 1003, 1004]}},
                           rows)
    html = make_comparison_report([folder], tmp_path / "out", formats=("html",))[0].read_text()
    head = _table(html, "Study table (study.csv)")[0]
    assert head[:2] == ["h v", "t ref"] and "tf (braking)" in head and "tf (descent)" in head
    assert "{" not in "".join(c for row in _table(html, "Study table (study.csv)") for c in row)
    # the message only where a point failed
    assert html.count("Maximum Number of Iterations Exceeded.") == 1 and ">ok<" not in html
    assert any("against the swept parameter h_v" in c for c in _captions(html))


# -------------------------------------------------------------------------- mesh
def test_mesh_figure_has_the_error_panel_and_the_mesh_per_iteration(tmp_path):
    it = np.arange(1.0, 10.0)
    mh = {"iteration": it, "phase": np.zeros(9), "segments": 2 + 3 * it, "min_degree": np.full(9, 3.0),
          "max_degree": np.full(9, 3.0), "nlp_variables": 20 + 30 * it, "nlp_constraints": 15 + 20 * it,
          "ipopt_iterations": np.full(9, 12.0), "objective": 1.0 + 1e-3 / it, "max_error": 10.0 ** -it,
          "max_error_segment": np.zeros(9), "max_error_t": np.zeros(9), "time_s": np.full(9, 0.5)}
    hist = [{"iteration": int(k), "meshes": {"main": {"breakpoints": list(np.linspace(0, 1, 3 + 3 * int(k)))}}}
            for k in it]
    t = np.linspace(0, 1, 11)
    res = Result(name="mesh", status="optimal", objective=1.0, tf=1.0, method={"mesh": {"tolerance": 1e-8}},
                 phases=[PhaseTrajectory("main", t, {"x": t}, {"u": t})], extra={"mesh_history": hist},
                 tables={"mesh_history": mh, "mesh_error": {"phase": np.zeros(3), "t_start": np.array([0, .3, .6]),
                                                            "t_end": np.array([.3, .6, 1.]),
                                                            "error": np.array([1e-9, 3e-9, 2e-9])}},
                 problem={"name": "mesh", "phases": {"main": {"states": ["x"], "controls": ["u"]}}})
    html = build_run_html(res.write(tmp_path / "m"))
    caps = _captions(html)
    assert any("Mesh refinement history" in c for c in caps)
    assert any("Mesh breakpoints of every refinement iteration" in c for c in caps)
    assert any("final mesh" in c for c in caps)
    hist_svg = _svgs(html)[[i for i, c in enumerate(caps) if "Mesh refinement history" in c][0]]
    # 9 iterations, more than the old panel limit would have kept with the constants; the
    # error panel is there (log axis label), the constant columns are not panels
    # the error panel is there, and the columns that change (segments, NLP variables, objective);
    # the constant ones (degrees, Ipopt iterations, time) are not panels
    assert "<!-- largest estimated error -->" in hist_svg
    assert hist_svg.count('id="axes_') == 4
    mesh_tab = _table(html, "Mesh refinement history.")
    assert "phase" not in mesh_tab[0] and "min degree" not in mesh_tab[0]
    assert "The same in every row" in html


# ----------------------------------------------------------------------- Sundman
def test_sundman_run_shows_physical_time(tmp_path):
    """The independent variable s runs to 31.87, the flight time is 1.5448: the time axes
    and the summary show the clock state, not s."""
    s = np.linspace(0, 31.87, 50)
    clock = 1.5448 * (s / 31.87) ** 1.3
    res = Result(name="sundman", status="optimal", objective=1.5448, tf=31.87,
                 phases=[PhaseTrajectory("main", s, {"x": np.cos(s), "time": clock}, {"u": np.sin(s)})],
                 problem={"name": "sundman", "time_variable": "time", "units": {"t": "TU", "time": "TU", "x": "LU"},
                          "phases": {"main": {"states": ["x", "time"], "controls": ["u"]}}})
    html = build_run_html(res.write(tmp_path / "s"))
    summary = _table(html, "Solution summary")
    flight = [r for r in summary if r and r[0].startswith("flight time")]
    assert flight and flight[0][1] == "1.5448"
    assert not any(r[0].startswith("final time t_f") for r in summary if r)
    svg = _svgs(html)[[i for i, c in enumerate(_captions(html)) if c.startswith("State histories")][0]]
    # the x axis ends near 1.5 (physical time), not at 30
    ticks = [float(x) for x in re.findall(r"<!-- ([\d.]+) -->", svg) if re.fullmatch(r"[\d.]+", x)]
    assert ticks and max(ticks) < 2.0, ticks


# ------------------------------------------------------------------ controllers
def test_controller_comparison_table_has_numbers_in_every_cell(tmp_path):
    t = np.linspace(0, 10, 101)
    tables, extra = {}, {}
    for i, c in enumerate(("lqr", "sdre", "theta_d")):
        tables[f"closed_loop_{c}"] = {"t": t, "phi": 0.17 * np.exp(-t) * np.cos(t), "h1": 0.3 + 0 * t,
                                      "u1": -np.exp(-t)}
        extra[c] = {"status": "stable", "metrics": {
            "cost": 6.4 + 0.01 * i, "control_cost": 3.5, "peak_control": [1.2, 1.3, 1.1 + i],
            "settling_time@0.00174533": 40.0 + i, "settling_time@1.74533e-05": 80.0 + i,
            "states": {"phi": {"overshoot_pct": 42.0 + i}},
            "controller_time_s": {"mean": 1e-5 * (1 + i), "p95": 2e-5 * (1 + i), "max": 5e-5}}}
    phases = [PhaseTrajectory(c, t, {"phi": tables[f"closed_loop_{c}"]["phi"]}, {"u1": -np.exp(-t)})
              for c in ("lqr", "sdre", "theta_d")]
    res = Result(name="att", status="stable", tables=tables, extra=extra, phases=phases,
                 problem={"name": "att", "units": {"phi": "rad", "t": "s"},
                          "phases": {"main": {"states": ["phi", "h1"], "controls": ["u1"]}}})
    html = build_run_html(res.write(tmp_path / "c"))
    rows = _table(html, "Controller comparison")
    assert rows[0][:4] == ["controller", "status", "settling to 0.1° [s]", "settling to 0.001° [s]"]
    assert len(rows) == 4
    for r in rows[1:]:
        assert all(c not in ("", "—") for c in r), r
    cl = _table(html, "Closed-loop runs")
    assert all(c not in ("", "—") for r in cl[1:] for c in r)      # timing from the metrics
    # the final size counts the regulated states only (not the wheel momentum h1 = 0.3)
    assert all(float(r[3].replace("−", "-")) < 0.1 for r in cl[1:])
    # each law's run is drawn once (its phase and its closed-loop table are the same run)
    caps = _captions(html)
    assert any(c.startswith("Closed-loop state responses") for c in caps)
    assert not any(c.startswith("State histories") for c in caps)


# --------------------------------------------------------------- statuses
def test_failed_certificate_shows_on_the_badge_and_in_the_index(tmp_path):
    t = np.linspace(0, 1, 11)
    res = Result(name="mg", status="optimal", objective=1.0, tf=1.0,
                 phases=[PhaseTrajectory("main", t, {"x": t}, {"u": t})],
                 expect=[{"name": "tf", "value": 1.0, "reference": 1.0, "rtol": 1e-6, "error": 0.0, "passed": True}],
                 certificate={"passed": False, "failed": ["hamiltonian"],
                              "hamiltonian": {"relative_max_deviation": 0.2, "expected": -0.0, "passed": False},
                              "tolerances": {"hamiltonian_max": 0.03}},
                 verification={"status": "verified", "tolerance": 1e-5, "checks": [], "summary": "verified"},
                 problem={"name": "mg", "phases": {"main": {"states": ["x"], "controls": ["u"]}}})
    run = res.write(tmp_path / "mg")
    make_report(run, formats=("html",))
    head = (run / "report.html").read_text().split("</header>")[0]
    assert re.search(r'certificate <span class="badge fail"[^>]*>failed</span>', head)
    # a failed certificate fails the run (Result.ok, exit 1; docs/verification.md)
    assert re.search(r'overall <span class="badge fail"[^>]*>not ok \(exit 1\)</span>', head)
    assert "expected 0;" in build_run_html(run) or "expected 0<" in build_run_html(run)    # not -0
    index = make_index([run], tmp_path / "index.html", []).read_text()
    item = re.search(r"<li>.*?</li>", index, re.S).group(0)
    assert re.search(r'certificate <span class="badge fail"[^>]*>failed</span>', item)


def test_maximize_best_objective_is_the_largest(tmp_path):
    starts = [{"start": i, "status": "optimal", "objective": v} for i, v in enumerate([149.85, 149.93, 149.90])]
    res = Result(name="max", status="optimal", objective=149.93, extra={"starts": starts},
                 problem={"name": "max", "objective": {"sense": "maximize"}})
    html = build_run_html(res.write(tmp_path / "mx"))
    assert "best objective 149.93" in html


def test_loose_bounds_do_not_flatten_the_curves(tmp_path):
    """h <= 1e6 on a descent from 1: the axis spans the data (the bound is not drawn), while a
    bound the state reaches (h >= 0) is drawn."""
    t = np.linspace(0, 1, 21)
    res = Result(name="land", status="optimal", objective=1.0, tf=1.0,
                 phases=[PhaseTrajectory("main", t, {"h": 1 - t ** 2}, {"u": t})],
                 problem={"name": "land", "phases": {"main": {"states": ["h"], "controls": ["u"],
                                                              "bounds": {"h": [0.0, 1.0e6], "u": [0.0, 1.0]}}}})
    html = build_run_html(res.write(tmp_path / "l"))
    svg = _svgs(html)[[i for i, c in enumerate(_captions(html)) if c.startswith("State histories")][0]]
    ticks = [float(x) for x in re.findall(r"<!-- (−?[\d.]+) -->", svg.replace("−", "-"))
             if re.fullmatch(r"-?[\d.]+", x)]
    assert ticks and max(ticks) <= 2.0, ticks
    assert "<!-- bound -->" in svg


def test_polar_positions_are_drawn_as_height_against_downrange(tmp_path):
    t = np.linspace(0, 1000, 41)
    r, th = 1738 + 15 * (1 - (t / 1000) ** 2), 0.3 * t / 1000
    res = Result(name="lander", status="optimal", objective=1.0, tf=1000.0,
                 phases=[PhaseTrajectory("main", t, {"r": r, "theta": th}, {"u": t})],
                 problem={"name": "lander", "positions": ["r", "theta"], "units": {"r": "km", "theta": "rad"},
                          "phases": {"main": {"states": ["r", "theta"], "controls": ["u"]}}})
    html = build_run_html(res.write(tmp_path / "p"))
    cap = [c for c in _captions(html) if c.startswith("Trajectory from")]
    assert cap and "height above the end point against downrange" in cap[0]
    svg = _svgs(html)[_captions(html).index(cap[0])]
    ticks = [float(x) for x in re.findall(r"<!-- ([\d.]+) -->", svg)]
    assert max(ticks) < 1000          # heights of 15 km and downrange of 520 km, not r = 1738 km


def test_pareto_set_takes_its_points_verification(tmp_path):
    from ocdsl.report.build import load_run

    run = Result(name="set", status="optimal", extra={"objectives": ["a", "b"]}, problem={"name": "set"}).write(
        tmp_path / "set")
    for i, st in enumerate(("verified", "verified")):
        Result(name=f"p{i}", status="optimal", verification={"status": st, "checks": []}).write(
            run / "points" / f"p{i}")
    res, _ = load_run(run)
    assert res.verification["status"] == "verified" and res.ok
    Result(name="p2", status="optimal", verification={"status": "failed", "checks": []}).write(run / "points" / "p2")
    res, _ = load_run(run)
    assert res.verification["status"] == "failed" and "2 of 3 points verified" in res.verification["summary"]
    head = build_run_html(run).split("</header>")[0]
    assert re.search(r'verification <span class="badge fail"[^>]*>failed</span>', head)


def test_a_table_wider_than_the_page_is_split_with_its_key_column(tmp_path):
    cols = {"factor": np.array([0.5, 1.0, 2.0])}
    for c in ("lqr", "sdre", "theta-d"):
        for q in ("stable", "cost", "peak_control", "settling", "after60", "after150"):
            cols[f"{c}.{q}"] = np.array([1.0, 2.0, 3.0])
    res = Result(name="rob", status="stable", tables={"robustness": cols}, problem={"name": "rob"})
    html = build_run_html(res.write(tmp_path / "r"))
    heads = [_table(html, f"Table tables/robustness.csv (part {i} of 3")[0] for i in (1, 2, 3)]
    assert all(h[0] == "factor" and len(h) == 7 for h in heads)
    assert heads[0][1].startswith("lqr.") and heads[2][1].startswith("theta")


# ------------------------------------------------------------------------ angles, colour bars
def test_an_angle_crossing_pi_is_drawn_unwrapped():
    """A thrust angle beta that leaves [-pi, pi) is one continuous curve, not a 2 pi jump,
    and the caption says so; a non-angle with the same jump is drawn as it is."""
    from ocdsl.report import figures as F

    t = np.linspace(0.0, 1.0, 50)
    beta = np.angle(np.exp(1j * (2.5 + 1.5 * t)))          # 2.5 -> 4.0 rad, wrapped at pi
    res = Result(name="wrap", status="optimal", problem={"units": {"beta": "rad", "q": "m"}},
                 phases=[PhaseTrajectory("main", t, {"q": beta.copy()}, {"beta": beta})])
    (ctrl,) = [f for f in F.fig_states_controls(res) if f.key.startswith("controls")]
    y = ctrl.figure.axes[0].get_lines()[0].get_ydata()
    assert np.allclose(y, 2.5 + 1.5 * t) and "beta unwrapped" in ctrl.caption
    (st,) = [f for f in F.fig_states_controls(res) if f.key.startswith("states")]
    assert np.allclose(st.figure.axes[0].get_lines()[0].get_ydata(), beta) and "unwrapped" not in st.caption


def test_an_angle_without_a_value_at_the_phase_start_is_still_drawn_unwrapped():
    """LGR exports no control at the phase start (NaN): np.unwrap alone would turn the whole
    curve into NaN, an empty panel."""
    from ocdsl.report import figures as F

    t = np.linspace(0.0, 1.0, 50)
    beta = np.angle(np.exp(1j * (2.5 + 1.5 * t)))
    beta[0] = np.nan
    res = Result(name="wrap", status="optimal", problem={"units": {"beta": "rad"}},
                 phases=[PhaseTrajectory("main", t, {"q": t.copy()}, {"beta": beta})])
    (ctrl,) = [f for f in F.fig_states_controls(res) if f.key.startswith("controls")]
    y = np.asarray(ctrl.figure.axes[0].get_lines()[0].get_ydata(), float)
    assert np.isnan(y[0]) and np.allclose(y[1:], 2.5 + 1.5 * t[1:]) and "beta unwrapped" in ctrl.caption


def test_many_runs_coloured_in_order_get_a_colour_bar():
    from ocdsl.report import figures as F

    t = np.linspace(0.0, 1.0, 20)
    runs = [Result(name=f"p{i:02d}", status="optimal", problem={},
                   phases=[PhaseTrajectory("main", t, {"x": t * i})]) for i in range(14)]
    (fig,) = F.fig_compare_runs(runs)
    bars = [ax for ax in fig.figure.axes if ax.get_label() == "<colorbar>"]
    assert len(bars) == 1 and bars[0].get_ylabel() == "run, in order"
    (few,) = F.fig_compare_runs(runs[:3])
    assert not [ax for ax in few.figure.axes if ax.get_label() == "<colorbar>"]


def test_angles_the_file_gave_in_degrees_are_drawn_in_degrees():
    """seed3_attitude writes x0 as ``phi: 10deg``: its angle histories are drawn in degrees
    (the run keeps radians); an angle given in radians stays in radians."""
    from ocdsl.report import figures as F
    from ocdsl.spec.controller import degree_inputs

    assert degree_inputs({"phi": "10deg", "theta": "-2.5 deg", "psi": 0.1, "wx": "pi/18"}) == ["phi", "theta"]
    t = np.linspace(0.0, 10.0, 30)
    phi, psi = np.radians(10.0) * np.exp(-t), 0.1 * np.exp(-t)
    cl = {"closed_loop_lqr": {"t": t, "phi": phi, "psi": psi}}
    problem = {"units": {"phi": "rad", "psi": "rad"}, "display_units": {"phi": "deg"},
               "phases": {"main": {"states": ["phi", "psi"], "controls": []}}}
    (fig,) = F.fig_closed_loop(cl, problem)
    ax_phi, ax_psi = fig.figure.axes[:2]
    assert np.allclose(ax_phi.get_lines()[0].get_ydata(), np.degrees(phi)) and "deg" in ax_phi.get_ylabel()
    assert np.allclose(ax_psi.get_lines()[0].get_ydata(), psi) and "rad" in ax_psi.get_ylabel()


def test_a_control_bounded_differently_per_phase_has_a_row_per_bounds():
    """unseen9 F7: burn-coast-burn with u fixed to 1, 0, -1 showed [1, 1] for all three."""
    from ocdsl.report.tables.problem import variables_table
    from ocdsl.result import Result

    phases = {name: {"states": ["x"], "controls": ["u"], "bounds": {"u": [b, b]}}
              for name, b in (("burn1", 1.0), ("coast", 0.0), ("burn2", -1.0))}
    phases["burn3"] = {"states": ["x"], "controls": ["u"], "bounds": {"u": [1.0, 1.0]}}
    t = variables_table(Result("r", "optimal", problem={"phases": phases}), "controls")
    text = repr(t)
    for phs in ("burn1, burn3", "coast", "burn2"):
        assert phs in text, text
    assert len(t["rows"]) == 3, t["rows"]


def test_a_pareto_table_shows_its_labels_and_families_as_text():
    """unseen9 F8: labels 'e.1', 'e.2' were shown as 'label major NaN', 'label minor 1, 2'."""
    import numpy as np

    from ocdsl.report.build.run import _pareto_labels

    tab = {"family_id": np.array([0.0, 1.0]), "label_major": np.array([np.nan, np.nan]),
           "label_minor": np.array([1.0, 2.0]), "fuel": np.array([1.0, 0.5])}
    shown = _pareto_labels(tab, {"labels": ["e.1", "e.2"], "families": ["a", "b"]})
    assert shown["label"] == ["e.1", "e.2"] and shown["family"] == ["a", "b"]
    assert "label_major" not in shown and "family_id" not in shown and list(shown["fuel"]) == [1.0, 0.5]


def test_a_controller_report_says_what_the_run_did(tmp_path):
    """unseen33 F8: x' = x + u, LQR (gain 1 + sqrt 2) saturated at |u| <= 0.5 from x = 3, where
    the plant outruns the saturated command: the comparison table said "overshoot 0 %" for a
    response that never came back, the controls table gave u no bounds although every command
    was clipped to 0.5 (and the figure's caption promised dashed bounds that were not drawn),
    the laws were listed as "phases", and the robustness sweep's verdict was only a raw CSV."""
    from ocdsl.api import run_file

    path = tmp_path / "sat.yaml"
    path.write_text("""name: saturated scalar LQR
model:
  states: [x]
  controls: [u]
  parameters: {a: 1}
  dynamics: {x: a*x + u}
controller:
  type: [lqr, sdre]
  Q: [1]
  R: [1]
  saturation: 0.5
  simulate: {x0: {x: 3}, horizon: 20, step: 0.01}
  robustness: {parameters: [a], factors: [0.1, 2]}
""")
    res = run_file(path, tmp_path / "r")
    assert res.status == "unstable"
    html = build_run_html(tmp_path / "r")
    rows = _table(html, "Controller comparison")
    over = rows[0].index("overshoot [%]")
    assert [r[over] for r in rows[1:]] == ["—", "—"]
    controls = _table(html, "Controls of the problem")
    assert controls[0] == ["name", "unit", "lower bound", "upper bound"]          # no column of laws
    assert [c.replace("−", "-") for c in controls[1][2:]] == ["-0.5", "0.5"]
    cap = next(c for c in _captions(html) if c.startswith("Closed-loop control histories"))
    assert "dashed: the saturation" in cap
    svg = _svgs(html)[_captions(html).index(cap)]
    assert "stroke-dasharray" in svg
    # at a = 0.1 the saturated command wins (0.1 x 3 < 0.5: x = 5 - 2 exp(t / 10) reaches the
    # linear region at t = 8.7), at a = 2 it cannot (6 > 0.5)
    rob = _table(html, "Robustness")
    assert [(r[0], r[1], r[2]) for r in rob[1:]] == [("0.1", "lqr", "yes"), ("0.1", "sdre", "yes"),
                                                     ("2", "lqr", "no"), ("2", "sdre", "no")]
    assert "lqr regulates at 0.1; sdre regulates at 0.1." in html
    assert "tables/robustness.csv" not in html and "Phases of the solution" not in html


def test_the_files_report_block_chooses_the_formats(tmp_path):
    """unseen33 F11: `report: {formats: [html]}` was ignored (`--report` and `ocdsl report`
    wrote the PDF too); `enabled: true` writes the report without `--report`."""
    import os
    import subprocess
    import sys

    path = tmp_path / "di.yaml"
    path.write_text("""name: double integrator
model: {states: [x, v], controls: [u], dynamics: {x: v, v: u}}
problem:
  time: {t0: 0, tf: 1}
  constraints: [x(t0) == 0, v(t0) == 0, x(tf) == 1, v(tf) == 0]
  objective: minimize integral(u**2)
method: {transcription: LGR, segments: 2, degree: 4}
report: {formats: [html], enabled: true}
""")
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    cli = [sys.executable, "-m", "ocdsl.cli"]
    run = subprocess.run([*cli, "run", str(path), "--out", str(tmp_path / "r")], capture_output=True, text=True,
                         cwd=tmp_path, env=env)
    assert run.returncode == 0, run.stdout + run.stderr
    assert (tmp_path / "r" / "report.html").is_file() and not (tmp_path / "r" / "report.pdf").exists()
    (tmp_path / "r" / "report.html").unlink()
    again = subprocess.run([*cli, "report", str(tmp_path / "r")], capture_output=True, text=True, cwd=tmp_path,
                           env=env)
    assert again.returncode == 0 and again.stdout.split() == ["wrote", str(tmp_path / "r" / "report.html")], again
    assert not (tmp_path / "r" / "report.pdf").exists()


def test_a_comparison_and_a_study_say_which_runs_are_not_ok(tmp_path):
    """unseen33 F4: the comparison table had no verification or ok column, a max_iter run's
    last iterate sat in the objective column and was drawn like the solutions; a study's sweep
    figure drew three optimal but unverified points as a clean line, and no point's
    diagnosis was in the report."""
    t = np.linspace(0.0, 1.0, 11)
    kinds = {"good": ("optimal", "verified", 1.0), "unverified": ("optimal", "failed", 1.1),
             "stopped": ("max_iter", "not_run", 7.0)}
    folders = []
    for name, (status, checked, J) in kinds.items():
        res = Result(name=name, status=status, objective=J, tf=1.0, message="Maximum number of iterations exceeded."
                     if status == "max_iter" else "",
                     phases=[PhaseTrajectory("main", t, {"x": J * t}, {"u": 0 * t + J})],
                     verification={"status": checked, "tolerance": 1e-5, "checks": [],
                                   "summary": f"{checked}: dynamics per piece 3.2e-03 > 1e-05"},
                     problem={"name": "p", "phases": {"main": {"states": ["x"], "controls": ["u"]}}})
        folders.append(res.write(tmp_path / name))
    html = build_comparison_html(folders)
    rows = {r[0]: r for r in _table(html, "Compared runs")[1:]}
    head = _table(html, "Compared runs")[0]
    at = {c: head.index(c) for c in ("verification", "ok", "objective")}
    assert [rows["good"][at["ok"]], rows["unverified"][at["ok"]], rows["stopped"][at["ok"]]] == ["yes", "no", "no"]
    assert rows["unverified"][at["verification"]] == "failed"
    assert rows["stopped"][at["objective"]] == "7 (last iterate)" and rows["good"][at["objective"]] == "1"
    assert "unverified (optimal, not ok): verification failed (failed: dynamics per piece" in html
    svg = "".join(_svgs(html))
    assert "stopped (last iterate)" in svg and "unverified (not ok)" in svg

    study = tmp_path / "study"
    study.mkdir()
    (study / "study.json").write_text(json.dumps({"name": "s", "spec": {"sweep": {"grid": {"a": [1, 2, 3]}}}}))
    with open(study / "study.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["id", "a", "status", "ok", "verification", "objective", "message"])
        for i, a in enumerate((1, 2, 3)):
            w.writerow([f"p{i}", a, "optimal", False, "failed", 2.0 * a, "verification failed; certificate failed."])
    html = build_comparison_html([study])
    svg = _svgs(html)[[i for i, c in enumerate(_captions(html)) if c.startswith("Study outputs")][0]]
    assert "converged, not ok" in svg
    assert html.count("verification failed; certificate failed.") == 3


def test_a_pareto_sets_report_shows_the_set_not_one_point(tmp_path):
    """unseen33 F9: the report of an epsilon Pareto set (min int u^2 with t_f <= eps for the
    rest-to-rest double integrator, J = 12 / eps^3, eps = 1, 2, 3) said "objective: 0.1875" (one point's
    energy) in its header and summary, and had neither the file's description nor who ran it."""
    from ocdsl.study.pareto_run import run_pareto

    path = Path(__file__).parent / "data" / "pareto_energy_time.yaml"
    run_pareto(path, tmp_path / "front")
    html = build_run_html(tmp_path / "front")
    head = html.split("</header>")[0]
    assert "Pareto set: 3 solutions, 3 Pareto-optimal" in head and "objective:" not in head
    assert "run by: ocdsl" in head
    assert "gives J = 12/eps^3" in html.split("</header>")[1]
    summary = _table(html, "Solution summary")
    assert not any(r and r[0].startswith("objective") for r in summary)


def test_a_comparison_of_controller_runs_gives_each_laws_cost(tmp_path):
    """unseen35 F8: comparing two controller runs (lqr and sdre each) showed "—" as their
    objective and drew their laws as "r02, r02, r02b, r02b" in the compared runs' figures.
    The table gives each law's J, and the laws are drawn once, named, in the closed-loop
    comparison."""
    t = np.linspace(0, 5, 51)
    folders = []
    for run, k in (("r1", 1.0), ("r2", 2.0)):
        extra, tables, phases = {"laws": ["lqr", "sdre"]}, {}, []
        for law, J in (("lqr", 6.17 * k), ("sdre", 6.16 * k)):
            extra[law] = {"status": "stable", "cost": J}
            tables[f"closed_loop_{law}"] = {"t": t, "x": np.exp(-k * t), "u": -np.exp(-k * t)}
            phases.append(PhaseTrajectory(law, t, {"x": np.exp(-k * t)}, {"u": -np.exp(-k * t)}))
        res = Result(name=run, status="stable", tables=tables, extra=extra, phases=phases,
                     problem={"name": "p", "phases": {law: {"states": ["x"], "controls": ["u"]}
                                                       for law in ("lqr", "sdre")}})
        folders.append(res.write(tmp_path / run))
    html = build_comparison_html(folders)
    rows = {r[0]: r for r in _table(html, "Compared runs")[1:]}
    head = _table(html, "Compared runs")[0]
    assert rows["r2"][head.index("objective")] == "lqr 12.34, sdre 12.32"
    caps = _captions(html)
    assert any(c.startswith("Closed-loop state responses") for c in caps)
    assert not any("compared runs" in c for c in caps), caps
