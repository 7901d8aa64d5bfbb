"""Problem file -> validated spec -> symbolic :class:`~ocdsl.symbolic.problem.Problem`.

Every mistake becomes an :class:`~ocdsl.spec.errors.Issue` with file, line and text;
all issues found are raised together as one :class:`SpecError`.

Modules, one concept each: :mod:`.compiler` (top level, tables, method, the problem's
assembly, its description), :mod:`.models`, :mod:`.phases` (times, guesses, scopes),
:mod:`.constraints` (relations, links, their checks), :mod:`.loaded` (the result),
:mod:`.common` (limits and helpers).
"""
from __future__ import annotations

from pathlib import Path

from ..errors import Issue, SpecError
from ..loader import Located, load_yaml
from ..schema import ProblemFile
from ..validate import validate, validate_all  # noqa: F401  (ocdsl.spec.compile.validate*)
from .compiler import Compiler, validated_method
from .loaded import LoadedFile

_Compiler = Compiler       # the name its callers (api, study reuse, pareto check) use

__all__ = ["LoadedFile", "load", "compile_spec", "Compiler", "validate", "validate_all"]


def load(path: str | Path, parameters: dict[str, float] | None = None) -> LoadedFile:
    """Read, validate and compile ``path``; ``parameters`` override constants by name."""
    located = load_yaml(path)
    spec, issues = validate_all(located)
    return compile_spec(Path(path), located, spec, issues, parameters or {})


def compile_spec(path: Path, located: Located, spec: ProblemFile | None, issues: list[Issue],
                 parameters: dict[str, float]) -> LoadedFile:
    """Compile a validated spec; raises one SpecError with the schema's ``issues`` and every
    issue the compiler finds (none twice)."""
    if spec is None:
        data = located.data.get("method") if isinstance(located.data, dict) else None
        if isinstance(data, dict):      # its own mistakes in the same pass as the schema's
            found = validated_method(located, data)[1]
            issues = sorted(list(issues) + [i for i in found if i not in issues], key=lambda i: i.line or 0)
        raise SpecError(issues)
    try:
        loaded = Compiler(path, located, spec, dict(parameters)).compile()
    except SpecError as e:
        found = list(issues) + [i for i in e.issues if i not in issues]
        raise SpecError(sorted(found, key=lambda i: i.line or 0)) from None
    if issues:
        raise SpecError(issues)
    return loaded
