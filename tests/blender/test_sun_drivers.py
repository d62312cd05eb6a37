# SPDX-License-Identifier: GPL-3.0-or-later
"""The sun's direction and E_sun, and the sun lamp's colour and strength, follow the lamp through drivers
(:mod:`atmos_addon.blender.apply.sun_drivers`): a sun move writes nothing that makes Blender re-evaluate the scene,
the values are the physics' (E_sun through its table, within 0.2 %), and the drivers go exactly as they came.

Scenes built from scratch (an empty factory file: no world, a bare camera, a sun lamp of the user's own)."""

from __future__ import annotations

import math
from pathlib import Path

import bpy
import numpy as np
import pytest

import render_utils as ru
from atmos_addon.blender import orchestrator, scene_reading, sun_bake
from atmos_addon.blender.apply import sun_drivers, sun_lamp
from atmos_addon.physics import sun_irradiance_ground
from atmos_addon.physics.sun import LUMINANCE_WEIGHTS

SUN_PATHS = {('["atmos_sun_direction"]', i) for i in range(3)} | {('["atmos_sun_irradiance"]', i) for i in range(3)}
LIGHT_PATHS = {("color", 0), ("color", 1), ("color", 2), ("energy", 0)}


def _driven(idblock) -> set:
    animation = idblock.animation_data
    return set() if animation is None else {(c.data_path, c.array_index) for c in animation.drivers}


def _user_sun(scene, name: str = "Key Light", colour=(0.9, 0.8, 0.7), energy: float = 3.0):
    light = bpy.data.lights.new(name, "SUN")
    light.color, light.energy = colour, energy
    lamp = bpy.data.objects.new(name, light)
    scene.collection.objects.link(lamp)
    return lamp


def _scene(scene):
    ru.make_camera(scene, location=(0.0, 0.0, 2.0), rotation_euler=(math.radians(85.0), 0.0, 0.0))
    lamp = _user_sun(scene)
    scene.atmos.sun_object = lamp
    sun_lamp.set_sun_angles(scene, math.radians(30.0), math.radians(120.0))
    bpy.context.view_layer.update()
    return lamp


def test_a_sun_move_leaves_nothing_for_blender_to_re_evaluate(addon):
    """After the update that moves the sun (the drivers and Atmos's handler run in it), the next update has nothing
    to do: Atmos wrote nothing that tags the scene (a tagged scene re-evaluates every object: 0.4-0.5 s with 20000)."""
    scene = addon
    lamp = _scene(scene)
    orchestrator.enable_effect(scene)
    bpy.context.view_layer.update()
    updated = []

    def note(_scene, depsgraph):
        updated.append({kind for kind in ("SCENE", "OBJECT", "MATERIAL", "WORLD", "NODETREE", "LIGHT")
                        if depsgraph.id_type_updated(kind)})

    bpy.app.handlers.depsgraph_update_post.append(note)
    try:
        for turn in ((0.0, math.radians(2.0)), (math.radians(-4.0), 0.0)):   # an azimuth move, an elevation move
            lamp.rotation_euler.x += turn[0]
            lamp.rotation_euler.z += turn[1]
            bpy.context.view_layer.update()
            assert updated and "OBJECT" in updated[-1]   # the move itself
            updated.clear()
            bpy.context.view_layer.update()
            assert not any("SCENE" in kinds for kinds in updated), updated
            updated.clear()
    finally:
        bpy.app.handlers.depsgraph_update_post.remove(note)
    np.testing.assert_allclose(scene["atmos_sun_direction"], lamp.matrix_world.col[2][:3], atol=1e-6)


def test_the_driven_values_are_the_physics(addon):
    scene = addon
    lamp = _scene(scene)
    orchestrator.enable_effect(scene)
    assert _driven(scene) >= SUN_PATHS and _driven(lamp.data) == LIGHT_PATHS
    atmosphere = scene_reading.atmosphere_of(scene)
    radius = 0.5 * scene.atmos.sun_angular_diameter
    for elevation in (75.0, 12.0, 3.0, 0.3, -0.1, -2.0):
        sun_lamp.set_sun_angles(scene, math.radians(elevation), math.radians(200.0))
        bpy.context.view_layer.update()
        direction = np.asarray(lamp.matrix_world.col[2][:3])
        np.testing.assert_allclose(scene["atmos_sun_direction"], direction, atol=1e-6)
        # The lamp's own elevation (its float32 matrix: at 0.3 deg E_sun changes 1e-4 with its last bit).
        e_sun = sun_irradiance_ground(math.asin(direction[2]), atmosphere, 0.0, radius)
        driven = np.asarray(scene["atmos_sun_irradiance"])
        np.testing.assert_allclose(driven, e_sun, rtol=2e-3, atol=2e-5 * float(atmosphere.sun_irradiance_top.max()))
        light = lamp.data
        strength = float(driven @ LUMINANCE_WEIGHTS)
        assert light.energy == pytest.approx(strength, rel=1e-5, abs=1e-9)
        expected_colour = driven / strength if strength > 0.0 else np.ones(3)
        np.testing.assert_allclose(light.color, expected_colour, rtol=1e-5)
        # What the panel shows (written without a tag) is what renders: the lamp's.
        assert scene.atmos.sun_strength_display == pytest.approx(light.energy, rel=1e-5, abs=1e-9)
        np.testing.assert_allclose(scene.atmos.sun_colour_display, light.color, rtol=1e-5)
        assert f"{elevation:.1f} degrees" in scene.atmos.status_sun
    assert elevation < 0 and light.energy == 0.0 and tuple(light.color) == (1.0, 1.0, 1.0)


def test_disable_removes_the_drivers_and_gives_the_lamp_its_values_back(addon):
    scene = addon
    lamp = _scene(scene)
    orchestrator.enable_effect(scene)
    assert sun_drivers.state(scene) == {"lamp": lamp.name, "light": lamp.data.name,
                                        "table": sun_drivers.state(scene)["table"]}
    bpy.context.view_layer.update()
    assert lamp.data.energy != pytest.approx(3.0)
    orchestrator.disable_effect(scene)
    assert not _driven(scene) and not _driven(lamp.data)
    assert sun_drivers.STATE_KEY not in scene
    assert tuple(lamp.data.color) == pytest.approx((0.9, 0.8, 0.7)) and lamp.data.energy == pytest.approx(3.0)
    bpy.context.view_layer.update()   # nothing drives them any more
    assert lamp.data.energy == pytest.approx(3.0)


def test_the_drivers_follow_the_lamp_setting_and_the_drive_switch(addon):
    scene = addon
    first = _scene(scene)
    orchestrator.enable_effect(scene)
    table = sun_drivers.state(scene)["table"]
    second = _user_sun(scene, "Other Sun", (1.0, 1.0, 1.0), 5.0)
    second.rotation_euler = (math.radians(80.0), 0.0, 0.0)   # 10 deg up
    scene.atmos.sun_object = second
    bpy.context.view_layer.update()
    assert not _driven(first.data) and _driven(second.data) == LIGHT_PATHS
    # the lamp left has its own light back (it kept Atmos's until December 2026, after a disable too)
    assert tuple(first.data.color) == pytest.approx((0.9, 0.8, 0.7)) and first.data.energy == pytest.approx(3.0)
    assert sun_drivers.state(scene) == {"lamp": second.name, "light": second.data.name, "table": table}
    np.testing.assert_allclose(scene["atmos_sun_direction"], second.matrix_world.col[2][:3], atol=1e-6)
    assert second.data.energy != pytest.approx(5.0)   # driven
    scene.atmos.drive_sun_lamp = False
    bpy.context.view_layer.update()
    assert not _driven(second.data) and _driven(scene) >= SUN_PATHS
    assert tuple(second.data.color) == pytest.approx((1.0, 1.0, 1.0)) and second.data.energy == pytest.approx(5.0)
    scene.atmos.drive_sun_lamp = True
    assert _driven(second.data) == LIGHT_PATHS
    scene.atmos.mie_scattering_per_km = (0.2, 0.2, 0.2)   # a thicker haze: a new E_sun table
    bpy.context.view_layer.update()
    assert sun_drivers.state(scene)["table"] != table
    e_sun = sun_irradiance_ground(math.radians(10.0), scene_reading.atmosphere_of(scene), 0.0,
                                  0.5 * scene.atmos.sun_angular_diameter)
    np.testing.assert_allclose(scene["atmos_sun_irradiance"], e_sun, rtol=2e-3)
    orchestrator.disable_effect(scene)
    bpy.context.view_layer.update()
    for lamp, colour, energy in ((first, (0.9, 0.8, 0.7), 3.0), (second, (1.0, 1.0, 1.0), 5.0)):
        assert not _driven(lamp.data)
        assert tuple(lamp.data.color) == pytest.approx(colour) and lamp.data.energy == pytest.approx(energy)


def test_a_file_with_an_older_atmos_s_per_frame_sun_keys_loses_them(addon, tmp_path: Path):
    """An older Atmos keyed the sun's parameters and the lamp on every frame of an animated sun. Opening such a file
    removes the keys (the drivers, which override them anyway, now follow the sun) and records the animation again."""
    scene = addon
    lamp = _scene(scene)
    scene.frame_start, scene.frame_end = 1, 3
    for frame, angle in ((1, 40.0), (3, 85.0)):
        lamp.rotation_euler = (math.radians(angle), 0.0, math.radians(30.0))
        lamp.keyframe_insert("rotation_euler", frame=frame)
    scene.frame_set(1)
    orchestrator.enable_effect(scene)
    for frame in (1, 2, 3):   # what the older bake wrote
        scene.keyframe_insert('["atmos_sun_direction"]', frame=frame)
        lamp.data.keyframe_insert("energy", frame=frame)
    scene[sun_bake.BAKED_KEY] = {"lamp_data": lamp.data.name, "start": 1, "end": 3,
                                 "inputs": sun_bake.bake_inputs(scene)}
    assert sun_bake.baked_fcurves(scene) and sun_bake.baked_fcurves(lamp.data)
    path = tmp_path / "older.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.open_mainfile(filepath=str(path))
    scene = bpy.context.scene
    lamp = bpy.data.objects["Key Light"]
    assert not sun_bake.baked_fcurves(scene) and not sun_bake.baked_fcurves(lamp.data)
    assert scene[sun_bake.BAKED_KEY].to_dict()["driven"] and sun_bake.is_bake_current(scene)
    for frame in (1, 3):
        scene.frame_set(frame)
        np.testing.assert_allclose(scene["atmos_sun_direction"], lamp.matrix_world.col[2][:3], atol=1e-6)


def test_a_lamp_a_rig_drives_keeps_its_drivers(addon):
    """A light whose strength a rig drives keeps that driver through enable and disable: Atmos drives the scene's sun
    parameters but leaves the light's colour and strength to the rig."""
    scene = addon
    lamp = _scene(scene)
    scene["rig_strength"] = 7.0
    curve = lamp.data.driver_add("energy")
    curve.driver.type = "AVERAGE"
    variable = curve.driver.variables.new()
    variable.targets[0].id_type = "SCENE"
    variable.targets[0].id = scene
    variable.targets[0].data_path = '["rig_strength"]'
    orchestrator.enable_effect(scene)
    bpy.context.view_layer.update()
    assert _driven(scene) >= SUN_PATHS and _driven(lamp.data) == {("energy", 0)}
    assert sun_drivers.state(scene)["light"] == "" and lamp.data.energy == pytest.approx(7.0)
    assert lamp.data.animation_data.drivers[0].driver.variables[0].targets[0].data_path == '["rig_strength"]'
    orchestrator.disable_effect(scene)
    assert _driven(lamp.data) == {("energy", 0)} and not _driven(scene)
    bpy.context.view_layer.update()
    assert lamp.data.energy == pytest.approx(7.0)


def test_a_sun_lamp_switched_off_for_renders_is_not_the_one_driven(addon):
    """With no lamp picked Atmos takes the first sun lamp that renders: a lamp switched off for renders (an
    alternative kept in the file) that came first was driven until December 2026, its direction the sky's sun while
    the light came from another. With none that renders, the first is used."""
    scene = addon
    ru.make_camera(scene, location=(0.0, 0.0, 2.0), rotation_euler=(math.radians(85.0), 0.0, 0.0))
    spare = _user_sun(scene, "A Spare Sun", (1.0, 0.5, 0.5), 2.0)
    spare.hide_render = True
    key = _user_sun(scene, "Key Sun")
    assert [obj.name for obj in scene.objects if obj.type == "LIGHT"][0] == spare.name   # the spare comes first
    orchestrator.enable_effect(scene)
    bpy.context.view_layer.update()
    assert scene_reading.sun_object(scene) == key
    assert _driven(key.data) == LIGHT_PATHS and not _driven(spare.data)
    assert tuple(spare.data.color) == pytest.approx((1.0, 0.5, 0.5)) and spare.data.energy == pytest.approx(2.0)
    key.hide_render = True
    assert scene_reading.sun_object(scene) == spare   # none renders: the first
