"""``python -m ocdsl.report.reproduce``: the command line."""
from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Sequence

from ocdsl.report.reproduce.examples import CONFIGS, REPORTS, find_examples
from ocdsl.report.reproduce.numbers import write_index
from ocdsl.report.reproduce.runs import remake_reports, reproduce


# =================================================================================== CLI
def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m ocdsl.report.reproduce",
                                 description="Run every example of configs/ and write its reports under reports/.")
    ap.add_argument("--only", nargs="+", metavar="NAME", help="only these examples (file stems)")
    ap.add_argument("--skip-slow", action="store_true", help="leave out the examples that take minutes")
    ap.add_argument("--formats", default="html,pdf", help="comma-separated: html, pdf (default html,pdf)")
    ap.add_argument("--configs", type=Path, default=CONFIGS, help="folder of the examples (default configs/)")
    ap.add_argument("--out", type=Path, default=REPORTS, help="reports folder (default reports/)")
    ap.add_argument("--workers", type=int, default=None, help="worker processes of study files")
    ap.add_argument("--index-only", action="store_true", help="only rewrite reports/index.html")
    ap.add_argument("--reports-only", action="store_true",
                    help="re-make the reports of the run folders under --out from what they hold (no solving)")
    ap.add_argument("--list", action="store_true", help="list the examples and exit")
    args = ap.parse_args(argv)
    formats = tuple(f.strip() for f in args.formats.split(",") if f.strip())
    bad = [f for f in formats if f not in ("html", "pdf")]
    if bad:
        ap.error(f"unknown format(s) {bad}; choose from html, pdf")
    if args.index_only:
        print(f"[reproduce] wrote {write_index(args.out)}")
        return 0
    if args.reports_only:
        outcomes = remake_reports(args.out, formats, only=args.only, configs=args.configs)
        kept = [o.stem for o in outcomes if o.status == "skipped"]
        outcomes = [o for o in outcomes if o.status != "skipped"]
        bad_runs = [o.stem for o in outcomes if not o.ok]
        print(f"[reproduce] {len(outcomes) - len(bad_runs)} of {len(outcomes)} reports of ok runs"
              + (f"; not ok: {', '.join(bad_runs)}" if bad_runs else "")
              + (f"; kept as they are (run data not here): {', '.join(kept)}" if kept else ""))
        return 1 if any(o.status == "error" for o in outcomes) else 0
    examples = find_examples(args.configs, args.only, args.skip_slow)
    if args.list:
        for e in examples:
            print(f"{e.stem:28s} {e.kind:10s} {'slow' if e.slow else ''}")
        return 0
    os.environ.setdefault("MPLBACKEND", "Agg")
    outcomes = reproduce(examples, args.out, formats, workers=args.workers)
    bad_runs = [o.stem for o in outcomes if not o.ok]
    print(f"[reproduce] {len(outcomes) - len(bad_runs)} of {len(outcomes)} examples ok"
          + (f"; not ok: {', '.join(bad_runs)}" if bad_runs else ""))
    return 1 if bad_runs else 0
