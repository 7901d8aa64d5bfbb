"""Tables over several runs: one row per run, the expect checks side by side."""
from __future__ import annotations

from ocdsl.result import Result
from ocdsl.report.tables.cells import GOOD_STATUS, cell, finite_or_none, fmt, status_cell, table, verdict


# ----------------------------------------------------------------------- studies
def run_final_time(r) -> float | None:
    """The run's final time: its last phase's end. Phases that each start at 0 (the two-burn
    programme's) end after the sum of their durations. The sum of the phases' final times was
    shown for a two-phase run ending at 2 (1 + 2 = 3, unseen43 F4)."""
    tf = r.tf
    if not isinstance(tf, dict):
        return tf
    ends = [float(v) for v in tf.values() if finite_or_none(v) is not None]
    if not ends:
        return None
    starts = [float(p.time[0]) for p in r.phases if len(p.time)]
    if len(ends) > 1 and len(starts) == len(ends) and all(t0 == 0.0 for t0 in starts):
        return sum(ends)
    return max(ends)


def runs_table(results: list[Result], labels: list[str] | None = None) -> dict | None:
    """One row per run: status, objective, t_f, iterations, NLP size, wall time, checks,
    and the parameters that differ between runs."""
    if not results:
        return None
    labels = labels or [r.name for r in results]
    pnames: list[str] = []
    for r in results:
        pnames += [k for k in r.parameters if k not in pnames]
    varying = [k for k in pnames
               if len({fmt(r.parameters.get(k)) for r in results}) > 1]
    rows = []
    for lab, r in zip(labels, results):
        tf = run_final_time(r)
        n_ok = sum(bool(c.get("passed")) for c in r.expect)
        # a failed solve's J is its last iterate's (unseen33 F4: printed like a solution's)
        solved = r.status in GOOD_STATUS
        objective = (cell(r.objective, "num", 8) if solved or finite_or_none(r.objective) is None
                     else cell(f"{fmt(r.objective, 8)} (mesh not converged)", "")
                     if r.status == "mesh_not_converged"      # a solved mesh (unseen43 F8: "last iterate")
                     else cell(f"{fmt(r.objective, 8)} (last iterate)", ""))
        laws = (r.extra or {}).get("laws")
        if r.objective is None and isinstance(laws, list):
            # a controller file's runs have a J per law, not one (unseen35 F8: "—")
            objective = cell(", ".join(f"{law} {fmt((r.extra.get(law) or {}).get('cost'), 8)}" for law in laws), "")
        checked = (r.verification or {}).get("status") or "—"
        verification = {"text": checked, "cls": "pass" if checked in ("verified", "not_applicable") else "fail"}
        row = [cell(lab, "name"), status_cell(r.status), verification,
               {"text": "yes" if r.ok else "no", "cls": "pass" if r.ok else "fail"}, objective, cell(tf, "num", 8),
               cell(r.iterations), cell((r.nlp or {}).get("variables")),
               cell((r.wall_time_s or {}).get("total"), "num", 4),
               ({"text": f"{n_ok}/{len(r.expect)}", "cls": "pass" if n_ok == len(r.expect) else "fail"}
                if r.expect else cell(None))]
        row += [cell(r.parameters.get(k)) for k in varying]
        rows.append(row)
    return table("runs", "Compared runs: the solver's status, the independent verification, whether the run "
                 "is ok (its exit code 0), and a failed solve's objective marked as its last iterate's.",
                 ["run", "status", "verification", "ok", "objective", "t_f", "iterations",
                  "NLP variables", "wall time [s]", "checks"] + varying, rows)


def expect_comparison_table(results: list[Result], labels: list[str]) -> dict | None:
    rows = []
    for lab, r in zip(labels, results):
        for c in r.expect or []:
            rows.append([cell(lab, "name"), cell(c.get("name", "?"), ""), cell(c.get("reference"), "num", 10),
                         cell(c.get("value"), "num", 10), cell(c.get("error"), "num", 3), verdict(c.get("passed"))])
    return table("expect_all", "Expected values of every run.",
                 ["run", "check", "reference", "ocdsl", "error", "result"], rows)
