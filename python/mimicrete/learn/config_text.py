"""A config file's text and its YAML, read within bounds; the ranges a numeric field may take
(:class:`Range`); and the error every config check raises.

A config is a small file: at most :data:`MAX_CONFIG_BYTES`, UTF-8, YAML of at most
:data:`MAX_YAML_NODES` values (aliases counted at the size they expand to) nested at most
:data:`MAX_YAML_DEPTH` deep, strings of at most :data:`MAX_STRING` characters. Every message
names the file (and the line and column where YAML says) and shows values cut short
(:func:`short_repr`), so a hostile file never makes a huge error line. ``config.py`` builds and
checks the dataclasses from what this reads.
"""

from __future__ import annotations

import math
import reprlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from mimicrete._native import MimicreteError


class ConfigError(MimicreteError, ValueError):
    """A config file that does not match the schema."""


@dataclass(frozen=True)
class Range:
    """An allowed interval of a numeric field; ``None`` bounds are open-ended."""

    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False

    def __contains__(self, x: float) -> bool:
        if not math.isfinite(x):
            return False
        if self.lo is not None and (x < self.lo or (self.lo_open and x == self.lo)):
            return False
        return not (self.hi is not None and (x > self.hi or (self.hi_open and x == self.hi)))

    def __str__(self) -> str:
        if self.hi is None:
            return f"{'>' if self.lo_open else '>='} {_num(self.lo)}"
        lo = "(" if self.lo_open else "["
        hi = ")" if self.hi_open else "]"
        return f"{lo}{_num(self.lo)}, {_num(self.hi)}{hi}"


def _num(x: float | None) -> str:
    return f"{x:g}" if isinstance(x, float) else str(x)



_REPR = reprlib.Repr()
_REPR.maxlevel, _REPR.maxdict, _REPR.maxlist, _REPR.maxtuple = 2, 4, 4, 4
_REPR.maxstring, _REPR.maxlong, _REPR.maxother = 60, 40, 60


def short_repr(value: Any) -> str:
    """``repr(value)`` cut to a few dozen characters (a value can be an alias bomb)."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 128:
        return f"an integer of about {int(value.bit_length() * 0.30103)} digits"
    return _REPR.repr(value)


def _yaml_where(e: yaml.YAMLError) -> str:
    mark = getattr(e, "problem_mark", None)
    return f":{mark.line + 1}:{mark.column + 1}" if mark is not None else ""


def _yaml_problem(e: yaml.YAMLError) -> str:
    return str(getattr(e, "problem", None) or e).splitlines()[0]


#: what a config file may be: a few KiB in practice
MAX_CONFIG_BYTES = 1 << 20
#: YAML nodes once aliases are expanded (a config has a few hundred; an alias bomb billions)
MAX_YAML_NODES = 100_000
#: nesting of mappings and sequences (a config has 5 levels)
MAX_YAML_DEPTH = 32
#: characters of a string field (paths, names)
MAX_STRING = 4096


def parse_yaml(text: str, where: str) -> Any:
    """``yaml.safe_load(text)`` within bounds: at most :data:`MAX_YAML_NODES` nodes with every
    alias counted at the size it expands to, at most :data:`MAX_YAML_DEPTH` levels deep. The
    event stream is checked first (PyYAML's parser is not recursive, its composer is), so an
    alias bomb or a deeply nested file is refused before anything is built. Errors are a
    :class:`ConfigError` starting with ``where`` (and the line:column)."""
    stack: list[list[Any]] = []  # per open collection: [anchor, expanded size, start mark]
    anchors: dict[str, int] = {}

    def add(n: int, mark: Any) -> None:
        if stack:
            stack[-1][1] += n
            if stack[-1][1] > MAX_YAML_NODES:
                raise ConfigError(
                    f"{where}{_mark(mark)}: more than {MAX_YAML_NODES} values once aliases are "
                    "expanded (an alias bomb?)"
                )

    try:
        for ev in yaml.parse(text, Loader=yaml.SafeLoader):
            if isinstance(ev, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
                if len(stack) >= MAX_YAML_DEPTH:
                    raise ConfigError(
                        f"{where}{_mark(ev.start_mark)}: nested more than {MAX_YAML_DEPTH} "
                        "levels deep"
                    )
                stack.append([ev.anchor, 1, ev.start_mark])
            elif isinstance(ev, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
                anchor, size, _ = stack.pop()
                if anchor is not None:
                    anchors[anchor] = size
                add(size, ev.start_mark)
            elif isinstance(ev, yaml.ScalarEvent):
                if ev.anchor is not None:
                    anchors[ev.anchor] = 1
                add(1, ev.start_mark)
            elif isinstance(ev, yaml.AliasEvent):
                add(anchors.get(ev.anchor, 1), ev.start_mark)
        return yaml.load(text, Loader=yaml.SafeLoader)  # noqa: S506 (the safe loader)
    except yaml.YAMLError as e:
        raise ConfigError(f"{where}{_yaml_where(e)}: not valid YAML ({_yaml_problem(e)})") from None
    except (ValueError, RecursionError, OverflowError) as e:  # an int of > 4300 digits, ...
        if isinstance(e, ConfigError):
            raise
        why = str(e).splitlines()[0][:160] if str(e) else type(e).__name__
        raise ConfigError(f"{where}: not a usable YAML value ({why})") from None


def _mark(mark: Any) -> str:
    return f":{mark.line + 1}:{mark.column + 1}" if mark is not None else ""


def read_config_text(path: str | Path) -> str:
    """The text of a config file: at most :data:`MAX_CONFIG_BYTES`, UTF-8 (errors name the
    file and, for a bad byte, where it is)."""
    with open(path, "rb") as f:
        raw = f.read(MAX_CONFIG_BYTES + 1)
    if len(raw) > MAX_CONFIG_BYTES:
        raise ConfigError(
            f"{path}: larger than {MAX_CONFIG_BYTES // 1024} KiB; a config is a small YAML file"
        )
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as e:
        line = raw.count(b"\n", 0, e.start) + 1
        raise ConfigError(
            f"{path}:{line}: not UTF-8 text (byte {raw[e.start]:#04x} at offset {e.start})"
        ) from None
