"""Registry of non-pseudospectral methods (`method: {transcription: NAME, ...}`).

Each back end registers a pydantic spec class and a runner; the spec layer validates a
file's `method:` block with the spec of the named method.
"""
from __future__ import annotations

from typing import Any

_SPECS: dict[str, Any] = {}


def register_method(name: str, spec_class) -> None:
    _SPECS[name] = spec_class


def method_spec(name: str, data: dict) -> Any:
    return method_spec_class(name).model_validate(data)


def method_spec_class(name: str):
    """The spec class registered for ``name`` (its keys are what a misspelt key is matched to)."""
    _load()
    if name not in _SPECS:
        from .hints import did_you_mean

        known = ["LG", "LGR", "LGL", "LGR-start"] + sorted(_SPECS)
        raise ValueError(f"unknown transcription '{name}'{did_you_mean(name, known)}; known: {', '.join(known)}")
    return _SPECS[name]


def registered_method_classes() -> list:
    """The spec classes of the registered methods, by name (for ``ocdsl schema``)."""
    _load()
    return [_SPECS[name] for name in sorted(_SPECS)]


def _load() -> None:
    """Import the optional back ends' spec modules (each registers itself)."""
    import importlib

    for mod in ("ocdsl.spec.parametric", "ocdsl.search.problem_file", "ocdsl.transcribe.flat_bspline_spec"):
        try:
            importlib.import_module(mod)
        except ImportError:
            pass


_RUNNERS: dict[str, Any] = {}


def register_runner(name: str, fn) -> None:
    """``fn(file, timer, *, seed, warm_start, verbose, progress) -> Result``."""
    _RUNNERS[name] = fn


def runner(name: str):
    _load()
    if name not in _RUNNERS:
        raise ValueError(f"method '{name}' has no runner")
    return _RUNNERS[name]
