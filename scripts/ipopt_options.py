"""Regenerate ocdsl/solve/ipopt_options.json: every option the bundled Ipopt knows, with its
type (real, integer, string), its valid range and, for a string option, its possible values.

Ipopt prints its option documentation on stdout from C, so this script runs itself in a
child process and reads that output (doxygen mode: the only one that names the types):

    python scripts/ipopt_options.py          # writes ocdsl/solve/ipopt_options.json
"""
import html
import json
import re
import subprocess
import sys
from pathlib import Path

OUT = Path(__file__).resolve().parents[1] / "ocdsl" / "solve" / "ipopt_options.json"


def print_documentation() -> None:
    import numpy as np

    import cyipopt

    class Tiny:
        def objective(self, x):
            return float(x[0] ** 2)

        def gradient(self, x):
            return np.array([2 * x[0]])

        def constraints(self, x):
            return np.zeros(0)

        def jacobian(self, x):
            return np.zeros(0)

    nlp = cyipopt.Problem(n=1, m=0, problem_obj=Tiny(), lb=[-1.0], ub=[1.0], cl=[], cu=[])
    for k, v in (("print_options_documentation", "yes"), ("print_advanced_options", "yes"),
                 ("print_options_mode", "doxygen"), ("hessian_approximation", "limited-memory")):
        nlp.add_option(k, v)
    nlp.solve(np.array([0.5]))


def _number(text: str) -> float:
    """``0.5``, ``10<sup>+20</sup>``, ``-inf``."""
    m = re.fullmatch(r"10<sup>([+-]?\d+)</sup>", text)
    return float(f"1e{m.group(1)}") if m else float(text)


def _is_number(text: str) -> bool:
    try:
        _number(text)
        return True
    except ValueError:
        return False


def parse(doc: str) -> dict:
    options = {}
    for block in re.split(r"\\anchor OPT_", doc)[1:]:
        name = block.split("\n", 1)[0].strip()
        body = html.unescape(block)
        entry: dict = {}
        m = re.search(r"The valid range for this (real|integer) option is (.*?) and its default", body, re.S)
        if m:
            entry["type"] = m.group(1)
            rng = " ".join(m.group(2).split())
            if rng != "unrestricted":
                parts = re.split(r"\s*(<|≤)\s*", rng)       # e.g. ['0', '<', 'tol', '≤', '1']
                # the option's own name (a few say another: "0 < rho < 1" of sigma_max)
                at = next(i for i, p in enumerate(parts) if i % 2 == 0 and not _is_number(p))
                if at >= 2:
                    entry["lower"], entry["lower_strict"] = _number(parts[at - 2]), parts[at - 1] == "<"
                if at + 2 < len(parts):
                    entry["upper"], entry["upper_strict"] = _number(parts[at + 2]), parts[at + 1] == "<"
        elif "string option" in body:
            entry["type"] = "string"
            listed = body.split("Possible values:", 1)[1].split("</blockquote>", 1)[0] if "Possible values:" in body else ""
            values = (re.findall(r"^ - ([^:\s]+):", listed, re.M)
                      or [v.strip() for v in listed.strip().split(",") if v.strip()])
            if values and "*" not in values:        # "*": any text (a file name)
                entry["values"] = values
        else:
            continue
        options[name] = entry
    return options


if __name__ == "__main__":
    if sys.argv[1:] == ["--child"]:
        print_documentation()
        sys.exit(0)
    doc = subprocess.run([sys.executable, __file__, "--child"], capture_output=True, text=True, check=True).stdout
    options = parse(doc)
    # suppresses Ipopt's banner; accepted by Ipopt but not in its documentation
    options["sb"] = {"type": "string", "values": ["yes", "no"]}
    if len(options) < 200:
        sys.exit(f"only {len(options)} options parsed: is the documentation format the same?")
    OUT.write_text(json.dumps(dict(sorted(options.items())), indent=1) + "\n")
    print(f"wrote {OUT}: {len(options)} options")
