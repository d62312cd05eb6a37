# SPDX-License-Identifier: GPL-3.0-or-later
"""The preset library in Blender: where user presets live, applying a preset to a scene, and the operators.

Presets are data (:mod:`atmos_addon.presets`, TOML read with ``tomllib``); Blender's Python preset
system (``ExecutePreset``, preset files that are scripts) is never used, so loading a preset never
runs code.

User preset folder
  * Installed as an extension, the add-on's root package is the parent of ``atmos_addon``
    (``bl_ext.<repo>.atmos``) and user presets live in
    ``bpy.utils.extension_path_user(<root package>, path="presets", create=True)``, the folder
    Blender gives every extension for its user data (kept across updates of the extension).
  * From a source checkout (``atmos_addon`` is a top-level package: pip ``bpy`` tests, the CLI)
    there is no extension, so the folder is the one given to :func:`atmos_addon.presets.set_user_directory`
    (tests set a temporary one), else ``$ATMOS_USER_PRESETS``, else ``<Blender config>/atmos/presets``.

A refused preset changes nothing: the file is read and checked in full (schema, then the ranges of
the scene settings) before the first setting is written, and a failure while writing puts back
everything recorded just before (:mod:`.scene_state`).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import bpy
import numpy as np
from bpy.props import BoolProperty, StringProperty

from ... import presets
from ...presets import Preset, PresetError
from .. import orchestrator, scene_state, settings_io
from ..apply import sun_lamp

#: Environment variable naming the user preset folder when Atmos runs from a source checkout.
USER_DIRECTORY_ENV = "ATMOS_USER_PRESETS"


# --------------------------------------------------------------------------------------------------------------
# Where user presets live


def extension_package(blender_package: str = __package__.rpartition(".")[0]) -> str:
    """The add-on's root package for the Blender layer's package (``<root>.atmos_addon.blender``, the parent of this
    module's).

    ``bl_ext.user_default.atmos.atmos_addon.blender`` gives ``bl_ext.user_default.atmos``; a source
    checkout's ``atmos_addon.blender`` gives ``""`` (no extension).
    """
    parts = blender_package.split(".")
    if parts[-2:] != ["atmos_addon", "blender"]:
        raise ValueError(f"{blender_package!r} is not the package of the Atmos Blender layer")
    return ".".join(parts[:-2])


def user_directory() -> Path:
    """The folder of user presets (see the module docstring); also handed to :mod:`atmos_addon.presets`."""
    package = extension_package()
    if package:
        try:
            path = Path(bpy.utils.extension_path_user(package, path="presets", create=True))
        except (ValueError, OSError, RuntimeError, TypeError):
            path = None  # a legacy add-on install: not an extension; use the fallback below
        if path is not None:
            presets.set_user_directory(path)
            return path
    configured = presets.user_directory()
    if configured is not None:
        return configured
    if os.environ.get(USER_DIRECTORY_ENV):
        return Path(os.environ[USER_DIRECTORY_ENV])
    return Path(bpy.utils.user_resource("CONFIG", path=os.path.join("atmos", "presets")))


# --------------------------------------------------------------------------------------------------------------
# Reading presets (cached for drawing) and describing errors


_cache: dict[str, tuple[tuple, Preset]] = {}


def library_names() -> list[str]:
    """Built-in names in menu order, then the user presets."""
    return presets.names(user_directory())


def load(name: str) -> Preset:
    """A library preset by name, checked in full (raises :class:`PresetError`)."""
    return presets.load(name, user_directory())


def cached(name: str) -> Preset | None:
    """A library preset for drawing (tooltips, the "modified" mark), re-read when its file changes; None if broken."""
    try:
        path = presets.BUILTIN_DIRECTORY / f"{name.lower()}.toml" if presets.is_builtin(name) else (
            user_directory() / f"{name}.toml")
        stat = path.stat()
        key = (str(path), stat.st_mtime_ns, stat.st_size)
        hit = _cache.get(name)
        if hit is not None and hit[0] == key:
            return hit[1]
        preset = load(name)
    except (PresetError, OSError, ValueError):
        _cache.pop(name, None)
        return None
    _cache[name] = (key, preset)
    return preset


def describe(error: PresetError) -> str:
    """One line for the status bar naming the file, the field and the rule."""
    parts = []
    if error.path:
        parts.append(f"file '{Path(error.path).name}'")
    if error.field:
        parts.append(f"field '{error.field}'")
    where = ", ".join(parts)
    return f"Atmos preset refused ({where}): {error.rule}" if where else f"Atmos preset refused: {error.rule}"


# --------------------------------------------------------------------------------------------------------------
# The sun


def current_sun_angles_rad(scene) -> tuple[float, float]:
    """The scene's sun elevation and azimuth in radians (clockwise from north, +Y, toward east, +X)."""
    return sun_lamp.sun_angles(scene)


def set_sun_angles(scene, elevation_rad: float, azimuth_rad: float) -> None:
    """Point the scene's sun lamp (created when there is none, as enabling does)."""
    sun_lamp.set_sun_angles(scene, elevation_rad, azimuth_rad)


# --------------------------------------------------------------------------------------------------------------
# Applying


#: Atmosphere field -> the preset file's key, for messages.
_FILE_KEYS = {spec.target: spec.label for spec in presets.schema.FIELDS
              if spec.table == "atmosphere" and spec.kind != "choice" and spec.key != "sun_irradiance_top_scale"}


def check_fits_settings(preset: Preset) -> None:
    """Refuse a preset whose values the scene settings cannot hold (their hard limits), before any write."""
    rna = bpy.types.Scene.bl_rna.properties["atmos"].fixed_type.properties
    for prop_name, field_name, factor in settings_io.FIELD_MAP:
        prop = rna[prop_name]
        for value in np.atleast_1d(np.asarray(getattr(preset.atmosphere, field_name), dtype=float)) * factor:
            if not (prop.hard_min <= value <= prop.hard_max):
                key = _FILE_KEYS.get(field_name, field_name)
                raise PresetError(preset.path, key, f"{value:g} is outside what Atmos settings hold "
                                                    f"({prop.name}: {prop.hard_min:g} to {prop.hard_max:g})")


def apply_preset(scene, preset: Preset) -> None:
    """Write a checked preset into the scene: its atmosphere, its sun angles when it sets them, its name.

    Raises :class:`PresetError` before writing anything when the scene cannot hold the values; any
    other failure while writing puts the scene back as it was.
    """
    check_fits_settings(preset)
    state = scene_state.capture(scene)
    try:
        with orchestrator.batch(scene):
            orchestrator.apply_atmosphere(scene, preset.atmosphere)
            if preset.sun_elevation_deg is not None or preset.sun_azimuth_deg is not None:
                elevation, azimuth = current_sun_angles_rad(scene)
                if preset.sun_elevation_deg is not None:
                    elevation = math.radians(preset.sun_elevation_deg)
                if preset.sun_azimuth_deg is not None:
                    azimuth = math.radians(preset.sun_azimuth_deg)
                set_sun_angles(scene, elevation, azimuth)
            scene.atmos.preset_name = preset.name
    except BaseException:
        scene_state.restore(scene, state)
        raise


def preset_from_scene(scene, name: str, include_sun: bool, description: str = "") -> Preset:
    """The scene's current settings as a preset (checked like a file), with its sun angles if asked."""
    atmosphere = settings_io.atmosphere_from_settings(scene.atmos)
    elevation = azimuth = None
    if include_sun:
        elevation_rad, azimuth_rad = current_sun_angles_rad(scene)
        elevation, azimuth = math.degrees(elevation_rad), math.degrees(azimuth_rad)
    return presets.preset_from_atmosphere(name, atmosphere, elevation, azimuth, description=description)


def is_modified(scene) -> bool:
    """True when the settings differ from the preset named in ``preset_name`` (beyond float32 rounding)."""
    name = scene.atmos.preset_name
    preset = cached(name) if name else None
    if preset is None:
        return False
    current = settings_io.atmosphere_from_settings(scene.atmos)
    for _prop, field_name, _factor in settings_io.FIELD_MAP:
        a = np.asarray(getattr(current, field_name), dtype=float)
        b = np.asarray(getattr(preset.atmosphere, field_name), dtype=float)
        if not np.allclose(a, b, rtol=2e-6, atol=0.0):
            return True
    return False


# --------------------------------------------------------------------------------------------------------------
# Operators


class ATMOS_OT_preset_apply(bpy.types.Operator):
    """Set the atmosphere (and the sun, when the preset sets it) from a preset"""

    bl_idname = "atmos.preset_apply"
    bl_label = "Apply Atmosphere Preset"
    bl_options = {"REGISTER", "UNDO"}

    name: StringProperty(name="Preset", description="Name of the built-in or user preset to apply")

    @classmethod
    def description(cls, context, properties):
        preset = cached(properties.name) if properties.name else None
        if preset is None:
            return cls.__doc__
        return preset.description or f"Apply the preset '{preset.name}'"

    def execute(self, context):
        scene = context.scene
        try:
            preset = load(self.name)
            apply_preset(scene, preset)
        except PresetError as error:
            self.report({"ERROR"}, describe(error))
            return {"CANCELLED"}
        sun = "" if preset.sun_elevation_deg is None else f", sun {preset.sun_elevation_deg:g} degrees up"
        self.report({"INFO"}, f"Atmos: applied preset '{preset.name}'{sun}")
        return {"FINISHED"}


class ATMOS_OT_preset_add(bpy.types.Operator):
    """Save the current atmosphere settings as a user preset"""

    bl_idname = "atmos.preset_add"
    bl_label = "Save Atmosphere Preset"
    bl_options = {"REGISTER", "UNDO"}

    name: StringProperty(
        name="Name",
        description="Preset name: letters, digits, spaces, '-' and '_' (it is also the file name)",
        default="My Atmosphere",
    )
    preset_description: StringProperty(name="Description", description="One sentence shown as the preset's tooltip")
    include_sun: BoolProperty(
        name="Include Sun Direction",
        description="Store the sun's elevation and azimuth: applying the preset then moves the sun",
        default=False,
    )
    overwrite: BoolProperty(name="Overwrite", description="Replace a user preset of the same name", default=False)

    def invoke(self, context, event):
        current = context.scene.atmos.preset_name
        if current and not presets.is_builtin(current):
            self.name = current
        return context.window_manager.invoke_props_dialog(self)

    def draw(self, context):
        layout = self.layout
        layout.prop(self, "name")
        layout.prop(self, "preset_description")
        layout.prop(self, "include_sun")
        if presets.is_builtin(self.name):
            layout.label(text="Built-in presets cannot be replaced", icon="ERROR")
        elif (user_directory() / f"{self.name}.toml").exists():
            layout.prop(self, "overwrite", text="Overwrite the existing preset")

    def execute(self, context):
        scene = context.scene
        try:
            preset = preset_from_scene(scene, self.name, self.include_sun, self.preset_description)
            path = presets.save_user_preset(preset, user_directory(), overwrite=self.overwrite)
        except PresetError as error:
            self.report({"ERROR"}, describe(error))
            return {"CANCELLED"}
        except ValueError as error:  # settings the physics core refuses
            self.report({"ERROR"}, f"Atmos: the current settings cannot be saved: {error}")
            return {"CANCELLED"}
        scene.atmos.preset_name = preset.name
        self.report({"INFO"}, f"Atmos: saved preset '{preset.name}' to {path}")
        return {"FINISHED"}


def _user_preset_or_report(operator, name: str, action: str) -> bool:
    if not name:
        operator.report({"ERROR"}, f"Atmos: no preset to {action}; pick a user preset first")
        return False
    if presets.is_builtin(name):
        operator.report({"ERROR"}, f"Atmos: '{name}' is a built-in preset and cannot be {action}d; "
                                   "save a copy under another name to change it")
        return False
    return True


class ATMOS_OT_preset_remove(bpy.types.Operator):
    """Delete a user preset (built-in presets cannot be deleted)"""

    bl_idname = "atmos.preset_remove"
    bl_label = "Delete Atmosphere Preset"
    bl_options = {"REGISTER", "UNDO"}

    name: StringProperty(name="Preset", description="User preset to delete (empty: the scene's current preset)")

    def invoke(self, context, event):
        if not self.name:
            self.name = context.scene.atmos.preset_name
        return context.window_manager.invoke_confirm(self, event)

    def execute(self, context):
        name = self.name or context.scene.atmos.preset_name
        if not _user_preset_or_report(self, name, "delete"):
            return {"CANCELLED"}
        try:
            presets.delete_user_preset(name, user_directory())
        except PresetError as error:
            self.report({"ERROR"}, describe(error))
            return {"CANCELLED"}
        _cache.pop(name, None)
        if context.scene.atmos.preset_name == name:
            context.scene.atmos.preset_name = ""
        self.report({"INFO"}, f"Atmos: deleted preset '{name}'")
        return {"FINISHED"}


class ATMOS_OT_preset_rename(bpy.types.Operator):
    """Rename a user preset (built-in presets cannot be renamed)"""

    bl_idname = "atmos.preset_rename"
    bl_label = "Rename Atmosphere Preset"
    bl_options = {"REGISTER", "UNDO"}

    name: StringProperty(name="Preset", description="User preset to rename (empty: the scene's current preset)")
    new_name: StringProperty(name="New Name", description="Letters, digits, spaces, '-' and '_'")

    def invoke(self, context, event):
        if not self.name:
            self.name = context.scene.atmos.preset_name
        if not self.new_name:
            self.new_name = self.name
        return context.window_manager.invoke_props_dialog(self)

    def execute(self, context):
        name = self.name or context.scene.atmos.preset_name
        if not _user_preset_or_report(self, name, "rename"):
            return {"CANCELLED"}
        try:
            presets.rename_user_preset(name, self.new_name, user_directory())
        except PresetError as error:
            self.report({"ERROR"}, describe(error))
            return {"CANCELLED"}
        _cache.pop(name, None)
        for scene in bpy.data.scenes:
            if getattr(scene, "atmos", None) is not None and scene.atmos.preset_name == name:
                scene.atmos.preset_name = self.new_name
        self.report({"INFO"}, f"Atmos: renamed preset '{name}' to '{self.new_name}'")
        return {"FINISHED"}


class ATMOS_OT_preset_import(bpy.types.Operator):
    """Check a preset file and add it to your presets (and apply it)"""

    bl_idname = "atmos.preset_import"
    bl_label = "Import Atmosphere Preset"
    bl_options = {"REGISTER", "UNDO"}

    filepath: StringProperty(name="File", description="Preset file (.toml) to import", subtype="FILE_PATH")
    filter_glob: StringProperty(default="*.toml", options={"HIDDEN"})
    overwrite: BoolProperty(name="Overwrite", description="Replace a user preset of the same name", default=False)
    apply: BoolProperty(name="Apply", description="Apply the preset to the scene after importing it", default=True)

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        path = Path(bpy.path.abspath(self.filepath))
        try:
            checked = presets.validate_file(path)  # in full, before anything is copied or written
            check_fits_settings(checked)
            preset = presets.import_preset(path, user_directory(), overwrite=self.overwrite)
            if self.apply:
                apply_preset(context.scene, preset)
        except PresetError as error:
            self.report({"ERROR"}, describe(error))
            return {"CANCELLED"}
        _cache.pop(preset.name, None)
        applied = " and applied it" if self.apply else ""
        self.report({"INFO"}, f"Atmos: imported preset '{preset.name}'{applied}")
        return {"FINISHED"}


class ATMOS_OT_preset_export(bpy.types.Operator):
    """Write a preset file: the scene's current settings, or a preset of the library"""

    bl_idname = "atmos.preset_export"
    bl_label = "Export Atmosphere Preset"
    bl_options = {"REGISTER", "UNDO"}

    filepath: StringProperty(name="File", description="Preset file (.toml) to write", subtype="FILE_PATH")
    filter_glob: StringProperty(default="*.toml", options={"HIDDEN"})
    check_existing: BoolProperty(default=True, options={"HIDDEN"})
    name: StringProperty(
        name="Preset",
        description="Library preset to export; empty exports the scene's current settings, named after the file",
    )
    include_sun: BoolProperty(
        name="Include Sun Direction",
        description="When exporting the current settings, store the sun's elevation and azimuth too",
        default=False,
    )

    def invoke(self, context, event):
        if not self.filepath:
            stem = context.scene.atmos.preset_name or "atmosphere"
            folder = bpy.path.abspath("//") if bpy.data.filepath else ""
            self.filepath = os.path.join(folder, f"{stem}.toml")
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        path = Path(bpy.path.abspath(self.filepath))
        if path.suffix.lower() != ".toml":
            path = path.with_name(path.name + ".toml")
        try:
            if self.name:
                presets.export_preset(self.name, path, user_directory())
            else:
                presets.save(preset_from_scene(context.scene, path.stem, self.include_sun), path)
        except PresetError as error:
            self.report({"ERROR"}, describe(error))
            return {"CANCELLED"}
        except (OSError, ValueError) as error:
            self.report({"ERROR"}, f"Atmos: cannot write {path}: {error}")
            return {"CANCELLED"}
        self.report({"INFO"}, f"Atmos: exported preset to {path}")
        return {"FINISHED"}


CLASSES = (
    ATMOS_OT_preset_apply,
    ATMOS_OT_preset_add,
    ATMOS_OT_preset_remove,
    ATMOS_OT_preset_rename,
    ATMOS_OT_preset_import,
    ATMOS_OT_preset_export,
)
