"""ocdsl's disk cache: generated code that is costly to make and cheap to load.

One folder, ``$OCDSL_CACHE`` (default ``~/.cache/ocdsl``), with a subfolder per kind:

* ``nlp/``: the NLP functions of the direct NumPy route (``ocdsl.transcribe.direct_nlp``):
  the derivatives SymPy found, as NumPy source, and their sparsity, one JSON file per
  family of expressions (a phase's dynamics, path constraints or integrands; the
  objective and boundary conditions), and the shared libraries of the families compiled
  to C (``direct_nlp/native.py``);
* ``numeric/``: the certificate's and the verification's NumPy/``math`` functions of a
  phase (``ocdsl.symbolic.numeric``), one JSON file per family;
* ``simulate/``: the Numba modules of ``ocdsl.simulate``.

An entry's name is a hash of everything it is computed from (the expressions themselves,
the ocdsl version and the source of the module that generates it), so a changed problem
file, model or ocdsl never meets a stale entry: it has another name. Entries are written
to a temporary file in the same folder and renamed into place (atomic on POSIX), so
concurrent runs (a study's workers) never read a half-written one; two writers of the
same entry write the same bytes, and the last rename wins. An unreadable entry is
ignored and written again. Deleting the folder is always safe.

``OCDSL_NO_CACHE=1`` (what ``ocdsl run --no-cache`` and ``ocdsl study --no-cache`` set)
bypasses the cache: nothing is read or written.
"""
from __future__ import annotations

import hashlib
import json
import os
import tempfile
from pathlib import Path
from typing import Any

ENV_DIR = "OCDSL_CACHE"
ENV_OFF = "OCDSL_NO_CACHE"


def enabled() -> bool:
    return os.environ.get(ENV_OFF, "").strip().lower() in ("", "0", "false", "no")


def folder(kind: str) -> Path:
    """The cache subfolder of ``kind``, created if missing."""
    root = Path(os.environ.get(ENV_DIR) or (Path.home() / ".cache" / "ocdsl"))
    d = root / kind
    d.mkdir(parents=True, exist_ok=True)
    return d


def fingerprint(*parts: str) -> str:
    """A hex digest of ``parts`` (in order, separated so that ("ab", "c") != ("a", "bc"))."""
    h = hashlib.sha256()
    for p in parts:
        b = p.encode()
        h.update(len(b).to_bytes(8, "little"))
        h.update(b)
    return h.hexdigest()[:32]


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file in the same folder and a rename."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def read_entry(kind: str, key: str) -> Any | None:
    """The JSON entry ``key`` of ``kind``, or None (missing, unreadable, or the cache is off)."""
    if not enabled():
        return None
    try:
        return json.loads((folder(kind) / f"{key}.json").read_text())
    except (OSError, ValueError):
        return None


def write_entry(kind: str, key: str, value: Any) -> None:
    """Store a JSON-able ``value``; a cache that cannot be written is no error (the run goes on)."""
    if not enabled():
        return
    try:
        write_atomic(folder(kind) / f"{key}.json", json.dumps(value))
    except OSError:
        pass
