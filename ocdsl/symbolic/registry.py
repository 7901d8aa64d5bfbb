"""Registry of SymPy models defined in the top-level ``models/`` package.

A model module defines a builder and registers it::

    @register("double_integrator", description="...")
    def build(options) -> Model: ...

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


_REGISTRY: dict[str, RegisteredModel] = {}
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
    import models  # the project's model package

    for info in pkgutil.iter_modules(models.__path__):
        if not info.name.startswith("_"):
            importlib.import_module(f"models.{info.name}")
    _LOADED = True


def model_names() -> list[str]:
    _load_all()
    return sorted(_REGISTRY)


def registered(name: str) -> RegisteredModel:
    _load_all()
    if name not in _REGISTRY:
        from ..hints import did_you_mean

        raise KeyError(f"unknown model {name!r}{did_you_mean(name, _REGISTRY)}; known: {', '.join(sorted(_REGISTRY))}")
    return _REGISTRY[name]


def build_model(name: str, options: dict[str, Any] | None = None) -> Model:
    """Build registered model ``name`` with model ``options``."""
    entry = registered(name)
    unknown = set(options or {}) - set(entry.options)
    if unknown:
        raise ValueError(f"model {name!r}: unknown options {sorted(unknown)}; known: {sorted(entry.options)}")
    return entry.builder(dict(options or {}))
