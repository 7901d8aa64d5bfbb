"""``python -m ocdsl.bench`` (``make bench``): the core table, then the other back ends' benches.

``--sections core,control,search,study`` selects sections (default: all found);
``--segments 1,4,16,64`` and ``--problems a,b`` change the core table.
"""
from __future__ import annotations

import argparse
import importlib
import sys

PEERS = {"control": "ocdsl.control.bench", "search": "ocdsl.search.bench", "study": "ocdsl.study.bench"}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m ocdsl.bench")
    ap.add_argument("--sections", default="core," + ",".join(PEERS),
                    help="comma-separated: core, control, search, study")
    ap.add_argument("--segments", default="1,4,16,64")
    ap.add_argument("--problems", default="double_integrator,brachistochrone")
    ap.add_argument("--out", default="reports/bench/core.md")
    a = ap.parse_args(argv)
    sections = [s.strip() for s in a.sections.split(",") if s.strip()]
    rc = 0
    if "core" in sections:
        from pathlib import Path

        from .core import main_core

        print(main_core(a.problems.split(","), [int(k) for k in a.segments.split(",")], Path(a.out)))
    for name in sections:
        if name == "core":
            continue
        if name not in PEERS:
            print(f"unknown section '{name}'", file=sys.stderr)
            rc = 2
            continue
        try:
            mod = importlib.import_module(PEERS[name])
        except ImportError as e:
            print(f"\n## {name}: not available ({e})")
            continue
        print(f"\n## {name}")
        try:
            rc = max(rc, int(mod.main([]) or 0))
        except SystemExit as e:
            rc = max(rc, int(e.code or 0))
    return rc


if __name__ == "__main__":
    sys.exit(main())
