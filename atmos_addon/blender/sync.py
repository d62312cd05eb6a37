# SPDX-License-Identifier: GPL-3.0-or-later
"""Scene settings and sun lamp -> the values the built nodes read. Values only: nothing here builds a node tree.

:func:`sync_scene` writes the shader parameters (scene custom properties read by the node groups), the world's
sky-lighting table and the haze domes' shapes, and has the sun's parameters and the sun lamp's colour and strength
follow the lamp (drivers, :mod:`.apply.sun_drivers`, whose E_sun table it rewrites when the air changes). It runs on
every parameter change (the orchestrator's :func:`~.orchestrator.update`, after checking the built groups against
the plan), so the physics behind it is computed once per change of the atmosphere or the sun (a cache on what each
value depends on): a slider that changes neither costs only the writes.
"""

from __future__ import annotations

import math

import numpy as np

from ..physics import Atmosphere, sun_irradiance_ground
from ..physics.sun import LUMINANCE_WEIGHTS, interpolate_sun_irradiance, sun_irradiance_table
from . import scene_reading
from .apply import in_render, sun_drivers, sun_lamp, world

#: Per scene: ((what E_sun depends on, elevation, sun radius, limb darkening), E_sun, colour, strength),
#: (what E_sun depends on, E_sun table), the lamp's matrix, the camera's z (caches only;
#: nothing here is needed to restore a file).
_last_sun_values: dict[str, tuple] = {}
_last_sun_table: dict[str, tuple] = {}
_last_sun_matrix: dict[str, tuple] = {}
_last_camera_z: dict[str, float | None] = {}
#: Per scene: what the sun's drivers evaluate to after the last sync (direction, E_sun, lamp colour, lamp strength),
#: or None where nothing is driven.
_driven_values: dict[str, tuple | None] = {}


def _sun_values(scene, dependence: tuple, atmosphere: Atmosphere, elevation_rad: float, sun_radius: float,
                limb_darkening: float, table=None):
    """E_sun at the ground and the lamp's colour and strength (as :func:`sun_color_and_strength` splits it),
    cached on ``dependence`` (:func:`_sun_dependence`), the elevation and the sun's disk. With the sun's drivers'
    ``table`` (:func:`sun_irradiance_table`), E_sun read from it as they read it (what renders; within 0.16 % of
    :func:`sun_irradiance_ground`, which gives it without)."""
    sun_key = (dependence, elevation_rad, sun_radius, limb_darkening, table is None)
    cached = _last_sun_values.get(scene.name)
    if cached is not None and cached[0] == sun_key:
        return cached[1:]
    if table is None:
        irradiance = np.asarray(sun_irradiance_ground(elevation_rad, atmosphere, 0.0, sun_radius, limb_darkening),
                                dtype=float)
    else:
        irradiance = interpolate_sun_irradiance(table, math.sin(elevation_rad))
    strength = float(irradiance @ LUMINANCE_WEIGHTS)
    colour = tuple(float(c) for c in irradiance / strength) if strength > 0.0 else (1.0, 1.0, 1.0)
    _last_sun_values[scene.name] = (sun_key, irradiance, colour, strength)
    return irradiance, colour, strength


def _sun_dependence(atmosphere: Atmosphere) -> tuple:
    """What E_sun depends on, hashable: the air's extinction and layers, the ozone, the sun above the air (an edit
    of the haze's anisotropy or the ground's albedo keeps the sun's values)."""
    return (atmosphere.rayleigh_scattering.tobytes(), atmosphere.mie_extinction.tobytes(),
            atmosphere.ozone_absorption.tobytes(), np.asarray(atmosphere.sun_irradiance_top).tobytes(),
            atmosphere.rayleigh_scale_height, atmosphere.mie_scale_height, atmosphere.planet_radius,
            atmosphere.atmosphere_height, atmosphere.ozone_column_du)


def _sun_table(scene, dependence: tuple, atmosphere: Atmosphere, sun_radius: float, limb_darkening: float):
    """:func:`sun_irradiance_table` of the scene's atmosphere and sun, cached on ``dependence``
    (:func:`_sun_dependence`) and the sun's disk."""
    table_key = (dependence, sun_radius, limb_darkening)
    cached = _last_sun_table.get(scene.name)
    if cached is not None and cached[0] == table_key:
        return cached[1]
    table = sun_irradiance_table(atmosphere, sun_radius, limb_darkening)
    _last_sun_table[scene.name] = (table_key, table)
    return table


def sync_scene(scene) -> None:
    """Write the values the built nodes of ``scene`` read, from its settings and sun lamp (module docstring).

    E_sun at the ground follows the sun's elevation through the transmittance of the whole air column
    (:func:`sun_irradiance_ground`); the shader multiplies its unit-sun in-scattering by it. With the effect on and
    a sun lamp, the sun's direction and E_sun (and the lamp's colour and strength) are drivers on the lamp
    (:mod:`.apply.sun_drivers`): a sun move then writes nothing that tags the scene, and the values shown in the
    panel are written without a tag (:func:`_show_sunlight`).
    """
    settings = scene.atmos
    atmosphere = scene_reading.atmosphere_of(scene)
    lamp = scene_reading.sun_object(scene)
    direction, sun_status = scene_reading.direction_of(lamp, scene)
    elevation_rad = math.asin(float(np.clip(direction[2], -1.0, 1.0)))
    diameter = float(settings.sun_angular_diameter)
    sun_radius = 0.5 * diameter
    limb_darkening = float(settings.sun_limb_darkening)
    enabled = settings.enabled
    driven = enabled and lamp is not None
    dependence = _sun_dependence(atmosphere)
    table = _sun_table(scene, dependence, atmosphere, sun_radius, limb_darkening) if driven else None
    irradiance, colour, strength = _sun_values(scene, dependence, atmosphere, elevation_rad, sun_radius,
                                               limb_darkening, table)
    if enabled and settings.sky_enabled:
        world.write_sky_lighting_table(scene, atmosphere)
    parameters = scene_reading.groups().parameters
    parameters.write_shader_parameters(
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
        skip=parameters.SUN_PARAMETER_NAMES if driven else (),
    )
    if driven:
        sun_drivers.install(scene, lamp, table, drive_light=settings.drive_sun_lamp)
    else:
        sun_drivers.remove(scene)
    if settings.status_sun != sun_status:
        settings["status_sun"] = sun_status   # shown, not a setting: no tag (see _show_sunlight)
    if enabled and in_render.is_installed(scene):
        in_render.sync_domes(scene, atmosphere, scene_reading.metres_per_unit(scene))
    _show_sunlight(scene, lamp, (colour, strength, diameter), enabled=enabled, driven=driven)
    _driven_values[scene.name] = (tuple(float(v) for v in direction), irradiance, colour, strength) if driven else None
    _last_sun_matrix[scene.name] = lamp_matrix_key(lamp, scene)
    note_camera(scene)


def _show_sunlight(scene, lamp, values, *, enabled: bool, driven: bool) -> None:
    """Show E_sun's colour and strength (``values``: colour, strength, angle) in the settings and, with
    ``drive_sun_lamp``, on the lamp (changes only; with ``driven``, the lamp's colour and strength are its drivers'
    and only its angle is written).

    The two display settings are written as the settings' ID properties, which skips the property update: an
    update would tag the scene, and a tagged scene re-evaluates every object (on every sun move). The panel reads
    them when it next draws."""
    settings = scene.atmos
    colour, strength, angle = values
    if sun_lamp.differs(tuple(settings.sun_colour_display), colour):
        settings["sun_colour_display"] = colour
    if sun_lamp.differs(settings.sun_strength_display, strength):
        settings["sun_strength_display"] = strength
    if lamp is not None and enabled and settings.drive_sun_lamp:
        sun_lamp.drive_lamp(scene, lamp, colour, strength, angle, driven=driven)
    elif enabled and not settings.drive_sun_lamp:
        sun_lamp.release_lamp(scene)   # the lamp's own light back


def show_driven_values(scene) -> None:
    """Write what the sun's drivers (:mod:`.apply.sun_drivers`) evaluate to after the last :func:`sync_scene`: the
    sun's direction and E_sun parameters and, with Drive Sun Lamp, the lamp's colour and strength. For a script that
    reads them before anything evaluates the scene (the next evaluation writes the same values over them); the
    interface evaluates before every redraw and needs none of this."""
    values = _driven_values.get(scene.name)
    lamp = scene_reading.sun_object(scene)
    if values is None or lamp is None:
        return
    direction, irradiance, colour, strength = values
    parameters = scene_reading.groups().parameters
    parameters.store_if_changed(scene, parameters.SUN_DIRECTION, direction)
    parameters.store_if_changed(scene, parameters.SUN_IRRADIANCE, tuple(float(v) for v in np.atleast_1d(irradiance)))
    if scene.atmos.drive_sun_lamp:
        for name, value in (("color", tuple(float(v) for v in colour)), ("energy", float(strength))):
            if sun_lamp.differs(getattr(lamp.data, name), value):
                setattr(lamp.data, name, value)


def lamp_matrix_key(lamp, scene) -> tuple:
    """The sun lamp's name and world matrix, to tell whether it moved since the last sync."""
    if lamp is None:
        return ()
    return (lamp.name, *(tuple(row) for row in scene_reading.world_matrix(lamp, scene)))


def sun_moved(scene) -> bool:
    """True when the sun lamp moved (or another lamp took over) since the last :func:`sync_scene`."""
    return lamp_matrix_key(scene_reading.sun_object(scene), scene) != _last_sun_matrix.get(scene.name)


def _camera_z(scene) -> float | None:
    """The scene camera's world z (the Precise tables depend on its altitude), None without a camera."""
    return None if scene.camera is None else round(float(scene_reading.world_matrix(scene.camera, scene).translation.z),
                                                   6)


def note_camera(scene) -> bool:
    """Record the camera's z; True when it changed since the last call."""
    camera_z = _camera_z(scene)
    changed = camera_z != _last_camera_z.get(scene.name, camera_z)
    _last_camera_z[scene.name] = camera_z
    return changed


def forget(scene_name: str | None = None) -> None:
    """Drop the cached sync state (all scenes when ``scene_name`` is None)."""
    scene_reading.forget(scene_name)
    for cache in (_last_sun_matrix, _last_sun_values, _last_sun_table, _last_camera_z):
        if scene_name is None:
            cache.clear()
        else:
            cache.pop(scene_name, None)

