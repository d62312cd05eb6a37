# SPDX-License-Identifier: GPL-3.0-or-later
"""Parts (:mod:`atmos_addon.node_groups.parts`): pieces of the equations built once as node groups of their own.

Blender re-runs a tree's whole update after each node a script adds, so a tree's build costs the square of its
size; the parts keep every tree Atmos builds small. These tests hold what that must not cost: each part is one
data-block however often it is used, the trees stay under a size, the sky evaluates as many nodes as before, a
user's group that bears a part's name is left alone, a hand edit inside a part is reported and reset, a stale part
is rebuilt in place, and nothing is left behind by a mode switch or a disable.
"""

from __future__ import annotations

import math

import bpy
import pytest

from atmos_addon import api
from atmos_addon.blender import group_integrity, orchestrator
from atmos_addon.node_groups import SKY_NODE_COUNTS, parts, registry, stamps

pytestmark = pytest.mark.usefixtures("addon")

#: The most nodes any tree Atmos builds for the default may hold (the largest, the Precise sky's, holds 115 since the
#: parts; 244 before).
LARGEST_TREE = 120


def _new_user_scene() -> bpy.types.Scene:
    """An empty factory file: a camera, a sun 20 deg up and one plane with a node-based material."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.location = (0.0, 0.0, 2.0)
    camera.rotation_euler = (math.pi / 2.0, 0.0, 0.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    scene.collection.objects.link(sun)
    mesh = bpy.data.meshes.new("Plane")
    mesh.from_pydata([(-5, 50, 0), (5, 50, 0), (5, 50, 5), (-5, 50, 5)], [], [(0, 1, 2, 3)])
    material = bpy.data.materials.new("Grey")
    if bpy.app.version < (5, 0, 0):
        material.use_nodes = True
    mesh.materials.append(material)
    scene.collection.objects.link(bpy.data.objects.new("Plane", mesh))
    return scene


def _part_groups() -> list:
    return [tree for tree in bpy.data.node_groups if parts.is_part(tree)]


def _part_nodes(tree) -> list:
    return [node for node in tree.nodes if parts.instanced_part(node) is not None]


def test_default_builds_each_part_once_and_small_trees():
    scene = _new_user_scene()
    api.enable(scene, preset="clear", sun_elevation_deg=20.0)
    managed = [tree for _, tree in registry.managed_trees()]
    found = _part_groups()
    assert {tree.name for tree in found} >= {"Atmos Table Sample (Compositor)", "Atmos Table Sample (Row)",
                                            "Atmos phi1", "Atmos Distance to Top", "Atmos Sun Disk",
                                            "Atmos Sky Path Length"}
    assert len({tree.name for tree in found}) == len(found)
    assert not any(tree.name[-4:-3] == "." for tree in bpy.data.node_groups), "a part built twice"
    for tree in managed:
        assert len(tree.nodes) <= LARGEST_TREE, (tree.name, len(tree.nodes))
        for node in _part_nodes(tree):
            part = parts.part_of(node.node_tree[stamps.FEATURES_KEY])
            assert stamps.is_current(node.node_tree, parts.kind_for(node.node_tree.bl_idname), part.key)
    sky = bpy.data.node_groups[stamps.SKY.name]
    features_key = sky[stamps.FEATURES_KEY]
    assert _part_nodes(sky), "the sky instances its parts"
    assert parts.inline_count(sky) == SKY_NODE_COUNTS[features_key]   # the same equations as one flat tree
    table_samples = [node for node in sky.nodes if node.bl_idname == "ShaderNodeGroup"
                     and node.node_tree.name.startswith("Atmos Table Sample")]
    assert len(table_samples) == 5 and len({node.node_tree for node in table_samples}) == 1
    image = bpy.data.images["Atmos Precise Table"]
    for tree in found:
        for node in tree.nodes:
            if node.bl_idname in ("ShaderNodeTexImage", "CompositorNodeImage"):
                assert node.image == image, tree.name   # the table's image reaches the nodes inside the parts
    assert group_integrity.edited_groups(force=True) == []


def test_mode_switch_and_disable_leave_no_part_behind():
    scene = _new_user_scene()
    api.enable(scene, preset="clear")
    assert any(tree.bl_idname == "CompositorNodeTree" for tree in _part_groups())   # the Per Pixel group's
    scene.atmos.render_mode = "COMPOSITOR"
    assert not [tree.name for tree in _part_groups() if tree.users == 0]
    composite = bpy.data.node_groups[stamps.COMPOSITE.name]   # the Per Pixel group's parts gone, the composite's kept
    assert {tree for tree in _part_groups() if tree.bl_idname == "CompositorNodeTree"} == parts.used_parts(composite)
    assert not any("Per Pixel" in tree.name or tree.name.startswith("Atmos Two Point (Compositor)")
                   for tree in _part_groups())
    scene.atmos.render_mode = "PER_PIXEL"
    api.disable(scene)
    assert _part_groups() == []
    assert registry.managed_trees() == []


def test_a_users_group_with_a_parts_name_is_left_alone():
    scene = _new_user_scene()
    theirs = bpy.data.node_groups.new("Atmos Sun Disk", "ShaderNodeTree")
    theirs.nodes.new("ShaderNodeMath")
    theirs.use_fake_user = True
    api.enable(scene, preset="clear")
    assert theirs.name == "Atmos Sun Disk (not Atmos)" and len(theirs.nodes) == 1
    ours = bpy.data.node_groups["Atmos Sun Disk"]
    assert ours != theirs and parts.is_part(ours)
    api.disable(scene)
    assert bpy.data.node_groups.get("Atmos Sun Disk (not Atmos)") == theirs and len(theirs.nodes) == 1


def test_a_hand_edit_inside_a_part_is_reported_and_reset():
    scene = _new_user_scene()
    api.enable(scene, preset="clear")
    part = bpy.data.node_groups["Atmos Sun Disk"]
    maths = next(node for node in part.nodes if node.bl_idname == "ShaderNodeMath" and not node.inputs[1].is_linked)
    maths.inputs[1].default_value += 1.0
    assert "Atmos Sun Disk" in group_integrity.edited_groups(force=True)
    users = [node for tree in bpy.data.node_groups for node in _part_nodes(tree) if node.node_tree == part]
    assert "Atmos Sun Disk" in group_integrity.reset_groups(["Atmos Sun Disk"])
    assert bpy.data.node_groups["Atmos Sun Disk"] == part   # rebuilt in place: its users keep it
    assert all(node.node_tree == part and node.outputs[0].is_linked for node in users)
    assert "Atmos Sun Disk" not in group_integrity.edited_groups(force=True)


def test_a_stale_part_is_rebuilt_in_place_when_its_user_is():
    scene = _new_user_scene()
    api.enable(scene, preset="clear")
    part = bpy.data.node_groups["Atmos Sky Path Length"]
    part[stamps.FEATURES_KEY] = "Atmos Sky Path Length|0"   # as an older release would have stamped it
    part.nodes.clear()
    sky = bpy.data.node_groups[stamps.SKY.name]
    sky[stamps.VERSION_KEY] = stamps.SKY.version - 1
    orchestrator.refresh_effect(scene)
    assert bpy.data.node_groups["Atmos Sky Path Length"] == part and bpy.data.node_groups[stamps.SKY.name] == sky
    assert stamps.is_current(part, stamps.PART, parts.PARTS["Atmos Sky Path Length"].key) and len(part.nodes) > 2
    assert stamps.is_current(sky, stamps.SKY, sky[stamps.FEATURES_KEY])
    assert parts.inline_count(sky) == SKY_NODE_COUNTS[sky[stamps.FEATURES_KEY]]
    assert not bpy.data.node_groups.get("Atmos Sky Path Length.001")


def test_a_part_name_is_one_part_and_a_reload_redefines_it():
    def build(g, x):
        return g.mul(x, 2.0)

    def other(g, x):
        return g.mul(x, 3.0)

    other.__module__ = "somewhere.else"
    try:
        first = parts.define("Atmos Test Part", 1, (("x", parts.FLOAT),), (("y", parts.FLOAT),), build)
        again = parts.define("Atmos Test Part", 2, (("x", parts.FLOAT),), (("y", parts.FLOAT),), build)
        assert parts.PARTS["Atmos Test Part"] == again != first   # the module reloaded: the new definition
        with pytest.raises(ValueError, match="defined twice"):
            parts.define("Atmos Test Part", 1, (("x", parts.FLOAT),), (("y", parts.FLOAT),), other)
    finally:
        parts.PARTS.pop("Atmos Test Part", None)


def test_one_walk_reads_each_node_once_and_the_table_reaches_every_part():
    scene = _new_user_scene()
    api.enable(scene, preset="clear")
    named = [bpy.data.node_groups[stamps.SKY.name], bpy.data.node_groups[stamps.PER_PIXEL.name]]
    used = set()
    for tree in named:
        parts.used_parts(tree, used)
    walked = [(tree.name, node.name, idname) for tree, node, idname in parts.nodes_with_parts(named)]
    assert len(walked) == len(set(walked)), "a part's nodes walked twice"
    assert set(walked) == {(tree.name, node.name, node.bl_idname) for tree in named + list(used) for node in tree.nodes}
    assert used and used == set().union(*(parts.used_parts(tree) for tree in named))   # the shared set: the same parts
    assert ([tree.name for tree in bpy.data.node_groups if parts.is_part(tree)]
            == [tree.name for tree in bpy.data.node_groups if stamps.kind_of(tree) in stamps.PART_KINDS])
    # The table image deleted by hand: the next bake makes a new one and points every table node at it, inside the
    # parts too (the bake walks the groups once, :func:`parts.nodes_with_parts`).
    bpy.data.images.remove(bpy.data.images["Atmos Precise Table"])
    orchestrator.refresh_effect(scene)
    image = bpy.data.images["Atmos Precise Table"]
    taps = [(tree.name, node) for tree, node, idname in parts.nodes_with_parts(named)
            if idname in ("ShaderNodeTexImage", "CompositorNodeImage")]
    assert {name for name, _ in taps} == {"Atmos Table Sample (Row)", "Atmos Table Sample (Compositor)"}
    assert all(node.image == image for _, node in taps)
    assert group_integrity.edited_groups(force=True) == []


def test_the_status_counts_the_per_pixel_groups_nodes_after_each_rebuild():
    scene = _new_user_scene()
    api.enable(scene, preset="clear")

    def counted() -> int:
        return int(scene.atmos.status_built.split("per pixel: ")[1].split()[0])

    per_pixel = bpy.data.node_groups[stamps.PER_PIXEL.name]
    precise_count = parts.inline_count(per_pixel)
    assert counted() == precise_count
    scene.atmos.quality = "FAST"        # the same group rebuilt in place for the Fast level: another count
    assert bpy.data.node_groups[stamps.PER_PIXEL.name] == per_pixel
    assert counted() == parts.inline_count(per_pixel) != precise_count
    scene.atmos.quality = "PRECISE"
    assert counted() == precise_count
