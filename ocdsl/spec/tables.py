"""The ``tables:`` block: inline numbers or CSV columns -> :class:`ocdsl.symbolic.tables.Table`."""
from __future__ import annotations

import csv
import math
from pathlib import Path

from ..hints import did_you_mean
from ..symbolic.tables import Table
from .schema import TableSpec


class TableError(ValueError):
    """A bad table; ``key`` is the entry of the table the error is about."""

    def __init__(self, message: str, key: str | None = None):
        super().__init__(message)
        self.key = key


def build_table(name: str, spec: TableSpec, base: Path) -> Table:
    if spec.csv is None:
        for key in ("x", "y", "values"):
            if isinstance(getattr(spec, key), str):
                raise TableError(f"table '{name}': {key} names a column, but no `csv:` file is given", key)
        grids = [spec.x] + ([spec.y] if spec.y is not None else [])
        two_d = spec.y is not None
        rows_ok = all(isinstance(v, list) for v in spec.values) if two_d else \
            not any(isinstance(v, list) for v in spec.values)
        if not rows_ok:
            raise TableError(f"table '{name}': " + ("a 2-D table (x and y) gives values as one row per x, "
                             "e.g. [[1, 2], [3, 4]]" if two_d else "a 1-D table gives one value per x "
                             "(add y: for a 2-D table)"), "values")
        return _build(name, grids, spec.values, spec.spline)
    for key in ("x", "y", "values"):
        value = getattr(spec, key)
        if value is not None and not isinstance(value, str):
            raise TableError(f"table '{name}': with `csv:`, {key} is a column name of the file", key)
    columns = _read_csv(base / spec.csv, spec.csv)
    wanted = [spec.x] + ([spec.y] if spec.y else []) + [spec.values]
    for key, col in zip(["x"] + (["y"] if spec.y else []) + ["values"], wanted):
        if col not in columns:
            raise TableError(f"table '{name}': {spec.csv} has no column '{col}'"
                             + did_you_mean(col, columns) + f" (columns: {', '.join(columns)})", key)
    if spec.y is None:
        pairs = sorted(zip(columns[spec.x], columns[spec.values]))
        return _build(name, [[p[0] for p in pairs]], [p[1] for p in pairs], spec.spline)
    xs, ys, vs = columns[spec.x], columns[spec.y], columns[spec.values]
    gx, gy = sorted(set(xs)), sorted(set(ys))
    grid: dict[tuple[float, float], float] = {}
    for a, b, v in zip(xs, ys, vs):
        if (a, b) in grid:
            raise TableError(f"table '{name}': {spec.csv} gives ({spec.x}, {spec.y}) = ({a:g}, {b:g}) twice", "csv")
        grid[(a, b)] = v
    missing = [(a, b) for a in gx for b in gy if (a, b) not in grid]
    if missing:
        a, b = missing[0]
        raise TableError(f"table '{name}': {spec.csv} is not a full grid: no row for ({spec.x}, {spec.y}) = "
                         f"({a:g}, {b:g}) ({len(missing)} missing)", "csv")
    return _build(name, [gx, gy], [[grid[(a, b)] for b in gy] for a in gx], spec.spline)


def _build(name, grids, values, bc) -> Table:
    try:
        return Table.build(name, grids, values, bc)
    except ValueError as e:
        raise TableError(str(e), "values" if "values" in str(e) else "x") from None


def _read_csv(path: Path, shown: str) -> dict[str, list[float]]:
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise TableError(f"table file '{shown}' not found (looked for {path})", "csv") from None
    except (OSError, UnicodeDecodeError) as e:
        raise TableError(f"cannot read table file '{shown}' ({e})", "csv") from None
    rows = [r for r in csv.reader(line for line in text.splitlines() if not line.lstrip().startswith("#")) if r]
    if len(rows) < 2:
        raise TableError(f"table file '{shown}' needs a header row and at least one row of numbers", "csv")
    header = [h.strip() for h in rows[0]]
    out: dict[str, list[float]] = {h: [] for h in header}
    for i, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise TableError(f"{shown}, row {i}: {len(row)} cells, the header has {len(header)}", "csv")
        for h, cell in zip(header, row):
            try:
                v = float(cell)
            except ValueError:
                raise TableError(f"{shown}, row {i}: '{cell.strip()}' in column '{h}' is not a number", "csv") from None
            if not math.isfinite(v):
                raise TableError(f"{shown}, row {i}: column '{h}' is not a finite number", "csv")
            out[h].append(v)
    return out
