"""The examples of ``configs/``: their kind (problem, controller, Pareto, study), which are
slow, and their order (an example after those its guess comes from)."""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

from ocdsl.chain.check import sources_of


CONFIGS = Path("configs")      # relative to the working directory (the repository root under make)
REPORTS = Path("reports")

#: Examples that take minutes (multi-start 6-DOF collocation, PSO paper runs, Table 4 study).
SLOW = frozenset({"seed0_rendezvous", "seed0_exact_euler", "seed0_table4",
                  "seed1_2N_paper", "seed1_5N_paper", "seed1_10N_paper"})
#: Every seed-0 file is a multi-start 6-DOF collocation (minutes), whatever its name.
SLOW_PREFIXES = ("seed0_",)
SLOW_MARK = re.compile(r"^#\s*reproduce:\s*slow\b", re.M | re.I)
GOOD = ("optimal", "acceptable", "feasible", "stable")
# ================================================================================ configs
@dataclass
class Example:
    path: Path
    kind: str            # "problem" | "controller" | "pareto" | "study"
    slow: bool
    name: str = ""
    after: tuple[str, ...] = ()   # the examples whose solutions its guess comes from (ocdsl/chain)

    @property
    def stem(self) -> str:
        return self.path.stem


@dataclass
class Outcome:
    stem: str
    kind: str
    status: str                         # status of the run, "study", or "error"
    ok: bool
    seconds: float
    files: list[Path] = field(default_factory=list)
    message: str = ""


def classify(path: Path, _seen: tuple[str, ...] = ()) -> Example:
    """Kind of a configuration file (from its top-level blocks) and whether it is slow."""
    from ocdsl.spec.loader import load_yaml

    text = path.read_text()
    data = load_yaml(path).data
    if "pareto" in data:
        kind = "pareto"
    elif "study" in data:
        kind = "study"
    elif "controller" in data:
        kind = "controller"
    else:
        kind = "problem"
    slow = path.stem in SLOW or path.stem.startswith(SLOW_PREFIXES) or bool(SLOW_MARK.search(text))
    after = tuple(p.stem for p in sources_of(path) if p.resolve().parent == path.resolve().parent)
    # a chain runs its sources first when their runs under reports/ are not current
    slow = slow or any(classify(path.with_name(a + ".yaml"), _seen + (path.stem,)).slow for a in after
                       if path.with_name(a + ".yaml").is_file() and a not in _seen)
    return Example(path, kind, slow, str(data.get("name") or path.stem), after)


def find_examples(configs: Path = CONFIGS, only: Sequence[str] | None = None,
                  skip_slow: bool = False) -> list[Example]:
    """The examples of ``configs`` (``*.yaml``, sorted), restricted to ``only`` (stems or
    file names) and without the slow ones when ``skip_slow``."""
    files = sorted(Path(configs).glob("*.yaml"))
    if only:
        wanted = {Path(o).stem for o in only}
        unknown = wanted - {f.stem for f in files}
        if unknown:
            raise SystemExit(f"reproduce: no such example in {configs}: {', '.join(sorted(unknown))}")
        files = [f for f in files if f.stem in wanted]
    out = _sources_first([classify(f) for f in files])
    return [e for e in out if not (skip_slow and e.slow)]


def _sources_first(examples: list[Example]) -> list[Example]:
    """``examples`` in their order, each moved after the examples its guess comes from (so
    a chain reuses their fresh run folders instead of solving them again)."""
    by_stem = {e.stem: e for e in examples}
    done: dict[str, Example] = {}

    def place(e: Example, seen: tuple = ()) -> None:
        if e.stem in done or e.stem in seen:      # cycles are refused by `ocdsl check`
            return
        for a in e.after:
            if a in by_stem:
                place(by_stem[a], seen + (e.stem,))
        done[e.stem] = e
    for e in examples:
        place(e)
    return list(done.values())
