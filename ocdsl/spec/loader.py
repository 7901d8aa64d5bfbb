"""Read a YAML problem file keeping the line of every value, for error messages."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from .errors import Issue, SpecError

Path_ = tuple  # a location in the document: keys and list indices


class Located:
    """The parsed document plus a map from document paths to line numbers."""

    def __init__(self, file: str, data: Any, lines: dict[Path_, int]):
        self.file, self.data, self.lines = file, data, lines

    def line(self, path: Path_) -> int | None:
        """Line of ``path``, or of its nearest ancestor that has one."""
        path = tuple(path)
        while path:
            if path in self.lines:
                return self.lines[path]
            path = path[:-1]
        return self.lines.get((), 1)

    def issue(self, path: Path_, message: str, text: str = "") -> Issue:
        return Issue(self.file, self.line(path), message, text)


def load_yaml(path: str | Path) -> Located:
    """Parse ``path``; YAML syntax errors, duplicate keys and non-mapping tops are SpecErrors."""
    path = Path(path)
    name = str(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise SpecError([Issue(name, None, "file not found")]) from None
    except (OSError, UnicodeDecodeError) as e:
        raise SpecError([Issue(name, None, f"cannot read file ({e})")]) from None
    return load_yaml_text(text, name)


def load_yaml_text(text: str, name: str = "<string>") -> Located:
    try:
        node = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        line = mark.line + 1 if mark else None
        msg = getattr(e, "problem", None) or str(e)
        src = text.splitlines()[line - 1].strip() if line and line <= len(text.splitlines()) else ""
        raise SpecError([Issue(name, line, f"YAML syntax error: {msg}", src)]) from None
    if node is None:
        raise SpecError([Issue(name, 1, "the file is empty")])
    lines: dict[Path_, int] = {}
    issues: list[Issue] = []
    data = _convert(node, (), lines, issues, name)
    if issues:
        raise SpecError(issues)
    if not isinstance(data, dict):
        raise SpecError([Issue(name, 1, "a problem file must be a mapping (name:, model:, problem:, ...)")])
    return Located(name, data, lines)


def _convert(node: yaml.Node, path: Path_, lines: dict, issues: list, name: str) -> Any:
    lines[path] = node.start_mark.line + 1
    if isinstance(node, yaml.MappingNode):
        out: dict[Any, Any] = {}
        merged: dict[Any, Any] = {}
        for key_node, value_node in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":
                _merge(value_node, issues, name, merged)
                continue
            key = yaml.SafeLoader(" ").construct_object(key_node) if isinstance(key_node, yaml.ScalarNode) else None
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
            out[key] = _convert(value_node, path + (key,), lines, issues, name)
            lines[path + (key,)] = key_node.start_mark.line + 1  # errors point at the key's line
        for key, (value, sub_lines) in merged.items():   # keys written in the mapping win over merged ones
            if key not in out:
                out[key] = value
                lines.update({path + sub: line for sub, line in sub_lines.items()})
        return out
    if isinstance(node, yaml.SequenceNode):
        return [_convert(v, path + (i,), lines, issues, name) for i, v in enumerate(node.value)]
    return yaml.SafeLoader(" ").construct_object(node)


def _merge(value_node: yaml.Node, issues: list, name: str, merged: dict) -> None:
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
        data = _convert(src, (), sub_lines, issues, name)
        for key, value in data.items():
            if key not in merged:
                merged[key] = (value, {sub: line for sub, line in sub_lines.items() if sub and sub[0] == key})
