# SPDX-License-Identifier: GPL-3.0-or-later
"""An animated sun: what the Precise key tiles follow, kept current as the scene is edited.

A sun lamp that moves over time (its own animation, a parent's, a constraint, the Sun Position add-on's animated
settings) changes the shader parameters and the lamp's colour and strength every frame; drivers on the lamp evaluate
them (:mod:`.apply.sun_drivers`), on a farm without the add-on too. An older Atmos keyed them per frame:
:func:`clear_baked_keys` removes those keys. :func:`bake_sun_animation` records the animated range and a digest of
everything the sun's motion depends on (:func:`bake_inputs`); :func:`follow` re-bakes an animated scene's Precise key
tiles when it changes.
"""

from __future__ import annotations

import hashlib

import bpy
import numpy as np

from ..plan import Plan
from . import motion_path, scene_reading
from .apply import precise_tables
from .apply.sun_lamp import LAMP_PATHS
from .debounce import Debounced

#: Scene custom property: the frame range baked, the lamp data whose keys the bake wrote and the inputs' digest.
BAKED_KEY = "atmos_sun_baked"


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


def _object_text(obj) -> list[str]:
    """What moves ``obj`` over time, as text: its animation (action keys, drivers, NLA strips), the values of its
    channels that are not animated (read at any frame they are the same), its parenting and constraints."""
    parts = [f"{obj.name}|{obj.rotation_mode}|{obj.parent_type}|{tuple(map(tuple, obj.matrix_parent_inverse))}"]
    animated = set()
    animation = obj.animation_data
    if animation is not None:
        curves = motion_path.own_fcurves(animation) + list(animation.drivers)
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
    and what moves the sun lamp (:func:`_object_text` of the lamp, its parents and constraint targets; the Sun
    Position add-on's keys and settings where it turns the lamp). A bake whose stored digest differs is stale
    (:func:`follow`)."""
    settings = scene.atmos
    key, _ = scene_reading.atmosphere_with_key(scene)
    lamp = scene_reading.sun_object(scene)
    parts = [repr(key), repr((float(settings.sun_angular_diameter), bool(settings.drive_sun_lamp),
                              scene.frame_start, scene.frame_end))]
    for obj in scene_reading.motion_objects(lamp):
        parts.extend(_object_text(obj))
    if scene_reading.turned_by_sun_position(scene, lamp):   # the add-on's keys and its place and date
        parts.extend(_curve_text(curve) for curve in scene_reading.sun_position_curves(scene))
        parts.append(scene_reading.sun_position_settings(scene))
    return hashlib.sha1("\n".join(parts).encode()).hexdigest()


def is_bake_current(scene: bpy.types.Scene) -> bool:
    """True when the scene needs no record (a still sun, none recorded) or its record is of the current inputs and
    of the driven sun (a record of an older Atmos's per-frame keys is stale: its keys are removed)."""
    baked = scene.get(BAKED_KEY)
    if baked is None:
        return not scene_reading.is_sun_animated(scene)
    return bool(baked.get("driven")) and baked.get("inputs") == bake_inputs(scene)


def follow(scene: bpy.types.Scene, plan: Plan) -> None:
    """After a sync or an edit: record the sun's animation again when its inputs changed (:func:`bake_inputs`: an
    edited sun animation, a new frame range, a slider). In the background (scripts, the CLI) at once, with an
    animated Precise scene's key tiles re-baked; in the interface 0.3 s after the last change
    (:class:`.debounce.Debounced`), the record only (re-baking the key tiles takes 0.4-0.8 s a tile, so the UI leaves
    them to Refresh). The sun's light itself needs nothing: its drivers follow every frame. Cheap when current
    (one digest of a few objects' animation). ``plan``: the scene's (whether it bakes the tables)."""
    if is_bake_current(scene):
        return
    if bpy.app.background:
        rebake(scene, plan)
        return
    _later.request(scene)


def rebake(scene: bpy.types.Scene, plan: Plan | None = None) -> int:
    """Record the sun's animation again (:func:`bake_sun_animation`) and, where ``plan`` bakes the tables, re-bake an
    animated scene's Precise key tiles (0.4-0.8 s a tile); the number of frames of the animated range."""
    frames = bake_sun_animation(scene)
    if plan is not None and plan.tables and precise_tables.moves(scene):
        precise_tables.bake(scene)
    return frames


def _rebake_if_stale(scene: bpy.types.Scene) -> None:
    if getattr(scene, "atmos", None) is not None and scene.atmos.enabled and not is_bake_current(scene):
        rebake(scene)   # interactive: the record only (Refresh re-bakes the Precise key tiles)


_later = Debounced(_rebake_if_stale)


def finish_pending() -> None:
    """Record now what the UI has queued (before a save)."""
    _later.flush()


def cancel_pending() -> None:
    """Drop queued re-bakes and their timer (unregister)."""
    _later.cancel()


def bake_sun_animation(scene: bpy.types.Scene, frame_start: int | None = None, frame_end: int | None = None) -> int:
    """Record the animation of the sun that the Precise key tiles follow, and remove the per-frame keys an older
    Atmos wrote.

    Nothing is keyed: the sun's direction and E_sun, and the lamp's colour and strength, are drivers on the lamp
    (:mod:`.apply.sun_drivers`), which a render without the add-on (``blender -b file.blend -f N`` on a farm)
    evaluates on every frame and sub-frame. What is stored is the frame range and a digest of the sun's motion and
    the settings (:func:`bake_inputs`), which :func:`follow` compares to re-bake an animated scene's Precise key
    tiles when they change. Returns the number of frames of the animated range (0 when the sun is not animated;
    then nothing is recorded).
    """
    clear_baked_keys(scene)
    if not scene_reading.is_sun_animated(scene):
        return 0
    start = scene.frame_start if frame_start is None else int(frame_start)
    end = scene.frame_end if frame_end is None else int(frame_end)
    if end < start:
        raise ValueError(f"bake_sun_animation: frame_end {end} is before frame_start {start}")
    scene[BAKED_KEY] = {"driven": True, "start": start, "end": end, "inputs": bake_inputs(scene)}
    return end - start + 1


def baked_fcurves(idblock) -> list:
    """The F-curves of ``idblock`` on the paths a bake writes."""
    animation = idblock.animation_data
    if animation is None or animation.action is None:
        return []
    parameters = scene_reading.groups().parameters
    names = set(parameters.PARAMETER_NAMES) - set(parameters.PRECISE_PARAMETER_NAMES)   # those keys are the tables'
    paths = {f'["{name}"]' for name in names} if isinstance(idblock, bpy.types.Scene) else set(LAMP_PATHS)
    return [c for c in parameters.fcurves_of(animation.action) if c.data_path in paths]


def clear_baked_keys(scene: bpy.types.Scene) -> None:
    """Remove the record of :func:`bake_sun_animation` and the per-frame keys an older Atmos's bake wrote (shader
    parameters and lamp data)."""
    baked = scene.get(BAKED_KEY)
    if baked is None:
        return
    remove = scene_reading.groups().parameters.remove_fcurve
    lights = [bpy.data.lights.get(baked.get("lamp_data", ""))]
    for idblock in [scene, *[light for light in lights if light is not None]]:
        for fcurve in baked_fcurves(idblock):
            remove(idblock.animation_data.action, fcurve)
    del scene[BAKED_KEY]
