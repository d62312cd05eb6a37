# SPDX-License-Identifier: GPL-3.0-or-later
"""Where the camera and the sun lamp stand on each frame, read off their keys without evaluating the scene.

The Precise key tiles follow the camera's altitude and the sun's elevation frame by frame
(:func:`.apply.precise_tables.frame_inputs`). Sampling them with ``scene.frame_set`` evaluates the whole depsgraph
on every frame: 57 ms a frame in a scene of 20000 objects, 14-18 s for 250 frames, to read two objects' matrices.
Where what moves those two is their own and their parents' transform keys alone (:func:`keys_alone`: no constraint,
no driver, no NLA strip, no physics, plain object parenting), their world matrices are composed here from the
F-curves as Blender composes an object's (``BKE_object_to_mat4``: rotation with its delta times scale, plus
location and delta location; a parent's world matrix times the parent inverse times that), in the same single
precision (:mod:`mathutils`). ``frame_inputs`` checks them against the evaluated scene at the range's first, middle
and last frames and samples every frame as before where they differ.
"""

from __future__ import annotations

import bpy
from mathutils import Euler, Matrix, Quaternion, Vector

#: The channels of an object's transform, each (RNA path, length).
TRANSFORM_CHANNELS = (("location", 3), ("rotation_euler", 3), ("rotation_quaternion", 4), ("scale", 3),
                      ("delta_location", 3), ("delta_rotation_euler", 3), ("delta_rotation_quaternion", 4),
                      ("delta_scale", 3))


def own_fcurves(animation) -> list:
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


def keys_alone(obj) -> bool:
    """True when nothing but transform keys (its own and its parents') moves ``obj`` over time: no constraint, driver,
    NLA strip, rigid body, axis-angle rotation, parent of another kind than a plain object or a curve parent (whose
    path moves its children) on the chain; then :func:`world_matrix` is its world matrix on any frame."""
    while obj is not None:
        animation = obj.animation_data
        if (len(obj.constraints) or obj.rotation_mode == "AXIS_ANGLE" or obj.rigid_body is not None
                or (animation is not None and (len(animation.drivers) or len(animation.nla_tracks)
                                               or getattr(animation, "action_influence", 1.0) != 1.0))):
            return False
        parent = obj.parent
        if parent is not None and (obj.parent_type != "OBJECT" or parent.type == "CURVE"):
            return False
        obj = parent
    return True


def _channels_at(obj, frame: float) -> dict:
    """The transform channels of ``obj`` at ``frame``: its keys' values where keyed, its current values elsewhere."""
    values = {name: list(getattr(obj, name)) for name, _ in TRANSFORM_CHANNELS}
    if obj.animation_data is not None:
        for curve in own_fcurves(obj.animation_data):
            channel = values.get(curve.data_path)
            if channel is not None and curve.array_index < len(channel) and not curve.mute:
                channel[curve.array_index] = curve.evaluate(frame)
    return values


def _basis(obj, values: dict) -> Matrix:
    """``obj``'s local matrix from its channel ``values``, as ``BKE_object_to_mat4`` composes it."""
    if obj.rotation_mode == "QUATERNION":
        rotation = Quaternion(values["rotation_quaternion"]).normalized().to_matrix()
        delta = Quaternion(values["delta_rotation_quaternion"]).normalized().to_matrix()
    else:
        rotation = Euler(values["rotation_euler"], obj.rotation_mode).to_matrix()
        delta = Euler(values["delta_rotation_euler"], obj.rotation_mode).to_matrix()
    scale = Matrix.Diagonal(Vector([a * b for a, b in zip(values["scale"], values["delta_scale"])]))
    basis = ((delta @ rotation) @ scale).to_4x4()
    basis.translation = Vector(values["location"]) + Vector(values["delta_location"])
    return basis


def world_matrix(obj, frame: float) -> Matrix:
    """``obj``'s world matrix at ``frame`` composed from its keys and its parents' (:func:`keys_alone` must hold)."""
    basis = _basis(obj, _channels_at(obj, frame))
    if obj.parent is None:
        return basis
    return (world_matrix(obj.parent, frame) @ obj.matrix_parent_inverse) @ basis


def time_is_remapped(scene: bpy.types.Scene) -> bool:
    """True when the scene's time is remapped (Output > Time Stretching): its frames are not the keys' frames."""
    return scene.render.frame_map_old != scene.render.frame_map_new
