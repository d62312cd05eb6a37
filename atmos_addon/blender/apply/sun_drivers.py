# SPDX-License-Identifier: GPL-3.0-or-later
"""The sun's shader parameters and the sun lamp's colour and strength, driven by the lamp object: a sun move is
evaluated by Blender's depsgraph, with no Python and no tag on the scene.

Why drivers
    A value Python writes into the scene tags it, and a tagged scene re-evaluates every object: 0.4-0.5 s a sun move
    with 20000 objects, against 60-80 ms for Blender alone (the scene of ``tools/bench_scale.py``, the median
    ``view_layer.update()`` after the write). Drivers on the scene's custom properties, reading the lamp's matrix,
    cost a sun move nothing more (83 ms against 80 ms, measured in that scene). They also follow an animated sun on
    every frame and sub-frame on a farm without the add-on.

What is driven (all simple expressions, which Blender evaluates without Python, so a file opened with scripts
disabled renders the same)
    * ``atmos_sun_direction[i]`` = the lamp's world +Z axis (toward the sun), normalised:
      ``x / sqrt(x*x + y*y + z*z)`` with x, y, z = ``matrix_world[2][0..2]`` (the matrix's third column; RNA paths
      index the stored columns).
    * ``atmos_sun_irradiance[i]`` = E_sun at the ground for the lamp's elevation: the driver's value is
      :data:`SINE_SCALE` times the sine of the elevation, and its F-curve holds :func:`~atmos_addon.physics.sun.
      sun_irradiance_table` (LINEAR keys, CONSTANT beyond the ends: 0 once the disk has set). The scale keeps the
      keys, dense at the horizon, further apart than the 0.01 under which Blender merges keys.
    * With ``drive_sun_lamp``, the light's ``energy`` = luminance of E_sun and ``color[i]`` = E_sun / luminance
      (white when the sun has set), read from the scene's E_sun (:mod:`.sun_lamp`'s split).

Ownership: the scene custom property :data:`STATE_KEY` records the lamp, the light data driven and a digest of
the table, so an unchanged table is not rewritten and :func:`remove` deletes exactly these drivers (the lamp's own
values are put back by :func:`.sun_lamp.remove`).
"""

from __future__ import annotations

import hashlib

import bpy
import numpy as np

from .. import drivers, scene_reading

#: Scene custom property: {"lamp": object name, "light": light data name or "", "table": digest}.
STATE_KEY = "atmos_sun_drivers"
#: The E_sun drivers' value is this times the sine of the sun's elevation (the F-curve's x axis).
SINE_SCALE = 100000.0
#: Rec. 709 luminance weights, as :data:`atmos_addon.physics.sun.LUMINANCE_WEIGHTS` (the lamp's strength).
_LUMINANCE = "0.2126*r+0.7152*g+0.0722*b"
_AXIS = "xyz"


def _lamp_axis(driver, lamp) -> None:
    """Variables x, y, z: the lamp's world +Z axis (the third stored column of ``matrix_world``)."""
    for index, name in enumerate(_AXIS):
        drivers.add_variable(driver, "OBJECT", lamp, f"matrix_world[2][{index}]", name)


def _scene_irradiance(driver, scene, parameter: str) -> None:
    """Variables r, g, b: the scene's E_sun per channel."""
    for index, name in enumerate("rgb"):
        drivers.add_variable(driver, "SCENE", scene, f'["{parameter}"][{index}]', name)


def digest(table: tuple[np.ndarray, np.ndarray]) -> str:
    """A digest of an E_sun table's values (what the keys hold)."""
    sines, irradiance = table
    return hashlib.sha1(np.concatenate([np.asarray(sines, np.float32).ravel(),
                                        np.asarray(irradiance, np.float32).ravel()]).tobytes()).hexdigest()


def _write_table(curve, sines: np.ndarray, values: np.ndarray) -> None:
    """The F-curve's keys: (SINE_SCALE sine, value), LINEAR, constant beyond the ends. Keys already there at the same
    sines get their values only (an edit of the atmosphere; LINEAR keys ignore their handles)."""
    points = curve.keyframe_points
    coordinates = np.column_stack([SINE_SCALE * np.asarray(sines, np.float64), values]).astype(np.float32).ravel()
    if len(points) == len(sines):
        current = np.empty(2 * len(points), np.float32)
        points.foreach_get("co", current)
        if np.array_equal(current[0::2], coordinates[0::2]):
            points.foreach_set("co", coordinates)
            return
    points.clear()
    points.add(len(sines))
    for name in ("co", "handle_left", "handle_right"):
        points.foreach_set(name, coordinates)
    linear = bpy.types.Keyframe.bl_rna.properties["interpolation"].enum_items["LINEAR"].value
    points.foreach_set("interpolation", np.full(len(sines), linear, dtype=np.int32))
    curve.extrapolation = "CONSTANT"


def state(scene) -> dict | None:
    """The recorded drivers (:data:`STATE_KEY`) of ``scene``, or None."""
    recorded = scene.get(STATE_KEY)
    return None if recorded is None else recorded.to_dict()


def install(scene, lamp, table: tuple[np.ndarray, np.ndarray], *, drive_light: bool) -> bool:
    """Drive ``scene``'s sun direction and E_sun from ``lamp`` (and, with ``drive_light``, the lamp's colour and
    strength from E_sun), the E_sun keys from ``table`` (:func:`~atmos_addon.physics.sun.sun_irradiance_table`).

    The two parameters must exist (written once by the sync). A light whose colour or strength a rig already drives
    (drivers Atmos did not write) keeps them: its colour and strength are left to the rig. Idempotent: drivers
    already on this lamp with this table are left alone; True when anything was (re)written."""
    parameters = scene_reading.groups().parameters
    recorded = state(scene)
    light = lamp.data if drive_light and not _driven_by_user(lamp.data, recorded) else None
    table_digest = digest(table)
    wanted = {"lamp": lamp.name, "light": light.name if light is not None else "", "table": table_digest}
    if recorded == wanted and _present(scene, lamp, light):
        return False
    rebuild = recorded is None or recorded.get("lamp") != wanted["lamp"] or not _present(scene, lamp, None)
    if recorded is not None and recorded.get("light") and recorded.get("light") != wanted["light"]:
        _remove_light_drivers(bpy.data.lights.get(recorded["light"]))
    sines, irradiance = table
    for index in range(3):
        if rebuild:
            curve = drivers.fresh(scene, f'["{parameters.SUN_DIRECTION}"]', index,
                                f"{_AXIS[index]}/sqrt(x*x+y*y+z*z)")
            _lamp_axis(curve.driver, lamp)
            curve = drivers.fresh(scene, f'["{parameters.SUN_IRRADIANCE}"]', index,
                                f"{SINE_SCALE:.0f}*z/sqrt(x*x+y*y+z*z)")
            _lamp_axis(curve.driver, lamp)
        else:
            curve = scene.animation_data.drivers.find(f'["{parameters.SUN_IRRADIANCE}"]', index=index)
        if rebuild or recorded.get("table") != table_digest:
            _write_table(curve, sines, irradiance[:, index])
    if light is not None and (rebuild or recorded.get("light") != light.name or not _present(scene, lamp, light)):
        for index in range(3):
            curve = drivers.fresh(light, "color", index,
                                f"{'rgb'[index]}/({_LUMINANCE}) if r+g+b > 0 else 1.0")
            _scene_irradiance(curve.driver, scene, parameters.SUN_IRRADIANCE)
        curve = drivers.fresh(light, "energy", None, _LUMINANCE)
        _scene_irradiance(curve.driver, scene, parameters.SUN_IRRADIANCE)
    elif light is None and recorded is not None and recorded.get("light"):
        _remove_light_drivers(bpy.data.lights.get(recorded["light"]))
    scene[STATE_KEY] = wanted
    return True


def _driven_by_user(light, recorded: dict | None) -> bool:
    """True when ``light``'s colour or strength has drivers that Atmos did not write (a rig's)."""
    if recorded is not None and recorded.get("light") == light.name:
        return False
    drivers = light.animation_data.drivers if light.animation_data is not None else ()
    return any(curve.data_path in ("color", "energy") for curve in drivers)


def _present(scene, lamp, light) -> bool:
    """True when every driver :func:`install` writes is there, on ``lamp`` (a user may delete one by hand)."""
    parameters = scene_reading.groups().parameters
    animation = scene.animation_data
    if animation is None:
        return False
    for name in (parameters.SUN_DIRECTION, parameters.SUN_IRRADIANCE):
        for index in range(3):
            curve = animation.drivers.find(f'["{name}"]', index=index)
            if curve is None or len(curve.driver.variables) != 3 or curve.driver.variables[0].targets[0].id != lamp:
                return False
    if light is not None:
        drivers = light.animation_data.drivers if light.animation_data is not None else ()
        found = {(curve.data_path, curve.array_index) for curve in drivers}
        return {("color", 0), ("color", 1), ("color", 2), ("energy", 0)} <= found
    return True


def _remove_light_drivers(light) -> None:
    if light is None or light.animation_data is None:
        return
    for path, indices in (("color", (0, 1, 2)), ("energy", (None,))):
        for index in indices:
            if index is None:
                light.driver_remove(path)
            else:
                light.driver_remove(path, index)


def remove(scene) -> None:
    """Remove the drivers :func:`install` wrote (the parameters keep their last values; the sync writes them from
    then on)."""
    recorded = state(scene)
    if recorded is None:
        return
    parameters = scene_reading.groups().parameters
    for name in (parameters.SUN_DIRECTION, parameters.SUN_IRRADIANCE):
        if name in scene:
            for index in range(3):
                scene.driver_remove(f'["{name}"]', index)
    if recorded.get("light"):
        _remove_light_drivers(bpy.data.lights.get(recorded["light"]))
    del scene[STATE_KEY]
