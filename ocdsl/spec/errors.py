"""Problem-file errors: each names the file, the line and the offending text."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Issue:
    file: str
    line: int | None
    message: str
    text: str = ""

    def __str__(self) -> str:
        where = f"{self.file}:{self.line}" if self.line else self.file
        text = self.text if len(self.text) <= 200 else self.text[:200] + " ..."
        shown = f"\n    {text}" if text else ""
        return f"{where}: {self.message}{shown}"


class SpecError(ValueError):
    """One or more problems in a problem file (all collected, then raised together)."""

    def __init__(self, issues: list[Issue]):
        self.issues = list(issues)
        super().__init__("\n".join(str(i) for i in self.issues))


class ExprError(ValueError):
    """A bad expression; the loader adds file and line."""

    def __init__(self, message: str, text: str = ""):
        self.message, self.text = message, text
        super().__init__(f"{message}: {text}" if text else message)


class UnknownNames(ExprError):
    """Names an expression uses that nothing declares: (name, its phrase with a did-you-mean)."""

    def __init__(self, unknown: list[tuple[str, str]], text: str = ""):
        self.unknown = list(unknown)
        phrases = [p for _, p in self.unknown]
        super().__init__(("unknown name " if len(phrases) == 1 else "unknown names ") + ", ".join(phrases), text)

    def without(self, names: set[str]) -> "UnknownNames | None":
        """The same error without ``names`` (each reported where it was declared), or None."""
        kept = [(n, p) for n, p in self.unknown if n not in names]
        return UnknownNames(kept, self.text) if kept else None


class FollowOnError(ExprError):
    """A use of something whose own error is already reported (a table or a named
    expression that did not compile): not reported again at each use."""
