# SPDX-License-Identifier: GPL-3.0-or-later
"""Atmosphere presets: TOML data files (built-in and user) turned into physics-core ``Atmosphere`` values.

No ``bpy`` here; the Blender layer calls :func:`set_user_directory` with its extension user folder
and applies :class:`Preset` values to the scene.

Library rules
  * Built-ins live in ``presets/builtin/<name>.toml`` and are read-only: :func:`delete_user_preset`
    and :func:`rename_user_preset` refuse them.
  * User presets live in one folder (``set_user_directory`` or a ``user_dir`` argument), one file
    ``<name>.toml`` each, whose ``[preset] name`` must equal the file name.
  * User presets cannot shadow built-ins: a name equal to a built-in's, ignoring case (file systems
    on Windows and macOS ignore case), is refused by :func:`save_user_preset`, :func:`import_preset`
    and :func:`rename_user_preset`; such a file put there by hand is left out of :func:`names`, and
    :func:`load` of that name gives the built-in. So a built-in always means the same thing.
  * Names are 1 to 64 letters, digits, spaces, ``-`` or ``_`` (see :data:`schema.NAME_RULE`): no path
    characters, so a name can never point outside the folder.

Loading never executes code: files are parsed with ``tomllib`` after a size check and every value
is checked against :data:`schema.FIELDS`; anything wrong raises :class:`PresetError` naming the
file, the field and the rule.
"""

from __future__ import annotations

import dataclasses
import os
import re
import shutil
import tempfile
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from . import schema, writer
from .schema import MAX_FILE_BYTES, SCHEMA_VERSION, PresetError, check_name

__all__ = [
    "BUILTIN_DIRECTORY", "BUILTIN_NAMES", "Preset", "PresetError", "atmospheres_equal", "delete_user_preset",
    "export_preset", "import_preset", "is_builtin", "load", "names", "preset_from_atmosphere",
    "rename_user_preset", "save", "save_user_preset", "set_user_directory", "to_document", "user_directory",
    "validate_file",
]

#: Folder of the read-only presets shipped with Atmos.
BUILTIN_DIRECTORY = Path(__file__).resolve().parent / "builtin"
#: Built-in presets in menu order.
BUILTIN_NAMES: tuple[str, ...] = ("clear", "overcast", "sunset", "mars")

_FILE_HEADER = (
    f"Atmos atmosphere preset (schema version {SCHEMA_VERSION}). Units are in the key names;\n"
    "the fields are listed in atmos_addon/presets/schema.py. A missing [atmosphere] key means clear Earth."
)

_user_directory: Path | None = None


def _physics():
    """The physics-core names presets use (imported late: the core is numpy only, but not needed to list names)."""
    from types import SimpleNamespace

    from ..physics.atmosphere import Atmosphere
    from ..physics.rayleigh import rayleigh_coefficients

    return SimpleNamespace(Atmosphere=Atmosphere, rayleigh_coefficients=rayleigh_coefficients)


# --------------------------------------------------------------------------------------------------------------
# The Preset value


def atmospheres_equal(a: Any, b: Any) -> bool:
    """True when two physics-core ``Atmosphere`` values hold exactly the same numbers in every field."""
    if type(a) is not type(b):
        return False
    for item in dataclasses.fields(a):
        x, y = getattr(a, item.name), getattr(b, item.name)
        if np.shape(x) != np.shape(y) or not np.array_equal(np.asarray(x), np.asarray(y)):
            return False
    return True


@dataclass(frozen=True, eq=False)
class Preset:
    """One preset: what it is, where its numbers come from, the atmosphere it sets and, optionally, the sun.

    ``sun_elevation_deg`` / ``sun_azimuth_deg`` are None when the preset leaves the user's sun alone.
    ``path`` (where it was read from) and ``builtin`` are bookkeeping: equality ignores them, so
    ``load(save(p, path)) == p``.
    """

    name: str
    description: str
    sources: tuple[str, ...]
    atmosphere: Any  # physics.Atmosphere
    sun_elevation_deg: float | None = None
    sun_azimuth_deg: float | None = None
    path: Path | None = None
    builtin: bool = False

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Preset):
            return NotImplemented
        return (
            (self.name, self.description, tuple(self.sources), self.sun_elevation_deg, self.sun_azimuth_deg)
            == (other.name, other.description, tuple(other.sources), other.sun_elevation_deg, other.sun_azimuth_deg)
            and atmospheres_equal(self.atmosphere, other.atmosphere)
        )

    __hash__ = None  # type: ignore[assignment]  # holds numpy arrays


def _build(validated: schema.Validated, path: Path | str | None, builtin: bool = False) -> Preset:
    """Turn checked values into a :class:`Preset`, filling missing atmosphere fields from clear Earth."""
    physics = _physics()
    default = physics.Atmosphere()
    values = dict(validated.atmosphere)
    choice = values.pop("rayleigh_choice", None)
    scale = values.pop("sun_irradiance_top_scale", None)
    wavelengths = values.get("wavelengths_nm")
    if "rayleigh_scattering" not in values and (choice == "earth_standard" or wavelengths is not None):
        # Clear-Earth air at the preset's wavelengths: the same formula as the default, not its numbers.
        values["rayleigh_scattering"] = physics.rayleigh_coefficients(
            np.asarray(wavelengths if wavelengths is not None else default.wavelengths_nm, dtype=float))
    if scale is not None:
        values["sun_irradiance_top"] = np.asarray(default.sun_irradiance_top, dtype=float) * scale
    for key, value in values.items():
        if isinstance(value, tuple):
            values[key] = np.asarray(value, dtype=float)
    try:
        atmosphere = dataclasses.replace(default, **values)
    except ValueError as error:
        # The core's own cross-field checks; its message names the Atmosphere field, we name the file's key.
        message = str(error)
        keys = [spec.label for spec in schema.FIELDS if spec.table == "atmosphere" and spec.target in message
                and spec.kind != "choice"]
        raise PresetError(path, keys[0] if keys else "[atmosphere]", message) from None
    return Preset(
        name=validated.name,
        description=validated.description,
        sources=tuple(validated.sources),
        atmosphere=atmosphere,
        sun_elevation_deg=validated.sun_elevation_deg,
        sun_azimuth_deg=validated.sun_azimuth_deg,
        path=None if path is None else Path(path),
        builtin=builtin,
    )


def _floats(value: Any) -> float | list[float]:
    array = np.asarray(value, dtype=float)
    return float(array) if array.ndim == 0 else [float(item) for item in array.ravel()]


def to_document(preset: Preset) -> dict[str, Any]:
    """The TOML document (nested dicts) of ``preset``, every atmosphere number explicit."""
    atmosphere = preset.atmosphere
    table: dict[str, Any] = {}
    for spec in schema.FIELDS:
        if spec.table != "atmosphere" or spec.kind == "choice" or spec.key == "sun_irradiance_top_scale":
            continue
        value = _floats(getattr(atmosphere, spec.target))
        if spec.kind == "float_or_vec3" and isinstance(value, list) and len(set(value)) == 1:
            value = value[0]  # one g for all channels reads back to the same three values
        table[spec.key] = value
    doc: dict[str, Any] = {
        "schema_version": SCHEMA_VERSION,
        "preset": {"name": preset.name, "description": preset.description, "sources": list(preset.sources)},
        "atmosphere": table,
    }
    sun = {}
    if preset.sun_elevation_deg is not None:
        sun["elevation_deg"] = float(preset.sun_elevation_deg)
    if preset.sun_azimuth_deg is not None:
        sun["azimuth_deg"] = float(preset.sun_azimuth_deg)
    if sun:
        doc["sun"] = sun
    return doc


def preset_from_atmosphere(
    name: str,
    atm: Any,
    sun_elevation_deg: float | None = None,
    sun_azimuth_deg: float | None = None,
    description: str = "",
    sources: tuple[str, ...] | list[str] = (),
) -> Preset:
    """A :class:`Preset` holding ``atm`` (e.g. the scene's current settings), checked like a file would be."""
    preset = Preset(name, description, tuple(sources), atm, sun_elevation_deg, sun_azimuth_deg)
    schema.validate_document(to_document(preset), f"preset {name!r}")
    return preset


# --------------------------------------------------------------------------------------------------------------
# Files


def _read_document(path: Path) -> dict[str, Any]:
    """Parse ``path`` as TOML after the size check; never executes anything."""
    try:
        if not path.is_file():
            raise PresetError(path, None, "no such preset file" if not path.exists() else "is not a file")
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            raise PresetError(path, "file size", f"{size} bytes is over the {MAX_FILE_BYTES // 1024} KiB limit "
                                                 "for presets; refused before parsing")
        with path.open("rb") as handle:
            data = handle.read(MAX_FILE_BYTES + 1)
    except OSError as error:
        raise PresetError(path, None, f"cannot be read ({error.strerror or error})") from None
    if len(data) > MAX_FILE_BYTES:
        raise PresetError(path, "file size", f"over the {MAX_FILE_BYTES // 1024} KiB limit for presets")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise PresetError(path, f"byte {error.start}", "is not UTF-8 text; save the preset as UTF-8") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        message = str(error)
        line = re.search(r"line (\d+)", message)
        raise PresetError(path, f"line {line.group(1)}" if line else None, f"TOML syntax error: {message}") from None


def _is_builtin_path(path: Path) -> bool:
    resolved = path.resolve()
    return resolved.parent == BUILTIN_DIRECTORY and resolved.stem in BUILTIN_NAMES


def validate_file(path: str | Path) -> Preset:
    """Read and check one preset file; return its :class:`Preset` or raise :class:`PresetError`."""
    path = Path(path)
    validated = schema.validate_document(_read_document(path), path)
    return _build(validated, path, builtin=_is_builtin_path(path))


def _atomic_write(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(handle, "w", encoding="utf-8", newline="\n") as stream:
            stream.write(text)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def _plain(value: Any) -> Any:
    """Mappings to dicts, tuples and arrays to lists, numpy scalars to Python ones (for validation/writing)."""
    if isinstance(value, Mapping):
        return {str(key): _plain(item) for key, item in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_plain(item) for item in (value.tolist() if isinstance(value, np.ndarray) else value)]
    if isinstance(value, np.generic):
        return value.item()
    return value


def save(preset_or_fields: Preset | Mapping[str, Any], path: str | Path) -> Path:
    """Write a preset file and return its path; ``load(save(p, path)) == p`` exactly.

    ``preset_or_fields`` is a :class:`Preset` (written with every number explicit) or a document
    mapping in the file's own shape (``{"schema_version": 1, "preset": {...}, "atmosphere": {...}}``),
    which is checked like a file and written as given, keeping e.g. ``rayleigh = "earth_standard"``.
    """
    path = Path(path)
    if isinstance(preset_or_fields, Preset):
        doc = to_document(preset_or_fields)
        schema.validate_document(doc, path)
    elif isinstance(preset_or_fields, Mapping):
        doc = _plain(preset_or_fields)
        _build(schema.validate_document(doc, path), path)
    else:
        raise TypeError(f"save() takes a Preset or a mapping, not {type(preset_or_fields).__name__}")
    _atomic_write(path, writer.dumps(doc, header=_FILE_HEADER))
    return path


# --------------------------------------------------------------------------------------------------------------
# The library: built-ins and the user folder


def set_user_directory(path: str | Path | None) -> None:
    """Set the folder of user presets (the Blender layer passes its extension user folder); None unsets it."""
    global _user_directory
    _user_directory = None if path is None else Path(path)


def user_directory() -> Path | None:
    """The folder set by :func:`set_user_directory`, or None."""
    return _user_directory


def _folder(user_dir: str | Path | None, required: bool = False) -> Path | None:
    folder = Path(user_dir) if user_dir is not None else _user_directory
    if folder is None and required:
        raise PresetError(None, None, "no user preset folder is set; call set_user_directory() first")
    return folder


def is_builtin(name: str) -> bool:
    """True when ``name`` is (or, ignoring case, would shadow) a built-in preset."""
    return name.lower() in BUILTIN_NAMES


def names(user_dir: str | Path | None = None) -> list[str]:
    """Built-in names in menu order, then the user folder's presets sorted (files are not parsed here)."""
    result = list(BUILTIN_NAMES)
    folder = _folder(user_dir)
    if folder is not None and folder.is_dir():
        stems = [path.stem for path in folder.glob("*.toml") if path.is_file()]
        valid = [stem for stem in stems if schema.is_valid_name(stem) and not is_builtin(stem)]
        result += sorted(valid, key=lambda stem: (stem.lower(), stem))
    return result


def _find(name: str, user_dir: str | Path | None = None) -> tuple[Path, bool]:
    """The file of a library preset and whether it is built-in."""
    check_name(name)
    if is_builtin(name):
        return BUILTIN_DIRECTORY / f"{name.lower()}.toml", True
    folder = _folder(user_dir)
    path = None if folder is None else folder / f"{name}.toml"
    if path is None or not path.is_file():
        known = ", ".join(names(user_dir))
        raise PresetError(None, name, f"no preset of that name; known presets: {known}")
    return path, False


def load(name_or_path: str | Path, user_dir: str | Path | None = None) -> Preset:
    """A preset by library name (``"clear"``, a user preset's name) or by file path (``Path`` or a str with
    a path character or ``.toml``); raises :class:`PresetError` for anything wrong."""
    if isinstance(name_or_path, str) and schema.is_valid_name(name_or_path):
        path, builtin = _find(name_or_path, user_dir)
        preset = validate_file(path)
        if not builtin and preset.name != name_or_path:
            raise PresetError(path, "[preset] name", f"is {preset.name!r} but the file is {path.name}; in the "
                                                     "library the two must match: rename the file or the name")
        return preset
    return validate_file(Path(name_or_path))


def _user_path(name: str, user_dir: str | Path | None, action: str) -> Path:
    check_name(name)
    if is_builtin(name):
        raise PresetError(None, name, f"is a built-in preset (or its name, ignoring case) and cannot be {action}")
    return _folder(user_dir, required=True) / f"{name}.toml"


def save_user_preset(preset: Preset, user_dir: str | Path | None = None, overwrite: bool = False) -> Path:
    """Write ``preset`` into the user folder as ``<name>.toml``; refuses built-in names and, unless
    ``overwrite``, an existing preset."""
    path = _user_path(preset.name, user_dir, "overwritten by a user preset")
    if path.exists() and not overwrite:
        raise PresetError(path, preset.name, "a user preset of that name exists; delete or rename it first")
    return save(preset, path)


def delete_user_preset(name: str, user_dir: str | Path | None = None) -> None:
    """Delete a user preset's file; built-ins are refused."""
    path = _user_path(name, user_dir, "deleted")
    if not path.is_file():
        raise PresetError(path, name, "no user preset of that name")
    path.unlink()


def rename_user_preset(old: str, new: str, user_dir: str | Path | None = None) -> Path:
    """Rename a user preset (file and ``[preset] name``); built-ins are refused on either side.

    The file is rewritten from its parsed values, so comments in it are not kept.
    """
    old_path = _user_path(old, user_dir, "renamed")
    new_path = _user_path(new, user_dir, "used as a new name")
    if not old_path.is_file():
        raise PresetError(old_path, old, "no user preset of that name")
    if new_path.exists() and old.lower() != new.lower():
        raise PresetError(new_path, new, "a user preset of that name exists; delete it or pick another name")
    load(old, user_dir)  # refuse to rename a broken file
    doc = _read_document(old_path)
    doc["preset"]["name"] = new
    os.replace(old_path, new_path)  # first, so a change of case works on case-insensitive file systems
    _atomic_write(new_path, writer.dumps(doc, header=_FILE_HEADER))
    return new_path


def import_preset(path: str | Path, user_dir: str | Path | None = None, overwrite: bool = False) -> Preset:
    """Check a preset file and copy it (byte for byte, comments kept) into the user folder."""
    source = Path(path)
    preset = validate_file(source)
    target = _user_path(preset.name, user_dir, "imported: change its [preset] name")
    if target.exists() and not overwrite:
        raise PresetError(target, preset.name, "a user preset of that name exists; delete or rename it first")
    target.parent.mkdir(parents=True, exist_ok=True)
    if not (target.exists() and target.samefile(source)):
        shutil.copyfile(source, target)
    return load(preset.name, user_dir)


def export_preset(name: str, path: str | Path, user_dir: str | Path | None = None) -> Path:
    """Copy a library preset (built-in or user; checked first) to ``path``; returns ``path``."""
    source = load(name, user_dir).path
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    if not (target.exists() and target.samefile(source)):
        shutil.copyfile(source, target)
    return target
