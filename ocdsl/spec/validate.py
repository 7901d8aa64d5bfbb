"""A problem file's YAML against the schema: every mistake an :class:`Issue` at its line, the
most specific one per location, and what is left valid for the compiler to check further
(so that a file's independent mistakes come in one pass)."""
from __future__ import annotations

import re
from typing import Any

import pydantic

from ..hints import did_you_mean
from .errors import Issue, SpecError
from .loader import Located
from .schema import ProblemFile

def validate(located: Located) -> ProblemFile:
    try:
        spec = ProblemFile.model_validate(located.data)
    except pydantic.ValidationError as e:
        raise SpecError(_schema_issues(located, e.errors())) from None
    misread = booleans_read_as_values(located, spec)
    if misread:
        raise SpecError(misread)
    return spec


_ABSENT = object()


def booleans_read_as_values(located: Located, spec: pydantic.BaseModel) -> list[Issue]:
    """An unquoted true or false where the schema took a number or an expression: pydantic
    reads it as 1 or 0 (`y: true` in dynamics was solved as y' = 1, optimal and verified,
    unseen40 F1). Only where the validated value became a number: `enabled: true` stays a
    boolean, an Ipopt yes/no option's `true` the word yes."""
    issues: list[Issue] = []

    def child(value, key):
        if isinstance(value, dict):
            return value.get(key, _ABSENT)
        if isinstance(value, (list, tuple)):
            return value[key] if isinstance(key, int) and key < len(value) else _ABSENT
        if isinstance(value, pydantic.BaseModel):
            for name, f in type(value).model_fields.items():
                if key in (name, f.alias):
                    return getattr(value, name)
            return (value.model_extra or {}).get(key, _ABSENT)
        return _ABSENT

    def walk(raw, value, path):
        if value is _ABSENT:
            return
        if isinstance(raw, bool):
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                word = str(raw).lower()
                issues.append(located.issue(path, f"{'.'.join(map(str, path))}: YAML reads an unquoted {word} as "
                                                  f"a boolean, not a number or an expression: quote it ('{word}') "
                                                  f"if it is a name, or write the number",
                                            _source_line(located, path)))
            return
        if isinstance(raw, dict):
            for key, sub in raw.items():
                walk(sub, child(value, key), path + (key,))
        elif isinstance(raw, list):
            for i, sub in enumerate(raw):
                walk(sub, child(value, i), path + (i,))

    walk(located.data, spec, ())
    return issues


def _schema_issues(located: Located, errors: list, root: tuple | None = None) -> list[Issue]:
    """One issue per location: a value that is none of a union's types (text or a number)
    fails each of them, which is one mistake. ``root``: (location prefix, pydantic class)
    of a block validated by its own class (`method:`), for the did-you-mean of its keys."""
    # a validator's own message first: the value passed that member's types, so it is the
    # member meant (`p: {free: true, bounds: [2, -2]}` was "Input should be a valid number",
    # the float member's complaint, not "bounds reversed")
    errors = sorted(errors, key=lambda err: err.get("type") != "value_error")
    locs = [_document_loc(err["loc"]) for err in errors]
    out, seen = [], set()
    for err, loc in zip(errors, locs):
        # one per location, the most specific: `segments: [0, x, 1]` is not an integer
        # either, but the item that is not a number is the mistake
        if loc in seen or any(len(o) > len(loc) and o[:len(loc)] == loc for o in locs):
            continue
        seen.add(loc)
        out.append(_issue_from_pydantic(located, err, root))
    return out


SPLICED = ("constraints", "links")
DECLARED_LISTS = ("states", "controls")


def splice_lists(located: Located) -> None:
    """A list item of ``constraints:`` or ``links:`` that is itself a list (``- *bounds``, an
    anchored list of shared constraints) is spliced in its place; lines follow the items."""
    def walk(node, path):
        if isinstance(node, dict):
            for key, value in node.items():
                if key in SPLICED and isinstance(value, list) and any(isinstance(v, list) for v in value):
                    node[key] = splice(value, path + (key,))
                else:
                    walk(value, path + (key,))

    def splice(items, path):
        out, lines = [], {}
        for i, item in enumerate(items):
            parts = [(item, path + (i,))] if not isinstance(item, list) else \
                [(v, path + (i, k)) for k, v in enumerate(item)]
            for value, old in parts:
                line = located.lines.get(old)
                if line is not None:
                    lines[path + (len(out),)] = line
                out.append(value)
        for key in [k for k in located.lines if k[:len(path)] == path and len(k) > len(path)]:
            del located.lines[key]
        located.lines.update(lines)
        return out

    walk(located.data, ())


def validate_all(located: Located) -> tuple[ProblemFile | None, list[Issue]]:
    """The schema's issues, and a spec of what is left once the entries they name are set
    aside, so that compiling it reports the file's other mistakes in the same pass (a
    misspelt key and a bad expression elsewhere come together, not one per run). None when
    nothing valid is left (e.g. a required key is missing)."""
    import copy

    splice_lists(located)
    try:
        spec = ProblemFile.model_validate(located.data)
    except pydantic.ValidationError as e:
        errors = e.errors()
    else:
        return spec, booleans_read_as_values(located, spec)
    issues = _schema_issues(located, errors)
    data = copy.deepcopy(located.data)
    for _ in range(3):          # setting a value aside may expose a check of its parent
        for err in errors:
            _set_aside(data, _document_loc(err["loc"]))
        try:
            return ProblemFile.model_validate(data), issues
        except pydantic.ValidationError as e:
            errors = e.errors()
            if any(err["type"] == "missing" or not err["loc"] for err in errors):
                break
    return None, issues


def _set_aside(data, loc: tuple) -> None:
    parent = data
    for p in loc[:-1]:
        if isinstance(parent, dict) and p in parent:
            parent = parent[p]
        elif isinstance(parent, list) and isinstance(p, int) and p < len(parent):
            parent = parent[p]
        else:
            return
    if isinstance(parent, dict) and loc and loc[-1] in parent:
        value = parent[loc[-1]]
        if loc[-1] in DECLARED_LISTS and isinstance(value, (str, dict)):
            # `controls: u`: its error is reported; the names it meant stay declared for the
            # rest of the compile, so their uses are not reported as unknown names too
            names = _declared_names(value)
            if names:          # (a repaired value that still fails is deleted next round)
                parent[loc[-1]] = names
                return
        del parent[loc[-1]]


def _issue_from_pydantic(located: Located, err: dict, root: tuple | None = None) -> Issue:
    loc = _document_loc(err["loc"])
    msg = err["msg"].removeprefix("Value error, ")
    if err["type"] == "extra_forbidden":
        parent = located.data
        for p in loc[:-1]:
            parent = parent.get(p, {}) if isinstance(parent, dict) else {}
        msg = f"unknown key '{loc[-1]}'"
        if isinstance(parent, dict):
            if root is not None and loc[:len(root[0])] == root[0]:
                msg += did_you_mean(loc[-1], _known_keys(loc[len(root[0]):-1], root[1]))
            else:
                msg += did_you_mean(loc[-1], _known_keys(loc[:-1]))
    elif err["type"] == "missing":
        msg = f"missing required key '{loc[-1]}'"
    elif err["type"] == "list_type" and loc and loc[-1] in DECLARED_LISTS:
        msg = f"a list of names is expected, e.g. {loc[-1]}: [{_example_names(err.get('input'))}]"
    elif err["type"] == "string_type" and isinstance(err.get("input"), bool):
        # an unquoted true/false is a boolean (unseen24: a state `no`, when YAML 1.1's yes/no/on/off were too)
        msg += "; YAML reads an unquoted true or false as a boolean: quote the name ('true')"
    if loc and isinstance(loc[-1], str) and ("(" in loc[-1]) != (")" in loc[-1]):
        # YAML split `{a: f(x, y)}` at the comma: the tail became a key
        msg += "; inside { } a comma ends the value: quote an expression with commas, e.g. {a: 'f(x, y)'}"
    where = ".".join(str(p) for p in loc) or "top level"
    return located.issue(loc, f"{where}: {msg}", _source_line(located, loc))


def _declared_names(value) -> list[str]:
    """The names a scalar or mapping meant as a declaration list (`controls: u`, `states: {x: 1}`)."""
    if isinstance(value, str):
        return re.findall(r"[A-Za-z_]\w*", value)
    return [k for k in value if isinstance(k, str)] if isinstance(value, dict) else []


def _example_names(value) -> str:
    return ", ".join(_declared_names(value)) or "x, v"


def _document_loc(loc) -> tuple:
    """A pydantic error location as a path in the document: without the names pydantic gives
    the members of a union (``float``, ``function-after[_check(), ParameterSpec]``, ...)."""
    return tuple(p for p in loc if not (isinstance(p, str) and (p in _UNION_TAGS or p.startswith(_TAG_PREFIXES))))


_TAG_PREFIXES = ("function-", "list[", "dict[", "union[", "literal[", "tuple[")
_UNION_TAGS = {"float", "int", "str", "ParameterSpec", "list[float]", "list[int]",
               "function-after[_segments(), union[int,list[float]]]", "literal['free']"}


def _known_keys(loc: tuple, model: Any = None) -> list[str]:
    from . import schema

    model = schema.ProblemFile if model is None else model
    for p in loc:
        if isinstance(p, int):
            continue
        f = getattr(model, "model_fields", {}).get(p)
        if f is None:
            return []
        ann = f.annotation
        for cand in getattr(ann, "__args__", ()) + (ann,):
            if isinstance(cand, type) and issubclass(cand, pydantic.BaseModel):
                model = cand
                break
    return list(getattr(model, "model_fields", {}))


def _source_line(located: Located, loc: tuple) -> str:
    return located.source(located.line(loc))
