# SPDX-License-Identifier: GPL-3.0-or-later
"""Undo and redo across enable, disable, presets, sun moves, quality and mode changes, renames and deletions.

Undo runs headless: after a first ``bpy.ops.ed.undo_push`` creates the undo stack, ``bpy.ops.ed.undo`` and
``bpy.ops.ed.redo`` restore the file's data from memory (memfile undo, as in the UI), and an operator called with
``undo=True`` (``bpy.ops.atmos.enable("EXEC_DEFAULT", True)``) pushes its own step, as a click does. (Their
``poll()`` is false until the stack holds a step to undo, which is why it looked unavailable headless.)

The walk test records the whole state Atmos touches after every step (materials' nodes and links, node groups
and their users, images and the Precise table's pixels, objects, settings, shader parameters and their keys,
compositor, view layer AOVs, world, lamp), undoes every step and redoes them, and compares at each stop.
"""

from __future__ import annotations

import hashlib
import math

import bpy
import numpy as np
import pytest

from atmos_addon.blender.apply import materials
from atmos_addon.blender import scene_reading

from test_robustness import (compositor_state, lamp_direction, mesh_object, orphan_groups, small_scene, snapshot,
                             user_compositor, user_material)

pytestmark = pytest.mark.usefixtures("addon")

SETTINGS = ("enabled", "quality", "render_mode", "sky_enabled", "drive_sun_lamp", "rayleigh_scattering_per_km",
            "mie_scattering_per_km", "mie_absorption_per_km", "mie_g", "distance_scale", "status_sun")


def _plain(value):
    if hasattr(value, "to_dict"):
        return value.to_dict()
    if hasattr(value, "__len__") and not isinstance(value, str):
        return tuple(_plain(v) for v in value)
    return value


def push(message: str) -> None:
    bpy.ops.ed.undo_push(message=message)


def undo() -> bpy.types.Scene:
    """Undo one step and let the depsgraph handlers run, as the UI's redraw does; the scene afterwards (every
    Python reference to data is stale after a memfile undo)."""
    assert bpy.ops.ed.undo() == {"FINISHED"}
    bpy.context.view_layer.update()
    return bpy.context.scene


def redo() -> bpy.types.Scene:
    assert bpy.ops.ed.redo() == {"FINISHED"}
    bpy.context.view_layer.update()
    return bpy.context.scene


def _table_digest() -> str | None:
    """A digest of the Precise table's pixels as the render reads them (None without a table)."""
    image = bpy.data.images.get("Atmos Precise Table")
    if image is None:
        return None
    pixels = np.empty(len(image.pixels), dtype=np.float32)
    image.pixels.foreach_get(pixels)
    return hashlib.sha1(pixels.tobytes()).hexdigest()


def state(scene) -> dict:
    """Everything Atmos adds to or changes in a file, in comparable form."""
    lamp = bpy.data.objects.get("Sun")
    action = scene.animation_data.action if scene.animation_data else None
    return {
        "materials": {m.name: snapshot(m.node_tree) for m in bpy.data.materials if m.node_tree is not None},
        "groups": sorted((g.name, g.users) for g in bpy.data.node_groups),
        "images": sorted(i.name for i in bpy.data.images),
        "table": _table_digest(),
        "objects": sorted(o.name for o in bpy.data.objects),
        "settings": {name: _plain(getattr(scene.atmos, name)) for name in SETTINGS},
        "parameters": {key: _plain(scene[key]) for key in scene.keys() if key.startswith("atmos_")},
        "keys": sorted((c.data_path, len(c.keyframe_points)) for c in _fcurves(action)),
        "compositor": compositor_state(scene),
        "aovs": {layer.name: [a.name for a in layer.aovs] for layer in scene.view_layers},
        "world": snapshot(scene.world.node_tree) if scene.world else None,
        "lamp": None if lamp is None else (tuple(lamp.rotation_euler), tuple(lamp.data.color), lamp.data.energy),
    }


def _fcurves(action):
    if action is None:
        return []
    return scene_reading.groups().parameters.fcurves_of(action)


def assert_states_equal(got: dict, want: dict, where: str) -> None:
    for key in want:
        assert got[key] == want[key], f"{where}: {key} differs"


def sun_consistent(scene) -> None:
    """The shader's sun direction is the lamp's (the parameters follow the restored lamp)."""
    lamp = scene_reading.sun_object(scene)
    np.testing.assert_allclose(scene["atmos_sun_direction"], lamp_direction(lamp), atol=1e-6)


def test_undo_and_redo_walk_back_and_forth_through_every_kind_of_change() -> None:
    scene, sun, _ = small_scene()
    scene.render.engine = "CYCLES"
    user_compositor(scene)
    push("scene built")
    states = [("scene built", state(scene))]

    def step(message, action):
        action()
        bpy.context.view_layer.update()   # the depsgraph handler follows the change, as after a click
        push(message)
        states.append((message, state(bpy.context.scene)))

    def move_sun(x_deg, z_deg):
        def action():
            bpy.data.objects["Sun"].rotation_euler = (math.radians(x_deg), 0.0, math.radians(z_deg))
        return action

    def settings(**values):
        def action():
            for name, value in values.items():
                setattr(bpy.context.scene.atmos, name, value)
        return action

    def new_object():
        mesh_object("Late", user_material("Late material"), location=(2.0, 30.0, 0.0))
        assert bpy.ops.atmos.refresh("EXEC_DEFAULT", False) == {"FINISHED"}

    step("enable", lambda: bpy.ops.atmos.enable("EXEC_DEFAULT", False))
    step("preset sunset", lambda: bpy.ops.atmos.preset_apply("EXEC_DEFAULT", False, name="sunset"))
    step("sun moved", move_sun(60.0, 40.0))
    step("quality Fast", settings(quality="FAST"))   # from the default, Precise
    step("sun moved again", move_sun(75.0, 10.0))
    step("mode Compositor", settings(render_mode="COMPOSITOR"))   # from the default, Per Pixel
    step("preset overcast", lambda: bpy.ops.atmos.preset_apply("EXEC_DEFAULT", False, name="overcast"))
    step("quality Auto", settings(quality="AUTO"))
    step("mode In-Render", settings(render_mode="IN_RENDER"))
    step("new object, refresh", new_object)
    step("slider", settings(mie_g=(0.5, 0.5, 0.5), distance_scale=2.0))
    step("disable", lambda: bpy.ops.atmos.disable("EXEC_DEFAULT", False))
    assert len({repr(s) for _, s in states}) == len(states), "two steps left the same state: the walk proves less"

    for index in range(len(states) - 1, 0, -1):
        scene = undo()
        message, want = states[index - 1]
        assert_states_equal(state(scene), want, f"undo to '{message}'")
        if scene.atmos.enabled:
            sun_consistent(scene)
        assert orphan_groups() == [], f"undo to '{message}'"
    for message, want in states[1:]:
        scene = redo()
        assert_states_equal(state(scene), want, f"redo to '{message}'")
        assert orphan_groups() == []


@pytest.mark.parametrize("mode", ["COMPOSITOR", "PER_PIXEL", "IN_RENDER"])
def test_undo_enable_and_disable_restores_the_users_scene_exactly(mode) -> None:
    scene, _, mats = small_scene()
    scene.render.engine = "CYCLES"
    scene.atmos.render_mode = mode
    user_compositor(scene)
    push("scene built")
    before = state(scene)
    assert bpy.ops.atmos.enable("EXEC_DEFAULT", True) == {"FINISHED"}   # pushes its own step, as a click does
    bpy.context.view_layer.update()
    enabled = state(bpy.context.scene)
    assert enabled["groups"] != before["groups"] and enabled["materials"] != before["materials"]
    scene = undo()
    assert_states_equal(state(scene), before, "undo enable")
    assert not any(materials.is_injected(m) for m in bpy.data.materials)
    scene = redo()
    assert_states_equal(state(scene), enabled, "redo enable")
    assert bpy.ops.atmos.disable("EXEC_DEFAULT", True) == {"FINISHED"}
    bpy.context.view_layer.update()
    assert_states_equal(state(bpy.context.scene), before, "disable")
    scene = undo()
    assert_states_equal(state(scene), enabled, "undo disable")
    scene = redo()
    assert_states_equal(state(scene), before, "redo disable")
    assert orphan_groups() == []


def test_undo_of_a_precise_sun_move_restores_the_table_the_render_reads() -> None:
    """Blender keeps image buffers across undo: without the undo handler the table's pixels would stay those of
    the sun undone from, while the file's packed table (and a farm) has the other."""
    scene, _, _ = small_scene()
    scene.render.engine = "CYCLES"
    scene.atmos.quality = "PRECISE"
    push("scene built")
    bpy.ops.atmos.enable("EXEC_DEFAULT", True)
    table_a = _table_digest()
    bpy.data.objects["Sun"].rotation_euler = (math.radians(80.0), 0.0, 0.5)
    bpy.context.view_layer.update()
    push("sun moved")
    table_b = _table_digest()
    assert table_a != table_b
    undo()
    assert _table_digest() == table_a
    redo()
    assert _table_digest() == table_b


def test_undo_to_a_step_saved_before_the_handler_synced_resyncs() -> None:
    """In the UI a transform pushes its undo step before the depsgraph handler writes the sun's parameters, so
    that step holds the moved lamp with the old parameters. Undoing back to it must not render them."""
    scene, _, _ = small_scene()
    scene.render.engine = "CYCLES"
    push("scene built")
    bpy.ops.atmos.enable("EXEC_DEFAULT", True)
    bpy.data.objects["Sun"].rotation_euler = (math.radians(70.0), 0.0, math.radians(-20.0))
    push("move")                      # the step holds the new lamp and the old parameters
    bpy.context.view_layer.update()   # the handler writes the new parameters after the push
    sun_consistent(bpy.context.scene)
    bpy.context.scene.atmos.mie_g = (0.5, 0.5, 0.5)
    push("slider")
    scene = undo()
    assert tuple(scene.atmos.mie_g) != pytest.approx((0.5, 0.5, 0.5))
    sun_consistent(scene)


def test_undo_and_redo_rename_and_delete_of_sun_camera_and_world_give_status_not_exceptions() -> None:
    scene, sun, mats = small_scene()
    names = [m.name for m in mats]   # Python references to data go stale on undo
    scene.render.engine = "CYCLES"
    push("scene built")
    bpy.ops.atmos.enable("EXEC_DEFAULT", True)
    sun.name = "Sol"
    bpy.context.view_layer.update()
    push("rename sun")
    assert "'Sol'" in bpy.context.scene.atmos.status_sun
    scene = undo()
    assert "'Sun'" in scene.atmos.status_sun
    scene = redo()
    assert "'Sol'" in scene.atmos.status_sun

    sun = bpy.data.objects["Sol"]
    lamp_data = sun.data
    bpy.data.objects.remove(sun)
    bpy.data.lights.remove(lamp_data)
    bpy.context.view_layer.update()
    push("delete sun")
    assert "no sun lamp" in bpy.context.scene.atmos.status_sun.lower()
    scene = undo()
    assert "'Sol'" in scene.atmos.status_sun
    bpy.data.objects["Sol"].rotation_euler = (math.radians(65.0), 0.0, 0.3)   # the restored lamp is followed
    bpy.context.view_layer.update()
    sun_consistent(scene)
    push("move restored sun")

    bpy.data.objects.remove(scene.camera)
    bpy.data.worlds.remove(scene.world)
    bpy.context.view_layer.update()
    assert bpy.ops.atmos.refresh("EXEC_DEFAULT", True) == {"FINISHED"}
    scene = undo()
    assert scene.camera is not None and scene.world is not None
    assert all(materials.is_injected(bpy.data.materials[name]) for name in names)
    scene = redo()
    assert scene.camera is None and scene.world.name == "Atmos Sky World"   # the refresh gave the sky a world
    assert bpy.ops.atmos.refresh("EXEC_DEFAULT", True) == {"FINISHED"}
    assert orphan_groups() == []
