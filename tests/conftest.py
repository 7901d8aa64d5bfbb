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


@pytest.fixture(autouse=True)
def _floating_point_environment():
    """Tests that read an NL file through PyNumero themselves (PyomoNLP) leave the x87 unit
    at the ASL's 53-bit precision; restored so that no test depends on which ran before it
    in its worker (ocdsl.solve.process_state.floating_point_environment_kept)."""
    from ocdsl.solve.process_state import floating_point_environment_kept

    with floating_point_environment_kept():
        yield
