# SPDX-License-Identifier: GPL-3.0-or-later
"""The camera's and the sun's path over the frame range read off their keys (:mod:`atmos_addon.blender.motion_path`).

The Precise key tiles follow the camera's altitude and the sun's elevation on every frame. Sampled with
``scene.frame_set``, each frame evaluates the whole scene (57 ms with 20000 objects: 14-18 s for 250 frames); where
transform keys alone move the two, their matrices are composed from the keys, checked against the scene at three
frames. These tests hold that the path read off the keys is the evaluated scene's, to the bake key's rounding, on
every frame of a rig that uses what keys can (a keyed parent, Euler orders, unnormalised quaternion keys, deltas,
scale), that only the three checks evaluate the scene, and that whatever else can move the camera or the sun makes
it sample every frame as before (a constraint, a driver, a camera cut, remapped time, a script's frame handler).
"""

from __future__ import annotations

import math

import bpy
import mathutils
import pytest

from atmos_addon.blender import motion_path, scene_reading
from atmos_addon.blender.apply import precise_tables

pytestmark = pytest.mark.usefixtures("addon")

FRAMES = 40


def _rigged_scene():
    """Frames 1-40: a camera on a keyed, scaled rig (ZXY Euler, a delta location) climbing 0 -> 150 m; a sun with
    unnormalised quaternion keys and a delta rotation, setting from 30 to -3 deg."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, FRAMES
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(camera)
    scene.camera = camera
    rig = bpy.data.objects.new("Rig", None)
    scene.collection.objects.link(rig)
    rig.rotation_mode = "ZXY"
    rig.delta_location = (0.0, 0.0, 3.0)
    rig.scale = (2.0, 2.0, 2.0)
    for frame, z, turn in ((1, 0.0, 0.0), (FRAMES, 150.0, 0.7)):
        rig.location.z = z
        rig.rotation_euler = (turn, 0.3, 2.0 * turn)
        rig.keyframe_insert("location", frame=frame)
        rig.keyframe_insert("rotation_euler", frame=frame)
    camera.parent = rig
    camera.location = (0.0, 5.0, 2.0)
    camera.rotation_euler = (1.2, 0.0, 0.0)
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    scene.collection.objects.link(sun)
    sun.rotation_mode = "QUATERNION"
    sun.delta_rotation_quaternion = mathutils.Euler((0.05, 0.02, 0.0)).to_quaternion()
    for frame, elevation in ((1, 30.0), (FRAMES, -3.0)):
        sun.rotation_quaternion = mathutils.Euler((math.radians(90.0 - elevation), 0.0, 0.4)).to_quaternion() * 1.7
        sun.keyframe_insert("rotation_quaternion", frame=frame)
    scene.frame_set(1)
    return scene, camera, sun


def _evaluated_path(scene) -> list:
    """Every frame's (frame, altitude m, sun elevation rad), the scene evaluated on each (the current frame kept)."""
    current, path = scene.frame_current, []
    for frame in range(scene.frame_start, scene.frame_end + 1):
        scene.frame_set(frame)
        direction, _ = scene_reading.sun_direction(scene)
        altitude = float(scene.atmos.origin_altitude) + scene.camera.matrix_world.translation.z
        path.append((frame, altitude, math.asin(max(-1.0, min(1.0, float(direction[2]))))))
    scene.frame_set(current)
    return path


def _counting_frame_changes():
    changes = []

    @bpy.app.handlers.persistent
    def count(_scene, *_):
        changes.append(1)

    bpy.app.handlers.frame_change_post.append(count)
    return changes, count


def _sampled(scene) -> tuple[list, int]:
    """(frame_inputs, how many frames it evaluated)."""
    changes, count = _counting_frame_changes()
    try:
        return precise_tables.frame_inputs(scene), len(changes)
    finally:
        bpy.app.handlers.frame_change_post.remove(count)


def _assert_is_the_evaluated_path(inputs, path) -> None:
    assert [frame for frame, _, _ in inputs] == [frame for frame, _, _ in path]
    for (_, altitude, elevation), (_, true_altitude, true_elevation) in zip(inputs, path):
        assert abs(altitude - true_altitude) <= 1.5e-3 and abs(elevation - true_elevation) <= 1.5e-7


def test_the_path_read_off_the_keys_is_the_evaluated_scenes_and_evaluates_three_frames():
    scene, camera, sun = _rigged_scene()
    assert motion_path.keys_alone(camera) and motion_path.keys_alone(sun)
    inputs, evaluated = _sampled(scene)
    path = _evaluated_path(scene)
    assert path[-1][1] - path[0][1] > 100.0 and path[0][2] - path[-1][2] > math.radians(30.0)   # it moves
    _assert_is_the_evaluated_path(inputs, path)
    assert evaluated == 4 and scene.frame_current == 1          # the three checks and the current frame restored
    for obj in (scene.objects["Rig"], camera, sun):             # the matrices themselves, to float32's last bits
        for frame in (1, 17, FRAMES):
            scene.frame_set(frame)
            composed = motion_path.world_matrix(obj, frame)
            assert max(abs(a - b) for row_a, row_b in zip(obj.matrix_world, composed) for a, b in zip(row_a, row_b)) \
                <= 2e-5, (obj.name, frame)


def _track_the_camera_to_an_empty(scene, camera, _sun):
    target = bpy.data.objects.new("Target", None)
    scene.collection.objects.link(target)
    constraint = camera.constraints.new("TRACK_TO")
    constraint.target = target


def _drive_the_suns_turn(scene, _camera, sun):
    curve = sun.driver_add("delta_rotation_euler", 0)
    curve.driver.expression = "frame * 0.01"


def _cut_to_a_second_camera(scene, camera, _sun):
    other = bpy.data.objects.new("Other Camera", bpy.data.cameras.new("Other Camera"))
    other.location.z = 500.0
    scene.collection.objects.link(other)
    scene.timeline_markers.new("Start", frame=1).camera = camera
    scene.timeline_markers.new("Cut", frame=20).camera = other


def _stretch_time(scene, _camera, _sun):
    scene.render.frame_map_old, scene.render.frame_map_new = 100, 50


def _turn_the_sun_by_axis_angle(scene, _camera, sun):
    sun.rotation_mode = "AXIS_ANGLE"
    sun.rotation_axis_angle = (0.3, 1.0, 0.0, 0.0)
    sun.keyframe_insert("rotation_axis_angle", frame=1)
    sun.rotation_axis_angle = (1.3, 1.0, 0.0, 0.0)
    sun.keyframe_insert("rotation_axis_angle", frame=FRAMES)


@pytest.mark.parametrize("edit", [_track_the_camera_to_an_empty, _drive_the_suns_turn, _cut_to_a_second_camera,
                                  _stretch_time, _turn_the_sun_by_axis_angle])
def test_whatever_else_moves_the_camera_or_the_sun_samples_every_frame(edit):
    scene, camera, sun = _rigged_scene()
    edit(scene, camera, sun)
    scene.frame_set(1)
    inputs, evaluated = _sampled(scene)
    assert evaluated == FRAMES + 1                              # every frame, then the current one again
    _assert_is_the_evaluated_path(inputs, _evaluated_path(scene))


def test_a_script_that_moves_the_camera_on_frame_changes_is_caught_by_the_checks():
    """A frame handler no key shows (a script's rig): the keys say the camera stands still, the scene evaluated at the
    first checked frame says otherwise, and every frame is sampled."""
    scene, camera, _sun = _rigged_scene()

    @bpy.app.handlers.persistent
    def lift(scene_, *_):
        scene_.camera.delta_location.z = 10.0 * scene_.frame_current

    bpy.app.handlers.frame_change_post.append(lift)
    try:
        scene.frame_set(1)
        inputs, evaluated = _sampled(scene)
        path = _evaluated_path(scene)
    finally:
        bpy.app.handlers.frame_change_post.remove(lift)
    assert evaluated > FRAMES                                   # the checks, then every frame
    _assert_is_the_evaluated_path(inputs, path)


def test_the_precise_parameters_are_keyed_on_every_frame_constant_between():
    """The bake keys the Precise parameters on every frame of a moving camera's and sun's range (the first frame's
    keys inserted, the rest written into their curves at once): each frame evaluates to its key tile's origin, the
    camera's altitude and its blend weight, constant between frames."""
    from atmos_addon import api
    from atmos_addon.node_groups.parameters import PRECISE_SCALE, PRECISE_TILE
    from atmos_addon.physics.precise import key_tiles

    scene, _camera, _sun = _rigged_scene()
    api.enable(scene, preset="clear", quality="PRECISE")
    inputs = precise_tables.frame_inputs(scene)
    path = key_tiles([altitude for _, altitude, _ in inputs], [elevation for _, _, elevation in inputs],
                     max_keys=precise_tables.TILES_PER_COLUMN)
    assert len(path.keys) > 2
    for (frame, altitude, _), segment, weight in zip(inputs, path.segments, path.weights):
        for at in (frame, frame + 0.5):                           # on the frame and half a frame later
            scene.frame_set(frame, subframe=at - frame)
            origin = precise_tables.tile_origin(segment)
            assert tuple(scene[PRECISE_TILE]) == pytest.approx((origin[0], origin[1], altitude), abs=1e-2), frame
            assert scene[PRECISE_SCALE][2] == pytest.approx(weight, abs=1e-6), frame
