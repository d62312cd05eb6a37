# SPDX-License-Identifier: GPL-3.0-or-later
"""Objects a collection holds out carry the mark the AOV outputs group reads (``apply/holdouts.py``): set on the
enable and when a collection's Holdout changes, kept off where view layers disagree (the panel's note then), and
removed with the effect. The render the marks give is held by ``test_silhouettes.py``."""

from __future__ import annotations

import math

import bpy

import render_utils as ru
from atmos_addon import api
from atmos_addon.blender import facts
from atmos_addon.plan import HOLDOUT_ATTRIBUTE, NOTE_HOLDOUT


def _scene(scene):
    """A factory-empty scene: a camera and two triangles, "Plate" in a collection "Held out" (not yet held out)
    and "Ground" in the scene's own collection; no world, no sun."""
    ru.make_camera(scene, rotation_euler=(math.radians(90.0), 0.0, 0.0))
    held = bpy.data.collections.new("Held out")
    scene.collection.children.link(held)
    for name, collection in (("Plate", held), ("Ground", scene.collection)):
        mesh = bpy.data.meshes.new(name)
        mesh.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
        material = bpy.data.materials.new(name)
        ru.set_use_nodes(material)   # Blender 4.5 makes a material without nodes
        mesh.materials.append(material)
        collection.objects.link(bpy.data.objects.new(name, mesh))
    return scene


def _marked(scene) -> set[str]:
    return {obj.name for obj in scene.objects if HOLDOUT_ATTRIBUTE in obj}


def test_the_held_out_objects_are_marked_and_follow_the_collections_holdout(addon):
    scene = _scene(addon)
    layer_collection = scene.view_layers[0].layer_collection.children["Held out"]
    layer_collection.holdout = True
    api.enable(scene, preset="clear")
    assert _marked(scene) == {"Plate"}
    assert bpy.data.objects["Plate"][HOLDOUT_ATTRIBUTE] == 1.0
    assert NOTE_HOLDOUT not in facts.plan_of(scene).notes   # marked: the edges are exact, nothing to note
    layer_collection.holdout = False
    scene.view_layers[0].update()                          # the depsgraph handler follows the switch
    assert _marked(scene) == set()
    layer_collection.holdout = True
    scene.view_layers[0].update()
    assert _marked(scene) == {"Plate"}
    api.disable(scene)
    assert _marked(scene) == set()                         # the scene keeps nothing of Atmos


def test_view_layers_that_disagree_leave_the_object_unmarked_and_the_panel_says_so(addon):
    scene = _scene(addon)
    scene.view_layers[0].layer_collection.children["Held out"].holdout = True
    second = scene.view_layers.new("Beauty")
    assert not second.layer_collection.children["Held out"].holdout
    api.enable(scene, preset="clear")
    assert _marked(scene) == set()
    assert NOTE_HOLDOUT in facts.plan_of(scene).notes
    second.use = False                                     # only the first layer renders: it alone decides
    scene.view_layers[0].update()
    assert _marked(scene) == {"Plate"}
    assert NOTE_HOLDOUT not in facts.plan_of(scene).notes


def test_the_marks_and_the_group_that_reads_them_are_saved_for_a_farm_without_the_add_on(addon, tmp_path):
    import atmos_addon
    from atmos_addon.node_groups import stamps

    scene = _scene(addon)
    scene.view_layers[0].layer_collection.children["Held out"].holdout = True
    api.enable(scene, preset="clear")
    path = tmp_path / "held_out.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    atmos_addon.unregister()
    try:
        bpy.ops.wm.open_mainfile(filepath=str(path))
        assert bpy.data.objects["Plate"].get(HOLDOUT_ATTRIBUTE) == 1.0
        outputs = bpy.data.node_groups[stamps.SURFACE_OUTPUTS.name]
        assert any(node.bl_idname == "ShaderNodeAttribute" and node.attribute_type == "OBJECT"
                   and node.attribute_name == HOLDOUT_ATTRIBUTE for node in outputs.nodes)
    finally:
        atmos_addon.register()   # the fixture unregisters
