"""A small TOML writer for scenes given as dicts.

Keys keep the dict's order, because pidm makes grid axes in the order their
keys appear in the file. Top-level tables become ``[table]`` sections (a table
of tables becomes ``[table.sub]`` sections), lists of tables at the top level
``[[table]]`` sections, and every table deeper down an inline table. A key with
dots (``"axis.x.voltage"``) is a dotted key, so it means the same as the nested
dicts. Floats are written with ``repr`` and read back bit for bit; numpy scalars
and arrays are taken as their Python values.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator, Mapping
from typing import Any

_BARE = re.compile(r"^[A-Za-z0-9_-]+$")


def dumps(scene: Mapping[str, Any]) -> str:
    """The TOML text of a scene dict shaped like the TOML file."""
    if not isinstance(scene, Mapping):
        raise TypeError(f"a scene dict must be a mapping, not {type(scene).__name__}")
    lines: list[str] = []
    # Keys of the root table come before the first section.
    for key, value in scene.items():
        if not _is_table(value) and not _is_table_list(value):
            lines.append(f"{_key(key)} = {_value(value, key)}")
    for key, value in scene.items():
        if _is_table(value):
            lines.extend(_section([key], value))
        elif _is_table_list(value):
            for entry in value:
                lines.append("")
                lines.append(f"[[{_key(key)}]]")
                lines.extend(_body(entry, key))
    return "\n".join(lines).lstrip("\n") + "\n"


def _section(path: list[str], table: Mapping[str, Any]) -> Iterator[str]:
    header = ".".join(_key(p) for p in path)
    if table and all(_is_table(v) for v in table.values()):
        for key, value in table.items():
            yield from _section(path + [key], value)
        return
    yield ""
    yield f"[{header}]"
    yield from _body(table, ".".join(path))


def _body(table: Mapping[str, Any], where: str) -> Iterator[str]:
    for key, value in table.items():
        yield f"{_key(key)} = {_value(value, f'{where}.{key}')}"


def _is_table(value: Any) -> bool:
    return isinstance(value, Mapping)


def _is_table_list(value: Any) -> bool:
    return (
        isinstance(value, (list, tuple))
        and len(value) > 0
        and all(isinstance(v, Mapping) for v in value)
    )


def _key(key: Any) -> str:
    if not isinstance(key, str):
        raise TypeError(f"scene keys must be strings, not {key!r}")
    parts = key.split(".")
    if all(_BARE.match(p) for p in parts):
        return key
    return _string(key)


def _value(value: Any, where: str) -> str:
    value = _python(value)
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return _string(value)
    if isinstance(value, Mapping):
        fields = ", ".join(f"{_key(k)} = {_value(v, f'{where}.{k}')}" for k, v in value.items())
        return "{ " + fields + " }" if fields else "{}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_value(v, where) for v in value) + "]"
    raise TypeError(f"scene key {where}: cannot write {value!r} ({type(value).__name__}) as TOML")


def _python(value: Any) -> Any:
    """numpy scalars and arrays as Python values; anything else as it is."""
    tolist = getattr(value, "tolist", None)
    if tolist is not None and type(value).__module__ == "numpy":
        return tolist()
    return value


def _string(text: str) -> str:
    out = ['"']
    for ch in text:
        code = ord(ch)
        if ch == '"':
            out.append('\\"')
        elif ch == "\\":
            out.append("\\\\")
        elif ch == "\n":
            out.append("\\n")
        elif ch == "\t":
            out.append("\\t")
        elif ch == "\r":
            out.append("\\r")
        elif code < 0x20 or code == 0x7F:
            out.append(f"\\u{code:04X}")
        else:
            out.append(ch)
    out.append('"')
    return "".join(out)
