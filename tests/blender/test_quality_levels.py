# SPDX-License-Identifier: GPL-3.0-or-later
"""Quality levels in the add-on: the setting, Auto's choice, what the group contains, the parameters written.

The graphs' numbers are tested against the physics core in test_node_groups (the group alone) and
test_aerial_application (composited, end to end); here: which graph a scene gets and why.
"""

from __future__ import annotations

import math

import bpy
import numpy as np
import pytest

from atmos_addon.blender.apply import in_render
from atmos_addon.blender import orchestrator, quality_choice
from atmos_addon.physics.quality import SceneSummary
from atmos_addon.node_groups import parts
from atmos_addon.node_groups.aerial_perspective import NODE_COUNTS
from atmos_addon.node_groups.parameters import PRECISE_TILE, RETIRED_PARAMETER_NAMES
from render_utils import emission_material

GROUP = "Atmos Aerial Perspective"


pytestmark = pytest.mark.usefixtures("addon")


def _scene(camera_z: float = 2.0, far: float = 3000.0):
    """A camera ``camera_z`` units up looking along +Y, a sun lamp, and a ground plane reaching ``far`` units; the
    Compositor mode, whose per-sample shader group ("Atmos Aerial Perspective") these tests inspect (the default Per
    Pixel mode evaluates the same level in its compositor group: tests/blender/test_aerial_application.py)."""
    scene = bpy.context.scene
    scene.atmos.render_mode = "COMPOSITOR"
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.location = (0.0, 0.0, camera_z)
    camera.rotation_euler = (math.radians(85.0), 0.0, 0.0)
    camera.data.clip_end = 1.0e6
    scene.collection.objects.link(camera)
    scene.camera = camera
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.rotation_euler = (math.radians(40.0), 0.0, 0.0)
    scene.collection.objects.link(sun)
    mesh = bpy.data.meshes.new("Ground")
    mesh.from_pydata([(-far, 0, 0), (far, 0, 0), (far, far, 0), (-far, far, 0)], [], [(0, 1, 2, 3)])
    mesh.materials.append(emission_material("Ground", (0.1, 0.1, 0.1)))
    scene.collection.objects.link(bpy.data.objects.new("Ground", mesh))
    return scene


def test_quality_switch_edits_the_same_group_and_materials_keep_it():
    scene = _scene()
    orchestrator.enable_effect(scene)
    tree = bpy.data.node_groups[GROUP]  # the default: Precise with multiple scattering
    assert tree["atmos_features"] == "rayleigh+mie+abs+precise" and scene.atmos.status_quality.startswith("Precise")
    groups_before = {tree.name for tree in bpy.data.node_groups}
    pointer = tree.as_pointer()
    scene.atmos.quality = "FAST"
    tree = bpy.data.node_groups[GROUP]
    assert tree.as_pointer() == pointer and tree["atmos_features"] == "rayleigh+mie+abs"
    assert parts.inline_count(tree) == NODE_COUNTS["rayleigh+mie+abs"]
    # Only the Precise camera sky view's group goes (Cycles' camera rays read the Fast sky directly), and the parts
    # only the Precise groups used (the table samples...)
    gone = groups_before - {tree.name for tree in bpy.data.node_groups}
    assert "Atmos Sky View" in gone and all(name == "Atmos Sky View" or name in parts.PARTS for name in gone), gone
    assert "Atmos Sun Disk" in bpy.data.node_groups   # the Fast sky's disk too
    assert scene.atmos.status_built.startswith("Fast, ") and scene.atmos.status_quality.startswith("Fast")
    material = bpy.data.materials["Ground"]
    users = [n for n in material.node_tree.nodes if n.bl_idname == "ShaderNodeGroup"]
    assert any(_uses(n.node_tree, tree) for n in users)
    scene.atmos.quality = "PRECISE"
    assert bpy.data.node_groups[GROUP]["atmos_features"] == "rayleigh+mie+abs+precise"
    assert not any(name in scene for name in RETIRED_PARAMETER_NAMES)   # the retired Balanced level's: never written
    orchestrator.disable_effect(scene)
    assert not any(name.startswith("atmos_") for name in scene.keys())


def _uses(tree, target) -> bool:
    """True if ``tree`` is ``target`` or holds a group node that (recursively) uses it."""
    if tree is None:
        return False
    if tree.as_pointer() == target.as_pointer():
        return True
    return any(_uses(n.node_tree, target) for n in tree.nodes if n.bl_idname == "ShaderNodeGroup")


def test_the_origin_altitude_raises_the_precise_tables_camera():
    """Precise bakes its table at the camera's altitude: the origin's altitude plus the camera's z."""
    scene = _scene()
    scene.atmos.quality = "PRECISE"
    orchestrator.enable_effect(scene)
    assert scene[PRECISE_TILE][2] == pytest.approx(2.0)
    scene.atmos.origin_altitude = 1500.0
    bpy.context.view_layer.update()
    assert scene[PRECISE_TILE][2] == pytest.approx(1502.0)


def test_auto_picks_precise_for_a_drone_and_fast_when_the_tolerance_allows():
    """Auto chooses between the levels the add-on builds (Fast, Precise): a drone at the default 2 % needs
    Precise (Fast's measured drone error is 4.7 %), a ground view at 20 % takes Fast (12.5 %)."""
    scene = _scene(camera_z=2000.0)
    scene.atmos.quality = "AUTO"
    orchestrator.enable_effect(scene)
    assert scene.atmos.auto_level == "precise"
    assert bpy.data.node_groups[GROUP]["atmos_features"].endswith("+precise")
    assert "Auto chose Precise" in scene.atmos.status_quality and "drone" in scene.atmos.status_quality
    scene.camera.location.z = 2.0
    scene.atmos.auto_tolerance = 20.0
    assert scene.atmos.auto_level == "fast"
    assert bpy.data.node_groups[GROUP]["atmos_features"] == "rayleigh+mie+abs"
    assert "Auto chose Fast" in scene.atmos.status_quality


def test_auto_summary_reads_the_scene():
    scene = _scene(camera_z=10.0, far=40_000.0)
    scene.atmos.origin_altitude = 100.0
    scene.unit_settings.scale_length = 2.0
    camera = scene.camera
    camera.location.z = 10.0
    camera.keyframe_insert("location", frame=1)
    camera.location.z = 60.0
    camera.keyframe_insert("location", frame=scene.frame_end)
    scene.frame_set(7)
    summary = quality_choice.summarize(scene)
    assert scene.frame_current == 7  # the sampled frames are undone
    assert summary.camera_altitude_range_m == pytest.approx((100.0 + 20.0, 100.0 + 120.0))
    assert summary.geometry_altitude_span_m == pytest.approx(0.0)
    corner = math.hypot(40_000.0, 40_000.0)  # the ground's far corners, from the camera where it is now
    height = camera.matrix_world.translation.z
    assert summary.max_view_distance_m == pytest.approx(2.0 * math.hypot(corner, height), rel=1e-6)
    assert summary.sun_elevation_deg == pytest.approx(50.0, abs=1e-4)
    assert not summary.sun_animated and not summary.mie_zero
    assert isinstance(summary, SceneSummary)


def test_in_render_mode_builds_fast_segments_and_says_so():
    scene = _scene()
    scene.render.engine = "CYCLES"
    scene.atmos.render_mode = "IN_RENDER"
    scene.atmos.quality = "PRECISE"
    orchestrator.enable_effect(scene)
    assert in_render.is_installed(scene)
    assert "In-Render mode applies Fast" in scene.atmos.status_quality
    stamped = [t.get("atmos_features", "") for t in bpy.data.node_groups]
    assert not any("+precise" in key for key in stamped)


def test_an_animated_sun_bakes_key_tiles_that_each_frame_blends_and_a_pan_bakes_one():
    """A camera that pans at one altitude: one tile, no keys, no blend. A sun setting 20 -> 10 deg over 60 frames
    (keys added after enabling: the depsgraph handler re-bakes): a key tile every 2 deg, the groups rebuilt to blend
    two keys, every frame's key and weight at its own sun elevation, in the same image, grown in place. The sun's
    animation removed: one tile again, the groups without the blend."""
    from atmos_addon.blender import facts, scene_reading
    from atmos_addon.node_groups import precise as precise_nodes
    from atmos_addon.node_groups import stamps
    from atmos_addon.node_groups.parameters import PRECISE_SCALE, PRECISE_TILE

    scene = _scene()
    scene.frame_start, scene.frame_end = 1, 60
    camera = scene.camera
    for frame, x, turn in ((1, 0.0, 0.0), (60, 400.0, 1.0)):
        camera.location.x, camera.rotation_euler.z = x, turn
        camera.keyframe_insert("location", frame=frame)
        camera.keyframe_insert("rotation_euler", frame=frame)
    report = orchestrator.enable_effect(scene)
    assert any("baked 1 table tile " in message for message in report.messages), report.messages
    assert scene[facts.KEY_TILES] == 1 and not facts.plan_of(scene).blend

    def blends() -> set[bool]:
        return {"+blend" in bpy.data.node_groups[kind.name][stamps.FEATURES_KEY]
                for kind in (stamps.AERIAL, stamps.SKY)}

    assert blends() == {False}
    first_image = bpy.data.images[precise_nodes.IMAGE_NAME]
    action = scene.animation_data.action if scene.animation_data else None   # the sun's drivers: no action
    keyed = {c.data_path for c in action.fcurves} if action is not None else set()
    assert not any(PRECISE_TILE in path for path in keyed), "nothing changes over the range: nothing keyed"

    sun = bpy.data.objects["Sun"]
    for frame, angle in ((1, 70.0), (60, 80.0)):
        sun.rotation_euler.x = math.radians(angle)
        sun.keyframe_insert("rotation_euler", frame=frame)
    bpy.context.view_layer.update()                          # the handler re-bakes the sun and the tables
    tiles = scene[facts.KEY_TILES]
    assert tiles in (6, 7), tiles                            # 20, 18, ..., 10 deg (and the last frame's rest)
    image = bpy.data.images[precise_nodes.IMAGE_NAME]
    assert image.size[1] == tiles * precise_nodes.ALTITUDES
    # resized in place: the groups' image nodes still point at it (re-pointing them re-evaluates every material)
    assert image == first_image
    taps = [node for node in parts.inline_nodes(bpy.data.node_groups[GROUP]) if node.bl_idname == "ShaderNodeTexImage"]
    assert taps and all(node.image == image for node in taps)
    assert blends() == {True} and facts.plan_of(scene).blend
    for frame in (1, 17, 30, 44, 60):
        scene.frame_set(frame)
        direction, _ = scene_reading.sun_direction(scene)
        elevation = math.degrees(math.asin(direction[2]))
        position = scene[PRECISE_TILE][1] / precise_nodes.ALTITUDES + scene[PRECISE_SCALE][2]
        assert position == pytest.approx((20.0 - elevation) / 2.0, abs=2e-3), (frame, elevation, position)
        assert scene[PRECISE_TILE][2] == pytest.approx(2.0)

    sun.animation_data_clear()
    bpy.context.view_layer.update()
    orchestrator.refresh_effect(scene)
    assert scene[facts.KEY_TILES] == 1 and blends() == {False}
    assert bpy.data.images[precise_nodes.IMAGE_NAME].size[1] == precise_nodes.ALTITUDES


def test_precise_bakes_follows_the_sun_and_camera_and_cleans_up():
    """Precise: one tile baked and packed, the group's image nodes point at it; moving the sun or the camera
    re-bakes (a still scene), an unrelated slider does not; leaving Precise or disabling removes the image and
    the parameters."""
    from atmos_addon.physics.precise import DEFAULT_SHAPE
    from atmos_addon.node_groups import precise as precise_nodes
    from atmos_addon.node_groups.parameters import PRECISE_PARAMETER_NAMES, PRECISE_TILE

    scene = _scene(camera_z=300.0)
    scene.atmos.quality = "PRECISE"
    report = orchestrator.enable_effect(scene)
    assert any("baked 1 table tile" in message for message in report.messages), report.messages
    image = bpy.data.images[precise_nodes.IMAGE_NAME]
    assert image.packed_file is not None and tuple(image.size) == (DEFAULT_SHAPE.width, DEFAULT_SHAPE.altitudes)
    taps = [n for n in parts.inline_nodes(bpy.data.node_groups[GROUP]) if n.bl_idname == "ShaderNodeTexImage"]
    assert len(taps) == 20 and all(n.image == image and n.interpolation == "Closest" for n in taps)
    assert scene[PRECISE_TILE][2] == pytest.approx(300.0)
    assert scene.atmos.status_built.startswith("Precise, ")

    def pixels():
        values = np.empty(len(image.pixels), dtype=np.float32)
        image.pixels.foreach_get(values)
        return values

    before = pixels()
    scene.atmos.distance_scale = 1.0                         # same value: nothing to bake
    np.testing.assert_array_equal(pixels(), before)
    bpy.data.objects["Sun"].rotation_euler = (math.radians(20.0), 0.0, 0.0)
    bpy.context.view_layer.update()                          # depsgraph handler: re-bake at once (background)
    after_sun = pixels()
    assert not np.array_equal(after_sun, before)
    scene.camera.location.z = 900.0
    bpy.context.view_layer.update()
    assert scene[PRECISE_TILE][2] == pytest.approx(900.0)
    assert not np.array_equal(pixels(), after_sun)

    scene.atmos.quality = "FAST"
    assert precise_nodes.IMAGE_NAME not in bpy.data.images
    assert not any(name in scene for name in PRECISE_PARAMETER_NAMES)
    scene.atmos.quality = "PRECISE"
    assert precise_nodes.IMAGE_NAME in bpy.data.images
    orchestrator.disable_effect(scene)
    assert precise_nodes.IMAGE_NAME not in bpy.data.images
    assert not any(name in scene for name in PRECISE_PARAMETER_NAMES)
