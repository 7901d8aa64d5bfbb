"""What ``ocdsl check`` (and every compile) says of a chained guess: ``from`` names a
problem file that exists and whose chain comes back to no file twice, ``transform`` is
registered, ``reuse`` goes with a problem-file ``from``. The source file's own mistakes
are reported when it is compiled to run, with its own file and line."""
from __future__ import annotations

from pathlib import Path
from typing import Callable

PROBLEM_SUFFIXES = (".yaml", ".yml")


def is_problem_file(source: str) -> bool:
    """``from:`` names a problem file (solved first) rather than a run folder."""
    return str(source).lower().endswith(PROBLEM_SUFFIXES)


def resolve(base: Path, source: str) -> Path:
    """A path of a problem file, relative to that file's folder."""
    p = Path(source)
    return p if p.is_absolute() else Path(base).parent / p


def check_guess(path: Path, guess, loc: tuple, issue: Callable[[tuple, str], None]) -> None:
    """Report, through ``issue(loc, message)``, what is wrong with ``guess``'s chain keys."""
    from ..hints import did_you_mean
    from .registry import get_transform, transform_names

    source, transform, reuse = guess.from_, guess.transform, guess.reuse
    if source is None:
        if transform is not None:
            issue(loc + ("guess", "transform"), "a transform needs `from:` (a problem file or a run folder)")
        if reuse is not None:
            issue(loc + ("guess", "reuse"), "`reuse:` needs `from:` (the problem file it is a run of)")
        return
    if transform is not None:
        try:
            get_transform(transform)
        except KeyError:
            names = transform_names()
            issue(loc + ("guess", "transform"), f"unknown transform '{transform}'{did_you_mean(transform, names)} "
                  f"(registered: {', '.join(names)})")
    target = resolve(path, source)
    if not is_problem_file(source):
        if reuse is not None:
            issue(loc + ("guess", "reuse"), f"`reuse:` names an earlier run of a problem file, but `from: {source}` "
                  "is a run folder (use it directly)")
        if not (target / "result.json").exists():
            issue(loc + ("guess", "from"), f"guess from '{source}': no run folder there "
                  f"(looked for {target / 'result.json'})")
        else:
            from ..result import unusable_start

            why = unusable_start(target)
            if why:
                issue(loc + ("guess", "from"), f"guess from '{source}': {why}")
        return
    if not target.is_file():
        issue(loc + ("guess", "from"), f"guess from '{source}': no such problem file (looked for {target})")
        return
    cycle = _cycle(Path(path), target)
    if cycle:
        issue(loc + ("guess", "from"), f"guess from '{source}': the chain of files comes back to "
              f"{cycle[-1].name}: {' -> '.join(p.name for p in cycle)}")


def sources_of(path: Path) -> list[Path]:
    """The problem files the guesses of ``path`` come from (its phases' ``guess: from``);
    a file that does not parse has none here (its compile reports it)."""
    from ..spec.errors import SpecError
    from ..spec.loader import load_yaml

    try:
        data = load_yaml(path).data
    except (SpecError, OSError):
        return []
    guesses = []
    if isinstance(data.get("problem"), dict):
        guesses.append(data["problem"].get("guess"))
    if isinstance(data.get("phases"), dict):
        guesses += [ph.get("guess") for ph in data["phases"].values() if isinstance(ph, dict)]
    out = []
    for g in guesses:
        if isinstance(g, dict) and isinstance(g.get("from"), str) and is_problem_file(g["from"]):
            out.append(resolve(path, g["from"]))
    return out


def _cycle(start: Path, first: Path) -> list[Path] | None:
    """The chain start -> first -> ... that reaches a file already on it, or None."""
    def walk(chain: list[Path]) -> list[Path] | None:
        here = chain[-1]
        seen = [p.resolve() for p in chain[:-1]]
        if here.resolve() in seen:
            return chain
        for nxt in sources_of(here):
            found = walk(chain + [nxt])
            if found:
                return found
        return None
    return walk([start, first])
