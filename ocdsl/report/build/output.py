"""Writing a report: the HTML from the templates, the PDF (WeasyPrint or headless
Chromium), the figure files, into an ocdsl folder only."""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import Any, Callable, Sequence

from ocdsl import run_folder
from ocdsl.report import status as S
from ocdsl.report.build.document import Doc, ReportError


TEMPLATES = Path(__file__).parent.parent / "templates"
FORMATS = ("html", "pdf")
CHROMIUM_CANDIDATES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
# ================================================================================ output
_INNER_HYPHEN = re.compile(r"(?<=\w)-(?=\w)")


def nobreak(text: Any) -> Any:
    """Hyphens inside words as non-breaking hyphens: a table cell never breaks
    "bang-bang" across lines."""
    from markupsafe import Markup, escape

    if isinstance(text, Markup):
        return text
    return Markup(_INNER_HYPHEN.sub("\u2011", str(escape(text))))


def _env():
    import jinja2
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(str(TEMPLATES)), autoescape=True,
                             trim_blocks=False, lstrip_blocks=False)
    env.filters["nobreak"] = nobreak
    return env


def _render(doc: Doc, title: str, subtitle: str, meta: list[tuple[str, str]], badges: Sequence = ()) -> str:
    if doc.warnings:
        b = doc.section("warnings", "Notes on this report")
        b.append({"type": "warnings", "entries": doc.warnings})
    return _env().get_template("report.html.j2").render(
        title=title, subtitle=subtitle, meta=meta, badges=list(badges), sections=doc.sections,
        build=S.ocdsl_build())


def _atomic_write(path: Path, data: bytes | str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    run_folder.atomic_write_text(path, data)


class ReportFolderError(ReportError, run_folder.FolderError):
    """A report refused before anything is written: its folder holds what ocdsl did not write
    (a usage error, exit 2, like ``run --out``)."""


def _output_folder(out_dir: Path, names: Sequence[str]) -> None:
    """Reports go into an ocdsl folder (a run, a study) or a new one, never over files
    ocdsl did not write (ocdsl/run_folder.py): in an ocdsl folder, a report file that exists
    must be one its marker lists (unseen12 F1: a report.html the user put in a run folder was
    replaced); in a run folder of an ocdsl from before the marker, none may exist."""
    # a folder of the report's (figures/) that is a link: writing into it, or clearing an
    # earlier report's figures there, would reach the user's own folder (unseen24 V1: the
    # user's states-0.svg and solver.pdf replaced through run/figures -> ../paper_figs)
    linked = sorted({Path(n).parts[0] for n in names
                     if len(Path(n).parts) > 1 and (out_dir / Path(n).parts[0]).is_symlink()})
    if linked:
        raise ReportFolderError(f"{out_dir / linked[0]} is a symbolic link (to {os.readlink(out_dir / linked[0])}); "
                                "ocdsl writes its report's files only into folders it made: remove the link, or "
                                "write the report elsewhere with --out")
    marker = run_folder.read_marker(out_dir) if out_dir.is_dir() else None
    if marker is not None or (out_dir / "result.json").is_file():
        listed = set(marker.get("entries", [])) if marker else set()
        digests = (marker or {}).get("digests") or {}
        foreign = [n for n in names if os.path.lexists(out_dir / n) and n not in listed
                   and not any(n.startswith(e + "/") for e in listed)]
        # a report the user edited since ocdsl wrote it is the user's (unseen40 F2: appended
        # notes were replaced by `ocdsl report`, and the report deleted by `ocdsl run --out`)
        edited = [n for n in names if n in digests and (out_dir / n).is_file()
                  and run_folder.file_digest(out_dir / n) != digests[n]]
        if edited:
            raise ReportFolderError(f"{out_dir / edited[0]} was changed since ocdsl wrote it"
                                    f"{f' (and {len(edited) - 1} more)' if len(edited) > 1 else ''}; ocdsl does "
                                    "not replace it: move it away, or write the report elsewhere with --out")
        if foreign:
            raise ReportFolderError(f"{out_dir} holds {', '.join(foreign[:4])}{' ...' if len(foreign) > 4 else ''}, "
                              "which ocdsl did not write; ocdsl does not replace it: move it, or write the "
                              "report elsewhere with --out")
        return
    try:
        run_folder.check_destination(out_dir, "comparison")
    except run_folder.FolderError as e:
        raise ReportFolderError(str(e)) from None
    out_dir.mkdir(parents=True, exist_ok=True)
    run_folder.write_marker(out_dir, "comparison", names)


def chromium_binary() -> str | None:
    for name in CHROMIUM_CANDIDATES:
        p = shutil.which(name)
        if p:
            return p
    return None


def _pdf_weasyprint(html: str, pdf: Path) -> None:
    import logging
    import weasyprint  # noqa: PLC0415  (optional: needs Pango; raises OSError without it)
    logging.getLogger("weasyprint").setLevel(logging.ERROR)
    logging.getLogger("fontTools").setLevel(logging.ERROR)
    data = weasyprint.HTML(string=html, base_url=str(pdf.parent)).write_pdf()
    _atomic_write(pdf, data)


def _pdf_chromium(html: str, pdf: Path) -> None:
    exe = chromium_binary()
    if exe is None:
        raise FileNotFoundError("no chromium binary on PATH")
    with tempfile.TemporaryDirectory(prefix="ocdsl-report-") as tmp:
        src = Path(tmp) / "report.html"
        src.write_text(html, encoding="utf-8")
        out = Path(tmp) / "report.pdf"
        cmd = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
               "--disable-background-networking", "--disable-component-update", "--disable-sync",
               f"--user-data-dir={tmp}/profile", "--no-pdf-header-footer",
               f"--print-to-pdf={out}", src.as_uri()]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=180)
        if not out.is_file() or out.stat().st_size == 0:
            raise OSError(f"chromium made no PDF (exit {proc.returncode}): {proc.stderr[-500:]}")
        _atomic_write(pdf, out.read_bytes())


PDF_ENGINES: dict[str, Callable[[str, Path], None]] = {"weasyprint": _pdf_weasyprint, "chromium": _pdf_chromium}


def write_pdf(html: str, pdf: Path, engine: str = "auto") -> str:
    """Write ``pdf`` from ``html``; returns the engine used. ``auto`` tries WeasyPrint, then
    Chromium."""
    names = list(PDF_ENGINES) if engine == "auto" else [engine]
    errors = []
    for name in names:
        if name not in PDF_ENGINES:
            raise ReportError(f"unknown PDF engine {name!r}; choose from {sorted(PDF_ENGINES)} or 'auto'")
        try:
            PDF_ENGINES[name](html, pdf)
            return name
        except (ImportError, OSError, subprocess.SubprocessError) as exc:
            errors.append(f"{name}: {type(exc).__name__}: {exc}")
    raise ReportError("could not write the PDF report (" + "; ".join(errors) + "). Install WeasyPrint "
                      "(pip install weasyprint; Debian packages libpango-1.0-0 libpangoft2-1.0-0) "
                      "or Debian's chromium, or ask for formats=('html',).")


def _write_outputs(html: str, out_dir: Path, formats: Sequence[str], engine: str, stem: str = "report",
                   files: dict[str, bytes] | None = None) -> list[Path]:
    formats = tuple(formats)
    bad = [f for f in formats if f not in FORMATS]
    if bad:
        raise ReportError(f"unknown report format(s) {bad}; choose from {list(FORMATS)}")
    written: dict[str, Path] = {}
    _output_folder(out_dir, [f"{stem}.{f}" for f in formats] + list(files or ()))
    run_folder.claim(out_dir, [f"{stem}.{f}" for f in formats])
    if files:       # each figure as SVG and PDF, for reuse in a paper
        marker = run_folder.read_marker(out_dir)
        if marker is not None:     # an earlier report's figures (ocdsl's own, listed) go
            stale = [n for n in marker.get("entries", []) if n.startswith("figures/") and n not in files]
            for name in stale:
                (out_dir / name).unlink(missing_ok=True)
            run_folder.write_marker(out_dir, marker["kind"], [n for n in marker.get("entries", []) if n not in stale],
                                    partial=marker.get("partial", False))
        run_folder.claim(out_dir, ["figures", *files])
        for name, data in files.items():
            _atomic_write(out_dir / name, data)
    if "html" in formats:
        written["html"] = out_dir / f"{stem}.html"
        _atomic_write(written["html"], html)
    if "pdf" in formats:
        written["pdf"] = out_dir / f"{stem}.pdf"
        write_pdf(html, written["pdf"], engine)
    run_folder.record_digests(out_dir, [p.name for p in written.values()] + list(files or ()))
    return [written[f] for f in formats if f in written]
