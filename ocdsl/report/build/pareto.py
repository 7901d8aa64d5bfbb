"""The two criteria of a Pareto set, from its declared objectives."""
from __future__ import annotations

from typing import Any

import numpy as np

from ocdsl.report import tables as T


STUDY_OUTPUT_COLS = {"status", "objective", "tf", "t_f", "iterations", "wall_time", "wall_time_s",
                     "host", "message", "run", "run_dir", "folder", "dir", "path", "pareto", "seed",
                     "point", "index", "id", "name", "family", "label", "solution", "elapsed",
                     "worker", "attempt", "started", "finished", "nlp_variables", "ok"}

def _rows_of(cols: dict[str, np.ndarray]) -> list[dict[str, Any]]:
    n = max((len(v) for v in cols.values()), default=0)
    return [{k: (v[i] if i < len(v) else None) for k, v in cols.items()} for i in range(n)]


def pareto_criteria(rows: list[dict], meta: dict) -> tuple[str, str] | None:
    """The two Pareto criteria: named by study.json (``criteria``/``objectives``, possibly
    under ``pareto``), else the first two numeric columns that are not bookkeeping."""
    if not rows:
        return None
    for src in (meta, meta.get("pareto") if isinstance(meta.get("pareto"), dict) else {}):
        for key in ("criteria", "objectives"):
            v = src.get(key) if isinstance(src, dict) else None
            if isinstance(v, list) and len(v) >= 2:
                names = [x if isinstance(x, str) else (x.get("name") if isinstance(x, dict) else None) for x in v]
                if all(n in rows[0] for n in names[:2] if n):
                    if names[0] and names[1]:
                        return names[0], names[1]
    numeric = [k for k in rows[0] if k not in STUDY_OUTPUT_COLS and k != "t"
               and sum(T.finite_or_none(r.get(k)) is not None for r in rows) >= max(1, len(rows) // 2)]
    return (numeric[0], numeric[1]) if len(numeric) >= 2 else None


def pareto_senses(criteria: tuple[str, str], meta: dict) -> tuple[str, str]:
    """Each criterion's sense from a Pareto run's ``objectives`` and ``senses`` (result.json's
    extra, or study.json); minimize where not said."""
    names, senses = meta.get("objectives"), meta.get("senses")
    if isinstance(names, list) and isinstance(senses, list) and len(names) == len(senses):
        by = {str(n): str(s) for n, s in zip(names, senses)}
        return by.get(criteria[0], "minimize"), by.get(criteria[1], "minimize")
    return "minimize", "minimize"
