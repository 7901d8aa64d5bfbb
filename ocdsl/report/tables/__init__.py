"""Tables of a report, as plain data for the templates.

A table is a dict ``{"key", "caption", "columns", "rows", "note"}``; each cell is a
dict ``{"text": str, "cls": str}`` (``cls`` among ``num``, ``pass``, ``fail``, ``warn``,
``""``) or ``{"html": Markup}`` for pre-escaped content (symbol names with sub/superscripts).
Builders return ``None`` when the run folder has nothing for that table. One module per
kind of table: cells and formatting (:mod:`.cells`), the problem (:mod:`.problem`), the
solution (:mod:`.solution`), the checks (:mod:`.checks`), back-end details
(:mod:`.details`), column tables (:mod:`.columns`), controllers (:mod:`.controller`) and
several runs (:mod:`.studies`).
"""
from __future__ import annotations

from ocdsl.report.tables.cells import cell, finite_or_none, fmt, table, truthy
from ocdsl.report.tables.checks import (
    certificate_table, compare_text, expect_table, switch_table, tolerance_text, verification_table)
from ocdsl.report.tables.columns import column_table, reintegration_table
from ocdsl.report.tables.controller import closed_loop_table, controller_table, robustness_table
from ocdsl.report.tables.details import extra_table, starts_table
from ocdsl.report.tables.problem import method_table, parameters_table, phases_table, variables_table
from ocdsl.report.tables.solution import summary_table, wall_time_table
from ocdsl.report.tables.studies import expect_comparison_table, runs_table

__all__ = ["cell", "certificate_table", "closed_loop_table", "column_table", "compare_text", "controller_table",
           "expect_comparison_table", "expect_table", "extra_table", "finite_or_none", "fmt", "method_table",
           "parameters_table", "phases_table", "reintegration_table", "robustness_table", "runs_table", "starts_table",
           "summary_table", "switch_table", "table", "tolerance_text", "truthy", "variables_table",
           "verification_table", "wall_time_table"]
