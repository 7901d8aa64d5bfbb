"""Registry of SymPy models: the project's own (the repository's ``models/`` folder,
installed as the package ``ocdsl.models``) and those of other packages, found through the
entry-point group ``ocdsl.models``.

A model module defines a builder and registers it::

    @register("double_integrator", description="...")
    def build(options) -> Model: ...

Another package adds its models by naming its model modules in its own ``pyproject.toml``::

    [project.entry-points."ocdsl.models"]
    my_models = "my_package.models"

Each entry point is imported when models are first looked up, and its ``@register`` calls
register its models (docs/architecture.md).

``options`` is a dict of model options from the problem file (``model: {use: NAME,
options: {...}}``); builders reject unknown options with a ValueError naming them.
"""
from __future__ import annotations

import importlib
import pkgutil
from dataclasses import dataclass
from typing import Any, Callable

from .model import Model

Builder = Callable[[dict[str, Any]], Model]


@dataclass(frozen=True)
class RegisteredModel:
    name: str
    builder: Builder
    description: str
    options: dict[str, str]  # option name -> one-line description


ENTRY_POINT_GROUP = "ocdsl.models"
_REGISTRY: dict[str, RegisteredModel] = {}
_BROKEN: dict[str, str] = {}       # entry point name -> why importing it failed
_LOADED = False


def register(name: str, description: str = "", options: dict[str, str] | None = None):
    """Decorator registering a model builder under ``name``."""

    def wrap(builder: Builder) -> Builder:
        if name in _REGISTRY and _REGISTRY[name].builder is not builder:
            raise ValueError(f"model {name!r} registered twice")
        _REGISTRY[name] = RegisteredModel(name, builder, description, dict(options or {}))
        return builder

    return wrap


def _load_all() -> None:
    global _LOADED
    if _LOADED:
        return
    from .. import models  # the project's own models (the repository's models/ folder)

    for info in pkgutil.iter_modules(models.__path__):
        if not info.name.startswith("_"):
            importlib.import_module(f"{models.__name__}.{info.name}")
    from importlib.metadata import entry_points   # 30-50 ms of import: on the first look-up only

    for entry in entry_points(group=ENTRY_POINT_GROUP):
        try:
            entry.load()
        except Exception as e:  # a broken third-party package must not hide the others
            _BROKEN[entry.name] = f"{entry.value}: {type(e).__name__}: {e}"
    _LOADED = True


def model_names() -> list[str]:
    _load_all()
    return sorted(_REGISTRY)


def registered(name: str) -> RegisteredModel:
    _load_all()
    if name not in _REGISTRY:
        from ..hints import did_you_mean

        broken = "".join(f"; entry point {k} failed to import ({v})" for k, v in sorted(_BROKEN.items()))
        raise KeyError(f"unknown model {name!r}{did_you_mean(name, _REGISTRY)}; known: "
                       f"{', '.join(sorted(_REGISTRY))}{broken}")
    return _REGISTRY[name]


def build_model(name: str, options: dict[str, Any] | None = None) -> Model:
    """Build registered model ``name`` with model ``options``."""
    entry = registered(name)
    unknown = set(options or {}) - set(entry.options)
    if unknown:
        raise ValueError(f"model {name!r}: unknown options {sorted(unknown)}; known: {sorted(entry.options)}")
    return entry.builder(dict(options or {}))
