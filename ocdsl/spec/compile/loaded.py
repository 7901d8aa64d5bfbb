"""What compiling a problem file gives."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import sympy as sp

from ...symbolic.model import Model
from ...symbolic.problem import Problem
from ..loader import Located
from ..schema import ProblemFile


@dataclass
class LoadedFile:
    """A parsed and compiled problem file."""

    path: Path
    located: Located
    spec: ProblemFile
    problem: Problem | None
    method: Any                                   # validated method spec
    expect: dict[str, sp.Expr] = field(default_factory=dict)
    parameters: dict[str, float] = field(default_factory=dict)   # constants in force
    model: Model | None = None                                   # controller files: the plant
    controller: Any = None                                       # validated ControllerSpec
