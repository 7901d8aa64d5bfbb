import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = ROOT / "configs"
SHARED = ROOT.parent / "shared"

os.environ.setdefault("MPLBACKEND", "Agg")


@pytest.fixture
def configs() -> Path:
    return CONFIGS


def write(tmp_path: Path, text: str, name: str = "problem.yaml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p
