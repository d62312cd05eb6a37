# SPDX-License-Identifier: GPL-3.0-or-later
"""Scene settings -> shader parameter values, and the handlers that keep them current.

Syncing writes values only (scene custom properties read by the shader); it never rebuilds a
node tree unless the feature set changed, so it is cheap enough for every ``update=`` callback
and for a depsgraph handler that follows the sun lamp.
"""

from __future__ import annotations

import math

import bpy
import numpy as np
from bpy.app.handlers import persistent
from mathutils import Vector

from .. import import_sibling
from . import facts, group_integrity, materials, world
from ..physics import Atmosphere, sun_irradiance_ground
from ..physics.balanced import sun_optical_depths_ground
from ..physics.sun import LUMINANCE_WEIGHTS
from .settings_io import FIELD_MAP, atmosphere_from_settings  # noqa: F401  (re-exported for callers of sync)

#: Used when the scene has no sun lamp: 45 degrees above the horizon, towards +Y (north in Blender's convention).
DEFAULT_SUN_DIRECTION = (0.0, math.sqrt(0.5), math.sqrt(0.5))

#: Last synced state per scene (a cache only; nothing here is needed to restore a file).
_last_sun_matrix: dict[str, tuple] = {}
_last_counts: dict[str, tuple[int, int]] = {}
#: Per scene: (settings values, Atmosphere) and ((settings values, elevation, sun radius), E_sun, colour, strength).
#: A slider that moves neither the atmosphere nor the sun (distance scale, albedo) skips the physics.
_last_atmosphere: dict[str, tuple] = {}
_last_sun_values: dict[str, tuple] = {}
_last_camera_z: dict[str, float | None] = {}


def node_groups():
    """The extension's ``node_groups`` package (imported on first use)."""
    return import_sibling("node_groups")


def features_from_settings(settings):
    """The aerial node groups' feature set for the settings' scene: its plan's terms and level
    (:func:`.facts.plan_of`)."""
    plan = facts.plan_of(settings.id_data)
    return node_groups().aerial_perspective.AerialFeatures(mie=plan.mie, absorption=plan.absorption,
                                                          level=plan.level)


def sun_object(scene):
    """The sun lamp that drives the atmosphere: ``scene.atmos.sun_object``, else the first sun lamp in the scene."""
    chosen = scene.atmos.sun_object
    if chosen is not None and chosen.type == "LIGHT" and chosen.data.type == "SUN":
        return chosen
    for obj in scene.objects:
        if obj.type == "LIGHT" and obj.data.type == "SUN":
            return obj
    return None


def sun_direction(scene) -> tuple[np.ndarray, str]:
    """Unit direction TO the sun in world space, and a sentence saying where it came from.

    A sun lamp shines along its local -Z axis, so the direction towards the sun is its local +Z
    axis in world space.
    """
    return _direction_of(sun_object(scene))


def _direction_of(lamp) -> tuple[np.ndarray, str]:
    if lamp is None:
        return np.array(DEFAULT_SUN_DIRECTION), "No sun lamp: using the default sun 45 degrees above the horizon"
    axis = lamp.matrix_world.to_3x3() @ Vector((0.0, 0.0, 1.0))
    if axis.length == 0.0:
        return np.array(DEFAULT_SUN_DIRECTION), f"Sun lamp '{lamp.name}' has zero scale: using the default sun"
    axis.normalize()
    elevation = math.degrees(math.asin(max(-1.0, min(1.0, axis.z))))
    return np.array(axis), f"Sun: '{lamp.name}', {elevation:.1f} degrees above the horizon"


def metres_per_unit(scene) -> float:
    """Metres per Blender unit as the atmosphere sees them (unit scale times the distance scale)."""
    return float(scene.unit_settings.scale_length) * float(scene.atmos.distance_scale)


def _set_if_changed(settings, name: str, value: str) -> None:
    if getattr(settings, name) != value:
        setattr(settings, name, value)


def ensure_group(scene):
    """Get or (re)build the group the scene's materials use, for its feature set and mode: the aerial
    perspective group (Compositor mode) or the "Atmos In-Render Surface" group (In-Render mode). In the Per Pixel
    mode the compositor group evaluates the atmosphere and the materials need no shader group: the aerial group is
    returned only when another enabled scene's Compositor mode uses it (None otherwise), so none is built for nothing
    (at Balanced it is a thousand nodes)."""
    aerial = node_groups().aerial_perspective
    plan = facts.plan_of(scene)
    features = aerial.AerialFeatures(mie=plan.mie, absorption=plan.absorption, level=plan.level)
    mode = plan.mode
    if mode == "IN_RENDER":
        group = node_groups().in_render.ensure_surface_group(features)
    elif mode == "COMPOSITOR":
        group = aerial.ensure_aerial_perspective_group(features)
    else:
        group = bpy.data.node_groups.get(aerial.GROUP_NAME)
        if group is None and "COMPOSITOR" in plan.surface_modes:
            group = aerial.ensure_aerial_perspective_group(features)
    built = aerial.describe_features(features)
    if mode == "PER_PIXEL":
        from . import compositor

        per_pixel = compositor.ensure_per_pixel_group(features)
        built = f"{built.split(':')[0]}, per pixel: {len(per_pixel.nodes)} compositor nodes"
    _set_if_changed(scene.atmos, "status_built", built)
    return group


def _atmosphere(scene, settings) -> tuple[tuple, Atmosphere]:
    """The settings' values (each read once) and their :class:`Atmosphere`, reused while the values are unchanged."""
    raw = tuple(getattr(settings, prop) for prop, _, _ in FIELD_MAP)
    key = tuple(value if isinstance(value, float) else tuple(value) for value in raw)
    cached = _last_atmosphere.get(scene.name)
    if cached is not None and cached[0] == key:
        return key, cached[1]
    values = {}
    for (_, field, factor), value in zip(FIELD_MAP, key):
        array = np.asarray(value, dtype=float) / factor
        values[field] = array if array.ndim else float(array)
    atmosphere = Atmosphere(**values)
    _last_atmosphere[scene.name] = (key, atmosphere)
    return key, atmosphere


def _sun_values(scene, key: tuple, atmosphere: Atmosphere, elevation_rad: float, sun_radius: float,
                limb_darkening: float):
    """E_sun at the ground, the lamp's colour and strength (as :func:`sun_color_and_strength` splits it) and the
    sun's ground optical depths (tau_R, tau_M) of the Balanced level, cached."""
    sun_key = (key, elevation_rad, sun_radius, limb_darkening)
    cached = _last_sun_values.get(scene.name)
    if cached is not None and cached[0] == sun_key:
        return cached[1:]
    irradiance = np.asarray(sun_irradiance_ground(elevation_rad, atmosphere, 0.0, sun_radius, limb_darkening),
                            dtype=float)
    strength = float(irradiance @ LUMINANCE_WEIGHTS)
    colour = tuple(float(c) for c in irradiance / strength) if strength > 0.0 else (1.0, 1.0, 1.0)
    depths = sun_optical_depths_ground(elevation_rad, atmosphere)
    _last_sun_values[scene.name] = (sun_key, irradiance, colour, strength, depths)
    return irradiance, colour, strength, depths


def atmosphere_of(scene) -> Atmosphere:
    """The physics :class:`Atmosphere` of the scene's settings (cached while they are unchanged)."""
    return _atmosphere(scene, scene.atmos)[1]


def sync_scene(scene) -> None:
    """Write the shader parameters of ``scene`` from its settings and sun lamp (values only).

    E_sun at the ground follows the sun's elevation through the transmittance of the whole air
    column (:func:`sun_irradiance_ground`); the shader multiplies its unit-sun in-scattering by it.
    It is computed once per change of the atmosphere or the sun (a cache on their values), so a slider
    that changes neither costs only the writes.
    """
    settings = scene.atmos
    key, atmosphere = _atmosphere(scene, settings)
    lamp = sun_object(scene)
    direction, sun_status = _direction_of(lamp)
    elevation_rad = math.asin(float(np.clip(direction[2], -1.0, 1.0)))
    diameter = float(settings.sun_angular_diameter)
    sun_radius = 0.5 * diameter
    irradiance, colour, strength, sun_depths = _sun_values(scene, key, atmosphere, elevation_rad, sun_radius,
                                                           float(settings.sun_limb_darkening))
    enabled = settings.enabled
    if enabled:
        ensure_group(scene)  # cheap when current; rebuilds in place when the feature set changed
        if settings.sky_enabled:
            ensure_sky_group(scene)
            world.sync_sky_lighting(scene, atmosphere, sky_features_from_settings(settings))
        group_integrity.stamp_new()  # cheap when every group is stamped
    node_groups().parameters.write_shader_parameters(
        scene,
        beta_rayleigh=atmosphere.rayleigh_scattering,
        beta_mie=atmosphere.mie_scattering,
        beta_mie_absorption=atmosphere.mie_absorption,
        mie_g=atmosphere.mie_g,
        sun_direction=direction,
        sun_irradiance=irradiance,
        metres_per_unit=float(scene.unit_settings.scale_length) * float(settings.distance_scale),
        planet_radius=atmosphere.planet_radius,
        rayleigh_scale_height=atmosphere.rayleigh_scale_height,
        mie_scale_height=atmosphere.mie_scale_height,
        sun_angular_radius=sun_radius,
        sun_limb_darkening=settings.sun_limb_darkening,
        ground_albedo=tuple(settings.ground_albedo),
        origin_altitude=float(settings.origin_altitude),
        sun_optical_depth_rayleigh=sun_depths[0],
        sun_optical_depth_mie=sun_depths[1],
    )
    _set_if_changed(settings, "status_sun", sun_status)
    from . import in_render

    if enabled and in_render.is_installed(scene):
        node_groups().in_render.ensure_sky_group(features_from_settings(settings))
        in_render.sync_domes(scene, atmosphere, metres_per_unit(scene))
    _sync_sun_lamp(scene, lamp, elevation_rad, (colour, strength, diameter), enabled=enabled)
    _last_sun_matrix[scene.name] = _matrix_key(lamp)
    _note_camera(scene)
    from . import precise_tables

    if enabled and precise_tables.uses_precise(scene):
        precise_tables.follow(scene)
    elif node_groups().parameters.PRECISE_TILE in scene:   # left the Precise level: drop its tables
        precise_tables.remove(scene)
        for name in node_groups().parameters.PRECISE_PARAMETER_NAMES:
            del scene[name]
    if enabled:
        from . import sun_lamp

        sun_lamp.follow(scene)   # an animated sun's keys: re-baked when the settings or its animation changed


def _camera_z(scene) -> float | None:
    """The scene camera's world z (the Precise tables depend on its altitude), None without a camera."""
    return None if scene.camera is None else round(float(scene.camera.matrix_world.translation.z), 6)


def _note_camera(scene) -> bool:
    """Record the camera's z; True when it changed since the last call. A change also clears the "invalid" flag
    of the Per Pixel group node's drivers: a camera driver that failed while the scene had no camera reads again
    (:func:`.compositor.revalidate_drivers`)."""
    camera_z = _camera_z(scene)
    changed = camera_z != _last_camera_z.get(scene.name, camera_z)
    _last_camera_z[scene.name] = camera_z
    if changed:
        from . import compositor

        compositor.revalidate_drivers(scene)
    return changed


def sky_features_from_settings(settings):
    """The sky group's feature set: the plan's terms, ground and sky level (the Precise table's sky at the Precise
    level, the virtual dome otherwise)."""
    plan = facts.plan_of(settings.id_data)
    return node_groups().sky.SkyFeatures(mie=plan.mie, absorption=plan.absorption, ground=plan.sky_ground,
                                         level=plan.sky_level)


def ensure_sky_group(scene):
    """Get or (re)build the "Atmos Sky" world group for the scene's feature set."""
    return node_groups().sky.ensure_sky_group(sky_features_from_settings(scene.atmos))


def _sync_sun_lamp(scene, lamp, elevation_rad: float, values=None, *, enabled: bool | None = None) -> None:
    """Show E_sun's colour and strength in the settings and, with ``drive_sun_lamp``, on the lamp (changes only).

    ``values`` is (colour, strength, angle) when the caller has them; otherwise they are computed.
    """
    from . import sun_lamp

    settings = scene.atmos
    colour, strength, angle = values if values is not None else sun_lamp.lamp_values(scene, elevation_rad)
    if sun_lamp._differs(tuple(settings.sun_colour_display), colour):
        settings.sun_colour_display = colour
    if sun_lamp._differs(settings.sun_strength_display, strength):
        settings.sun_strength_display = strength
    if enabled is None:
        enabled = settings.enabled
    if lamp is not None and enabled and settings.drive_sun_lamp:
        sun_lamp.drive_lamp(scene, lamp, colour, strength, angle)


def _matrix_key(lamp) -> tuple:
    if lamp is None:
        return ()
    return (lamp.name, *(tuple(row) for row in lamp.matrix_world))


def forget(scene_name: str | None = None) -> None:
    """Drop the cached sync state (all scenes when ``scene_name`` is None)."""
    if scene_name is None:
        _last_sun_matrix.clear()
        _last_counts.clear()
        _last_atmosphere.clear()
        _last_sun_values.clear()
        _last_camera_z.clear()
    else:
        for cache in (_last_sun_matrix, _last_counts, _last_atmosphere, _last_sun_values, _last_camera_z):
            cache.pop(scene_name, None)


@persistent
def on_depsgraph_update(scene, depsgraph) -> None:
    """Follow the sun lamp and pick up new materials in scenes with the effect on (cheap checks first)."""
    group_integrity.on_depsgraph_update(scene, depsgraph)  # drops the panel's cached edit check (one flag query)
    settings = getattr(scene, "atmos", None)
    if settings is None or not settings.enabled:
        return
    from . import effect

    if effect.mode_mismatch(scene):  # the render engine or the mode changed: switch Compositor <-> In-Render
        effect.enable_effect(scene)
        return
    if _matrix_key(sun_object(scene)) != _last_sun_matrix.get(scene.name):
        sync_scene(scene)
    elif _note_camera(scene):   # the Precise tables follow the camera
        from . import precise_tables

        precise_tables.follow(scene)
    elif any(depsgraph.id_type_updated(kind) for kind in ("ACTION", "OBJECT", "SCENE")):
        from . import sun_lamp

        sun_lamp.follow(scene)   # keys edited at other frames, a parent or a target moved, the frame range changed
    if depsgraph.id_type_updated("MATERIAL"):
        materials.follow_edits(depsgraph)   # a surface Cycles folds away stays opaque
    counts = (len(bpy.data.materials), len(scene.objects))
    if _last_counts.get(scene.name) != counts:
        _last_counts[scene.name] = counts
        effect.pick_up_new_materials(scene)
        group_integrity.stamp_new()


def _resync_all() -> None:
    """Drop every cache and re-sync every scene with the effect on (stale node groups are rebuilt)."""
    forget()
    group_integrity.invalidate()
    for scene in bpy.data.scenes:
        settings = getattr(scene, "atmos", None)
        if settings is not None and settings.enabled:
            sync_scene(scene)
            _last_counts[scene.name] = (len(bpy.data.materials), len(scene.objects))


@persistent
def on_load_post(*_args) -> None:
    """After a file loads: rebuild stale node groups and re-sync every scene with the effect on; subscribe to the
    render settings again (loading a file clears the message bus)."""
    _resync_all()
    _subscribe()


@persistent
def on_undo_redo(*_args) -> None:
    """After an undo or redo step, which restores the file's data from memory (memfile undo).

    - Our caches describe the state undone from: they are dropped and every enabled scene re-synced. A step can
      hold parameters older than its lamp (in the UI a transform pushes its step before the depsgraph handler
      writes the sun's parameters), which the sun-matrix cache would otherwise take as current.
    - Blender keeps image buffers across undo, so the Precise table would keep the pixels of the state undone from
      while its packed data and bake key are restored: its buffer is freed (read again from the packed data)
      before the re-sync compares bake keys.
    """
    from . import precise_tables

    precise_tables.free_buffers()
    _resync_all()


#: The owner of Atmos' message-bus subscriptions (cleared on unregister, made again after a file loads).
_MSGBUS_OWNER = object()


def follow_render_settings(*_args) -> None:
    """Switch every enabled scene whose render settings now call for another mode (the engine changed, Cycles'
    Open Shading Language toggled: :func:`atmos_addon.plan.mode_for`). The message bus calls this when the user
    changes those settings in the interface; Cycles' settings do not tag the depsgraph, so the depsgraph handler
    would see the change only at the next edit."""
    from . import effect

    for scene in bpy.data.scenes:
        if getattr(scene, "atmos", None) is not None and effect.mode_mismatch(scene):
            effect.enable_effect(scene)


def _subscribe() -> None:
    bpy.msgbus.clear_by_owner(_MSGBUS_OWNER)
    keys = [(bpy.types.RenderSettings, "engine")]
    cycles = getattr(bpy.types, "CyclesRenderSettings", None)
    if cycles is not None:
        keys.append((cycles, "shading_system"))
    for key in keys:
        bpy.msgbus.subscribe_rna(key=key, owner=_MSGBUS_OWNER, args=(), notify=follow_render_settings)


HANDLERS = (
    (bpy.app.handlers.depsgraph_update_post, on_depsgraph_update),
    (bpy.app.handlers.load_post, on_load_post),
    (bpy.app.handlers.undo_post, on_undo_redo),
    (bpy.app.handlers.redo_post, on_undo_redo),
)


def add_handlers() -> None:
    for handler_list, function in HANDLERS:
        if function not in handler_list:
            handler_list.append(function)
    _subscribe()


def remove_handlers() -> None:
    """Remove our handlers, also copies left by an earlier import of this module (add-on reload)."""
    for handler_list, function in HANDLERS:
        for registered in list(handler_list):
            if registered is function or (
                getattr(registered, "__module__", None) == function.__module__
                and getattr(registered, "__qualname__", None) == function.__qualname__
            ):
                handler_list.remove(registered)
    bpy.msgbus.clear_by_owner(_MSGBUS_OWNER)
    forget()
