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


class FollowOnError(ExprError):
    """A use of something whose own error is already reported (a table or a named
    expression that did not compile): not reported again at each use."""
