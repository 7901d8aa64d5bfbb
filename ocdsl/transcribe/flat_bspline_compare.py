"""Flat B-spline against the core's pseudospectral transcription on the same problem file.

``compare(path, parameters)`` solves the file as written (``transcription: flat-bspline``)
and again with the method replaced by ``PseudospectralMethod`` (full state space: every
state and control collocated), and returns the optimum, landing time, NLP size and wall
time of both. ``python -m ocdsl.transcribe.flat_bspline_compare`` prints the seed-2 rows
(docs/flatness.md).
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Any

LGR_DEFAULT = {"transcription": "LGR", "segments": 10, "degree": 5}


def _row(result, wall: float, tf_key: str | None) -> dict[str, Any]:
    tf = result.tf if tf_key is None else result.tf[tf_key]
    return {"status": result.status, "objective": result.objective, "tf": tf,
            "variables": result.nlp.get("variables"), "constraints": result.nlp.get("constraints"),
            "nonzeros": result.nlp.get("nonzeros"), "iterations": result.iterations,
            "wall_s": wall, "solve_s": result.wall_time_s.get("solve"),
            "flat_reduction": result.extra.get("flat_reduction", {}).get("total"),
            "expect": {c["name"]: (c["value"], c["passed"]) for c in result.expect},
            "verification": (result.verification or {}).get("status"),
            "refinement": result.extra.get("refinement", {}).get("levels", [])}


def compare(path: str | Path, parameters: dict[str, float] | None = None,
            pseudospectral: dict[str, Any] | None = None, tf_key: str | None = None) -> dict[str, dict]:
    """``{"flat": row, "pseudospectral": row}`` for one point of a problem file."""
    import ocdsl
    from ocdsl.spec.schema import PseudospectralMethod

    out = {}
    for kind in ("flat", "pseudospectral"):
        t = time.perf_counter()
        ld = ocdsl.load(path, parameters=parameters)
        if kind == "pseudospectral":
            ld.file.method = PseudospectralMethod(**{**LGR_DEFAULT, **(pseudospectral or {})})
        res = ld.solve()
        out[kind] = _row(res, time.perf_counter() - t, tf_key)
        out[kind]["result"] = res
    return out


def _main() -> None:  # pragma: no cover - prints the docs table
    import argparse
    import json

    from ocdsl.models.lunar_lander import TABLE2, TABLE3

    ap = argparse.ArgumentParser()
    ap.add_argument("--configs", default="configs")
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    cfg = Path(args.configs)
    rows = []
    for h in sorted(TABLE2, reverse=True):
        f = cfg / ("seed2_strategy1.yaml" if h == 100 else "seed2_strategy2.yaml")
        c = compare(f, None if h == 100 else {"h_i": float(h)})
        rows.append(("table2", h, TABLE2[h], c))
    for h in sorted(TABLE3, reverse=True):
        c = compare(cfg / "seed2_strategy3.yaml", {"h_v": float(h)}, tf_key="descent")
        rows.append(("table3", h, TABLE3[h], c))
    data = []
    for table, h, paper, c in rows:
        f, p = c["flat"], c["pseudospectral"]
        line = {"table": table, "row": h, "paper": paper,
                **{f"flat_{k}": v for k, v in f.items() if k != "result"},
                **{f"ps_{k}": v for k, v in p.items() if k != "result"}}
        data.append(line)
        print(f"{table} {h:>3}: flat {f['objective']:.3f} kg {f['tf']:.3f} s {f['variables']}/{f['constraints']} "
              f"{f['wall_s']:.2f} s | LGR {p['objective']:.3f} kg {p['tf']:.3f} s {p['variables']}/"
              f"{p['constraints']} {p['wall_s']:.2f} s | rel {abs(f['objective'] - p['objective']) / abs(p['objective']):.1e}",
              flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(data, indent=1, default=str))


if __name__ == "__main__":  # pragma: no cover
    _main()
