# SPDX-License-Identifier: GPL-3.0-or-later
"""The sun lamp: the source of truth for the sun's direction, and the light that E_sun drives.

Direction to the sun for elevation e and azimuth A (clockwise from +Y, north, toward +X, east):

    d = (cos e sin A, cos e cos A, sin e),    lamp rotation_euler = (pi/2 - e, 0, pi - A)

(a sun lamp shines along its local -Z, so its local +Z is d). The lamp's colour and strength are the
ground irradiance E_sun (:func:`~atmos_addon.physics.sun.sun_color_and_strength`): strength = luminance of
E_sun in W/m^2, colour = E_sun / strength, so colour x strength == E_sun, the E_sun the sky and the haze
use; its angle is the sun's angular diameter. Animated suns are baked to keyframes
(:func:`bake_sun_animation`) so a render without the add-on (a farm) gets every frame right.
"""

from __future__ import annotations

import hashlib
import math

import bpy
import numpy as np
from mathutils import Euler, Matrix

from ..physics import sun_color_and_strength
from . import sync
from .debounce import Debounced

#: Name of the lamp :func:`ensure_sun_lamp` creates when the scene has none.
CREATED_SUN_NAME = "Atmos Sun"
#: Scene custom property: what enabling changed on the lamp, so disabling restores it (survives save/reload).
LAMP_STATE_KEY = "atmos_sun_lamp"
#: Scene custom property: the frame range baked, and the lamp data whose keys the bake wrote.
BAKED_KEY = "atmos_sun_baked"
#: Light data paths the lamp drive writes (and bakes).
LAMP_PATHS = ("color", "energy")
#: Relative change below which lamp values are not rewritten (each write re-tags the depsgraph).
WRITE_TOLERANCE = 1.0e-6


def ensure_sun_lamp(scene: bpy.types.Scene) -> tuple[bpy.types.Object, str]:
    """The scene's sun lamp (``atmos.sun_object``, else the first sun lamp), created if there is none.

    Returns the lamp and a sentence for the report. A created lamp is named "Atmos Sun", linked to the
    scene's master collection, points 45 degrees up toward north, and is remembered so disabling removes it.
    """
    lamp = sync.sun_object(scene)
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


def direction_from_angles(elevation_rad: float, azimuth_rad: float) -> np.ndarray:
    """Unit direction to the sun, (cos e sin A, cos e cos A, sin e), world space (z up, A clockwise from +Y)."""
    return np.array([math.cos(elevation_rad) * math.sin(azimuth_rad),
                     math.cos(elevation_rad) * math.cos(azimuth_rad), math.sin(elevation_rad)])


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
    direction, _ = sync.sun_direction(scene)
    return angles_from_direction(direction)


def lamp_values(scene: bpy.types.Scene, elevation_rad: float) -> tuple[tuple[float, float, float], float, float]:
    """(colour, strength W/m^2, angle rad) of the sun lamp for the scene's atmosphere and a sun elevation."""
    settings = scene.atmos
    atmosphere = sync.atmosphere_from_settings(settings)
    diameter = float(settings.sun_angular_diameter)
    colour, strength = sun_color_and_strength(elevation_rad, atmosphere, 0.0, 0.5 * diameter,
                                              float(settings.sun_limb_darkening))
    return tuple(float(c) for c in colour), float(strength), diameter


def _differs(old, new) -> bool:
    old, new = np.atleast_1d(np.asarray(old, dtype=float)), np.atleast_1d(np.asarray(new, dtype=float))
    return bool(np.any(np.abs(old - new) > WRITE_TOLERANCE * np.maximum(np.abs(new), 1e-3)))


def drive_lamp(scene: bpy.types.Scene, lamp: bpy.types.Object, colour, strength: float, angle: float) -> bool:
    """Write colour, strength and angle to the lamp's light data where they changed; True if anything was written.

    Comparing first keeps the depsgraph handler from feeding itself (every write re-tags the light).
    The first write remembers the lamp's own values in the scene so :func:`restore_lamp` can put them back.
    """
    light = lamp.data
    state = dict(scene.get(LAMP_STATE_KEY, {}))
    if state.get("lamp") != lamp.name:
        state.update(lamp=lamp.name, color=tuple(light.color), energy=float(light.energy), angle=float(light.angle))
        scene[LAMP_STATE_KEY] = state
    wrote = False
    for name, value in (("color", colour), ("energy", strength), ("angle", angle)):
        if _differs(getattr(light, name), value):
            setattr(light, name, value)
            wrote = True
    return wrote


def restore_lamp(scene: bpy.types.Scene) -> None:
    """Undo what enabling did to the sun lamp: its own colour/strength/angle back, or remove a lamp we created."""
    clear_baked_keys(scene)
    state = scene.get(LAMP_STATE_KEY)
    if state is None:
        return
    created = state.get("created")
    lamp = bpy.data.objects.get(state.get("lamp", "")) if "lamp" in state else None
    if lamp is not None and lamp.type == "LIGHT" and lamp.name != created:
        lamp.data.color = tuple(state["color"])
        lamp.data.energy = float(state["energy"])
        lamp.data.angle = float(state["angle"])
    if created and created in bpy.data.objects:
        obj = bpy.data.objects[created]
        data = obj.data
        bpy.data.objects.remove(obj)
        if data is not None and data.users == 0:
            bpy.data.lights.remove(data)
    del scene[LAMP_STATE_KEY]


# -- farm-safe animation --------------------------------------------------------------------------


def _animated(idblock) -> bool:
    animation = getattr(idblock, "animation_data", None)
    return animation is not None and (animation.action is not None or len(animation.drivers) > 0
                                      or len(animation.nla_tracks) > 0)


def is_sun_animated(scene: bpy.types.Scene) -> bool:
    """True if the sun lamp's direction can change over time: it, or a parent, is animated or constrained."""
    return moves_over_time(sync.sun_object(scene))


def moves_over_time(obj) -> bool:
    """True if ``obj`` (None: False), or a parent, is animated (action, drivers, NLA) or constrained."""
    while obj is not None:
        if _animated(obj) or len(obj.constraints) > 0:
            return True
        obj = obj.parent
    return False


def _motion_objects(obj) -> list:
    """``obj``, its parents and its constraints' targets (with theirs): every object whose animation or transform
    can move it."""
    found, todo, seen = [], [obj], set()
    while todo:
        current = todo.pop()
        if current is None or current.as_pointer() in seen:
            continue
        seen.add(current.as_pointer())
        found.append(current)
        todo.append(current.parent)
        todo.extend(getattr(constraint, "target", None) for constraint in current.constraints)
    return found


def _curve_text(curve) -> str:
    points = curve.keyframe_points
    arrays = []
    for name in ("co", "handle_left", "handle_right"):
        values = np.empty(2 * len(points))
        points.foreach_get(name, values)
        arrays.append(values)
    digest = hashlib.sha1(np.concatenate(arrays).tobytes()).hexdigest()
    driver = ""
    if curve.driver is not None:
        variables = [(v.name, v.type, [(t.id.name if t.id else "", t.data_path, t.transform_type, t.transform_space)
                                       for t in v.targets]) for v in curve.driver.variables]
        driver = f"{curve.driver.type}|{curve.driver.expression}|{variables}"
    return (f"{curve.data_path}[{curve.array_index}]|{curve.extrapolation}|{curve.mute}|{len(curve.modifiers)}|"
            f"{[p.interpolation for p in points]}|{digest}|{driver}")


#: Object channels that can turn a lamp (or a parent) when they are not animated.
_STATIC_CHANNELS = ("location", "rotation_euler", "rotation_quaternion", "rotation_axis_angle", "scale",
                    "delta_location", "delta_rotation_euler", "delta_rotation_quaternion", "delta_scale")


def _own_fcurves(animation) -> list:
    """The F-curves of the action's slot this ID uses (Blender 4.4+ actions can hold several IDs' curves: the lamp's
    light data keys land in the lamp object's action), or all of a legacy action's."""
    action = animation.action
    if action is None:
        return []
    slot = getattr(animation, "action_slot", None)
    if slot is None or not hasattr(action, "layers"):
        return list(getattr(action, "fcurves", ()))
    curves = []
    for layer in action.layers:
        for strip in layer.strips:
            bag = strip.channelbag(slot) if hasattr(strip, "channelbag") else None
            if bag is not None:
                curves.extend(bag.fcurves)
    return curves


def _object_text(obj) -> list[str]:
    """What moves ``obj`` over time, as text: its animation (action keys, drivers, NLA strips), the values of its
    channels that are not animated (read at any frame they are the same), its parenting and constraints."""
    parts = [f"{obj.name}|{obj.rotation_mode}|{obj.parent_type}|{tuple(map(tuple, obj.matrix_parent_inverse))}"]
    animated = set()
    animation = obj.animation_data
    if animation is not None:
        curves = _own_fcurves(animation) + list(animation.drivers)
        slot = getattr(animation, "action_slot", None)
        parts.append(f"{animation.action.name if animation.action else ''}|{slot.identifier if slot else ''}")
        for curve in curves:
            animated.add((curve.data_path, curve.array_index))
            parts.append(_curve_text(curve))
        for track in animation.nla_tracks:
            parts.append(f"{track.mute}|{track.is_solo}|" + ";".join(
                f"{strip.action.name if strip.action else ''},{strip.frame_start},{strip.frame_end},{strip.scale},"
                f"{strip.repeat},{strip.influence},{strip.mute},{strip.blend_type},{strip.extrapolation}"
                for strip in track.strips))
    for channel in _STATIC_CHANNELS:
        values = tuple(getattr(obj, channel))
        parts.append(f"{channel}:" + ",".join("~" if (channel, index) in animated else repr(round(v, 9))
                                              for index, v in enumerate(values)))
    for constraint in obj.constraints:
        target = getattr(constraint, "target", None)
        parts.append(f"{constraint.type}|{constraint.mute}|{constraint.influence}|{target.name if target else ''}|"
                     f"{getattr(constraint, 'subtarget', '')}")
    return parts


def bake_inputs(scene: bpy.types.Scene) -> str:
    """A digest of everything the sun's baked keys depend on: the atmosphere and sun settings, the frame range,
    and what moves the sun lamp (:func:`_object_text` of the lamp, its parents and constraint targets). A bake
    whose stored digest differs is stale (:func:`follow`)."""
    settings = scene.atmos
    key, _ = sync._atmosphere(scene, settings)
    lamp = sync.sun_object(scene)
    parts = [repr(key), repr((float(settings.sun_angular_diameter), bool(settings.drive_sun_lamp),
                              scene.frame_start, scene.frame_end))]
    for obj in _motion_objects(lamp):
        parts.extend(_object_text(obj))
    return hashlib.sha1("\n".join(parts).encode()).hexdigest()


def is_bake_current(scene: bpy.types.Scene) -> bool:
    """True when the scene needs no sun bake (a still sun, none baked) or its bake is of the current inputs."""
    baked = scene.get(BAKED_KEY)
    if baked is None:
        return not is_sun_animated(scene)
    return baked.get("inputs") == bake_inputs(scene)


_baking: set[str] = set()


def follow(scene: bpy.types.Scene) -> None:
    """After a sync or an edit: re-bake the sun's keys when their inputs changed (:func:`bake_inputs`): a slider, an
    edited sun animation or a new frame range would otherwise be overridden by the old keys at every other frame
    and in renders. At once in the background (scripts, the CLI; an animated Precise scene's tables too), else
    0.3 s after the last change (:class:`.debounce.Debounced`), so a slider drag bakes once (the sun's keys only:
    re-baking the per-frame Precise tables takes about 0.5 s a frame, so the UI leaves them to Refresh). Cheap when
    current (one digest of a few objects' animation)."""
    if scene.name in _baking or is_bake_current(scene):
        return
    if bpy.app.background:
        rebake(scene)
        return
    _later.request(scene)


def rebake(scene: bpy.types.Scene, *, precise: bool = True) -> int:
    """Bake the sun's keys again (:func:`bake_sun_animation`) and, with ``precise``, an animated scene's Precise
    tables with them (about 0.5 s a frame); the number of frames baked."""
    from . import precise_tables

    frames = bake_sun_animation(scene)
    if precise and precise_tables.uses_precise(scene) and precise_tables.moves(scene):
        precise_tables.bake(scene)
    return frames


def _rebake_if_stale(scene: bpy.types.Scene) -> None:
    if getattr(scene, "atmos", None) is not None and scene.atmos.enabled and not is_bake_current(scene):
        rebake(scene, precise=False)   # interactive: Refresh re-bakes the per-frame Precise tables


_later = Debounced(_rebake_if_stale)


def cancel_pending() -> None:
    """Drop queued re-bakes and their timer (unregister)."""
    _later.cancel()


def bake_sun_animation(scene: bpy.types.Scene, frame_start: int | None = None, frame_end: int | None = None) -> int:
    """Keyframe, one key per frame, everything the sun drives: shader parameters and the lamp's colour/strength.

    With the keys in the file, a render without the add-on (``blender -b file.blend -f N`` on a farm) evaluates
    the sun's direction, E_sun, the sky and the lamp for every frame; no Python drivers are involved.
    Keys are LINEAR (motion blur sub-frames interpolate). When the sun is not animated nothing is keyed and
    earlier baked keys are removed. The current frame is restored. Returns the number of frames baked.
    """
    clear_baked_keys(scene)
    if not is_sun_animated(scene):
        return 0
    inputs = bake_inputs(scene)
    lamp = sync.sun_object(scene)
    start = scene.frame_start if frame_start is None else int(frame_start)
    end = scene.frame_end if frame_end is None else int(frame_end)
    if end < start:
        raise ValueError(f"bake_sun_animation: frame_end {end} is before frame_start {start}")
    parameters = sync.node_groups().parameters
    current, subframe = scene.frame_current, scene.frame_subframe
    _baking.add(scene.name)
    try:
        for frame in range(start, end + 1):
            scene.frame_set(frame)
            sync.sync_scene(scene)
            parameters.keyframe_shader_parameters(scene, frame)
            if scene.atmos.drive_sun_lamp:
                for path in LAMP_PATHS:
                    lamp.data.keyframe_insert(path, frame=frame)
    finally:
        scene.frame_set(current, subframe=subframe)
        _baking.discard(scene.name)
    for idblock in (scene, lamp.data):
        for fcurve in _baked_fcurves(idblock):
            for point in fcurve.keyframe_points:
                point.interpolation = "LINEAR"
    scene[BAKED_KEY] = {"lamp_data": lamp.data.name if scene.atmos.drive_sun_lamp else "", "start": start,
                        "end": end, "inputs": inputs}
    return end - start + 1


def _baked_fcurves(idblock) -> list:
    """The F-curves of ``idblock`` on the paths a bake writes."""
    animation = idblock.animation_data
    if animation is None or animation.action is None:
        return []
    parameters = sync.node_groups().parameters
    names = set(parameters.PARAMETER_NAMES) - set(parameters.PRECISE_PARAMETER_NAMES)   # those keys are the tables'
    paths = {f'["{name}"]' for name in names} if isinstance(idblock, bpy.types.Scene) else set(LAMP_PATHS)
    return [c for c in sync.node_groups().parameters._fcurves(animation.action) if c.data_path in paths]


def clear_baked_keys(scene: bpy.types.Scene) -> None:
    """Remove the keys a previous :func:`bake_sun_animation` wrote (shader parameters and lamp data)."""
    baked = scene.get(BAKED_KEY)
    if baked is None:
        return
    remove = sync.node_groups().parameters._remove_fcurve
    lights = [bpy.data.lights.get(baked.get("lamp_data", ""))]
    for idblock in [scene, *[light for light in lights if light is not None]]:
        for fcurve in _baked_fcurves(idblock):
            remove(idblock.animation_data.action, fcurve)
    del scene[BAKED_KEY]


class ATMOS_OT_bake_sun(bpy.types.Operator):
    """Keyframe the sun's shader parameters and lamp colour/strength on every frame, so the animation renders
    right without the add-on (render farms)"""

    bl_idname = "atmos.bake_sun"
    bl_label = "Bake Sun Animation"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        scene = context.scene
        try:
            frames = bake_sun_animation(scene)
        except (RuntimeError, ValueError, TypeError) as error:
            self.report({"ERROR"}, f"Atmos could not bake the sun: {error}")
            return {"CANCELLED"}
        if frames:
            self.report({"INFO"}, f"Atmos: sun baked on {frames} frame(s), {scene.frame_start}-{scene.frame_end}")
        else:
            self.report({"INFO"}, "Atmos: the sun lamp is not animated; nothing to bake (earlier keys removed)")
        return {"FINISHED"}


CLASSES = (ATMOS_OT_bake_sun,)
