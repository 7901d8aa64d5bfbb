"""Read a YAML problem file keeping the line of every value, for error messages."""
from __future__ import annotations

import re

import stat
from pathlib import Path
from typing import Any

import yaml

from .errors import Issue, SpecError

Path_ = tuple  # a location in the document: keys and list indices


# Input limits (docs/problem-language.md, "Input limits"), checked before any expensive
# work: each bounds what a hostile or mistaken file can cost (an alias bomb of 513 bytes
# once expanded to 1.3 GB, deep nesting ended in RecursionError)
MAX_FILE_BYTES = 1_000_000      # problem files are a few kB
MAX_DEPTH = 40                  # nested mappings/lists
MAX_VALUES = 10_000             # values in the document after aliases (*name) are expanded
MAX_DIGITS = 300                # digits of an integer (floats end at about 1e308)
# libyaml's parser where PyYAML has it: 8x faster than the pure-Python one on a large file
_YAML_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
# a plain number with an exponent whose sign YAML 1.1 requires and the writer left out
_EXPONENT_NUMBER = re.compile(r"[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)[eE][-+]?[0-9]+")
_TAGS = {f"tag:yaml.org,2002:{t}" for t in ("str", "int", "float", "bool", "null", "seq", "map")} | {"!"}


class Located:
    """The parsed document plus a map from document paths to line numbers."""

    def __init__(self, file: str, data: Any, lines: dict[Path_, int], text: str | None = None):
        self.file, self.data, self.lines = file, data, lines
        self._text, self._split = text, None

    def line(self, path: Path_) -> int | None:
        """Line of ``path``, or of its nearest ancestor that has one."""
        path = tuple(path)
        while path:
            if path in self.lines:
                return self.lines[path]
            path = path[:-1]
        return self.lines.get((), 1)

    def source(self, line: int | None) -> str:
        """The text of ``line`` (stripped); the file is read once, not once per error."""
        if self._split is None:
            text = self._text
            if text is None:
                try:
                    text = Path(self.file).read_text()
                except (OSError, UnicodeDecodeError):
                    text = ""
            self._split = text.splitlines()
        return self._split[line - 1].strip() if line and 0 < line <= len(self._split) else ""

    def issue(self, path: Path_, message: str, text: str = "") -> Issue:
        return Issue(self.file, self.line(path), message, text)


def load_yaml(path: str | Path) -> Located:
    """Parse ``path``; YAML syntax errors, duplicate keys and non-mapping tops are SpecErrors."""
    path = Path(path)
    name = str(path)
    try:
        if not stat.S_ISREG(path.stat().st_mode):
            # a device reads for ever (/dev/zero: a MemoryError), a pipe is read once and then
            # hangs the second reading (unseen24): problem files are files
            raise SpecError([Issue(name, None, "not a regular file (a folder, a device or a pipe): give the "
                                               "problem file itself (save piped text to a file first)")])
        if path.stat().st_size > MAX_FILE_BYTES:
            raise SpecError([Issue(name, None, f"file larger than {MAX_FILE_BYTES:,} bytes "
                                   f"({path.stat().st_size:,}); a problem file is a few kB")])
        text = path.read_text()
    except FileNotFoundError:
        raise SpecError([Issue(name, None, "file not found")]) from None
    except (OSError, UnicodeDecodeError) as e:
        raise SpecError([Issue(name, None, f"cannot read file ({e})")]) from None
    return load_yaml_text(text, name)


def load_yaml_text(text: str, name: str = "<string>") -> Located:
    if len(text) > MAX_FILE_BYTES:
        raise SpecError([Issue(name, None, f"text longer than {MAX_FILE_BYTES:,} characters")])
    lines_of_text = text.splitlines()
    try:
        _scan(text, name)
        node = yaml.compose(text, Loader=_YAML_LOADER)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        line = mark.line + 1 if mark else None
        if line is None and isinstance(getattr(e, "position", None), int):   # a ReaderError
            line = text.count("\n", 0, e.position) + 1
        msg = getattr(e, "problem", None) or str(e)
        opened, context = getattr(e, "context_mark", None), getattr(e, "context", None) or ""
        if mark and opened and "flow" in context and opened.line < mark.line:
            # `time: {t0: 0, tf: 1` on line 7: PyYAML stops at the next line's token; the fix
            # belongs where the bracket was opened
            bracket = "{" if "mapping" in context else "["
            msg = f"the '{bracket}' opened here is not closed ({msg} at line {mark.line + 1})"
            line = opened.line + 1
        src = lines_of_text[line - 1].strip() if line and line <= len(lines_of_text) else ""
        if "flow sequence" in context and re.search(r"(==|<=|>=|<|>)\s*\[", src):
            # unseen10 F6: `constraints: [r(t0) == [1, 0.5, 0.3], ...]`: valid YAML can not hold it
            msg += ("; a vector [...] inside a [...] list: YAML takes its commas for the list's, so "
                    "write the relations one per line (- r(t0) == [1, 0.5, 0.3]) or quote each")
        raise SpecError([Issue(name, line, f"YAML syntax error: {msg}", src)]) from None
    if node is None:
        raise SpecError([Issue(name, 1, "the file is empty")])
    lines: dict[Path_, int] = {}
    issues: list[Issue] = []
    data = _convert(node, (), lines, issues, name, yaml.constructor.SafeConstructor())
    if issues:
        raise SpecError(issues)
    if not isinstance(data, dict):
        raise SpecError([Issue(name, 1, "a problem file must be a mapping (name:, model:, problem:, ...)")])
    return Located(name, data, lines, text)


def _scan(text: str, name: str) -> None:
    """Nesting depth, tags and the size after alias expansion, from the event stream (which
    PyYAML makes without recursion and without building anything), before composing."""
    import yaml.events as ev

    sizes: dict[str, int] = {}          # anchor -> values below it, aliases expanded
    stack: list[list] = []              # [values so far, anchor] of each open collection
    total = 0

    def fail(event, message: str) -> None:
        line = event.start_mark.line + 1
        src = text.splitlines()[line - 1].strip() if line <= len(text.splitlines()) else ""
        raise SpecError([Issue(name, line, message, src)])

    for event in yaml.parse(text, Loader=_YAML_LOADER):
        if isinstance(event, (ev.ScalarEvent, ev.CollectionStartEvent)) and event.tag is not None \
                and event.tag not in _TAGS:
            fail(event, f"YAML tag '{event.tag}' is not allowed (a problem file holds plain mappings, "
                 "lists, strings and numbers)")
        if isinstance(event, ev.CollectionStartEvent):
            stack.append([1, event.anchor])
            if len(stack) > MAX_DEPTH:
                fail(event, f"nested deeper than {MAX_DEPTH} levels")
            continue
        if isinstance(event, ev.CollectionEndEvent):
            n, anchor = stack.pop()
            if anchor:
                sizes[anchor] = n
        elif isinstance(event, ev.ScalarEvent):
            n = 1
            if event.anchor:
                sizes[event.anchor] = 1
        elif isinstance(event, ev.AliasEvent):
            if any(anchor == event.anchor for _, anchor in stack):
                fail(event, f"*{event.anchor} refers to a mapping or list that contains it")
            n = sizes.get(event.anchor, 1)
        else:
            continue
        if stack:
            stack[-1][0] += n
        if isinstance(event, ev.CollectionEndEvent):
            continue            # counted value by value as they came
        total += n
        if total > MAX_VALUES:
            fail(event, f"the file holds more than {MAX_VALUES:,} values once its aliases (*name) "
                 "are expanded")


def _convert(node: yaml.Node, path: Path_, lines: dict, issues: list, name: str, make) -> Any:
    lines[path] = node.start_mark.line + 1
    if isinstance(node, yaml.MappingNode):
        out: dict[Any, Any] = {}
        merged: dict[Any, Any] = {}
        for key_node, value_node in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":
                _merge(value_node, issues, name, merged, make)
                continue
            key = _scalar(key_node, issues, name, make) if isinstance(key_node, yaml.ScalarNode) else None
            if not isinstance(key, (str, int, float)) or isinstance(key, bool):
                # YAML reads `on`, `yes`, `no` as booleans; a key must stay a name
                key = key_node.value if isinstance(key_node, yaml.ScalarNode) else None
                if key is None:
                    issues.append(Issue(name, key_node.start_mark.line + 1, "a key must be a plain name"))
                    continue
            key = str(key)
            if key in out:
                issues.append(Issue(name, key_node.start_mark.line + 1, f"duplicate key '{key}'"))
                continue
            out[key] = _convert(value_node, path + (key,), lines, issues, name, make)
            lines[path + (key,)] = key_node.start_mark.line + 1  # errors point at the key's line
        for key, (value, sub_lines) in merged.items():   # keys written in the mapping win over merged ones
            if key not in out:
                out[key] = value
                lines.update({path + sub: line for sub, line in sub_lines.items()})
        return out
    if isinstance(node, yaml.SequenceNode):
        return [_convert(v, path + (i,), lines, issues, name, make) for i, v in enumerate(node.value)]
    if node.tag == "tag:yaml.org,2002:str" and not node.style and _EXPONENT_NUMBER.fullmatch(node.value):
        # a value, unquoted: YAML 1.1 (PyYAML) reads 6.678e6 and 1e-10 as text, YAML 1.2 and
        # every reader of the file as the numbers they are (a guess [6.678e6, 1.0e7] was refused
        # as not numbers, unseen20); keys stay names
        return float(node.value)
    return _scalar(node, issues, name, make)


def _scalar(node: yaml.ScalarNode, issues: list, name: str, make) -> Any:
    """One scalar; a number Python cannot or should not hold is an issue at its line."""
    line = node.start_mark.line + 1
    if node.tag == "tag:yaml.org,2002:int" and sum(c.isdigit() for c in node.value) > MAX_DIGITS:
        issues.append(Issue(name, line, f"an integer of more than {MAX_DIGITS} digits"))
        return None
    try:
        value = make.construct_object(node)
    except (yaml.YAMLError, ValueError) as e:
        issues.append(Issue(name, line, f"cannot read the value '{node.value[:40]}' ({e})"))
        return None
    if isinstance(value, bool) and not node.style and node.value.lower() not in ("true", "false"):
        # YAML 1.2, as every current reader: only true and false are booleans. YAML 1.1 (PyYAML)
        # also reads yes, no, on, off: `x: on` (a state named 'on') was solved as x' = 1, and
        # `k: off` as k = 0, optimal and verified (unseen40 F1)
        return node.value
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) > 10 ** MAX_DIGITS:
        issues.append(Issue(name, line, f"an integer beyond 1e{MAX_DIGITS} ('{node.value[:40]}')"))
        return None     # e.g. 0xfff...: few digits, far beyond any float
    return value


def _merge(value_node: yaml.Node, issues: list, name: str, merged: dict, make) -> None:
    """``<<: *anchor`` or ``<<: [*a, *b]``: the keys of the anchored mappings into ``merged``
    (key -> (value, lines below it)); the first mapping named wins, as YAML specifies, and
    error lines stay where the anchored text was written."""
    sources = value_node.value if isinstance(value_node, yaml.SequenceNode) else [value_node]
    for src in sources:
        if not isinstance(src, yaml.MappingNode):
            issues.append(Issue(name, src.start_mark.line + 1,
                                "a merge key (<<) takes a mapping or a list of mappings, e.g. <<: *defaults"))
            continue
        sub_lines: dict = {}
        data = _convert(src, (), sub_lines, issues, name, make)
        for key, value in data.items():
            if key not in merged:
                merged[key] = (value, {sub: line for sub, line in sub_lines.items() if sub and sub[0] == key})
