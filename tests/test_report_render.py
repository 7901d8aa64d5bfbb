"""Every committed report, rendered as a reader sees it (issue 25): headless Chromium lays
out each ``reports/*/report.html`` and a script reads the DOM: no element is wider than the
page body and no table cell breaks inside a word; pdftoppm renders every page of each
``report.pdf`` and nothing is drawn right of the right margin.

To look again by hand (the screenshots of the closing note):
    chromium --headless --no-sandbox --window-size=900,4000 --screenshot=shot.png reports/goddard/report.html
    pdftoppm -r 60 -png reports/goddard/report.pdf page
"""
from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from ocdsl.report.build import chromium_binary

ROOT = Path(__file__).resolve().parents[1]
REPORTS = ROOT / "reports"
CHROMIUM = chromium_binary()
PDFTOPPM = shutil.which("pdftoppm")
#: Rendered in CI (one of each kind); the others are marked slow (``make reproduce``):
#: a Chromium start per report is seconds each on a loaded machine.
FAST = {"index", "mesh_goddard", "study_moon_landing_sweep", "seed3_attitude", "seed4_case_A"}


def _params(files: list[Path]) -> list:
    out = []
    for p in files:
        name = p.parent.name if p.name.startswith("report.") else p.stem
        out.append(pytest.param(p, id=name, marks=() if name in FAST else pytest.mark.slow))
    return out


HTML = _params(sorted(REPORTS.glob("*/report.html")) + sorted(REPORTS.glob("index.html")))
PDF = _params(sorted(REPORTS.glob("*/report.pdf")))

# Measures the laid-out page and leaves the result in an attribute of <body>.
PROBE = r"""<script>
window.addEventListener('load', () => {
  const body = document.body.getBoundingClientRect();
  const wide = [];
  for (const el of document.body.querySelectorAll('*')) {
    const r = el.getBoundingClientRect();
    if (r.width > 0 && r.right > body.right + 1)
      wide.push(`${el.tagName.toLowerCase()}.${el.className}: ${Math.round(r.right - body.right)} px`);
  }
  const broken = [];
  for (const cell of document.querySelectorAll('td, th')) {
    const walk = document.createTreeWalker(cell, NodeFilter.SHOW_TEXT);
    let node;
    while ((node = walk.nextNode())) {
      const re = /\S+/g;
      let m;
      while ((m = re.exec(node.data))) {
        const range = document.createRange();
        range.setStart(node, m.index);
        range.setEnd(node, m.index + m[0].length);
        const tops = new Set([...range.getClientRects()].filter(r => r.width > 0).map(r => Math.round(r.top)));
        if (tops.size > 1) broken.push(m[0]);
      }
    }
  }
  document.body.setAttribute('data-layout', JSON.stringify({wide: wide.slice(0, 20), broken: broken.slice(0, 20),
                                                           width: Math.round(body.width)}));
});
</script>"""


def _layout(html_file: Path, tmp: Path) -> dict:
    probe = tmp / html_file.parent.name / "probe.html"
    probe.parent.mkdir(parents=True, exist_ok=True)
    probe.write_text(html_file.read_text().replace("</body>", PROBE + "</body>", 1))
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
           "--disable-background-networking", "--disable-component-update", "--disable-sync",
           f"--user-data-dir={tmp / 'profile'}", "--window-size=1000,3000", "--virtual-time-budget=5000",
           "--dump-dom", probe.as_uri()]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=180).stdout
    m = re.search(r'data-layout="([^"]*)"', out)
    assert m, f"{html_file}: the layout probe did not run"
    return json.loads(m.group(1).replace("&quot;", '"').replace("&amp;", "&").replace("&lt;", "<").replace("&gt;", ">"))


@pytest.mark.skipif(CHROMIUM is None, reason="needs Debian's chromium")
@pytest.mark.parametrize("html_file", HTML)
def test_report_fits_the_page_in_chromium(html_file, tmp_path):
    lay = _layout(html_file, tmp_path)
    assert lay["width"] > 300
    assert not lay["wide"], f"elements wider than the body: {lay['wide']}"
    assert not lay["broken"], f"table cells broken inside a word: {lay['broken']}"


# A4 is 210 mm wide and the right margin 18 mm (report.css @page)
RIGHT_EDGE_MM = 210.0 - 18.0


@pytest.mark.skipif(PDFTOPPM is None, reason="needs poppler-utils")
@pytest.mark.parametrize("pdf", PDF)
def test_pdf_pages_stay_inside_the_right_margin(pdf, tmp_path):
    import matplotlib.image as mpimg

    subprocess.run([PDFTOPPM, "-r", "40", "-png", str(pdf), str(tmp_path / "page")], check=True, timeout=300)
    pages = sorted(tmp_path.glob("page*.png"))
    assert pages
    for p in pages:
        img = mpimg.imread(p)[..., :3].mean(axis=-1)
        w = img.shape[1]
        edge = int(np.ceil(w * (RIGHT_EDGE_MM + 1.0) / 210.0))
        ink = np.flatnonzero((img[:, edge:] < 0.75).any(axis=0))
        assert ink.size == 0, f"{pdf.parent.name} {p.name}: drawn right of the margin at {edge + ink[0]} of {w} px"


def test_every_report_folder_has_html_and_pdf():
    folders = [d for d in REPORTS.iterdir() if d.is_dir() and not d.name.startswith(".")
               and ((d / "result.json").is_file() or (d / "study.csv").is_file())]
    assert folders
    missing = [d.name for d in folders if not (d / "report.html").is_file() or not (d / "report.pdf").is_file()]
    assert not missing, f"report folders without report.html/report.pdf: {missing}"
