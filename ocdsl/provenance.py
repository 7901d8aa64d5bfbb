"""Which ocdsl made a run: its version and the commit of its source tree, stamped into every
run folder's ``result.json`` (``extra.ocdsl``). A report showed only the commit of the ocdsl
that built the report (unseen33 F10: a run made at 11cf681 reported "commit 896a2fa").

The commit is read from the checkout's git files (HEAD, a loose ref or packed-refs): no git
process in every run; "unknown" outside a git checkout."""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path


@lru_cache(maxsize=1)
def source() -> dict[str, str]:
    from ocdsl import __version__

    return {"version": __version__, "commit": _commit(Path(__file__).resolve().parents[1] / ".git")}


def _commit(git: Path) -> str:
    try:
        if git.is_file():                    # a worktree: "gitdir: <path>"
            git = Path(git.read_text().split(":", 1)[1].strip())
        head = (git / "HEAD").read_text().strip()
        if not head.startswith("ref:"):
            return head[:7]
        ref = head.split(":", 1)[1].strip()
        common = Path((git / "commondir").read_text().strip()) if (git / "commondir").is_file() else None
        roots = [git] + ([(git / common).resolve()] if common is not None else [])
        for root in roots:
            if (root / ref).is_file():
                return (root / ref).read_text().strip()[:7]
            packed = root / "packed-refs"
            if packed.is_file():
                for line in packed.read_text().splitlines():
                    if line.endswith(" " + ref):
                        return line.split()[0][:7]
    except (OSError, IndexError, ValueError):
        pass
    return "unknown"
