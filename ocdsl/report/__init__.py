"""Reports of run folders and studies: one self-contained HTML file and a paginated PDF.

``make_report(run_dir, formats=("html", "pdf"))``, ``make_comparison_report(run_dirs,
out_dir, formats)`` and ``make_index(report_dirs, out_path, paper_numbers)``; see
:mod:`ocdsl.report.build`. Imported lazily so that ``import ocdsl.report`` stays cheap.
"""
from __future__ import annotations

__all__ = ["make_report", "make_comparison_report", "make_index", "ReportError"]


def __getattr__(name: str):
    if name in __all__:
        from ocdsl.report import build
        return getattr(build, name)
    raise AttributeError(name)
