# SPDX-License-Identifier: GPL-3.0-or-later
"""The preset file format (schema version 1): one table of fields drives validation, messages and docs.

A preset is a TOML file::

    schema_version = 1

    [preset]
    name = "clear"
    description = "..."
    sources = ["Author (year). Title.", ...]

    [atmosphere]                      # every key optional: a missing key takes the clear-Earth default
    rayleigh = "earth_standard"       # or rayleigh_scattering_per_m = [r, g, b]
    mie_scattering_per_m = [r, g, b]
    ...

    [sun]                             # optional: an absent key leaves the user's sun alone
    elevation_deg = 2.0

Keys carry their unit in their name. Vectors are three values for the R, G, B channels at the
atmosphere's ``wavelengths_nm``. Everything here is plain data: TOML is parsed with ``tomllib`` and
nothing in a file is ever executed. This module knows nothing of the physics core; it turns a parsed
document into plain Python values (:class:`Validated`) or raises :class:`PresetError`.
"""

from __future__ import annotations

import difflib
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

#: The only schema version this code reads and writes.
SCHEMA_VERSION = 1

#: Files larger than this are refused before they are parsed (a preset is a few hundred bytes).
MAX_FILE_BYTES = 64 * 1024

#: Names the ``rayleigh`` key may take instead of explicit coefficients.
RAYLEIGH_CHOICES = ("earth_standard",)

_NAME_RE = re.compile(r"^[A-Za-z0-9](?:[A-Za-z0-9 _-]{0,62}[A-Za-z0-9_-])?$")
_RESERVED_NAMES = frozenset(
    ["con", "prn", "aux", "nul"] + [f"com{i}" for i in range(1, 10)] + [f"lpt{i}" for i in range(1, 10)]
)
NAME_RULE = (
    "must be 1 to 64 letters, digits, spaces, '-' or '_', starting with a letter or digit and not ending "
    "with a space (no path characters such as '/', '\\', ':' or '.')"
)


class PresetError(ValueError):
    """A preset file or name that Atmos refuses; the message says which file, which field and which rule.

    ``path``, ``field`` and ``rule`` hold the parts separately for a user interface.
    """

    def __init__(self, path: str | Path | None, field_name: str | None, rule: str):
        self.path = None if path is None else str(path)
        self.field = field_name
        self.rule = rule
        where = ": ".join(part for part in (self.path, field_name) if part)
        super().__init__(f"{where}: {rule}" if where else rule)


@dataclass(frozen=True)
class Field:
    """One key of the preset file: where it lives, what it holds, its unit and range, what it maps to."""

    table: str  # "" for the top level, else the TOML table name
    key: str
    kind: str  # "int", "float", "vec3", "float_or_vec3", "str", "str_list", "name", "choice"
    unit: str
    target: str  # Atmosphere field or Preset attribute the value lands in
    doc: str
    minimum: float | None = None
    maximum: float | None = None
    min_open: bool = False  # True: minimum itself is refused
    max_open: bool = False
    required: bool = False
    choices: tuple[str, ...] = ()
    excludes: str | None = None  # a key of the same table that must not be given together with this one

    @property
    def label(self) -> str:
        return f"[{self.table}] {self.key}" if self.table else self.key

    def range_text(self) -> str:
        """The allowed interval in words, e.g. 'between -1 and 1 (both excluded)'."""
        lo, hi = self.minimum, self.maximum
        if lo is None and hi is None:
            return "any finite number"
        if hi is None:
            return f"{'>' if self.min_open else '>='} {_num(lo)}"
        if lo is None:
            return f"{'<' if self.max_open else '<='} {_num(hi)}"
        left = "(" if self.min_open else "["
        right = ")" if self.max_open else "]"
        return f"in {left}{_num(lo)}, {_num(hi)}{right}"


def _num(value: float) -> str:
    return f"{value:g}".replace("e+0", "e").replace("e+", "e").replace("e-0", "e-")


_SCATTER_MAX = 1.0  # 1/m: extinction over 4 m of fog reaches e^-4; anything larger is a typo
_HEIGHT_MAX = 1.0e6  # m

#: The schema: every key a preset may hold. Messages, validation and :func:`markdown_table` read it.
FIELDS: tuple[Field, ...] = (
    Field("", "schema_version", "int", "", "", "Version of this file format; must be 1.", required=True),
    # [preset]
    Field("preset", "name", "name", "", "name", "Preset name, unique in the library; equals the file name "
          "(without .toml) for presets in a library folder. It " + NAME_RULE + ".", required=True),
    Field("preset", "description", "str", "", "description", "One or two sentences for the preset menu tooltip."),
    Field("preset", "sources", "str_list", "", "sources", "Citations for the numbers in the file."),
    # [atmosphere]
    Field("atmosphere", "wavelengths_nm", "vec3", "nm", "wavelengths_nm",
          "Wavelengths the R, G, B channels stand for.", 300.0, 1000.0),
    Field("atmosphere", "rayleigh", "choice", "", "rayleigh_scattering",
          "'earth_standard': the physics core's Rayleigh coefficients of sea-level air at wavelengths_nm.",
          choices=RAYLEIGH_CHOICES, excludes="rayleigh_scattering_per_m"),
    Field("atmosphere", "rayleigh_scattering_per_m", "vec3", "1/m", "rayleigh_scattering",
          "Molecular (Rayleigh) scattering coefficient at the surface.", 0.0, _SCATTER_MAX, excludes="rayleigh"),
    Field("atmosphere", "mie_scattering_per_m", "vec3", "1/m", "mie_scattering",
          "Aerosol (Mie) scattering coefficient at the surface.", 0.0, _SCATTER_MAX),
    Field("atmosphere", "mie_absorption_per_m", "vec3", "1/m", "mie_absorption",
          "Aerosol (Mie) absorption coefficient at the surface.", 0.0, _SCATTER_MAX),
    Field("atmosphere", "mie_g", "float_or_vec3", "", "mie_g",
          "Henyey-Greenstein anisotropy, positive = forward (Blender's convention); one value or R, G, B.",
          -1.0, 1.0, min_open=True, max_open=True),
    Field("atmosphere", "rayleigh_scale_height_m", "float", "m", "rayleigh_scale_height",
          "Height over which the molecular density falls by 1/e.", 0.0, _HEIGHT_MAX, min_open=True),
    Field("atmosphere", "mie_scale_height_m", "float", "m", "mie_scale_height",
          "Height over which the aerosol density falls by 1/e.", 0.0, _HEIGHT_MAX, min_open=True),
    Field("atmosphere", "planet_radius_m", "float", "m", "planet_radius",
          "Radius of the planet (sea level).", 1.0e3, 1.0e9),
    Field("atmosphere", "atmosphere_height_m", "float", "m", "atmosphere_height",
          "Thickness of the atmosphere shell above sea level.", 0.0, _HEIGHT_MAX * 10, min_open=True),
    Field("atmosphere", "sun_irradiance_top_w_m2", "vec3", "W/m^2", "sun_irradiance_top",
          "Sun irradiance at the top of the atmosphere, in Blender sun-strength units.", 0.0, 1.0e6,
          excludes="sun_irradiance_top_scale"),
    Field("atmosphere", "sun_irradiance_top_scale", "float", "", "sun_irradiance_top",
          "Top-of-atmosphere sun irradiance relative to Earth's default (Mars: 1 / 1.5237^2 = 0.4307).", 0.0, 1.0e3,
          excludes="sun_irradiance_top_w_m2"),
    Field("atmosphere", "ozone_column_du", "float", "DU", "ozone_column_du",
          "Total ozone column in Dobson units, in a layer 10-40 km up (Earth: about 300); absent: none.", 0.0, 1.0e4),
    # [sun]
    Field("sun", "elevation_deg", "float", "deg", "sun_elevation_deg",
          "Sun elevation above the horizon; absent leaves the user's sun alone.", -90.0, 90.0),
    Field("sun", "azimuth_deg", "float", "deg", "sun_azimuth_deg",
          "Sun azimuth in the add-on's sun convention; absent leaves the user's sun alone.", -360.0, 360.0),
)

TABLES: tuple[str, ...] = ("preset", "atmosphere", "sun")
_REQUIRED_TABLES = frozenset({"preset"})
_BY_TABLE: dict[str, dict[str, Field]] = {}
for _field in FIELDS:
    _BY_TABLE.setdefault(_field.table, {})[_field.key] = _field


def spec_for(table: str, key: str) -> Field:
    """The :class:`Field` for ``key`` in ``table`` ("" for the top level)."""
    return _BY_TABLE[table][key]


@dataclass(frozen=True)
class Validated:
    """A document that passed every rule, as plain Python values (no physics core involved).

    ``atmosphere`` maps :class:`Field` targets (Atmosphere field names, plus the pseudo-targets
    ``rayleigh_choice`` and ``sun_irradiance_top_scale``) to floats or 3-tuples of floats.
    """

    name: str
    description: str
    sources: tuple[str, ...]
    atmosphere: Mapping[str, Any] = field(default_factory=dict)
    sun_elevation_deg: float | None = None
    sun_azimuth_deg: float | None = None


def is_valid_name(name: object) -> bool:
    """True when ``name`` may name a preset (see :data:`NAME_RULE`)."""
    return isinstance(name, str) and bool(_NAME_RE.match(name)) and name.lower() not in _RESERVED_NAMES


def check_name(name: object, path: str | Path | None = None, field_name: str = "name") -> str:
    """Return ``name`` if it is a valid preset name, else raise :class:`PresetError` (no path characters)."""
    if not isinstance(name, str):
        raise PresetError(path, field_name, f"must be a string, got {_type_name(name)}")
    if not is_valid_name(name):
        raise PresetError(path, field_name, f"{name!r} is not a valid preset name: {NAME_RULE}")
    return name


def _type_name(value: object) -> str:
    return {bool: "a boolean", int: "an integer", float: "a number", str: "a string", list: "an array",
            dict: "a table"}.get(type(value), type(value).__name__)


def _suggest(key: str, known: list[str]) -> str:
    close = difflib.get_close_matches(key, known, n=1, cutoff=0.6)
    return f"; did you mean {close[0]!r}?" if close else f"; known keys: {', '.join(sorted(known))}"


def _elsewhere(key: str, table: str) -> str:
    if key in TABLES and table:
        return f"; [{key}] is a table: start it on its own line after the keys of [{table}]"
    for other, keys in _BY_TABLE.items():
        if other != table and key in keys:
            return f"; it belongs in [{other}]" if other else "; it belongs at the top of the file"
    return ""


def _number(spec: Field, value: object, path: str, index: int | None = None) -> float:
    where = spec.label if index is None else f"{spec.label}[{index}]"
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise PresetError(path, where, f"must be a number, got {_type_name(value)} {value!r}")
    number = float(value)
    if not math.isfinite(number):
        raise PresetError(path, where, f"must be finite, got {value!r}")
    lo, hi = spec.minimum, spec.maximum
    too_low = lo is not None and (number <= lo if spec.min_open else number < lo)
    too_high = hi is not None and (number >= hi if spec.max_open else number > hi)
    if too_low or too_high:
        unit = f" {spec.unit}" if spec.unit else ""
        raise PresetError(path, where, f"must be {spec.range_text()}{unit}, got {value!r}")
    return number


def _vector(spec: Field, value: object, path: str) -> tuple[float, float, float]:
    if not isinstance(value, list):
        raise PresetError(path, spec.label, f"must be an array of 3 numbers (R, G, B), got {_type_name(value)}")
    if len(value) != 3:
        raise PresetError(path, spec.label, f"must have exactly 3 values (R, G, B), got {len(value)}")
    return tuple(_number(spec, item, path, i) for i, item in enumerate(value))  # type: ignore[return-value]


def _value(spec: Field, value: object, path: str) -> Any:
    """Check one value against its :class:`Field` and return it normalised."""
    kind = spec.kind
    if kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise PresetError(path, spec.label, f"must be an integer, got {_type_name(value)} {value!r}")
        return value
    if kind == "float":
        return _number(spec, value, path)
    if kind == "vec3":
        return _vector(spec, value, path)
    if kind == "float_or_vec3":
        if isinstance(value, list):
            return _vector(spec, value, path)
        return _number(spec, value, path)
    if kind == "name":
        return check_name(value, path, spec.label)
    if kind == "str":
        if not isinstance(value, str):
            raise PresetError(path, spec.label, f"must be a string, got {_type_name(value)}")
        return value
    if kind == "str_list":
        if not isinstance(value, list) or not all(isinstance(item, str) for item in value):
            raise PresetError(path, spec.label, "must be an array of strings (one citation each)")
        return tuple(value)
    if kind == "choice":
        if not isinstance(value, str) or value not in spec.choices:
            options = ", ".join(repr(choice) for choice in spec.choices)
            raise PresetError(path, spec.label, f"must be one of {options}, got {value!r}")
        return value
    raise AssertionError(f"unknown field kind {kind!r}")


def _check_keys(table: str, mapping: Mapping[str, object], path: str) -> None:
    known = _BY_TABLE.get(table, {})
    for key in mapping:
        if key not in known:
            if table == "":
                candidates = list(known) + list(TABLES)
                raise PresetError(path, key, "unknown top-level key or table" + _elsewhere(key, table)
                                  + _suggest(key, candidates))
            raise PresetError(path, f"[{table}] {key}", f"unknown key in [{table}]" + _elsewhere(key, table)
                              + _suggest(key, list(known)))
    for key, spec in known.items():
        if spec.required and key not in mapping:
            hint = f"; add {key} = {SCHEMA_VERSION}" if key == "schema_version" else ""
            raise PresetError(path, spec.label, "is required but missing" + hint)
        if spec.excludes and key in mapping and spec.excludes in mapping and key < spec.excludes:
            raise PresetError(path, spec.label, f"give either {key} or {spec.excludes}, not both")


def validate_document(doc: Mapping[str, Any], path: str | Path) -> Validated:
    """Check a parsed TOML document against :data:`FIELDS`; return its values or raise :class:`PresetError`."""
    path = str(path)
    version = doc.get("schema_version")
    if "schema_version" in doc:
        version = _value(spec_for("", "schema_version"), version, path)
        if version != SCHEMA_VERSION:
            raise PresetError(path, "schema_version", f"version {version} is not supported (this Atmos reads "
                                                      f"version {SCHEMA_VERSION}); update Atmos or re-save the preset")
    top = {key: value for key, value in doc.items() if key not in TABLES}
    _check_keys("", top, path)
    tables: dict[str, Mapping[str, object]] = {}
    for table in TABLES:
        if table not in doc:
            if table in _REQUIRED_TABLES:
                raise PresetError(path, f"[{table}]", "table is required but missing")
            tables[table] = {}
            continue
        content = doc[table]
        if not isinstance(content, dict):
            raise PresetError(path, f"[{table}]", f"must be a table, got {_type_name(content)}")
        _check_keys(table, content, path)
        tables[table] = content

    def values(table: str) -> dict[str, Any]:
        return {key: _value(spec_for(table, key), value, path) for key, value in tables[table].items()}

    preset = values("preset")
    atmosphere_in = values("atmosphere")
    sun = values("sun")
    atmosphere: dict[str, Any] = {}
    for key, value in atmosphere_in.items():
        spec = spec_for("atmosphere", key)
        if key == "rayleigh":
            atmosphere["rayleigh_choice"] = value
        elif key == "sun_irradiance_top_scale":
            atmosphere["sun_irradiance_top_scale"] = value
        else:
            atmosphere[spec.target] = value
    return Validated(
        name=preset["name"],
        description=preset.get("description", ""),
        sources=preset.get("sources", ()),
        atmosphere=atmosphere,
        sun_elevation_deg=sun.get("elevation_deg"),
        sun_azimuth_deg=sun.get("azimuth_deg"),
    )


def markdown_table() -> str:
    """The schema as a Markdown table (for the docs and the README): one row per key."""
    rows = ["| key | type | unit | allowed | meaning |", "|---|---|---|---|---|"]
    kinds = {"int": "integer", "float": "number", "vec3": "3 numbers (R, G, B)", "float_or_vec3": "number or 3 numbers",
             "str": "string", "str_list": "array of strings", "name": "string (name)", "choice": "string"}
    for spec in FIELDS:
        if spec.kind == "choice":
            allowed = ", ".join(repr(choice) for choice in spec.choices)
        elif spec.kind in ("float", "vec3", "float_or_vec3"):
            allowed = spec.range_text()
        elif spec.key == "schema_version":
            allowed = str(SCHEMA_VERSION)
        else:
            allowed = ""
        required = " (required)" if spec.required else ""
        rows.append(f"| `{spec.label}` | {kinds[spec.kind]} | {spec.unit} | {allowed} | {spec.doc}{required} |")
    return "\n".join(rows)
