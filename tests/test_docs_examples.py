"""docs/problem-language.md runs: each ```yaml block that starts with `name:` is a whole
problem file, each ```csv or ```yaml block that starts with `# file: NAME` a file beside it
(a table's data, a chain's source); every problem file solves, is verified and meets its
`expect` values."""
import re
from pathlib import Path

import pytest

from conftest import ROOT

DOC = ROOT / "docs" / "problem-language.md"
BLOCK = re.compile(r"^```(\w+)\n(.*?)^```", re.S | re.M)


def _blocks():
    return [(lang, body) for lang, body in BLOCK.findall(DOC.read_text())]


def _problems():
    return [body for lang, body in _blocks() if lang == "yaml" and body.startswith("name:")]


def _write_files(folder: Path) -> None:
    for lang, body in _blocks():
        m = re.match(r"# file: (\S+)\n", body)
        if lang in ("csv", "yaml") and m:
            (folder / m.group(1)).write_text(body)


def test_the_language_doc_has_runnable_examples():
    names = [re.match(r"name: (.*)", b).group(1) for b in _problems()]
    assert len(names) >= 3, names
    # a CSV the tables example reads is written out beside it
    assert any(lang == "csv" for lang, _ in _blocks())


@pytest.mark.ipopt
@pytest.mark.parametrize("index", range(len(_problems())))
def test_doc_example_solves_and_is_verified(index, tmp_path):
    from ocdsl.api import load

    _write_files(tmp_path)
    path = tmp_path / f"example{index}.yaml"
    path.write_text(_problems()[index])
    res = load(str(path)).solve()
    assert res.status == "optimal", res.message
    assert res.verification["status"] == "verified", res.verification.get("summary")
    assert res.expect and all(c["passed"] for c in res.expect), res.expect
