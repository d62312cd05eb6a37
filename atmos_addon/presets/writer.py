# SPDX-License-Identifier: GPL-3.0-or-later
"""A small TOML writer for the flat preset schema (Python reads TOML with ``tomllib`` but cannot write it).

It writes top-level scalars first, then one ``[table]`` per nested mapping, holding strings,
integers, floats and arrays of those. Floats are written with ``repr`` (the shortest string that
reads back to the same double), so ``tomllib.loads(dumps(doc)) == doc`` exactly. Anything the
schema does not use (nested tables, dates, non-finite floats) is refused with ``TypeError``.
"""

from __future__ import annotations

import math
from typing import Any, Mapping

_ESCAPES = {'"': '\\"', "\\": "\\\\", "\b": "\\b", "\t": "\\t", "\n": "\\n", "\f": "\\f", "\r": "\\r"}


def _string(text: str) -> str:
    out = []
    for char in text:
        if char in _ESCAPES:
            out.append(_ESCAPES[char])
        elif ord(char) < 0x20 or ord(char) == 0x7F:
            out.append(f"\\u{ord(char):04x}")
        else:
            out.append(char)
    return '"' + "".join(out) + '"'


def _scalar(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise TypeError(f"non-finite float {value!r} has no place in a preset")
        return repr(float(value))  # always holds '.' or 'e': a TOML float that reads back bit-exact
    if isinstance(value, str):
        return _string(value)
    raise TypeError(f"cannot write {type(value).__name__} {value!r} to a preset file")


#: Arrays longer than this on one line are written one item a line (citation lists).
_LINE_LIMIT = 100


def _value(value: Any) -> str:
    if isinstance(value, (list, tuple)):
        items = [_scalar(item) for item in value]
        one_line = "[" + ", ".join(items) + "]"
        if len(one_line) <= _LINE_LIMIT:
            return one_line
        return "[\n" + "".join(f"    {item},\n" for item in items) + "]"
    return _scalar(value)


def _key(key: str) -> str:
    if key and all(char.isascii() and (char.isalnum() or char in "_-") for char in key):
        return key
    return _string(key)


def dumps(doc: Mapping[str, Any], header: str = "") -> str:
    """The TOML text of ``doc`` (top-level scalars, then one table per nested mapping)."""
    lines = [f"# {line}".rstrip() for line in header.splitlines()]
    for key, value in doc.items():
        if not isinstance(value, Mapping):
            lines.append(f"{_key(key)} = {_value(value)}")
    for key, value in doc.items():
        if isinstance(value, Mapping):
            lines.append("")
            lines.append(f"[{_key(key)}]")
            for inner_key, inner in value.items():
                if isinstance(inner, Mapping):
                    raise TypeError(f"nested table [{key}.{inner_key}] is not part of the preset schema")
                lines.append(f"{_key(inner_key)} = {_value(inner)}")
    return "\n".join(lines) + "\n"
