"""Run every example in ``configs/`` and write its reports under ``reports/``.

``python -m ocdsl.report.reproduce [--only NAME ...] [--skip-slow] [--formats html,pdf]
[--configs DIR] [--out DIR]`` (``make reproduce`` runs it after the slow tests).

For every configuration file ``configs/<stem>.yaml`` (by kind):

* problem files and controller files (``controller:`` block): ``ocdsl.api.run_file`` (what
  ``ocdsl run`` does) into the run folder ``reports/<stem>/``, then ``report.html``/``report.pdf``
  in it (:func:`ocdsl.report.make_report`); a file whose guess comes from another example's
  file (``guess: {from: other.yaml, reuse: ../reports/other}``, ocdsl/chain) runs after it,
  and reuses its fresh run folder;
* ``pareto:`` files: ``ocdsl.study.pareto_run.run_pareto`` into the study folder
  ``reports/<stem>/`` (its own ``result.json`` with the set, one run folder per solution),
  then its report;
* study files (``study:`` block): ``ocdsl.study.run.run_study`` into ``reports/<stem>/``,
  then one comparison report over the study (:func:`ocdsl.report.make_comparison_report`).

Each example is made in a scratch folder ``reports/.new/<stem>`` and swapped in only when
its reports are written, so an interrupted reproduction leaves the previous reports. Last,
``reports/index.html`` (:func:`ocdsl.report.make_index`) is made from *every* report folder
under ``reports/`` (also those not re-run this time, e.g. the slow ones with
``--skip-slow``): one row per paper number (each ``expect`` check of the run folders, and
the reference tables of :data:`PAPER_TABLES` for studies) with reference, ocdsl value,
error, pass/fail and a link to the report. ``reports/reproduce.json`` records, per
example, its kind, status, wall time and the date and commit it was made at.

Slow examples (minutes each) are those in :data:`SLOW`, named ``seed0_*``, or whose file has a top-level
comment line ``# reproduce: slow``; ``--skip-slow`` leaves them out.

Exit code: 0 when every example ran, its reports were written and its ``expect`` checks
passed; 1 otherwise (the reports are still written); 2 for bad options.

One module per concept: the examples and their order (:mod:`.examples`), running them
and the manifest (:mod:`.runs`), where each reference number comes from
(:mod:`.references`), the index's rows and verdicts (:mod:`.numbers`) and the command
line (:mod:`.cli`).
"""
from __future__ import annotations

from ocdsl.report.reproduce.cli import main
from ocdsl.report.reproduce.examples import Example, Outcome, classify, find_examples
from ocdsl.report.reproduce.numbers import (


    expect_numbers, paper_numbers, report_folders, study_paper_numbers, verdict_of, write_index)
from ocdsl.report.reproduce.references import (
    AGREES, BETTER, DIFFERS, NOT_REPRODUCED, PAPER_TABLES, PRINTED_EXTRA, REFERENCES, REPRODUCED, SHOWN_WRONG)
from ocdsl.report.reproduce.runs import remake_reports, reproduce, run_example, write_manifest

__all__ = ["AGREES", "BETTER", "DIFFERS", "Example", "NOT_REPRODUCED", "Outcome", "PAPER_TABLES", "PRINTED_EXTRA",
           "REFERENCES", "REPRODUCED", "SHOWN_WRONG", "classify", "expect_numbers", "find_examples", "main",
           "paper_numbers", "remake_reports", "report_folders", "reproduce", "run_example", "study_paper_numbers",
           "verdict_of", "write_index", "write_manifest"]
