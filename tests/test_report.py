"""Reports from synthetic run folders: HTML (self-contained, rendered by headless
Chromium) and PDF (rendered to PNG pages by pdftoppm), for a solved run, a failed run,
a controller run and studies (sweep and Pareto)."""
from __future__ import annotations

import base64
import csv
import io
import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from ocdsl.report import build as B
from ocdsl.report import make_comparison_report, make_index, make_report
from ocdsl.result import PhaseTrajectory, Result

CHROMIUM = B.chromium_binary()
PDFTOPPM = shutil.which("pdftoppm")
PDFTOTEXT = shutil.which("pdftotext")
PDFIMAGES = shutil.which("pdfimages")
need_chromium = pytest.mark.skipif(CHROMIUM is None, reason="needs Debian's chromium (apt-get install chromium)")
need_poppler = pytest.mark.skipif(None in (PDFTOPPM, PDFTOTEXT, PDFIMAGES),
                                  reason="needs poppler-utils (apt-get install poppler-utils)")


def _pdf_engine_available() -> bool:
    try:
        import weasyprint  # noqa: F401
        return True
    except (ImportError, OSError):
        return CHROMIUM is not None


need_pdf = pytest.mark.skipif(not _pdf_engine_available(),
                              reason="no PDF engine: pip install weasyprint (needs libpango-1.0-0 "
                                     "libpangoft2-1.0-0) or apt-get install chromium")


# ------------------------------------------------------------------ synthetic runs
def brachistochrone_problem() -> dict:
    return {
        "name": "brachistochrone", "description": "Bead sliding on a wire in minimum time.",
        "phases": {"main": {
            "states": ["x", "y", "v"], "controls": ["theta"],
            "dynamics_latex": {"x": r"v \sin{\left(\theta \right)}", "y": r"- v \cos{\left(\theta \right)}",
                               "v": r"g \cos{\left(\theta \right)}"},
            "bounds": {"theta": [0.0, 3.141592653589793], "v": [0.0, None]},
            "constraints": ["x(t0) == 0", "y(t0) == 0", "x(tf) == 2", "y(tf) == -2"],
            "constraints_latex": [r"x(t_0) = 0", r"y(t_0) = 0", r"x(t_f) = 2", r"y(t_f) = -2"],
            "t0": 0.0, "tf": "free"}},
        "parameters": {"g": {"value": 9.80665, "free": False}},
        "units": {"x": "m", "y": "m", "v": "m/s", "theta": "rad", "g": "m/s^2", "t": "s"},
        "positions": ["x", "y"],
        "objective": {"sense": "minimize", "text": "tf", "latex": "t_f"},
        "links": [],
    }


def solved_result() -> Result:
    t = np.linspace(0.0, 0.8, 41)
    theta = np.clip(0.1 + 1.9 * t, 0, np.pi)
    x, y = 2 * (t / 0.8) ** 1.3, -2 * np.sin(np.pi / 2 * t / 0.8)
    v = 9.8 * t
    H = -np.ones_like(t) + 1e-7 * np.sin(20 * t)
    ph = PhaseTrajectory("main", t, states={"x": x, "y": y, "v": v}, controls={"theta": theta},
                         costates={"x": -0.3 + 0 * t, "y": 0.1 + 0 * t, "v": -0.1 + 0.05 * t},
                         extra={"H": H, "dH_dtheta": 1e-8 * np.cos(9 * t), "switch_theta": np.cos(5 * t)})
    tr = np.linspace(0, 0.8, 161)
    reint = {"t": tr, "x": 2 * (tr / 0.8) ** 1.3 + 1e-4 * tr, "y": -2 * np.sin(np.pi / 2 * tr / 0.8), "v": 9.8 * tr}
    mesh = {"iteration": np.arange(4.0), "nodes": np.array([11, 21, 31, 41.0]),
            "max_error": np.array([1e-2, 3e-4, 2e-6, 4e-8]), "nlp_variables": np.array([45, 85, 125, 165.0])}
    return Result(
        name="brachistochrone", status="optimal", message="Optimal Solution Found.", objective=0.8230,
        tf=0.8230, iterations=14,
        wall_time_s={"total": 1.52, "parse": 0.02, "symbolic": 0.3, "build": 0.4, "solve": 0.7, "post": 0.1},
        nlp={"variables": 165, "constraints": 124, "nonzeros": 610},
        method={"name": "radau", "degree": 3, "segments": 40, "mesh": {"tolerance": 1e-6, "max_iterations": 5}},
        parameters={"g": 9.80665}, phases=[ph],
        expect=[{"name": "tf", "value": 0.8230, "reference": 0.82446, "rtol": 1e-3, "atol": None,
                 "error": 1.7e-3, "passed": False},
                {"name": "x(tf)", "value": 2.0, "reference": 2.0, "rtol": 1e-6, "atol": 1e-9,
                 "error": 0.0, "passed": True}],
        certificate={  # the structure ocdsl.solve.certificate.certificate returns
            "passed": False, "objective": "min_tf", "nodes": 41, "failed": ["hamiltonian"],
            "hamiltonian": {"expected": -1.0, "mean": -0.93, "max_deviation": 0.07,
                            "relative_max_deviation": 0.07, "time_dependent": False, "passed": False},
            "stationarity": {"interior_nodes": 39, "max_abs": 3e-9, "max_relative": 2e-9,
                             "per_control": {"theta": {"interior_nodes": 39, "max_abs": 3e-9}},
                             "passed": True},
            "bang_bang": {"all": False, "per_control": {"theta": {"fraction_at_bound": 0.0,
                                                                  "switch_times": []}}},
            "tolerances": {"hamiltonian_max": 3e-2, "hamiltonian_mean": 2e-3, "stationarity": 1e-2,
                           "sign_agreement": 0.99}},
        verification={"mode": "enforce", "tolerance": 1e-5, "status": "verified",
                      "summary": "verified: 2 checks within 1e-05",
                      "checks": [{"name": "dynamics from x(t0)", "phase": "main", "value": 3.1e-7, "limit": 1e-5,
                                  "passed": True, "where": "x at t = 0.8", "detail": "DOP853, 90 steps"},
                                 {"name": "boundary conditions", "phase": None, "value": 2e-9, "limit": 1e-5,
                                  "passed": True, "where": "y(tf) == -2", "detail": "4 conditions"}]},
        problem=brachistochrone_problem(), extra={"solver": "ipopt", "ipopt_version": "3.14.16"},
        tables={"reintegration_main": reint, "mesh_history": mesh})


def failed_result() -> Result:
    return Result(name="brachistochrone_bad", status="infeasible",
                  message="Converged to a point of local infeasibility. Problem may be infeasible.\n"
                          "constraint residual 3.2e-1 at x(tf) == 50",
                  iterations=312, wall_time_s={"total": 3.1, "solve": 2.9},
                  nlp={"variables": 165, "constraints": 124}, method={"name": "radau", "segments": 40},
                  parameters={"g": 9.80665}, problem=brachistochrone_problem(),
                  expect=[{"name": "tf", "value": None, "reference": 0.82446, "rtol": 1e-3,
                           "error": None, "passed": False}])


def controller_result() -> Result:
    t = np.linspace(0, 5, 101)
    prob = {"name": "pendulum_control", "phases": {"main": {"states": ["theta", "omega"], "controls": ["u"],
                                                            "dynamics_latex": {"theta": r"\omega",
                                                                               "omega": r"- \sin{\left(\theta \right)} + u"},
                                                            "bounds": {"u": [-2.0, 2.0]}}},
            "units": {"theta": "rad", "omega": "rad/s", "u": "N m", "t": "s"}}
    rng = np.random.default_rng(0)
    tables = {}
    for i, c in enumerate(("sdre", "theta_d")):
        tables[f"closed_loop_{c}"] = {"t": t, "theta": np.exp(-(1 + i) * t) * np.cos(2 * t),
                                      "omega": -np.exp(-(1 + i) * t) * np.sin(2 * t),
                                      "u": np.clip(-3 * np.exp(-t) * np.cos(3 * t + i), -2, 2),
                                      "timing": 1e-4 * (1 + i) * (1 + 0.3 * rng.random(t.size))}
    return Result(name="pendulum_control", status="stable", problem=prob, tables=tables,
                  wall_time_s={"total": 0.4}, method={"name": "sdre"})


def di_result(x0: float, status: str = "optimal") -> Result:
    tf = 2 * np.sqrt(abs(x0)) + 0.5
    t = np.linspace(0, tf, 31)
    u = np.where(t < tf / 2, -1.0, 1.0)
    prob = {"name": "double_integrator",
            "phases": {"main": {"states": ["x", "v"], "controls": ["u"], "dynamics_latex": {"x": "v", "v": "u"},
                                "bounds": {"u": [-1, 1]}, "constraints": [], "constraints_latex": [],
                                "t0": 0.0, "tf": "free"}},
            "parameters": {"x0": {"value": 1.0, "free": False}}, "units": {"x": "m", "v": "m/s", "u": "m/s^2"},
            "positions": ["x"], "objective": {"sense": "minimize", "text": "tf", "latex": "t_f"}}
    ok = status == "optimal"
    phases = [PhaseTrajectory("main", t, {"x": x0 * (1 - t / tf) ** 2, "v": -2 * x0 * (1 - t / tf) / tf},
                              {"u": u}, extra={"switch_u": tf / 2 - t})] if ok else []
    return Result(name=f"di_x0_{x0:g}", status=status, message="" if ok else "Maximum Number of Iterations Exceeded.",
                  objective=tf if ok else None, tf=tf if ok else None, iterations=9 if ok else 3000,
                  wall_time_s={"total": 0.3}, nlp={"variables": 93}, parameters={"x0": x0},
                  problem=prob, method={"name": "radau", "segments": 10}, phases=phases,
                  expect=[{"name": "tf", "value": tf, "reference": tf, "error": 0.0, "rtol": 1e-6, "passed": ok}])


def write_study(folder: Path) -> Path:
    folder.mkdir(parents=True)
    rows = []
    for i, (x0, st) in enumerate([(1.0, "optimal"), (2.0, "optimal"), (3.0, "max_iter"), (4.0, "optimal")]):
        r = di_result(x0, st)
        r.write(folder / f"p{i:03d}")
        rows.append({"point": i, "x0": x0, "status": st, "objective": r.objective if r.objective else "",
                     "tf": r.tf if r.tf else "", "iterations": r.iterations, "wall_time": 0.3, "host": "localhost"})
    with open(folder / "study.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    (folder / "study.json").write_text(json.dumps({"kind": "sweep", "problem": "di.yaml", "points": len(rows)}))
    return folder


def write_pareto_study(folder: Path) -> Path:
    folder.mkdir(parents=True)
    pts = [("1.1", 1.0, 5.0, 1), ("2.1", 1.5, 3.5, 1), ("2.3", 2.2, 2.8, 1), ("2.5", 3.0, 2.6, 0),
           ("2.7", 3.5, 1.4, 1), ("1.4", 2.8, 4.0, 0)]
    with open(folder / "study.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["label", "family", "t_motor", "dv", "pareto", "status"])
        for lab, a, b, p in pts:
            w.writerow([lab, lab.split(".")[0], a, b, p, "optimal"])
    (folder / "study.json").write_text(json.dumps({"kind": "pareto", "criteria": ["t_motor", "dv"]}))
    return folder


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, Path]:
    base = tmp_path_factory.mktemp("report")
    return {"solved": solved_result().write(base / "solved"),
            "failed": failed_result().write(base / "failed"),
            "control": controller_result().write(base / "control"),
            "study": write_study(base / "study"),
            "pareto": write_pareto_study(base / "pareto"),
            "base": base}


# -------------------------------------------------------------------------- helpers
_IMG = re.compile(r'<img[^>]*src="data:image/png;base64,([^"]+)"')


def embedded_images(html: str) -> list[np.ndarray]:
    import matplotlib.image as mpimg
    return [mpimg.imread(io.BytesIO(base64.b64decode(b)), format="png") for b in _IMG.findall(html)]


def figure_images(html: str) -> list[bytes]:
    """The figures' embedded SVG documents (figures are vector graphics)."""
    blocks = re.findall(r'<figure[^>]*>\s*<img src="data:image/svg\+xml;base64,([^"]+)"', html)
    return [base64.b64decode(b) for b in blocks]


def svg_size(svg: bytes) -> tuple[float, float]:
    m = re.search(rb'<svg[^>]*width="([\d.]+)pt" height="([\d.]+)pt"', svg)
    return float(m.group(1)), float(m.group(2))


def assert_self_contained(html: str) -> None:
    assert not re.search(r"https?://", html), "the HTML refers to the network"
    assert "<link" not in html and "<script" not in html and "@import" not in html
    for attr in re.findall(r'(?:src|href)="([^"]*)"', html):
        assert attr.startswith(("data:", "#")), f"external reference {attr[:60]!r}"
    assert not re.search(r"url\((?!data:)", html)


def not_blank(img, min_std: float = 0.02) -> bool:
    if isinstance(img, bytes):      # an SVG figure: axes and drawn paths
        return img.count(b"<path") >= 20 and b'id="axes_1"' in img
    gray = img[..., :3].mean(axis=-1) if img.ndim == 3 else img
    return float(gray.std()) > min_std and float((gray < 0.9).mean()) > 0.002


def numbers(html: str, kind: str) -> list[int]:
    return [int(n) for n in re.findall(rf"<b>{kind} (\d+)\.</b>", html)]


@pytest.fixture(scope="module")
def solved_report(runs) -> list[Path]:
    """The solved run's report, made once: HTML, and the PDF when an engine is installed."""
    return make_report(runs["solved"], formats=("html", "pdf") if _pdf_engine_available() else ("html",))


# ------------------------------------------------------------------------------ HTML
def test_solved_report_html(runs, solved_report):
    assert solved_report[0] == runs["solved"] / "report.html"
    html = solved_report[0].read_text()
    assert_self_contained(html)
    # figures: states, controls, costates, H, dH/du, switching, positions, re-integration, mesh
    figs = figure_images(html)
    assert len(figs) >= 9, len(figs)
    assert all(not_blank(f) for f in figs)
    assert numbers(html, "Figure") == list(range(1, len(figs) + 1))
    tabs = numbers(html, "Table")
    assert tabs == list(range(1, len(tabs) + 1)) and len(tabs) >= 8
    for caption in ("State histories", "Control histories", "Costates", "Hamiltonian", "Switching functions",
                    "Trajectory in the (x, y) plane", "Re-integrated trajectory", "Mesh refinement history"):
        assert caption in html, caption
    # equations typeset as images: 3 dynamics + 4 constraints + t0 + tf + objective
    eqs = re.findall(r'<div class="eq">.*?</div>', html)
    assert len(eqs) == 10 and all('src="data:image/png' in e for e in eqs)
    # parameters with values and units, expect checks, certificate with pass/fail colouring
    assert "9.80665" in html and "m/s<sup>2</sup>" in html
    assert re.search(r"<td class=\"name\">tf</td>.*?0.82446.*?<td class=\"fail\">FAIL</td>", html, re.S)
    assert re.search(r"x\(tf\)</td>.*?<td class=\"pass\">pass</td>", html, re.S)
    cert = html[html.index("Optimality certificate"):]
    cert = cert[:cert.index("</table>")]
    assert re.search(r">hamiltonian</td>.*?<td class=\"fail\">FAIL</td>", cert, re.S)
    assert re.search(r">stationarity</td>.*?<td class=\"pass\">pass</td>", cert, re.S)
    # each check with its value, comparison and tolerance beside it
    assert re.search(r">hamiltonian</td>.*?expected [-−]1.*?0\.07</td><td class=\"\">≤</td><td class=\"num\">0\.03</td>",
                     cert, re.S)
    assert "switch times" in html and "Switching structure" in html
    ver = html[html.index("Independent verification of the returned"):]
    ver = ver[:ver.index("</table>")]
    assert re.search(r"dynamics from x\(t0\)</td>.*?3\.1e−07</td><td class=\"\">≤</td><td class=\"num\">1e−05</td>",
                     ver, re.S)
    # the header's badges: solver, verification, a failed certificate, expect, overall
    head = html[:html.index("</header>")]
    for label, cls, text in (("solver", "pass", "optimal"), ("verification", "pass", "verified"),
                             ("certificate", "fail", "failed"), ("expect", "fail", "1 of 2 pass"),
                             ("overall", "fail", "not ok (exit 1)")):
        assert re.search(rf'{label} <span class="badge {cls}"[^>]*>{re.escape(text)}</span>', head), label
    assert re.search(r'class="build">ocdsl \d+\.\d+\.\d+, commit \w+', head)
    assert "Optimality certificate" in html and "Wall-time breakdown" in html
    # no warnings: every optional part was drawn
    assert "could not be drawn" not in html


def test_failed_report_shows_diagnosis(runs):
    html = make_report(runs["failed"], formats=("html",))[0].read_text()
    assert_self_contained(html)
    assert "Diagnosis" in html and "local infeasibility" in html and "x(tf) == 50" in html
    assert "infeasible" in html and 'class="badge fail"' in html
    assert html.index("Diagnosis") < html.index("Dynamics")      # diagnosis before the problem
    assert "<figure" not in html                                  # no trajectory, no figure
    assert "could not be drawn" not in html


def test_broken_run_folder_still_reports(tmp_path):
    run = solved_result().write(tmp_path / "run")
    (run / "trajectory.csv").unlink()                # a damaged folder: trajectory gone
    html = make_report(run, formats=("html",))[0].read_text()
    assert "could not be read in full" in html and "Solution summary" in html
    with pytest.raises(B.ReportError, match="not a run folder"):
        make_report(tmp_path / "nothing", formats=("html",))
    with pytest.raises(B.ReportError, match="unknown report format"):
        make_report(run, formats=("docx",))


def test_controller_report(runs):
    html = make_report(runs["control"], formats=("html",))[0].read_text()
    assert_self_contained(html)
    assert "Closed-loop simulation" in html and "sdre" in html and "theta_d" in html
    assert "Controller computation time" in html
    assert all(not_blank(f) for f in figure_images(html)) and len(figure_images(html)) == 3


def test_study_comparison_report(runs, tmp_path):
    out = tmp_path / "cmp"
    paths = make_comparison_report([runs["study"]], out, formats=("html",))
    html = paths[0].read_text()
    assert_self_contained(html)
    assert "Study table (study.csv)" in html and "Compared runs" in html
    for i in range(4):
        assert f"p{i:03d}" in html
    assert "max_iter" in html and "Maximum Number of Iterations Exceeded" in html
    assert "Study outputs against the swept parameter x0" in html
    assert "State histories of the compared runs" in html
    assert all(not_blank(f) for f in figure_images(html))
    # several run folders and the controller run together
    html2 = make_comparison_report([runs["solved"], runs["failed"], runs["control"]], tmp_path / "cmp2",
                                   formats=("html",))[0].read_text()
    assert "solved" in html2 and "failed" in html2 and "Closed-loop comparison" in html2


def test_pareto_study(runs, tmp_path):
    html = make_comparison_report(runs["pareto"], tmp_path / "p", formats=("html",))[0].read_text()
    assert "Pareto front in the (t_motor, dv) criteria plane" in html
    figs = figure_images(html)
    assert len(figs) == 1 and not_blank(figs[0])
    assert html.count(">Pareto</td>") == 4


def test_index_page(runs, solved_report):
    out = runs["base"] / "reports" / "index.html"
    make_index([runs["solved"], runs["failed"]], out, [
        {"study": "seed0", "quantity": "t_f", "paper": 0.82446, "ocdsl": 0.8230, "error": 1.7e-3,
         "passed": False, "report_link": runs["solved"]},
        {"study": "seed0", "quantity": "x(t_f)", "paper": 2.0, "ocdsl": 2.0, "error": 0.0, "passed": True,
         "report_link": runs["solved"] / "report.html"}])
    html = out.read_text()
    assert '<td class="fail">not reproduced</td>' in html and '<td class="pass">reproduced</td>' in html
    assert html.count('href="../solved/report.html"') == 3
    assert not re.search(r"https?://", html)


# ------------------------------------------------------------- browser and PDF pages
def _chromium_screenshot(html_file: Path, png: Path, tmp: Path, size=(1000, 2400)) -> np.ndarray:
    import matplotlib.image as mpimg
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
           "--disable-background-networking", "--disable-component-update", "--disable-sync",
           "--hide-scrollbars", f"--user-data-dir={tmp / 'profile'}", f"--window-size={size[0]},{size[1]}",
           f"--screenshot={png}", html_file.as_uri()]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=90)
    assert png.is_file(), proc.stderr[-2000:]
    return mpimg.imread(png)


@need_chromium
def test_html_renders_in_chromium(solved_report, tmp_path):
    report = solved_report[0]
    full = _chromium_screenshot(report, tmp_path / "full.png", tmp_path)
    assert not_blank(full)
    # only the figures visible: whatever is drawn now comes from the embedded images
    html = report.read_text().replace(
        "</style>", "header, h2, h3, .eqgroup, .tblock, p, .diagnosis, .warnings, figcaption "
                    "{ display: none !important; } figure { margin: 0 !important; }</style>", 1)
    only = tmp_path / "figures_only.html"
    only.write_text(html)
    shot = _chromium_screenshot(only, tmp_path / "figures.png", tmp_path, size=(900, 7000))
    rgb = shot[..., :3]
    ink = (rgb.mean(axis=-1) < 0.85).mean()
    blue = ((np.abs(rgb - np.array([0x1f, 0x4e, 0x9c]) / 255).max(axis=-1)) < 0.12).sum()
    red = ((np.abs(rgb - np.array([0xc0, 0x39, 0x2b]) / 255).max(axis=-1)) < 0.12).sum()
    assert ink > 0.01, ink                 # axes, ticks, labels, curves
    assert blue > 2000 and red > 300, (blue, red)    # the curves themselves
    # the figures are laid out one below the other at their full size: the inked band is
    # as tall as the embedded images (a broken image would collapse to an icon)
    sizes = re.findall(r'<figure[^>]*>\s*<img src="data:image/svg\+xml;base64,([^"]+)"[^>]*style="width: ([\d.]+)cm"',
                       html)
    expected = 0.0
    for b64, width_cm in sizes:
        w, h = svg_size(base64.b64decode(b64))
        expected += float(width_cm) / 2.54 * 96 * h / w
    rows_with_ink = np.flatnonzero((rgb.mean(axis=-1) < 0.85).any(axis=1))
    assert len(sizes) >= 9 and rows_with_ink[0] < 60
    assert 0.9 * expected < rows_with_ink[-1] - rows_with_ink[0] < 1.05 * expected, (rows_with_ink[-1], expected)


@need_pdf
@need_poppler
def test_pdf_pages(solved_report, tmp_path):
    import matplotlib.image as mpimg
    html_path, pdf = solved_report
    assert pdf.read_bytes()[:5] == b"%PDF-"
    text = subprocess.run([PDFTOTEXT, "-layout", str(pdf), "-"], capture_output=True, text=True).stdout
    n_fig = len(numbers(html_path.read_text(), "Figure"))
    n_tab = len(numbers(html_path.read_text(), "Table"))
    for i in range(1, n_fig + 1):
        assert f"Figure {i}." in text
    for i in range(1, n_tab + 1):
        assert f"Table {i}." in text
    pages = text.count("\f")
    page_numbers = [int(a) for a, b in re.findall(r"^\s*(\d+) ?/ ?(\d+)\s*$", text, re.M) if int(b) == pages]
    assert pages >= 3 and page_numbers == list(range(1, pages + 1)), page_numbers   # page numbers
    lst = subprocess.run([PDFIMAGES, "-list", str(pdf)], capture_output=True, text=True).stdout
    n_img = len(lst.strip().splitlines()) - 2
    widths = [int(line.split()[3]) for line in lst.strip().splitlines()[2:]]
    # the equations are small images; the figures are vector graphics (a raster figure
    # would be a 960-pixel-wide image)
    assert n_img >= 10 and max(widths) < 600, lst
    subprocess.run([PDFTOPPM, "-r", "40", "-png", str(pdf), str(tmp_path / "page")], check=True)
    pngs = sorted(tmp_path.glob("page*.png"))
    assert len(pngs) == pages
    imgs = [mpimg.imread(p) for p in pngs]
    assert all(not_blank(i, 0.01) for i in imgs)
    # pages with figures carry much more ink than the text pages around them
    ink = [float((i[..., :3].mean(axis=-1) < 0.8).mean()) for i in imgs]
    assert max(ink) > 0.04, ink


@need_pdf
@need_poppler
def test_failed_and_study_pdf(runs, tmp_path):
    pdf = make_report(runs["failed"], formats=("pdf",))[0]
    text = subprocess.run([PDFTOTEXT, str(pdf), "-"], capture_output=True, text=True).stdout
    assert "Diagnosis" in text and "local infeasibility" in text
    pdf2 = make_comparison_report([runs["study"], runs["pareto"]], tmp_path / "cmp", formats=("pdf",))[0]
    text2 = subprocess.run([PDFTOTEXT, str(pdf2), "-"], capture_output=True, text=True).stdout
    assert "Pareto front" in text2 and "Compared runs" in text2


def multiphase_result() -> Result:
    phases = []
    for name, (a, b) in (("ascent", (0.0, 1.0)), ("coast", (1.0, 2.5))):
        t = np.linspace(a, b, 21)
        phases.append(PhaseTrajectory(name, t, {"x": np.cos(t), "y": np.sin(t), "z": t ** 2},
                                      {"u": np.full_like(t, 1.0 if name == "ascent" else 0.0)}))
    info = {"states": ["x", "y", "z"], "controls": ["u"], "dynamics_latex": {"x": "- y", "y": "x", "z": "2 t"},
            "bounds": {"u": [0, 1]}, "constraints": ["x(t0) == 1"], "constraints_latex": [],
            "t0": 0.0, "tf": "free"}
    prob = {"name": "two_phase", "phases": {"ascent": info, "coast": dict(info, t0="free")},
            "units": {"x": "km", "y": "km", "z": "km"}, "positions": ["x", "y", "z"],
            "objective": {"sense": "minimize", "text": "tf", "latex": "t_f"}, "links": ["x(ascent.tf) == x(coast.t0)"]}
    return Result(name="two_phase", status="acceptable", objective=2.5, tf={"ascent": 1.0, "coast": 2.5},
                  phases=phases, problem=prob,
                  tables={"mesh_history": {"iteration": np.array([0, 0, 0, 1, 1, 1, 1.0]),
                                           "t": np.array([0.2, 1.0, 2.0, 0.1, 0.5, 1.2, 2.2]),
                                           "error": np.array([1e-3, 2e-2, 5e-3, 1e-6, 3e-7, 2e-6, 8e-7])}})


def test_multiphase_report(tmp_path):
    run = multiphase_result().write(tmp_path / "mp")
    assert (run / "trajectory_ascent.csv").is_file()
    html = make_report(run, formats=("html",))[0].read_text()
    assert_self_contained(html)
    assert "Phases of the solution" in html and ">ascent</td>" in html and ">coast</td>" in html
    assert "Trajectory in the (x, y, z) space" in html
    assert "error per segment against time" in html
    assert "x(ascent.tf) == x(coast.t0)" in html          # phase link shown as written
    assert 'class="badge pass"' in html                   # 'acceptable' counts as converged
    figs = figure_images(html)
    assert len(figs) == 4 and all(not_blank(f) for f in figs)
    assert "could not be drawn" not in html


@need_chromium
@need_poppler
def test_chromium_pdf_engine(runs, tmp_path):
    pdf = make_report(runs["failed"], formats=("pdf",), out_dir=tmp_path, engine="chromium")[0]
    text = subprocess.run([PDFTOTEXT, str(pdf), "-"], capture_output=True, text=True).stdout
    assert "Diagnosis" in text and "Table 1." in text and "local infeasibility" in text
    with pytest.raises(B.ReportError, match="unknown PDF engine"):
        make_report(runs["failed"], formats=("pdf",), out_dir=tmp_path, engine="latex")


def test_pareto_criteria_fall_back_to_the_first_numeric_columns():
    """Without criteria in study.json, the Pareto plot takes the first two columns that hold
    numbers in most rows (this path once called a helper that no longer existed)."""
    from ocdsl.report.build.pareto import pareto_criteria

    rows = [{"label": "a", "fuel": "1.5", "time": "3.0", "note": "x"},
            {"label": "b", "fuel": "2.5", "time": "nan", "note": "y"},
            {"label": "c", "fuel": "0.5", "time": "4.0", "note": ""}]
    assert pareto_criteria(rows, {}) == ("fuel", "time")
    assert pareto_criteria(rows, {"pareto": {"criteria": ["time", "fuel"]}}) == ("time", "fuel")
    assert pareto_criteria(rows[:1], {}) == ("fuel", "time") and pareto_criteria([], {}) is None


def test_figures_are_vector_files_written_0644(runs, solved_report):
    """Each figure is embedded as SVG and also saved as SVG and PDF beside the report, and
    the report's files are written 0644 (the umask's mode, not mkstemp's 0600)."""
    import os
    html = solved_report[0].read_text()
    files = re.findall(r'<span class="ffile">\((figures/[^ ]+)\.svg, \.pdf\)</span>', html)
    assert files and len(files) == len(figure_images(html))
    for name in files:
        svg, pdf = runs["solved"] / f"{name}.svg", runs["solved"] / f"{name}.pdf"
        assert svg.read_bytes().lstrip().startswith((b"<?xml", b"<svg")) and pdf.read_bytes()[:5] == b"%PDF-"
    old = os.umask(0o022)
    try:
        for p in make_report(runs["solved"], formats=("html",)) + [runs["solved"] / f"{files[0]}.svg"]:
            assert p.stat().st_mode & 0o777 == 0o644, (p, oct(p.stat().st_mode))
    finally:
        os.umask(old)


def test_a_report_says_what_the_verification_did_not_judge_and_how_far_j_is_verified(tmp_path):
    """unseen33 F15: a verified open-loop-unstable run's re-integration section showed only its
    flight from x(t0), 5.6e9 off, with no word that the verification left it unjudged; F1: the
    caveat that J was verified to 6.7e-2 of J (a cost in kelvin) reached the console, not the
    report."""
    from ocdsl.api import run_file

    unstable = tmp_path / "unstable.yaml"
    unstable.write_text("""
name: unstable scalar LQ
model: {states: [x], controls: [u], dynamics: {x: 10*x + u}}
problem:
  time: {t0: 0, tf: 5}
  constraints: [x(t0) == 1]
  objective: minimize integral(x**2 + u**2)
method: {transcription: LGR, segments: 3, degree: 3, mesh: {tolerance: 1.0e-8, max_iterations: 15}}
""")
    run_file(unstable, tmp_path / "u")
    html = make_report(tmp_path / "u", formats=("html",))[0].read_text()
    assert html.count("Not judged by the verification") >= 2, "table and figure"
    furnace = tmp_path / "furnace.yaml"
    furnace.write_text("""
name: furnace in kelvin with a cap
parameters: {Tin: 1190, tau: 10, Tset: 1200, rho: 0.1}
model: {states: [T], controls: [Q], dynamics: {T: (Tin - T)/tau + Q}}
problem:
  time: {t0: 0, tf: 20}
  constraints: [T(t0) == 1199.9, T <= 1199.97]
  objective: minimize integral((T - Tset)**2 + rho*(Q - 1)**2)
method: {transcription: LG, segments: 4, degree: 3, mesh: {tolerance: 1.0e-6, max_iterations: 15}}
""")
    run_file(furnace, tmp_path / "f")
    html = make_report(tmp_path / "f", formats=("html",))[0].read_text()
    assert "of J, not 1e-05 of J" in html


def test_a_run_folder_changed_after_the_run_is_reported_as_changed(tmp_path):
    """unseen33 F2: a row of trajectory.csv moved by 1 m and `ocdsl report` still printed
    "verification verified, overall ok" over the edited data. The report now says which file
    changed since ocdsl wrote it and that its verdicts are of the run, not of these files."""
    run = solved_result().write(tmp_path / "run")
    clean = make_report(run, formats=("html",))[0].read_text()
    assert "changed since the run" not in clean
    csv_path = run / "trajectory.csv"
    lines = csv_path.read_text().splitlines()
    cells = lines[2].split(",")
    cells[1] = repr(float(cells[1]) + 1.0)
    lines[2] = ",".join(cells)
    csv_path.write_text("\n".join(lines) + "\n")
    html = make_report(run, formats=("html",))[0].read_text()
    assert "changed since the run" in html and "trajectory.csv changed after ocdsl wrote it" in html


def test_an_edited_result_json_gets_no_report(tmp_path):
    """unseen43 F1, F2: a failed run's result.json edited to optimal and verified got a report
    with "overall ok (exit 0)" beside "the verdicts in this report are of the run as ocdsl wrote
    it", and counted as ok in a comparison. Every verdict comes from result.json: an edited one
    is refused (a comparison leaves the run out, saying why)."""
    import json

    from ocdsl.report.build import ReportError, make_comparison_report

    run = solved_result().write(tmp_path / "run")
    other = solved_result().write(tmp_path / "other")
    data = json.loads((run / "result.json").read_text())
    data["objective"] = 1.5
    (run / "result.json").write_text(json.dumps(data))
    with pytest.raises(ReportError, match="result.json was changed after ocdsl wrote it"):
        make_report(run, formats=("html",))
    assert not (run / "report.html").exists()
    # a comparison leaves it out and says why
    html = make_comparison_report([other, run], tmp_path / "cmp", formats=("html",))[0].read_text()
    assert "run/result.json was changed after ocdsl wrote it" in html and "1 of 1" in html


def test_an_interrupted_runs_overall_badge_gives_its_exit_code():
    """unseen43 F3: "overall not ok (exit 1)", described as the exit code of ocdsl run, for a
    run Ctrl-C ended with 130 (SIGTERM: 143)."""
    from ocdsl.report import status as S

    for message, code in (("interrupted (Ctrl-C) at iteration 3", 130), ("interrupted (SIGTERM); ...", 143)):
        assert S.overall(Result(name="r", status="interrupted", message=message)).text == f"not ok (exit {code})"
    assert S.overall(Result(name="r", status="max_iter")).text == "not ok (exit 1)"


def test_a_multi_phase_runs_final_time_is_its_last_phases_end():
    """unseen43 F4: the comparison table gave a two-phase run ending at 2 the final time 3
    (the sum of the phases' final times 1 and 2)."""
    from ocdsl.report.tables.studies import run_final_time
    from ocdsl.result import PhaseTrajectory

    def run(spans):
        phases = [PhaseTrajectory(f"p{i}", np.linspace(a, b, 5), states={"x": np.zeros(5)})
                  for i, (a, b) in enumerate(spans)]
        return Result(name="r", status="optimal", tf={p.name: float(p.time[-1]) for p in phases}, phases=phases)

    assert run_final_time(run([(0, 1), (1, 2)])) == 2.0
    assert run_final_time(run([(0, 1.5), (0, 2)])) == 3.5        # phases that each start at 0
    assert run_final_time(Result(name="r", status="optimal", tf=1.25)) == 1.25


def test_a_loop_not_regulated_within_its_horizon_is_not_said_to_diverge(tmp_path):
    """unseen43 F5: "The closed loop diverged." for laws whose states stayed finite, only not
    regulated within the horizon."""
    from ocdsl.report.build import build_run_html

    res = solved_result()
    res.status, res.message = "unstable", "max |x| over the last tenth of the horizon = 0.5 of its scale > 0.01"
    html = build_run_html(res.write(tmp_path / "run"))
    assert "The closed loop diverged" not in html and "did not regulate the state within the horizon" in html


def test_a_failed_runs_final_time_says_whose_it_is(tmp_path):
    """unseen43 F6, F7: "final time t_f 5.05" with no label beside "objective of the last
    iterate", and for a solve the time limit refused before it started (its guess) the
    figures said "last iterate"."""
    from ocdsl.report.build import build_run_html

    res = solved_result()
    res.status, res.message = "max_iter", "Maximum number of iterations exceeded"
    assert "final time t_f [s] of the last iterate (not a solution)" in build_run_html(res.write(tmp_path / "a"))
    res.status, res.iterations = "time_limit", 0
    html = build_run_html(res.write(tmp_path / "b"))
    assert "final time t_f [s] of the guess (the solve did not start)" in html and "last iterate" not in html


def test_a_mesh_not_converged_objective_is_labelled_as_the_console_labels_it(tmp_path):
    """unseen43 F8: the report showed a mesh_not_converged run's J as a plain result, the
    comparison table as a "last iterate"; the console says "on the reported mesh"."""
    from ocdsl.report.build import build_run_html, make_comparison_report

    res = solved_result()
    res.status, res.message = "mesh_not_converged", "mesh refinement did not reach the tolerance"
    run = res.write(tmp_path / "run")
    assert "objective on the reported mesh (not converged)" in build_run_html(run)
    html = make_comparison_report([run], tmp_path / "cmp", formats=("html",))[0].read_text()
    assert "(mesh not converged)" in html and "(last iterate)" not in html


def test_a_certificate_that_holds_at_a_last_iterate_is_not_a_green_pass(tmp_path, capsys):
    """unseen43 F10: an interrupted run showed a green "certificate pass" for what the same
    report called a non-solution."""
    from ocdsl.cli import _summary
    from ocdsl.report import status as S

    res = solved_result()
    res.certificate = {"passed": True, "failed": []}
    assert S.badges(res)[2].text == "pass"
    res.status, res.message = "interrupted", "interrupted (Ctrl-C) at iteration 4"
    badge = next(b for b in S.badges(res) if b.label == "certificate")
    assert badge.text == "pass on the last iterate (not a solution)" and badge.cls == "neutral"
    _summary(res, tmp_path)
    assert "certificate (necessary conditions): pass on the last iterate (not a solution)" in capsys.readouterr().out


def test_a_comparison_says_which_runs_are_no_solution_and_why_runs_are_not_ok(tmp_path):
    """unseen43 F9, F12: a comparison's figures drew last iterates like solutions with nothing
    in the caption; a not-ok run's note gave the verification summary when an expect check
    failed; every axis took the first run's units and its bounds were drawn over runs without
    them; the objective read "minimize minimize tf"."""
    from ocdsl.report.build import make_comparison_report, build_run_html
    from ocdsl.report.figures.study import fig_compare_runs

    good = solved_result()
    good.certificate = {"passed": True, "failed": []}
    bare = solved_result()
    bare.status, bare.problem = "max_iter", {**bare.problem, "units": {}}
    html = make_comparison_report([good.write(tmp_path / "good"), bare.write(tmp_path / "bare")],
                                  tmp_path / "cmp", formats=("html",))[0].read_text()
    assert "1 of 2 did not end with a solution" in html
    assert "good (optimal, not ok): 1 expect check failed" in html
    def labels(runs):
        return [ax.get_ylabel() for f in fig_compare_runs(runs) for ax in f.figure.axes]

    assert labels([good, solved_result()]) == ["$x$ [m]", "$y$ [m]", "$v$ [m/s]", r"$\theta$ [rad]"]
    assert labels([good, bare]) == ["$x$", "$y$", "$v$", r"$\theta$"]              # units differ: none
    good.problem["objective"] = {"sense": "minimize", "text": "minimize tf", "latex": "t_f"}
    assert "minimize minimize" not in build_run_html(good.write(tmp_path / "g2"))


def test_the_rows_of_a_failed_run_are_not_drawn_as_a_solution(tmp_path):
    """unseen33 F3: an infeasible run's last iterate was drawn with the legend "solution" under
    "State histories"; the figures of a run that did not end with a solution now say what
    they show."""
    res = solved_result()
    res.status, res.message = "infeasible", "Ipopt: converged to a point of local infeasibility"
    html = make_report(res.write(tmp_path / "run"), formats=("html",))[0].read_text()
    assert "Not a solution: the run ended infeasible; drawn is its last iterate (not a solution)." in html
    assert "last iterate (not a solution)" in html.split("<figure")[0]          # the header too


def test_the_expect_table_shows_the_error_its_tolerance_holds():
    """unseen33 F5: "error 0.003 | rtol 0.001 | pass" for a relative error of 7.5e-4: under an
    rtol the table shows the relative error, as the console does."""
    from ocdsl.report.tables.cells import fmt
    from ocdsl.report.tables.checks import expect_table

    res = solved_result()
    res.expect = [{"name": "tf", "reference": 4.0, "value": 4.003, "rtol": 1e-3, "atol": None, "compare": "equal",
                   "error": 0.003, "relative_error": 7.5e-4, "passed": True}]
    row = expect_table(res)["rows"][0]
    assert [c["text"] for c in row][3] == fmt(7.5e-4, 3)


def test_a_run_folder_records_the_ocdsl_that_made_it_and_its_report_says_so(tmp_path):
    """unseen33 F10: the report showed the commit of the ocdsl that built the report (896a2fa
    for a run made at 11cf681), and result.json recorded none."""
    from conftest import CONFIGS, ROOT
    from ocdsl.api import run_file

    run_file(CONFIGS / "double_integrator.yaml", tmp_path / "run")
    made = json.loads((tmp_path / "run" / "result.json").read_text())["extra"]["ocdsl"]
    head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True, text=True)
    if head.returncode == 0:
        assert head.stdout.strip().startswith(made["commit"]) and len(made["commit"]) == 7
    html = make_report(tmp_path / "run", formats=("html",))[0].read_text()
    assert f"ocdsl {made['version']}, commit {made['commit']}" in html


def test_a_fixed_mesh_runs_notes_and_diagnosis_are_its_own(tmp_path):
    """unseen33 F6, F7: a fixed mesh whose bisection moved J was diagnosed "The mesh refinement
    did not reach its tolerance" (no refinement ran), and the run's notes (the console's
    `note:` lines) were only in the appendix's back-end table."""
    res = solved_result()
    res.method = {k: v for k, v in res.method.items() if k != "mesh"}
    res.status, res.message = "mesh_not_converged", "J = 2 on this mesh but with every segment bisected ..."
    res.extra["notes"] = ["the control at t_f jumped off its segment's other nodes; tied, J 1.99 -> 2"]
    html = make_report(res.write(tmp_path / "run"), formats=("html",))[0].read_text()
    assert "did not reach its tolerance" not in html and "On this fixed mesh J is the mesh" in html
    assert html.count("tied, J 1.99 -&gt; 2") == 2      # the solution's notes and the appendix's table


def test_a_column_is_the_same_in_every_row_only_when_its_values_are_equal():
    """unseen33 F14: a mesh history's J 10.024880738 and 10.024937811 (57 times the mesh
    tolerance apart) were "the same in every row: objective = 10.0249"; F11: J to six digits
    hid the convergence the table documents."""
    from ocdsl.report.tables.columns import column_table

    t = column_table("mesh_history", "", {"iteration": np.array([1.0, 2.0]), "phase": np.array([0.0, 0.0]),
                                          "objective": np.array([10.024880738, 10.024937811])},
                     drop_constant=True)
    assert "objective" in t["columns"] and "phase = 0" in t["note"]
    assert [r[-1]["text"] for r in t["rows"]] == ["10.02488074", "10.02493781"]


def test_the_problem_is_typeset_with_the_names_a_paper_prints():
    """unseen33 F11: "minimize tf" was set as the product t f, `Dc v^2 exp(-hc (h - 1))` as
    products D c and h c."""
    import sympy as sp

    from ocdsl.symbolic.latex import latex

    S = sp.Symbol
    assert latex(S("tf")) == "t_{f}" and latex(S("brake.tf")) == r"t_{f}^{\mathrm{brake}}"
    assert latex(-S("h(tf)")) == "- h(t_{f})"
    assert latex(S("Dc") * S("v") ** 2) == r"\mathrm{Dc} v^{2}"
    assert latex(S("theta") + S("x1") + S("v_max")) == r"\theta + v_{max} + x_{1}"


def test_the_summary_table_says_each_verdict_once(tmp_path):
    """unseen33 F11: the summary table read "verified: verified: 7 checks within 1e-05"."""
    from ocdsl.report.tables.solution import summary_table

    res = solved_result()
    res.verification = {"status": "verified", "summary": "verified: 7 checks within 1e-05", "checks": []}
    texts = [r[1]["text"] for r in summary_table(res)["rows"]]
    assert "verified: 7 checks within 1e-05" in texts and not any("verified: verified" in t for t in texts)
