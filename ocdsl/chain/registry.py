"""Registry of guess transforms: a change of variables from a source run's trajectory to
a target problem's, named in a problem file as ``guess: {from: ..., transform: NAME}``.

A transform module registers its function::

    @register_transform("my_change", description="...")
    def convert(source: Result, source_dir: Path, target: LoadedFile) -> Result: ...

``convert`` returns the guess as a Result in the target's variables (its phases named as
the target's, or a single phase); ``annotate(result, source_dir, target)``, when given,
adds what the transform knows of the finished run to ``result.extra`` (e.g. a comparison
with the source). No code lives in a problem file: only the name.

Other packages add transforms by naming their modules in their ``pyproject.toml``::

    [project.entry-points."ocdsl.transforms"]
    my_transforms = "my_package.transforms"
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Callable

ENTRY_POINT_GROUP = "ocdsl.transforms"
#: the project's own transform modules, imported on the first look-up
BUILTIN_MODULES = ("ocdsl.search.refine_optimal",)
#: the source's trajectory as it is, interpolated onto the new mesh (what ``from: RUN_DIR`` does)
IDENTITY = "identity"


@dataclass(frozen=True)
class Transform:
    name: str
    convert: Callable | None          # None: identity
    description: str
    annotate: Callable | None = None


_REGISTRY: dict[str, Transform] = {}
_BROKEN: dict[str, str] = {}
_LOADED = False


def register_transform(name: str, description: str = "", annotate: Callable | None = None):
    """Decorator registering ``convert`` under ``name``."""

    def wrap(convert: Callable) -> Callable:
        if name in _REGISTRY and _REGISTRY[name].convert is not convert:
            raise ValueError(f"transform {name!r} registered twice")
        _REGISTRY[name] = Transform(name, convert, description, annotate)
        return convert

    return wrap


def _load_all() -> None:
    global _LOADED
    if _LOADED:
        return
    _REGISTRY.setdefault(IDENTITY, Transform(IDENTITY, None, "the source's variables as they are"))
    for module in BUILTIN_MODULES:
        importlib.import_module(module)
    from importlib.metadata import entry_points   # 30-50 ms of import: on the first look-up only

    for entry in entry_points(group=ENTRY_POINT_GROUP):
        try:
            entry.load()
        except Exception as e:  # a broken third-party package must not hide the others
            _BROKEN[entry.name] = f"{entry.value}: {type(e).__name__}: {e}"
    _LOADED = True


def transform_names() -> list[str]:
    _load_all()
    return sorted(_REGISTRY)


def get_transform(name: str) -> Transform:
    """The transform ``name``; KeyError (with the known names) when there is none."""
    _load_all()
    if name not in _REGISTRY:
        broken = "".join(f"; entry point {k} failed: {v}" for k, v in _BROKEN.items())
        raise KeyError(f"unknown transform '{name}' (known: {', '.join(sorted(_REGISTRY))}){broken}")
    return _REGISTRY[name]
