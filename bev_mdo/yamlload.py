"""Parse the YAML a user gives (configs, parameter sets, configs stored in bags) within limits.

Like ``yaml.safe_load``, but
- a key given twice in one mapping is an error (plain YAML keeps the last);
- the text is at most ``MAX_YAML_BYTES`` long, nested at most ``MAX_DEPTH`` collections deep,
  holds at most ``MAX_ALIASES`` aliases (``*name``) and at most ``MAX_NODES`` values once every
  alias is expanded (an "alias bomb" of a few lines expands to billions);
- a sequence holds at most ``MAX_SEQUENCE`` items, an integer fits in 64 bits;
- every mapping key is a string: ``5:``, ``yes:`` (YAML 1.1 reads yes/no/on/off as booleans), ``~:``,
  ``? [a, b]`` are refused naming where the key is and what YAML read it as (code that reads a key as
  a name failed on them with an AttributeError or TypeError, or printed them as ``True: unknown key``).
Every violation is a ValueError of one line (the CLI prints it and exits 2); docs/security.md
("Input limits") lists the limits.
"""
from __future__ import annotations

from typing import Any

import yaml

MAX_YAML_BYTES = 8 * 1024 * 1024
MAX_DEPTH = 64
MAX_ALIASES = 1000
MAX_NODES = 2_000_000
MAX_SEQUENCE = 1_000_000
MAX_INT_DIGITS = 40  # with separators ('1_000'); the value itself must fit in 64 bits


class YamlLimitError(ValueError):
    """The YAML text exceeds one of this module's limits, or has a key that is not a string."""


class _Loader(yaml.SafeLoader):
    """SafeLoader that counts depth and aliases while composing and refuses duplicate keys."""

    def __init__(self, stream):
        super().__init__(stream)
        self._depth = 0
        self._aliases = 0

    def compose_node(self, parent, index):
        if self.check_event(yaml.AliasEvent):
            self._aliases += 1
            if self._aliases > MAX_ALIASES:
                mark = self.peek_event().start_mark
                raise YamlLimitError(f"more than {MAX_ALIASES} YAML aliases (at line {mark.line + 1})")
            return super().compose_node(parent, index)
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH:
                mark = self.peek_event().start_mark
                raise YamlLimitError(f"YAML nested deeper than {MAX_DEPTH} levels (at line {mark.line + 1})")
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)  # a string: _check_keys
            if key in seen:
                raise yaml.constructor.ConstructorError(None, None, f"duplicate key {key!r}", key_node.start_mark)
            seen.add(key)
        return super().construct_mapping(node, deep)


def _construct_int(loader, node):
    if len(node.value) > MAX_INT_DIGITS:
        raise YamlLimitError(f"a number of {len(node.value)} digits at line {node.start_mark.line + 1}; "
                             f"integers have at most {MAX_INT_DIGITS}")
    value = yaml.SafeLoader.construct_yaml_int(loader, node)
    if abs(value) >= 2 ** 63:
        raise YamlLimitError(f"the integer {node.value[:20]}... at line {node.start_mark.line + 1} is out of range "
                             "(at most 2**63 - 1 in magnitude)")
    return value


_Loader.add_constructor("tag:yaml.org,2002:int", _construct_int)


def _expanded_size(root) -> int:
    """Values in the document with every alias expanded (shared nodes counted once per use), without
    expanding: a node's size is computed once and reused. YamlLimitError past MAX_NODES."""
    sizes: dict[int, int] = {}
    open_: set[int] = set()  # nodes whose children are being sized: meeting one again is a cycle
    stack = [(root, False)]
    while stack:
        node, done = stack.pop()
        if id(node) in sizes:
            continue
        if not done and id(node) in open_:
            raise YamlLimitError(f"a recursive YAML alias (at line {node.start_mark.line + 1})")
        if isinstance(node, yaml.SequenceNode):
            children = list(node.value)
            if len(children) > MAX_SEQUENCE:
                raise YamlLimitError(f"a YAML list of {len(children)} items (at line {node.start_mark.line + 1}); "
                                     f"at most {MAX_SEQUENCE}")
        elif isinstance(node, yaml.MappingNode):
            children = [n for pair in node.value for n in pair]
        else:
            sizes[id(node)] = 1
            continue
        if not done:
            open_.add(id(node))
            stack.append((node, True))
            stack.extend((c, False) for c in children if id(c) not in sizes)
            continue
        total = 1 + sum(sizes.get(id(c), 1) for c in children)
        if total > MAX_NODES:
            raise YamlLimitError(f"the YAML expands to more than {MAX_NODES} values once its aliases are "
                                 f"expanded (at line {node.start_mark.line + 1}; an alias bomb?)")
        sizes[id(node)] = total
        open_.discard(id(node))
    return sizes.get(id(root), 0)


_READ_AS = {"int": "an integer", "float": "a number", "bool": "a boolean", "null": "null",
            "timestamp": "a date", "binary": "binary data"}


def _check_keys(root) -> None:
    """YamlLimitError naming the first key (in document order) that is not a string: where it is
    (``vehicle``, ``disciplines[2].options``), its text, line and what YAML read it as."""
    stack, seen = [(root, "")], set()
    while stack:
        node, where = stack.pop()
        if id(node) in seen:  # a node shared by aliases is checked once
            continue
        seen.add(id(node))
        if isinstance(node, yaml.SequenceNode):
            stack.extend(reversed([(c, f"{where}[{i}]") for i, c in enumerate(node.value)]))
        elif isinstance(node, yaml.MappingNode):
            for i, (key, value) in enumerate(node.value):
                if isinstance(key, yaml.ScalarNode) and key.tag == "tag:yaml.org,2002:str":
                    continue
                text = " ".join(key.start_mark.buffer[key.start_mark.index:key.end_mark.index].split())
                text = text if len(text) <= 40 else text[:37] + "..."
                at = f"{where}: " if where else ""
                line = key.start_mark.line + 1
                if key.tag == "tag:yaml.org,2002:merge":
                    raise YamlLimitError(f"{at}merge key << at line {line}: not supported, write the keys out")
                if not isinstance(key, yaml.ScalarNode):
                    kind = "a list" if isinstance(key, yaml.SequenceNode) else "a mapping"
                    raise YamlLimitError(f"{at}key {text} at line {line} is {kind}; a key must be a name")
                before = node.value[i - 1][1] if i else None  # {initial: 7,981}: 7 then a key 981 with no value
                if (key.tag == "tag:yaml.org,2002:int" and value.tag == "tag:yaml.org,2002:null" and not value.value
                        and isinstance(before, yaml.ScalarNode) and before.tag == "tag:yaml.org,2002:int"):
                    from bev_mdo.models.common import comma_hint

                    raise YamlLimitError(f"{at}{before.value},{key.value} at line {line}: a comma separates entries"
                                         + comma_hint(f"{before.value},{key.value}"))
                kind = _READ_AS.get(key.tag.rsplit(":", 1)[-1], f"tag {key.tag}")
                if kind == "a boolean" and key.value.lower() not in ("true", "false"):
                    kind += " (YAML 1.1 reads yes/no/on/off so)"
                raise YamlLimitError(f"{at}key {text} at line {line} is read as {kind}, not a name: "
                                     f"quote it ('{key.value}')")
            stack.extend(reversed([(v, f"{where}.{k.value}" if where else k.value) for k, v in node.value]))


def load_yaml(text: str) -> Any:
    """Parse one YAML document within the limits above (ValueError of one line otherwise; yaml.YAMLError
    for text that is not YAML)."""
    if len(text) > MAX_YAML_BYTES:
        raise YamlLimitError(f"YAML text of {len(text)} characters; at most {MAX_YAML_BYTES}")
    loader = _Loader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        _expanded_size(node)
        _check_keys(node)
        return loader.construct_document(node)
    finally:
        loader.dispose()


def read_yaml_file(path) -> Any:
    """``load_yaml`` of a file, with one-line ValueErrors naming the file for a missing, binary,
    oversized or malformed file."""
    from pathlib import Path

    p = Path(path)
    try:
        size = p.stat().st_size
        if size > MAX_YAML_BYTES:
            raise YamlLimitError(f"{p}: {size} bytes; a YAML file may hold at most {MAX_YAML_BYTES}")
        data = p.read_bytes()
    except OSError as exc:
        raise ValueError(f"{p}: cannot read ({exc.strerror})") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{p}: not a YAML text file (byte 0x{data[exc.start]:02x} at offset {exc.start} is "
                         "not UTF-8)") from None
    if "\x00" in text:
        raise ValueError(f"{p}: not a YAML text file (it holds NUL bytes)")
    try:
        return load_yaml(text)
    except YamlLimitError as exc:
        raise ValueError(f"{p}: {exc}") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        at = f" at line {mark.line + 1}" if mark else ""
        raise ValueError(f"{p}: not valid YAML{at}: {getattr(exc, 'problem', None) or exc}") from None
