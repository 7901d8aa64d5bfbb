"""The design note's examples marked 'must run as written' run exactly as written."""
import re

import pytest

import ocdsl
from conftest import SHARED

DESIGN = SHARED / "design" / "problem-files.md"


def _blocks():
    text = DESIGN.read_text()
    out = []
    for m in re.finditer(r"## ([^\n]*must run as written[^\n]*)\n(?:[^`]*?)```yaml\n(.*?)```", text, re.S):
        out.append((m.group(1), m.group(2)))
    return out


@pytest.mark.ipopt
@pytest.mark.skipif(not DESIGN.exists(), reason="../shared/design/problem-files.md not beside the checkout")
def test_must_run_as_written(tmp_path):
    blocks = _blocks()
    assert len(blocks) == 2, "the minimal and the named-expressions examples"
    for title, text in blocks:
        p = tmp_path / "example.yaml"
        p.write_text(text)
        res = ocdsl.load(p).solve()
        assert res.ok, (title, res.status, res.expect)
