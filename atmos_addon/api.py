# SPDX-License-Identifier: GPL-3.0-or-later
"""The Atmos Python API for scripts and pipelines (the CLI is built on it).

    import atmos_addon.api as atmos
    atmos.enable(scene, preset="sunset", distance_scale=2.0)
    atmos.set_sun(scene, elevation_deg=5.0, azimuth_deg=120.0)
    atmos.disable(scene)

Every function validates all of its input before it changes the scene: a refused call (unknown
preset, bad value, unknown setting) raises :class:`AtmosError` and leaves the scene as it was.
With an installed extension import it as ``bl_ext.user_default.atmos.atmos_addon.api``.
"""

from __future__ import annotations

import math
from typing import Any

from . import presets as _presets
from .plan import RETIRED_BALANCED_NOTE


class AtmosError(ValueError):
    """A refused API call; the message says what was wrong and what to do."""


def _ensure_registered() -> None:
    import bpy

    if not hasattr(bpy.types.Scene, "atmos"):
        from . import register

        register()


def _check_overrides(scene, overrides: dict[str, Any]) -> None:
    settings = scene.atmos
    known = {p.identifier for p in settings.bl_rna.properties if not p.is_readonly} - {"rna_type", "enabled"}
    for key, value in overrides.items():
        if key not in known:
            raise AtmosError(f"unknown Atmos setting '{key}'; known settings: {', '.join(sorted(known))}")
        prop = settings.bl_rna.properties[key]
        size = getattr(prop, "array_length", 0)
        values = list(value) if size else [value]
        if size and len(values) != size:
            raise AtmosError(f"setting '{key}' needs {size} values, got {len(values)}")
        if prop.type == "ENUM":
            _check_choice(key, value, [item.identifier for item in prop.enum_items])
        if prop.type in {"FLOAT", "INT"}:
            for v in values:
                if not isinstance(v, (int, float)) or not math.isfinite(v):
                    raise AtmosError(f"setting '{key}' must be a finite number, got {v!r}")
                if v < prop.hard_min or v > prop.hard_max:
                    raise AtmosError(f"setting '{key}' = {v!r} is outside [{prop.hard_min:g}, {prop.hard_max:g}]")


def _check_choice(key: str, value, choices: list[str]) -> None:
    """An enum setting's value must be one of ``choices``; the retired Balanced quality says what replaced it."""
    if key == "quality" and str(value).upper() == "BALANCED":
        raise AtmosError(f"quality 'BALANCED': {RETIRED_BALANCED_NOTE}; use 'PRECISE' (the default, every scattering "
                         "order) or 'FAST' (what a file saved at Balanced opens with)")
    if value not in choices:
        raise AtmosError(f"setting '{key}' must be one of {', '.join(repr(c) for c in choices)}; got {value!r}")


def _check_sun(elevation_deg: float | None, azimuth_deg: float | None) -> None:
    for name, value, low, high in (("elevation_deg", elevation_deg, -90.0, 90.0),
                                   ("azimuth_deg", azimuth_deg, -360.0, 360.0)):
        if value is None:
            continue
        if not isinstance(value, (int, float)) or not math.isfinite(value) or not low <= value <= high:
            raise AtmosError(f"sun {name} must be a number in [{low:g}, {high:g}] degrees, got {value!r}")


def load_preset(name_or_path) -> _presets.Preset:
    """Load and validate a preset (built-in name, user preset name or .toml path); AtmosError if refused."""
    try:
        return _presets.load(name_or_path)
    except _presets.PresetError as error:
        raise AtmosError(str(error)) from error


def set_sun(scene, elevation_deg: float, azimuth_deg: float) -> None:
    """Point the scene's sun lamp (created if there is none) at ``elevation_deg`` above the horizon and
    ``azimuth_deg`` clockwise from +Y (north); the atmosphere, sky and lamp colour follow."""
    _check_sun(elevation_deg, azimuth_deg)
    _ensure_registered()
    from .blender import orchestrator

    with orchestrator.batch(scene):
        _point_sun(scene, elevation_deg, azimuth_deg)
    _evaluate(scene)


def _evaluate(scene) -> None:
    """Bring what the scene holds up to date after a call that moved the sun, as the interface's evaluation before
    each redraw does. A sun lamp or camera moved by a constraint or a driver has its world matrix only once the
    depsgraph evaluates (:func:`.blender.scene_reading.needs_evaluation`): the view layers are evaluated then. One
    moved by its own transform is read without it (evaluating a scene of 5000 objects takes seconds, to read two
    matrices), and what the drivers on the lamp evaluate to is written directly (:func:`.blender.sync.
    show_driven_values`); a render evaluates the scene anyway."""
    from .blender import scene_reading, sync

    if scene_reading.needs_evaluation(scene):
        for view_layer in scene.view_layers:
            view_layer.update()
    elif scene.atmos.enabled:
        sync.show_driven_values(scene)


def _point_sun(scene, elevation_deg: float | None, azimuth_deg: float | None) -> None:
    """Rotate the sun lamp; an angle given as None keeps the lamp's current value. Nothing when both are None."""
    if elevation_deg is None and azimuth_deg is None:
        return
    from .blender.apply import sun_lamp

    current_elevation, current_azimuth = sun_lamp.sun_angles(scene)
    sun_lamp.set_sun_angles(
        scene,
        math.radians(elevation_deg) if elevation_deg is not None else current_elevation,
        math.radians(azimuth_deg) if azimuth_deg is not None else current_azimuth,
    )


def set_preset(scene, name_or_path) -> _presets.Preset:
    """Apply a preset's atmosphere (and its sun angles, when it sets them) to ``scene``; returns it."""
    preset = load_preset(name_or_path)
    _ensure_registered()
    _apply_preset(scene, preset)
    _evaluate(scene)
    return preset


def _apply_preset(scene, preset: _presets.Preset, sun_elevation_deg: float | None = None,
                  sun_azimuth_deg: float | None = None) -> None:
    from .blender import orchestrator

    with orchestrator.batch(scene):
        orchestrator.apply_atmosphere(scene, preset.atmosphere)
        if hasattr(scene.atmos, "preset_name"):
            scene.atmos.preset_name = preset.name
        _point_sun(scene,
                   sun_elevation_deg if sun_elevation_deg is not None else preset.sun_elevation_deg,
                   sun_azimuth_deg if sun_azimuth_deg is not None else preset.sun_azimuth_deg)


def enable(scene, preset=None, *, sun_elevation_deg: float | None = None, sun_azimuth_deg: float | None = None,
           **overrides):
    """Turn Atmos on for ``scene``: optional preset, sun angles and setting overrides (``scene.atmos`` names,
    e.g. ``distance_scale=2.0``). Returns the effect report (managed/skipped materials, messages)."""
    _ensure_registered()
    _check_sun(sun_elevation_deg, sun_azimuth_deg)
    _check_overrides(scene, overrides)
    chosen = load_preset(preset) if preset is not None else None
    if scene.camera is None:
        raise AtmosError(f"scene '{scene.name}' has no camera: aerial perspective is measured from the camera")
    from .blender import orchestrator

    with orchestrator.batch(scene):
        if chosen is not None:
            _apply_preset(scene, chosen, sun_elevation_deg, sun_azimuth_deg)
        else:
            _point_sun(scene, sun_elevation_deg, sun_azimuth_deg)
        for key, value in overrides.items():
            setattr(scene.atmos, key, value)
    report = orchestrator.enable_effect(scene)   # evaluates first where a constraint moves the sun or the camera
    _evaluate(scene)
    return report


def is_enabled(scene) -> bool:
    """True when ``scene`` has Atmos on (set up in the panel, by :func:`enable` or saved so in its file)."""
    _ensure_registered()
    return bool(scene.atmos.enabled)


def disable(scene) -> None:
    """Turn Atmos off for ``scene``, restoring materials, compositor and world exactly."""
    _ensure_registered()
    from .blender import orchestrator

    orchestrator.disable_effect(scene)
