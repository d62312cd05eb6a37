# SPDX-License-Identifier: GPL-3.0-or-later
"""Scene settings and sun lamp -> the values the built nodes read. Values only: nothing here builds a node tree.

:func:`sync_scene` writes the shader parameters (scene custom properties read by the node groups), the sun lamp's
colour and strength, the world's sky-lighting table and the haze domes' shapes. It runs on every parameter change
(the orchestrator's :func:`~.orchestrator.update`, after checking the built groups against the plan) and per
frame of a sun bake, so the physics behind it is computed once per change of the atmosphere or the sun (a cache
on their values): a slider that changes neither costs only the writes.
"""

from __future__ import annotations

import math

import numpy as np

from ..physics import Atmosphere, sun_irradiance_ground
from ..physics.sun import LUMINANCE_WEIGHTS
from . import scene_reading
from .apply import in_render, sun_lamp, world

#: Per scene: ((settings values, elevation, sun radius, limb darkening), E_sun, colour, strength),
#: the lamp's matrix, the camera's z (caches only; nothing here is needed to restore a file).
_last_sun_values: dict[str, tuple] = {}
_last_sun_matrix: dict[str, tuple] = {}
_last_camera_z: dict[str, float | None] = {}


def _sun_values(scene, key: tuple, atmosphere: Atmosphere, elevation_rad: float, sun_radius: float,
                limb_darkening: float):
    """E_sun at the ground and the lamp's colour and strength (as :func:`sun_color_and_strength` splits it),
    cached."""
    sun_key = (key, elevation_rad, sun_radius, limb_darkening)
    cached = _last_sun_values.get(scene.name)
    if cached is not None and cached[0] == sun_key:
        return cached[1:]
    irradiance = np.asarray(sun_irradiance_ground(elevation_rad, atmosphere, 0.0, sun_radius, limb_darkening),
                            dtype=float)
    strength = float(irradiance @ LUMINANCE_WEIGHTS)
    colour = tuple(float(c) for c in irradiance / strength) if strength > 0.0 else (1.0, 1.0, 1.0)
    _last_sun_values[scene.name] = (sun_key, irradiance, colour, strength)
    return irradiance, colour, strength


def sync_scene(scene) -> None:
    """Write the values the built nodes of ``scene`` read, from its settings and sun lamp (module docstring).

    E_sun at the ground follows the sun's elevation through the transmittance of the whole air column
    (:func:`sun_irradiance_ground`); the shader multiplies its unit-sun in-scattering by it.
    """
    settings = scene.atmos
    key, atmosphere = scene_reading.atmosphere_with_key(scene)
    lamp = scene_reading.sun_object(scene)
    direction, sun_status = scene_reading.direction_of(lamp)
    elevation_rad = math.asin(float(np.clip(direction[2], -1.0, 1.0)))
    diameter = float(settings.sun_angular_diameter)
    sun_radius = 0.5 * diameter
    irradiance, colour, strength = _sun_values(scene, key, atmosphere, elevation_rad, sun_radius,
                                               float(settings.sun_limb_darkening))
    enabled = settings.enabled
    if enabled and settings.sky_enabled:
        world.write_sky_lighting_table(scene, atmosphere)
    scene_reading.groups().parameters.write_shader_parameters(
        scene,
        beta_rayleigh=atmosphere.rayleigh_scattering,
        beta_mie=atmosphere.mie_scattering,
        beta_mie_absorption=atmosphere.mie_absorption,
        mie_g=atmosphere.mie_g,
        sun_direction=direction,
        sun_irradiance=irradiance,
        metres_per_unit=scene_reading.metres_per_unit(scene),
        planet_radius=atmosphere.planet_radius,
        rayleigh_scale_height=atmosphere.rayleigh_scale_height,
        mie_scale_height=atmosphere.mie_scale_height,
        sun_angular_radius=sun_radius,
        sun_limb_darkening=settings.sun_limb_darkening,
        ground_albedo=tuple(settings.ground_albedo),
    )
    scene_reading.set_if_changed(settings, "status_sun", sun_status)
    if enabled and in_render.is_installed(scene):
        in_render.sync_domes(scene, atmosphere, scene_reading.metres_per_unit(scene))
    _show_sunlight(scene, lamp, (colour, strength, diameter), enabled=enabled)
    _last_sun_matrix[scene.name] = lamp_matrix_key(lamp)
    note_camera(scene)


def _show_sunlight(scene, lamp, values, *, enabled: bool) -> None:
    """Show E_sun's colour and strength (``values``: colour, strength, angle) in the settings and, with
    ``drive_sun_lamp``, on the lamp (changes only)."""
    settings = scene.atmos
    colour, strength, angle = values
    if sun_lamp.differs(tuple(settings.sun_colour_display), colour):
        settings.sun_colour_display = colour
    if sun_lamp.differs(settings.sun_strength_display, strength):
        settings.sun_strength_display = strength
    if lamp is not None and enabled and settings.drive_sun_lamp:
        sun_lamp.drive_lamp(scene, lamp, colour, strength, angle)


def lamp_matrix_key(lamp) -> tuple:
    """The sun lamp's name and world matrix, to tell whether it moved since the last sync."""
    if lamp is None:
        return ()
    return (lamp.name, *(tuple(row) for row in lamp.matrix_world))


def sun_moved(scene) -> bool:
    """True when the sun lamp moved (or another lamp took over) since the last :func:`sync_scene`."""
    return lamp_matrix_key(scene_reading.sun_object(scene)) != _last_sun_matrix.get(scene.name)


def _camera_z(scene) -> float | None:
    """The scene camera's world z (the Precise tables depend on its altitude), None without a camera."""
    return None if scene.camera is None else round(float(scene.camera.matrix_world.translation.z), 6)


def note_camera(scene) -> bool:
    """Record the camera's z; True when it changed since the last call."""
    camera_z = _camera_z(scene)
    changed = camera_z != _last_camera_z.get(scene.name, camera_z)
    _last_camera_z[scene.name] = camera_z
    return changed


def forget(scene_name: str | None = None) -> None:
    """Drop the cached sync state (all scenes when ``scene_name`` is None)."""
    scene_reading.forget(scene_name)
    for cache in (_last_sun_matrix, _last_sun_values, _last_camera_z):
        if scene_name is None:
            cache.clear()
        else:
            cache.pop(scene_name, None)

