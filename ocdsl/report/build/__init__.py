"""Build HTML and PDF reports from run folders (never re-solves).

Public API (stable; the CLI calls these):

``make_report(run_dir, formats=("html", "pdf"), *, out_dir=None, engine="auto") -> list[Path]``
    Report of one run folder, written as ``report.html`` / ``report.pdf`` into the run
    folder (or ``out_dir``). Returns the paths written, in the order of ``formats``.

``make_comparison_report(run_dirs, out_dir, formats=("html", "pdf"), *, title=None, engine="auto") -> list[Path]``
    One report comparing several run folders and/or study folders (a folder with
    ``study.csv``/``study.json`` and one run folder per point, or any folder holding run
    folders), written to ``out_dir/report.html`` and ``out_dir/report.pdf``.

``make_index(report_dirs, out_path, paper_numbers, *, title=...) -> Path``
    ``reports/index.html``: every paper number against ocdsl's (``paper_numbers`` is a list
    of dicts ``{study, quantity, paper, ocdsl, error, passed, report_link}``) and a link to
    each report folder in ``report_dirs``.

The HTML is one self-contained file: figures are embedded SVG (``data:`` URIs; each also
written as ``figures/<key>.svg`` and ``.pdf``), equations are rendered offline by
matplotlib's mathtext, and nothing refers to the network. The PDF
is made from the same HTML with WeasyPrint (CSS paged media: A4 pages, page numbers,
repeated table headers); when WeasyPrint cannot be imported, headless Chromium is used if
installed. ``engine`` forces one (``"weasyprint"`` or ``"chromium"``).

One module per concept: the document (:mod:`.document`), reading run and study folders
(:mod:`.loading`), writing HTML and PDF (:mod:`.output`), the report of a run
(:mod:`.run`), of a comparison or study (:mod:`.study`), Pareto criteria
(:mod:`.pareto`) and the index (:mod:`.index`).
"""
from __future__ import annotations

from ocdsl.report.build.document import ReportError
from ocdsl.report.build.index import make_index
from ocdsl.report.build.loading import load_run, points_verification, read_study_table
from ocdsl.report.build.output import chromium_binary, write_pdf
from ocdsl.report.build.run import build_run_html, make_report
from ocdsl.report.build.study import build_comparison_html, make_comparison_report

__all__ = ["ReportError", "build_comparison_html", "build_run_html", "chromium_binary", "load_run",
           "make_comparison_report", "make_index", "make_report", "points_verification", "read_study_table",
           "write_pdf"]
