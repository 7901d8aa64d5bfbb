"""Read Ipopt's own figures from its output file (``output_file`` + ``print_timing_statistics``)."""
from __future__ import annotations

import re
from pathlib import Path

TIMING_OPTIONS = {"print_timing_statistics": "yes", "file_print_level": 5}

_PATTERNS = {
    "ipopt_wo_fe_s": r"Total seconds in IPOPT \(w/o function evaluations\)\s*=\s*([0-9.eE+-]+)",
    "ipopt_fe_s": r"Total seconds in NLP function evaluations\s*=\s*([0-9.eE+-]+)",
    "ipopt_total_s": r"Total seconds in IPOPT\s*=\s*([0-9.eE+-]+)",
    "iterations": r"Number of Iterations\.*:\s*(\d+)",
    "variables": r"Total number of variables\.*:\s*(\d+)",
    "equalities": r"Total number of equality constraints\.*:\s*(\d+)",
    "inequalities": r"Total number of inequality constraints\.*:\s*(\d+)",
    "jac_eq_nnz": r"Number of nonzeros in equality constraint Jacobian\.*:\s*(\d+)",
    "jac_ineq_nnz": r"Number of nonzeros in inequality constraint Jacobian\.*:\s*(\d+)",
}
# print_timing_statistics: "Name....: <cpu> (sys: <sys> wall: <wall>)"; CPU = user + sys. On a loaded
# machine Ipopt's "Total seconds" (wall) mostly measures the other processes; CPU does not.
_CPU = {"ipopt_cpu_s": "OverallAlgorithm", "ipopt_fe_cpu_s": "Function Evaluations"}
_CPU_RE = r"{}\.*:\s*([0-9.eE+-]+)\s*\(sys:\s*([0-9.eE+-]+)"


def options(path: str | Path) -> dict:
    """Ipopt options that write the statistics to ``path``."""
    return {**TIMING_OPTIONS, "output_file": str(path)}


def parse(path: str | Path) -> dict[str, float]:
    """Ipopt's sizes, iterations and times; the last solve in the file counts (ocdsl numbers
    the files of a run's later solves, ``ocdsl.solve.ipopt._numbered_output_file``)."""
    try:
        text = Path(path).read_text()
    except OSError:
        return {}
    out: dict[str, float] = {}
    for key, pat in _PATTERNS.items():
        hits = re.findall(pat, text)
        if hits:
            out[key] = float(hits[-1])
    for key, name in _CPU.items():
        hits = re.findall(_CPU_RE.format(name), text)
        if hits:
            out[key] = float(hits[-1][0]) + float(hits[-1][1])
    if "ipopt_cpu_s" in out:
        out["ipopt_wo_fe_cpu_s"] = out["ipopt_cpu_s"] - out.get("ipopt_fe_cpu_s", 0.0)
    if "ipopt_total_s" not in out and "ipopt_wo_fe_s" in out:
        out["ipopt_total_s"] = out["ipopt_wo_fe_s"] + out.get("ipopt_fe_s", 0.0)
    if "equalities" in out:
        out["constraints"] = out["equalities"] + out.get("inequalities", 0.0)
    return out
