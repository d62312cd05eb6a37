# SPDX-License-Identifier: GPL-3.0-or-later
"""The sun lamp: the source of truth for the sun's direction, and the light that E_sun drives.

Direction to the sun for elevation e and azimuth A (clockwise from +Y, north, toward +X, east):

    d = (cos e sin A, cos e cos A, sin e),    lamp rotation_euler = (pi/2 - e, 0, pi - A)

(a sun lamp shines along its local -Z, so its local +Z is d). The lamp's colour and strength are the
ground irradiance E_sun (:func:`~atmos_addon.physics.sun.sun_color_and_strength`): strength = luminance of
E_sun in W/m^2, colour = E_sun / strength, so colour x strength == E_sun, the E_sun the sky and the haze
use; its angle is the sun's angular diameter. With the effect on, the colour and strength are drivers that
follow the lamp's elevation (:mod:`.sun_drivers`), on every frame of an animated sun.
"""

from __future__ import annotations

import math

import bpy
import numpy as np
from mathutils import Euler, Matrix

from ...plan import Plan
from .. import scene_reading

#: Name of the lamp :func:`ensure_sun_lamp` creates when the scene has none.
CREATED_SUN_NAME = "Atmos Sun"
#: Scene custom property: what enabling changed on the lamp, so disabling restores it (survives save/reload).
LAMP_STATE_KEY = "atmos_sun_lamp"
#: Light data paths the lamp drive writes (and a sun bake keys).
LAMP_PATHS = ("color", "energy")
#: Relative change below which lamp values are not rewritten (each write re-tags the depsgraph).
WRITE_TOLERANCE = 1.0e-6


def ensure_sun_lamp(scene: bpy.types.Scene) -> tuple[bpy.types.Object, str]:
    """The scene's sun lamp (``atmos.sun_object``, else the first sun lamp that renders), created if there is none.

    Returns the lamp and a sentence for the report. A created lamp is named "Atmos Sun", linked to the
    scene's master collection, points 45 degrees up toward north, and is remembered so disabling removes it.
    """
    lamp = scene_reading.sun_object(scene)
    if lamp is not None:
        return lamp, f"Sun lamp: '{lamp.name}'"
    data = bpy.data.lights.new(CREATED_SUN_NAME, "SUN")
    lamp = bpy.data.objects.new(CREATED_SUN_NAME, data)
    scene.collection.objects.link(lamp)
    _rotate(lamp, math.radians(45.0), 0.0)
    state = dict(scene.get(LAMP_STATE_KEY, {}))
    state["created"] = lamp.name
    scene[LAMP_STATE_KEY] = state
    return lamp, f"No sun lamp in the scene: created '{lamp.name}' (45 degrees up, toward north)"


def install(scene: bpy.types.Scene, plan: Plan) -> str | None:
    """The sun lamp ``plan`` drives (:func:`ensure_sun_lamp`: created where the scene has none); the report's
    sentence, None where the plan drives no lamp."""
    if not plan.sun_lamp:
        return None
    _, message = ensure_sun_lamp(scene)
    return message


def angles_from_direction(direction) -> tuple[float, float]:
    """(elevation in [-pi/2, pi/2], azimuth in [0, 2 pi)) of a direction, rad."""
    x, y, z = (float(v) for v in direction)
    elevation = math.atan2(z, math.hypot(x, y))
    azimuth = math.atan2(x, y) % (2.0 * math.pi) if math.hypot(x, y) > 1e-12 else 0.0
    if azimuth > 2.0 * math.pi - 1e-6:  # float32 rotations land just below 2 pi for a sun due north
        azimuth = 0.0
    return elevation, azimuth


def _rotate(lamp: bpy.types.Object, elevation_rad: float, azimuth_rad: float) -> None:
    """Point ``lamp``'s +Z (world space) at the sun, keeping its world location and scale."""
    euler = Euler((0.5 * math.pi - elevation_rad, 0.0, math.pi - azimuth_rad), "XYZ")
    location, _, scale = lamp.matrix_world.decompose()
    lamp.matrix_world = Matrix.LocRotScale(location, euler.to_quaternion(), scale)
    if lamp.parent is None and lamp.rotation_mode == "XYZ":
        lamp.rotation_euler = euler  # the exact angles, not an equivalent decomposition


def set_sun_angles(scene: bpy.types.Scene, elevation_rad: float, azimuth_rad: float) -> bpy.types.Object:
    """Rotate the scene's sun lamp (created if missing) to ``elevation_rad``, ``azimuth_rad``; returns the lamp."""
    lamp, _ = ensure_sun_lamp(scene)
    _rotate(lamp, float(elevation_rad), float(azimuth_rad))
    return lamp


def sun_angles(scene: bpy.types.Scene) -> tuple[float, float]:
    """(elevation, azimuth) of the sun in rad, read from the lamp (the default sun when there is none)."""
    direction, _ = scene_reading.sun_direction(scene)
    return angles_from_direction(direction)


def differs(old, new) -> bool:
    """True when ``new`` differs from ``old`` by more than :data:`WRITE_TOLERANCE` (relative) in any component."""
    old, new = np.atleast_1d(np.asarray(old, dtype=float)), np.atleast_1d(np.asarray(new, dtype=float))
    return bool(np.any(np.abs(old - new) > WRITE_TOLERANCE * np.maximum(np.abs(new), 1e-3)))


def drive_lamp(scene: bpy.types.Scene, lamp: bpy.types.Object, colour, strength: float, angle: float, *,
               driven: bool = False) -> bool:
    """Write colour, strength and angle to the lamp's light data where they changed (with ``driven``, the angle
    only: colour and strength are drivers, :mod:`.sun_drivers`); True if anything was written.

    Comparing first keeps the depsgraph handler from feeding itself (every write re-tags the light).
    The first write remembers the lamp's own values in the scene so :func:`remove` can put them back.
    """
    light = lamp.data
    state = dict(scene.get(LAMP_STATE_KEY, {}))
    if state.get("lamp") != lamp.name:
        _put_back(state)   # another lamp picked: the one driven until now gets its own values back
        state.update(lamp=lamp.name, color=tuple(light.color), energy=float(light.energy), angle=float(light.angle))
        scene[LAMP_STATE_KEY] = state
    wrote = False
    for name, value in ((("angle", angle),) if driven else (("color", colour), ("energy", strength),
                                                               ("angle", angle))):
        if differs(getattr(light, name), value):
            setattr(light, name, value)
            wrote = True
    return wrote


def _put_back(state) -> None:
    """Give the lamp ``state`` records (the one Atmos drives) its own colour, strength and angle back; nothing for a
    lamp Atmos created or one that is gone. So a lamp the user replaces with another in the Sun field does not keep
    Atmos's values, after a disable either."""
    name = state.get("lamp")
    lamp = bpy.data.objects.get(name) if name else None
    if lamp is not None and lamp.type == "LIGHT" and lamp.name != state.get("created"):
        lamp.data.color = tuple(state["color"])
        lamp.data.energy = float(state["energy"])
        lamp.data.angle = float(state["angle"])


def release_lamp(scene: bpy.types.Scene) -> None:
    """*Drive Sun Lamp* turned off: the lamp Atmos drove gets its own colour, strength and angle back and is no longer
    recorded (a lamp Atmos created stays recorded, for the disable to remove)."""
    state = scene.get(LAMP_STATE_KEY)
    if state is None or "lamp" not in state:
        return
    state = dict(state)
    _put_back(state)
    for key in ("lamp", "color", "energy", "angle"):
        state.pop(key, None)
    if state:
        scene[LAMP_STATE_KEY] = state
    else:
        del scene[LAMP_STATE_KEY]


def remove(scene: bpy.types.Scene) -> None:
    """Undo what enabling did to the sun lamp: its own colour/strength/angle back, or remove a lamp we created (the
    baked keys are :func:`.sun_bake.clear_baked_keys`')."""
    state = scene.get(LAMP_STATE_KEY)
    if state is None:
        return
    created = state.get("created")
    _put_back(state)
    if created and created in bpy.data.objects:
        obj = bpy.data.objects[created]
        data = obj.data
        bpy.data.objects.remove(obj)
        if data is not None and data.users == 0:
            bpy.data.lights.remove(data)
    del scene[LAMP_STATE_KEY]
