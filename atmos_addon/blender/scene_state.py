# SPDX-License-Identifier: GPL-3.0-or-later
"""Capture and restore what Atmos look-development operations change in a scene, exactly.

Applying a preset (settings and sun) and rendering a contact sheet (settings, sun, render size,
engine, samples, output format) must leave the scene as it was after an error or a cancel, and
the contact sheet after success too. :func:`capture` records those values; :func:`restore` writes
back only the ones that differ (so update callbacks that rebuild things run as little as possible)
and removes sun lamps that appeared in between.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import bpy

from .apply import sun_lamp

#: ``scene.atmos`` properties that are views of other values (get/set), switches with side effects, or
#: outputs the sync writes (status lines, the ground-sun display): restoring the values they are computed
#: from restores them.
DERIVED_SETTINGS = frozenset({"rna_type", "enabled", "visibility_km", "haze_colour", "air_density",
                              "planet_radius_km", "atmosphere_height_km", "sun_elevation", "sun_azimuth",
                              "sun_colour_display", "sun_strength_display", "status_built", "status_sun",
                              "status_materials", "status_objects", "status_quality", "auto_level"})

#: Render settings a contact sheet changes (attribute paths from the scene), restored in this order.
RENDER_PATHS = (
    "render.engine",
    "render.resolution_x",
    "render.resolution_y",
    "render.resolution_percentage",
    "render.filepath",
    "render.image_settings.media_type",  # Blender 5.0+; must come before file_format
    "render.image_settings.file_format",
    "render.image_settings.color_mode",
    "render.image_settings.color_depth",
    "render.image_settings.compression",
    "cycles.samples",
    "eevee.taa_render_samples",
    "world.cycles.sampling_method",
    "world.cycles.sample_map_resolution",
)

#: ``scene.atmos`` values the sync writes (no update callbacks): put back after the restoring sync.
SYNC_WRITTEN = ("status_built", "status_sun", "status_materials", "status_objects", "sun_colour_display",
                "sun_strength_display", "status_quality", "auto_level")

#: Scene custom properties Atmos keeps bookkeeping in (the sun lamp it created, for disabling to remove).
SCENE_KEYS = (sun_lamp.LAMP_STATE_KEY,)

_OBJECT_PATHS = ("location", "rotation_mode", "rotation_euler", "rotation_quaternion", "rotation_axis_angle",
                 "scale")
_LAMP_PATHS = ("energy", "color", "angle")


def _resolve(root: Any, path: str) -> tuple[Any, str] | None:
    *parents, name = path.split(".")
    owner = root
    for part in parents:
        owner = getattr(owner, part, None)
        if owner is None:
            return None
    return (owner, name) if hasattr(owner, name) else None


def _plain(value: Any) -> Any:
    if isinstance(value, str) or not hasattr(value, "__len__"):
        return value
    return tuple(_plain(item) for item in value)


def settings_values(settings) -> dict[str, Any]:
    """Every stored, writable ``scene.atmos`` value (vectors as tuples, pointers as the data-block)."""
    values = {}
    for prop in settings.bl_rna.properties:
        if prop.identifier in DERIVED_SETTINGS or prop.is_readonly or prop.type == "COLLECTION":
            continue
        values[prop.identifier] = _plain(getattr(settings, prop.identifier))
    return values


def _sun_lamps(scene) -> list:
    return [obj for obj in scene.objects if obj.type == "LIGHT" and obj.data.type == "SUN"]


@dataclass
class SceneState:
    """Values of one scene to put back; see :func:`capture`."""

    scene_name: str
    settings: dict[str, Any]
    render: dict[str, Any]
    objects: set[str]
    lamps: dict[str, dict[str, Any]] = field(default_factory=dict)
    lamp_data: dict[str, dict[str, Any]] = field(default_factory=dict)
    scene_keys: dict[str, Any] = field(default_factory=dict)


def capture(scene) -> SceneState:
    """Record the scene's Atmos settings, its sun lamps' transforms and light values, and render settings."""
    render = {}
    for path in RENDER_PATHS:
        found = _resolve(scene, path)
        if found is not None:
            render[path] = _plain(getattr(*found))
    state = SceneState(scene.name, settings_values(scene.atmos), render, {obj.name for obj in scene.objects})
    for key in SCENE_KEYS:
        value = scene.get(key)
        state.scene_keys[key] = value.to_dict() if hasattr(value, "to_dict") else value
    for lamp in _sun_lamps(scene):
        state.lamps[lamp.name] = {name: _plain(getattr(lamp, name)) for name in _OBJECT_PATHS}
        state.lamp_data[lamp.name] = {name: _plain(getattr(lamp.data, name)) for name in _LAMP_PATHS}
    return state


def _write(owner: Any, name: str, value: Any) -> None:
    if _plain(getattr(owner, name)) != value:
        setattr(owner, name, value)


def restore(scene, state: SceneState) -> None:
    """Put back what :func:`capture` recorded; sun lamps added since are removed. Never raises for one value."""
    from . import orchestrator

    for obj in [obj for obj in _sun_lamps(scene) if obj.name not in state.objects]:
        data = obj.data
        bpy.data.objects.remove(obj)
        if data.users == 0:
            bpy.data.lights.remove(data)
    for key, value in state.scene_keys.items():
        if value is None:
            scene.pop(key, None)
        else:
            scene[key] = value
    for path, value in state.render.items():
        found = _resolve(scene, path)
        if found is not None:
            try:
                _write(*found, value)
            except (TypeError, ValueError, AttributeError):
                pass  # a value this Blender refuses in the restored combination; keep going
    for name, values in state.lamps.items():
        lamp = scene.objects.get(name)
        if lamp is None:
            continue
        for attribute, value in values.items():
            _write(lamp, attribute, value)
        for attribute, value in state.lamp_data[name].items():
            _write(lamp.data, attribute, value)
    for layer in scene.view_layers:
        layer.update()  # matrix_world of the restored lamps, read by the sync at the end of the batch
    settings = scene.atmos
    with orchestrator.batch(scene):
        for name, value in state.settings.items():
            if hasattr(settings, name):
                try:
                    _write(settings, name, value)
                except (TypeError, ValueError, AttributeError):
                    pass
    # the sync rewrites the status lines and sunlight displays; put the recorded values back exactly
    for name in SYNC_WRITTEN:
        if name in state.settings:
            _write(settings, name, state.settings[name])
