# SPDX-License-Identifier: GPL-3.0-or-later
"""Production robustness: save and reload, farm renders without the add-on, enable/disable invariants, user
edits, several scenes, many enable/disable cycles and bad input (undo and redo: ``test_undo.py``).

Handlers in the ``bpy`` module: ``depsgraph_update_post`` fires headless when the depsgraph is
evaluated, so the tests call ``bpy.context.view_layer.update()`` after a change (4.5 to 5.3 alike);
``load_post`` fires on ``bpy.ops.wm.open_mainfile``.
"""

from __future__ import annotations

import math
import textwrap
import warnings
from pathlib import Path

import bpy
import numpy as np
import pytest

from atmos_addon import plan
from atmos_addon.node_groups import stamps, surface
from atmos_addon.blender.apply import compositor, materials
from atmos_addon.blender import facts, orchestrator, scene_reading, sun_bake

import render_utils
from render_utils import snapshot_tree as snapshot

IS_5 = bpy.app.version >= (5, 0, 0)
PARAMETERS = ("atmos_beta_rayleigh", "atmos_beta_mie", "atmos_beta_mie_absorption", "atmos_mie_g",
              "atmos_sun_direction", "atmos_sun_irradiance", "atmos_metres_per_unit")


pytestmark = pytest.mark.usefixtures("addon")


# -- helpers -------------------------------------------------------------------------------------


def _quiet(function, *args):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        return function(*args)


def _node_material(name: str):
    material = bpy.data.materials.new(name)
    _quiet(setattr, material, "use_nodes", True)
    return material


def user_material(name: str = "User"):
    """Noise -> colour ramp -> Principled, plus a loose math node: a material with the user's own work."""
    material = _node_material(name)
    tree = material.node_tree
    noise = tree.nodes.new("ShaderNodeTexNoise")
    ramp = tree.nodes.new("ShaderNodeValToRGB")
    loose = tree.nodes.new("ShaderNodeMath")
    loose.inputs[0].default_value = 0.25
    tree.links.new(noise.outputs["Fac"], ramp.inputs["Fac"])
    tree.links.new(ramp.outputs["Color"], tree.nodes["Principled BSDF"].inputs["Base Color"])
    return material


emissive_material = render_utils.emission_material


def cutout_material(name: str) -> bpy.types.Material:
    """Principled whose Alpha is driven by a texture: the injection links it to the group's Opacity."""
    material = _node_material(name)
    tree = material.node_tree
    noise = tree.nodes.new("ShaderNodeTexNoise")
    tree.links.new(noise.outputs["Fac"], tree.nodes["Principled BSDF"].inputs["Alpha"])
    return material


def mix_transparent_material(name: str) -> bpy.types.Material:
    material = _node_material(name)
    tree = material.node_tree
    mix = tree.nodes.new("ShaderNodeMixShader")
    mix.inputs[0].default_value = 0.3
    transparent = tree.nodes.new("ShaderNodeBsdfTransparent")
    tree.links.new(transparent.outputs[0], mix.inputs[1])
    tree.links.new(tree.nodes["Principled BSDF"].outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    return material


def mesh_object(name: str, *mats, scene=None, location=(0.0, 0.0, 0.0), half_size: float = 0.5):
    h = half_size
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([(-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0)], [], [(0, 1, 2, 3)])
    for material in mats:
        mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    (scene or bpy.context.scene).collection.objects.link(obj)
    return obj


def sun_lamp(scene, name: str = "Sun", rotation=(math.radians(40.0), 0.0, math.radians(30.0))):
    lamp = bpy.data.objects.new(name, bpy.data.lights.new(name, "SUN"))
    lamp.rotation_euler = rotation
    scene.collection.objects.link(lamp)
    return lamp


def camera_looking_north(scene, name: str = "Camera", fov=math.radians(20.0)):
    """A camera at the origin looking along +Y with Z up."""
    return render_utils.make_camera(scene, rotation_euler=(math.pi / 2.0, 0.0, 0.0), fov_rad=fov,
                                    clip_start=0.1, clip_end=100_000.0)


def world(scene, colour=(0.05, 0.1, 0.2)):
    data = bpy.data.worlds.new("World")
    _quiet(setattr, data, "use_nodes", True)
    data.node_tree.nodes["Background"].inputs["Color"].default_value = (*colour, 1.0)
    scene.world = data
    return data


def user_part(material) -> tuple:
    """The material's snapshot without the Atmos-tagged nodes and their links."""
    ours = {node.name for node in materials.atmos_nodes(material)}
    nodes, links = snapshot(material.node_tree)
    return ([n for n in nodes if n[0] not in ours],
            [k for k in links if k[0] not in ours and k[2] not in ours])


def compositor_state(scene) -> tuple:
    if IS_5:
        tree = scene.compositing_node_group
        return (tree.name if tree else None, snapshot(tree), scene.render.use_compositing)
    return (_quiet(getattr, scene, "use_nodes"), snapshot(scene.node_tree), scene.render.use_compositing)


user_compositor = render_utils.user_compositor


def parameters(scene) -> dict:
    return {name: (tuple(scene[name]) if hasattr(scene[name], "__len__") else scene[name])
            for name in PARAMETERS if name in scene}


def orphan_groups() -> list[str]:
    """Atmos node groups nothing uses (no users, no fake user): left behind, they would be saved with the file."""
    return sorted(g.name for g in bpy.data.node_groups
                  if (g.name.startswith("Atmos ") or stamps.kind_of(g) is not None) and g.users == 0)


def lamp_direction(lamp) -> np.ndarray:
    axis = np.array(lamp.matrix_world.to_3x3().col[2])
    return axis / np.linalg.norm(axis)


def small_scene():
    """Camera, sun, world, three materials (plain, cut-out, mix-transparent) on four objects."""
    scene = bpy.context.scene
    camera_looking_north(scene)
    sun = sun_lamp(scene)
    world(scene)
    mats = [user_material("User"), cutout_material("Leaf"), mix_transparent_material("Glass")]
    for index, material in enumerate(mats):
        mesh_object(f"Obj{index}", material, location=(index - 1.0, 10.0, 0.0))
    mesh_object("TwoSlots", mats[0], mats[2], location=(0.0, 20.0, 0.0))
    return scene, sun, mats


# -- save and reopen -----------------------------------------------------------------------------


def test_save_and_reopen_keeps_the_effect_and_load_post_resyncs(tmp_path: Path) -> None:
    """Settings, injected materials, AOVs, compositor and parameters survive save + reopen; load_post
    re-syncs (a stale sun direction in the file is corrected); the depsgraph handler follows the sun
    after reload; disabling after reload still restores everything exactly."""
    scene, sun, mats = small_scene()
    scene.render.engine = "CYCLES"
    user_compositor(scene)
    before_materials = {m.name: snapshot(m.node_tree) for m in mats}
    before_compositor = compositor_state(scene)
    scene.atmos.mie_scattering_per_km = (0.05, 0.06, 0.07)
    scene.atmos.distance_scale = 3.0
    bpy.context.view_layer.update()   # the lamp's world matrix, as the GUI has it
    orchestrator.enable_effect(scene)
    np.testing.assert_allclose(scene["atmos_sun_direction"], lamp_direction(sun), atol=1e-6)
    settings = {name: tuple(getattr(scene.atmos, name)) if hasattr(getattr(scene.atmos, name), "__len__")
                else getattr(scene.atmos, name)
                for name in ("mie_scattering_per_km", "distance_scale", "rayleigh_scattering_per_km", "mie_g")}
    injected = {m.name: snapshot(m.node_tree) for m in mats}
    bpy.context.view_layer.update()   # the Per Pixel group node's driven inputs hold their values once evaluated
    composited = compositor_state(scene)
    params = parameters(scene)
    assert set(params) == set(PARAMETERS)
    scene["atmos_sun_direction"] = (1.0, 0.0, 0.0)  # stale on purpose: load_post must correct it
    path = tmp_path / "saved.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))

    bpy.ops.wm.open_mainfile(filepath=str(path))
    scene = bpy.context.scene
    assert scene.atmos.enabled
    for name, value in settings.items():
        got = getattr(scene.atmos, name)
        np.testing.assert_allclose(got, value, rtol=1e-7, err_msg=name)
    for name, shot in injected.items():
        material = bpy.data.materials[name]
        assert snapshot(material.node_tree) == shot, name
        (node,) = materials.atmos_nodes(material)
        assert node.node_tree.name == materials.SURFACE_GROUP
        assert surface.aov_names(node.node_tree) == {name for name, _ in plan.AOVS["PER_PIXEL"]}   # the default's
    assert [a.name for a in scene.view_layers[0].aovs] == [n for n, _ in plan.AOVS["PER_PIXEL"]]
    assert compositor_state(scene) == composited
    assert compositor.STATE_KEY in scene
    reloaded = parameters(scene)
    # A file holds no world matrices: load_post evaluates the scene before reading the lamp (it wrote the zenith).
    np.testing.assert_allclose(reloaded["atmos_sun_direction"], params["atmos_sun_direction"], atol=1e-6,
                               err_msg="load_post did not re-sync the sun direction")
    for name in PARAMETERS:
        np.testing.assert_allclose(reloaded[name], params[name], rtol=1e-6, err_msg=name)

    sun = bpy.data.objects["Sun"]
    sun.rotation_euler = (math.radians(75.0), 0.0, math.radians(-100.0))
    bpy.context.view_layer.update()  # fires depsgraph_update_post headless
    np.testing.assert_allclose(scene["atmos_sun_direction"], lamp_direction(sun), atol=1e-6)

    orchestrator.disable_effect(scene)
    for name, shot in before_materials.items():
        assert snapshot(bpy.data.materials[name].node_tree) == shot, name
    assert compositor_state(scene) == before_compositor


# -- farm: the saved file renders the same without the add-on ------------------------------------


FARM_SCRIPT = textwrap.dedent("""
    import json, sys
    import bpy
    import numpy as np
    blend, out = sys.argv[1], sys.argv[2]
    bpy.ops.wm.open_mainfile(filepath=blend)
    scene = bpy.context.scene
    if len(sys.argv) > 3:
        scene.frame_set(int(sys.argv[3]))
    assert not any(name.startswith("atmos_addon") for name in sys.modules), "the add-on was imported"
    assert not hasattr(bpy.types.Scene, "atmos")
    settings = scene.render.image_settings
    scene.render.filepath = out + ".exr"
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(out + ".exr", check_existing=False)
    width, height = image.size
    pixels = np.empty(width * height * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    np.save(out + ".npy", pixels.reshape(height, width, 4)[::-1])
    print(json.dumps({"addon_loaded": False}))
""")


@pytest.mark.parametrize("quality", ["FAST", "PRECISE"])
def test_farm_render_without_the_addon_matches(tmp_path: Path, quality: str) -> None:
    """A file saved with the effect on renders the same in a fresh process that never imports atmos_addon
    (empty HOME, no PYTHONPATH): Cycles, fixed seed, 16x16, max abs difference <= 1e-4, at each quality level
    (the camera 800 m above sea level)."""
    scene = bpy.context.scene
    scene.atmos.quality = quality
    scene.atmos.origin_altitude = 800.0
    render_utils.set_engine(scene, "CYCLES", width=16, height=16)
    scene.cycles.samples = 4
    scene.cycles.seed = 7
    camera_looking_north(scene)
    sun_lamp(scene)
    world(scene)
    near = mesh_object("Near", emissive_material("Near", (0.2, 0.5, 0.8)), location=(-40.0, 500.0, 0.0),
                       half_size=60.0)
    near.rotation_euler = (math.pi / 2.0, 0.0, 0.0)
    far = mesh_object("Far", user_material("Far"), location=(800.0, 6000.0, 0.0), half_size=900.0)
    far.rotation_euler = (math.pi / 2.0, 0.0, 0.0)
    orchestrator.enable_effect(scene)
    session = render_utils.render_to_array(scene)
    scene.render.use_compositing = False
    raw = render_utils.render_to_array(scene)
    scene.render.use_compositing = True
    assert np.max(np.abs(session - raw)) > 1e-2, "the effect changed nothing: the comparison would prove nothing"
    assert np.all(np.isfinite(session))

    blend = tmp_path / "farm.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    home = tmp_path / "home"
    home.mkdir()
    out = tmp_path / "farm"
    assert render_utils.run_farm(home, [str(blend), str(out)], FARM_SCRIPT) == {"addon_loaded": False}
    farm = np.load(str(out) + ".npy")
    difference = float(np.max(np.abs(farm - session)))
    print(f"farm render: max abs difference {difference:.3g}")
    assert difference <= 1e-4


def _farm_render(tmp_path: Path, blend: Path, frame: int) -> np.ndarray:
    """Render ``frame`` of ``blend`` in a fresh process that never imports the add-on (empty HOME)."""
    home = tmp_path / "home"
    home.mkdir(exist_ok=True)
    out = tmp_path / f"farm{frame}"
    render_utils.run_farm(home, [str(blend), str(out), str(frame)], FARM_SCRIPT)
    return np.load(str(out) + ".npy")


def _assert_farm_renders_frames_as_the_session(tmp_path: Path, session: dict, frames) -> None:
    """Save the open file and render each of ``frames`` without the add-on: max abs difference <= 1e-4."""
    blend = tmp_path / "farm.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    for frame in frames:
        difference = float(np.max(np.abs(_farm_render(tmp_path, blend, frame) - session[frame])))
        print(f"farm frame {frame}: max abs difference {difference:.3g}")
        assert difference <= 1e-4, frame


def _three_frames_of_a_setting_sun(scene, *, climbing_camera: bool) -> None:
    """Cycles 16x16, 4 samples, seed 7; frames 1-3: the sun keyed from 40 to 85 deg (from the zenith), the camera
    (looking north) keyed from 2 m to 3 km when ``climbing_camera``; a world, an emissive plane 9 km away; frame 1."""
    render_utils.set_engine(scene, "CYCLES", width=16, height=16)
    scene.cycles.samples = 4
    scene.cycles.seed = 7
    scene.frame_start, scene.frame_end = 1, 3
    camera = camera_looking_north(scene)
    if climbing_camera:
        for frame, z in ((1, 2.0), (3, 3000.0)):
            camera.location.z = z
            camera.keyframe_insert("location", index=2, frame=frame)
    sun = sun_lamp(scene)
    for frame, angle in ((1, 40.0), (3, 85.0)):
        sun.rotation_euler = (math.radians(angle), 0.0, math.radians(30.0))
        sun.keyframe_insert("rotation_euler", frame=frame)
    world(scene)
    far = mesh_object("Far", emissive_material("Far", (0.2, 0.5, 0.8)), location=(0.0, 9000.0, 0.0),
                      half_size=6000.0)
    far.rotation_euler = (math.pi / 2.0, 0.0, 0.0)
    scene.frame_set(1)


def test_an_animated_table_laid_out_by_an_older_atmos_is_baked_again_on_opening(tmp_path: Path) -> None:
    """Key tiles are not re-baked on every edit in the UI, but a file whose table an older Atmos laid out (before the
    camera sky view: narrower tiles, another bake key) would have the groups read the wrong columns: opening it
    bakes the key tiles again, at today's width."""
    from atmos_addon.node_groups import precise as precise_nodes
    from atmos_addon.physics.precise import DEFAULT_SHAPE

    scene = bpy.context.scene
    scene.atmos.quality = "PRECISE"
    _three_frames_of_a_setting_sun(scene, climbing_camera=True)
    orchestrator.enable_effect(scene)
    image = bpy.data.images[precise_nodes.IMAGE_NAME]
    del image["atmos_layout"]                       # as an older Atmos wrote it: no layout, its own key and width
    image["atmos_bake_key"] = "an older layout's key"
    image.scale(DEFAULT_SHAPE.width - 66, image.size[1])
    image.pack()
    path = tmp_path / "older.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.open_mainfile(filepath=str(path))
    image = bpy.data.images[precise_nodes.IMAGE_NAME]
    from atmos_addon.blender.apply import precise_tables
    assert image["atmos_layout"] == precise_tables._LAYOUT and image["atmos_bake_key"] != "an older layout's key"
    assert tuple(image.size) == (DEFAULT_SHAPE.width, 3 * precise_nodes.ALTITUDES)


def test_farm_renders_the_precise_tables_of_a_moving_camera_and_sun(tmp_path: Path, monkeypatch) -> None:
    """Precise with a camera climbing 0 -> 3 km and a sun setting over 3 frames: each frame moves more than a key
    step, so each is a key tile in the packed image, the groups blend two keys by the keyed weight (frame 3 is the
    second segment's end: weight 1), and a process without the add-on renders every frame as the session did (max
    abs difference <= 1e-4); the frames differ from each other."""
    from atmos_addon.node_groups import precise as precise_nodes
    from atmos_addon.node_groups.parameters import PRECISE_SCALE, PRECISE_TILE
    from atmos_addon.physics.precise import DEFAULT_SHAPE

    from atmos_addon.node_groups import per_pixel

    scene = bpy.context.scene
    scene.atmos.quality = "PRECISE"
    _three_frames_of_a_setting_sun(scene, climbing_camera=True)
    builds = []
    build = per_pixel.build_per_pixel_composite
    monkeypatch.setattr(per_pixel, "build_per_pixel_composite",
                        lambda tree, features, *args: builds.append(features.blend) or build(tree, features, *args))
    report = orchestrator.enable_effect(scene)
    assert any("baked 3 table tiles" in message for message in report.messages), report.messages
    assert builds == [True]   # built once, for the key tiles' blend (1.2-1.6 s a build: not first without it)
    image = bpy.data.images[precise_nodes.IMAGE_NAME]
    assert image.packed_file is not None and tuple(image.size) == (DEFAULT_SHAPE.width, 3 * precise_nodes.ALTITUDES)
    session = {}
    from atmos_addon.node_groups import stamps
    for kind in (stamps.PER_PIXEL, stamps.SKY, stamps.SKY_VIEW):   # the default Per Pixel mode's: all read two keys
        assert "+blend" in bpy.data.node_groups[kind.name][stamps.FEATURES_KEY], kind.name
    for frame, row, weight in ((1, 0, 0.0), (2, 1, 0.0), (3, 1, 1.0)):
        scene.frame_set(frame)
        assert scene[PRECISE_TILE][1] == row * precise_nodes.ALTITUDES
        assert scene[PRECISE_SCALE][2] == weight
        session[frame] = render_utils.render_to_array(scene)
    assert np.max(np.abs(session[1] - session[3])) > 1e-2
    _assert_farm_renders_frames_as_the_session(tmp_path, session, (1, 3))


def test_enable_samples_an_animated_scenes_frames_once_and_again_when_it_makes_the_sun(monkeypatch) -> None:
    """Enable bakes the Precise tables before the materials (so the groups link the image as they are built) and
    checks them at its end; an animated scene's frames are sampled one depsgraph evaluation a frame (57 ms a frame
    with 20000 objects: 17-23 s for 250 frames), once, as for Refresh, also where enable makes the sun lamp (it makes
    it before the first bake). Either way its last bake leaves the table current."""
    from atmos_addon.blender.apply import precise_tables

    scene = bpy.context.scene
    scene.atmos.quality = "PRECISE"
    _three_frames_of_a_setting_sun(scene, climbing_camera=True)
    sampled = []
    frame_inputs = precise_tables.frame_inputs
    monkeypatch.setattr(precise_tables, "frame_inputs", lambda scene_: sampled.append(1) or frame_inputs(scene_))
    orchestrator.enable_effect(scene)
    assert len(sampled) == 1 and scene[facts.KEY_TILES] == 3
    assert precise_tables.bake(scene) == 0 and len(sampled) == 2   # current: nothing to bake (a bake samples)
    sampled.clear()
    orchestrator.refresh_effect(scene)
    assert len(sampled) == 1 and precise_tables.bake(scene) == 0
    orchestrator.disable_effect(scene)
    bpy.data.objects.remove(scene_reading.sun_object(scene))   # no sun lamp: enable makes one between its bakes
    sampled.clear()
    report = orchestrator.enable_effect(scene)
    assert any("created" in message for message in report.messages), report.messages
    assert len(sampled) == 1 and precise_tables.bake(scene) == 0


@pytest.mark.parametrize("quality", ["FAST", "PRECISE"])
def test_farm_renders_the_per_pixel_mode_of_a_setting_sun(quality: str, tmp_path: Path) -> None:
    """Per Pixel mode with a sun setting over 3 frames (Precise: and the camera climbing 2 m -> 3 km, its tiles one
    per frame in the packed image): the compositor group's parameters are driven from the keyed scene properties,
    and a process without the add-on (no Python drivers to
    trust) renders frames 1 and 3 as the session did (max abs difference <= 1e-4); the frames differ."""
    scene = bpy.context.scene
    scene.atmos.render_mode = "PER_PIXEL"
    scene.atmos.quality = quality
    _three_frames_of_a_setting_sun(scene, climbing_camera=quality != "FAST")
    orchestrator.enable_effect(scene)
    assert compositor.current_tree(scene).nodes[compositor.COMPOSITE_NODE].node_tree is not None
    session = {}
    for frame in (1, 3):
        scene.frame_set(frame)
        session[frame] = render_utils.render_to_array(scene)
    assert np.max(np.abs(session[1] - session[3])) > 1e-2
    scene.render.use_compositing = False
    raw = render_utils.render_to_array(scene)
    scene.render.use_compositing = True
    assert np.max(np.abs(session[3] - raw)) > 1e-2, "the effect changed nothing: the comparison would prove nothing"
    _assert_farm_renders_frames_as_the_session(tmp_path, session, (1, 3))


def test_edits_after_enabling_an_animated_sun_are_baked_and_reach_the_farm(tmp_path: Path) -> None:
    """With an animated sun, every frame's sun parameters are drivers on the lamp, nothing keyed. A slider moved, a
    sun key edited and a longer frame range after enabling reach every frame (the E_sun table of the drivers is
    rewritten with the slider; the record the key tiles follow is renewed); a farm renders the edited animation."""
    from atmos_addon.blender import orchestrator, scene_reading
    from atmos_addon.physics import sun_irradiance_ground

    scene = bpy.context.scene
    _three_frames_of_a_setting_sun(scene, climbing_camera=False)
    orchestrator.enable_effect(scene)
    sun = scene_reading.sun_object(scene)
    assert not sun_bake.baked_fcurves(scene)
    driven = {c.data_path for c in scene.animation_data.drivers}
    assert {'["atmos_sun_direction"]', '["atmos_sun_irradiance"]'} <= driven

    def assert_frame_follows_the_settings(frame: int) -> None:
        scene.frame_set(frame)
        direction = lamp_direction(sun)
        np.testing.assert_allclose(scene["atmos_sun_direction"], direction, atol=1e-6)
        atmosphere = scene_reading.atmosphere_of(scene)
        np.testing.assert_allclose(scene["atmos_beta_mie"], atmosphere.mie_scattering, rtol=1e-6)
        expected = sun_irradiance_ground(math.asin(direction[2]), atmosphere, 0.0,
                                         0.5 * scene.atmos.sun_angular_diameter)
        np.testing.assert_allclose(scene["atmos_sun_irradiance"], expected, rtol=2e-3)   # the drivers' table

    scene.atmos.mie_scattering_per_km = (0.08, 0.08, 0.08)   # a slider, at frame 1
    assert_frame_follows_the_settings(3)
    scene.frame_set(3)                                        # a sun key edited at frame 3
    sun.rotation_euler = (math.radians(60.0), 0.0, math.radians(-40.0))
    sun.keyframe_insert("rotation_euler", frame=3)
    bpy.context.view_layer.update()
    scene.frame_set(1)
    assert_frame_follows_the_settings(3)
    scene.frame_end = 4                                        # a longer range
    bpy.context.view_layer.update()
    assert scene[sun_bake.BAKED_KEY]["end"] == 4 and sun_bake.is_bake_current(scene)
    session = {}
    for frame in (1, 3):
        scene.frame_set(frame)
        session[frame] = render_utils.render_to_array(scene)
    _assert_farm_renders_frames_as_the_session(tmp_path, session, (1, 3))


def test_every_view_layer_gets_the_atmosphere_and_disable_restores_them() -> None:
    """Two view layers, a Render Layers node for each in the user's compositor: both layers declare the AOVs,
    each Render Layers node gets its own combining group, a render of both is finite and hazed, and disabling
    restores the tree and the layers' AOV lists exactly."""
    scene = bpy.context.scene
    render_utils.set_engine(scene, "CYCLES", width=8, height=8)
    scene.cycles.samples = 1
    camera_looking_north(scene)
    sun_lamp(scene)
    world(scene)
    far = mesh_object("Far", emissive_material("Far", (0.5, 0.5, 0.5)), location=(0.0, 6000.0, 0.0),
                      half_size=3000.0)
    far.rotation_euler = (math.pi / 2.0, 0.0, 0.0)
    second = scene.view_layers.new("Second")
    user = second.aovs.add()
    user.name = "user_pass"
    tree = render_utils.user_compositor(scene)
    second_layers = tree.nodes.new("CompositorNodeRLayers")
    second_layers.layer = second.name
    before = snapshot(tree)
    aovs_before = {layer.name: [aov.name for aov in layer.aovs] for layer in scene.view_layers}

    orchestrator.enable_effect(scene)
    for layer in scene.view_layers:
        names = {aov.name for aov in layer.aovs}
        assert {name for name, _ in plan.AOVS["PER_PIXEL"]} <= names, layer.name   # the default mode's
    render_layers = [n for n in tree.nodes if n.bl_idname == "CompositorNodeRLayers"]
    assert len(render_layers) == 2
    for node in render_layers:
        targets = [link.to_node for link in node.outputs["Image"].links]
        assert any(target.get(materials.TAG) for target in targets), f"{node.layer}: no combining group after it"
    hazed = render_utils.render_to_array(scene)
    assert np.all(np.isfinite(hazed))

    orchestrator.disable_effect(scene)
    assert snapshot(tree) == before
    assert {layer.name: [aov.name for aov in layer.aovs] for layer in scene.view_layers} == aovs_before
    plain = render_utils.render_to_array(scene)
    assert np.max(np.abs(hazed - plain)) > 1e-2, "the effect changed nothing: the check above would prove nothing"

# -- enable/disable invariants -------------------------------------------------------------------


def test_enable_then_disable_restores_everything_and_leaves_no_orphans() -> None:
    """Enable -> disable restores every material's nodes and links and the compositor exactly, and leaves no
    Atmos node group (no zero-user orphans) behind."""
    scene, _, mats = small_scene()
    scene.render.engine = "CYCLES"
    user_compositor(scene)
    groups_before = sorted(g.name for g in bpy.data.node_groups)
    before = {m.name: snapshot(m.node_tree) for m in mats}
    before_compositor = compositor_state(scene)
    orchestrator.enable_effect(scene)
    assert all(materials.is_injected(m) for m in mats)
    assert materials.SURFACE_GROUP in bpy.data.node_groups
    orchestrator.disable_effect(scene)
    assert {m.name: snapshot(m.node_tree) for m in mats} == before
    assert compositor_state(scene) == before_compositor
    assert sorted(g.name for g in bpy.data.node_groups) == groups_before
    assert orphan_groups() == []


def test_renaming_or_deleting_sun_camera_world_gives_status_not_exception() -> None:
    scene, sun, mats = small_scene()
    orchestrator.enable_effect(scene)
    scene.atmos.sun_object = sun

    sun.name = "Sol"
    bpy.context.view_layer.update()
    assert "'Sol'" in scene.atmos.status_sun
    report = orchestrator.refresh_effect(scene)
    assert "'Sol'" in scene.atmos.status_sun and report.messages

    lamp_data = sun.data
    bpy.data.objects.remove(sun)
    bpy.data.lights.remove(lamp_data)
    bpy.context.view_layer.update()
    assert "no sun lamp" in scene.atmos.status_sun.lower()
    np.testing.assert_allclose(scene["atmos_sun_direction"], scene_reading.DEFAULT_SUN_DIRECTION, atol=1e-6)

    scene.camera.name = "Renamed Camera"
    orchestrator.refresh_effect(scene)
    camera = scene.camera
    bpy.data.objects.remove(camera)
    assert scene.camera is None
    bpy.context.view_layer.update()
    report = orchestrator.refresh_effect(scene)
    assert report.messages and scene.atmos.status_materials

    bpy.data.worlds.remove(scene.world)
    bpy.context.view_layer.update()
    report = orchestrator.refresh_effect(scene)
    orchestrator.update(scene)
    assert report.messages and scene.atmos.status_sun
    assert all(materials.is_injected(m) for m in mats)
    orchestrator.disable_effect(scene)


# -- user edits to managed materials -------------------------------------------------------------


def test_user_edits_after_enabling_survive_refresh_and_disable() -> None:
    scene, _, mats = small_scene()
    material = mats[0]
    orchestrator.enable_effect(scene)
    (ours,) = materials.atmos_nodes(material)
    user_xs = [n.location.x + n.width for n in material.node_tree.nodes if n != ours]
    assert ours.location.x > max(user_xs), "the Atmos node sits to the right of the user's nodes"

    tree = material.node_tree
    bump = tree.nodes.new("ShaderNodeBump")
    bump.inputs["Strength"].default_value = 0.3
    tree.links.new(tree.nodes["Noise Texture"].outputs["Fac"], bump.inputs["Height"])
    tree.links.new(bump.outputs["Normal"], tree.nodes["Principled BSDF"].inputs["Normal"])
    tree.nodes["Math"].inputs[0].default_value = 0.75
    tree.nodes["Principled BSDF"].inputs["Roughness"].default_value = 0.123
    tree.nodes["Noise Texture"].location = (-900.0, 120.0)
    edited = user_part(material)

    orchestrator.refresh_effect(scene)
    assert user_part(material) == edited
    assert len(materials.atmos_nodes(material)) == 1

    tree.nodes.remove(materials.atmos_nodes(material)[0])  # the user deletes our node: refresh puts it back
    orchestrator.refresh_effect(scene)
    assert len(materials.atmos_nodes(material)) == 1 and user_part(material) == edited

    copy = material.copy()  # a user duplicate carries our node; disable strips it too
    mesh_object("Copy", copy)
    orchestrator.refresh_effect(scene)
    assert len(materials.atmos_nodes(copy)) == 1

    orchestrator.disable_effect(scene)
    assert snapshot(material.node_tree) == edited
    assert materials.atmos_nodes(copy) == []


# -- several scenes ------------------------------------------------------------------------------


def test_scenes_keep_their_own_settings_and_shared_material_until_last_disable() -> None:
    first = bpy.context.scene
    first.name = "First"
    second = bpy.data.scenes.new("Second")
    shared = user_material("Shared")
    only_first, only_second = user_material("OnlyFirst"), user_material("OnlySecond")
    for scene, own in ((first, only_first), (second, only_second)):
        camera = bpy.data.objects.new(f"Camera {scene.name}", bpy.data.cameras.new(f"Camera {scene.name}"))
        scene.collection.objects.link(camera)
        scene.camera = camera
        mesh_object(f"Shared in {scene.name}", shared, scene=scene)
        mesh_object(f"Own of {scene.name}", own, scene=scene)
    second.atmos.mie_scattering_per_km = (0.2, 0.2, 0.2)
    second.atmos.distance_scale = 10.0
    sun_lamp(second, "Second Sun", rotation=(math.radians(80.0), 0.0, 0.0))

    orchestrator.enable_effect(first)
    orchestrator.enable_effect(second)
    a, b = parameters(first), parameters(second)
    assert a["atmos_metres_per_unit"] == pytest.approx(1.0) and b["atmos_metres_per_unit"] == pytest.approx(10.0)
    assert not np.allclose(a["atmos_beta_mie"], b["atmos_beta_mie"])
    assert not np.allclose(a["atmos_sun_direction"], b["atmos_sun_direction"])
    first.atmos.distance_scale = 2.0  # a change in one scene leaves the other alone
    assert parameters(first)["atmos_metres_per_unit"] == pytest.approx(2.0)
    assert parameters(second) == b
    assert first.atmos.mie_scattering_per_km[0] != pytest.approx(0.2)

    orchestrator.disable_effect(first)
    assert materials.is_injected(shared), "the second scene still uses the shared material"
    assert materials.is_injected(only_second)
    assert not materials.is_injected(only_first)
    assert parameters(first) == {} and parameters(second) == b
    assert second.atmos.enabled and compositor.STATE_KEY in second
    orchestrator.disable_effect(second)
    assert not any(materials.is_injected(m) for m in (shared, only_first, only_second))
    assert orphan_groups() == []


# -- many cycles ---------------------------------------------------------------------------------


def _counts() -> dict:
    data = bpy.data
    return {
        "node_groups": len(data.node_groups), "materials": len(data.materials), "images": len(data.images),
        "worlds": len(data.worlds), "objects": len(data.objects), "meshes": len(data.meshes),
        "lights": len(data.lights), "scenes": len(data.scenes),
        "aovs": sum(len(layer.aovs) for layer in bpy.context.scene.view_layers),
        "scene_keys": sorted(k for k in bpy.context.scene.keys() if k.startswith("atmos_")),
        "nodes": sum(len(m.node_tree.nodes) for m in data.materials if m.node_tree),
    }


def test_hundred_enable_disable_cycles_leave_counts_unchanged() -> None:
    scene, _, mats = small_scene()
    scene.render.engine = "CYCLES"
    start = _counts()
    before = {m.name: snapshot(m.node_tree) for m in mats}
    for _ in range(100):
        orchestrator.enable_effect(scene)
        orchestrator.disable_effect(scene)
    assert _counts() == start
    assert {m.name: snapshot(m.node_tree) for m in mats} == before


# -- bad input -----------------------------------------------------------------------------------


def _plane_pixel_scene(scale_length: float):
    """An emissive plane 10 scene units in front of the camera filling the view; 8x8 Cycles."""
    scene = bpy.context.scene
    render_utils.set_engine(scene, "CYCLES", width=8, height=8)
    scene.cycles.samples = 1
    scene.unit_settings.scale_length = scale_length
    camera_looking_north(scene)
    sun_lamp(scene)
    world(scene)
    if hasattr(scene.atmos, "sky_enabled"):
        scene.atmos.sky_enabled = False  # these tests are about distances; the sky's world shader costs 15 s a render
    plane = mesh_object("Wall", emissive_material("Wall", (0.5, 0.5, 0.5)), location=(0.0, 10.0, 0.0),
                        half_size=10.0)
    plane.rotation_euler = (math.pi / 2.0, 0.0, 0.0)
    return scene


@pytest.mark.parametrize("scale_length", [0.001, 1000.0])
def test_extreme_unit_scale_gives_sensible_metres_and_a_finite_render(scale_length: float) -> None:
    scene = _plane_pixel_scene(scale_length)
    orchestrator.enable_effect(scene)
    assert scene_reading.metres_per_unit(scene) == pytest.approx(scale_length)
    assert scene["atmos_metres_per_unit"] == pytest.approx(scale_length)
    pixels = render_utils.render_to_array(scene)
    assert np.all(np.isfinite(pixels)) and np.all(pixels[..., :3] >= 0.0)
    wall = pixels[4, 4, :3]
    if scale_length < 1.0:  # 1 cm away: the atmosphere does nothing measurable
        np.testing.assert_allclose(wall, 0.5, rtol=1e-4)
    else:  # 10 km away: visibly changed by the atmosphere
        assert np.max(np.abs(wall - 0.5)) > 0.02


def test_one_pixel_render_with_the_effect() -> None:
    scene = _plane_pixel_scene(1.0)
    orchestrator.enable_effect(scene)
    scene.render.resolution_x = scene.render.resolution_y = 1
    pixels = render_utils.render_to_array(scene)
    assert pixels.shape[-1] == 4 and pixels.size >= 4
    assert np.all(np.isfinite(pixels))


def test_empty_scene_enables_with_a_clear_report() -> None:
    scene = bpy.context.scene
    assert len(scene.objects) == 0
    report = orchestrator.enable_effect(scene)
    assert report.managed == [] and report.skipped == [] and report.objects_without_material == []
    assert any(message.startswith("0 material(s)") for message in report.messages)
    assert scene.atmos.status_sun
    assert scene.atmos.status_materials == "0 material(s) with aerial perspective"
    orchestrator.disable_effect(scene)
    assert compositor.STATE_KEY not in scene and len(scene.objects) == 0


def test_a_script_made_sun_is_read_where_it_points_by_the_api_and_after_reopening(tmp_path: Path) -> None:
    """A script that makes a sun lamp and calls ``api.enable`` at once (no depsgraph evaluation between: its
    ``matrix_world`` still reads the identity) gets the sun where the lamp points, not at the zenith; and so does
    the file saved and opened again (a file holds no world matrices: the load handler evaluates first). Both read
    the zenith before the fix, on 4.5 and 5.2."""
    from atmos_addon import api

    scene = bpy.context.scene
    camera_looking_north(scene)
    sun = sun_lamp(scene, rotation=(math.radians(70.0), 0.0, math.radians(-40.0)))
    mesh_object("A", user_material())
    api.enable(scene, quality="FAST")
    written = np.array(scene["atmos_sun_direction"])
    bpy.context.view_layer.update()   # the lamp's evaluated matrix, the reference (Atmos composed it without this)
    np.testing.assert_allclose(written, lamp_direction(sun), atol=1e-6)
    assert abs(scene["atmos_sun_direction"][2] - math.cos(math.radians(70.0))) < 1e-6
    path = tmp_path / "script.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.open_mainfile(filepath=str(path))
    scene = bpy.context.scene
    np.testing.assert_allclose(scene["atmos_sun_direction"], lamp_direction(bpy.data.objects["Sun"]), atol=1e-6)
    assert abs(scene["atmos_sun_direction"][2] - math.cos(math.radians(70.0))) < 1e-6


def test_no_camera_enable_effect_does_not_crash_and_the_api_refuses() -> None:
    from atmos_addon import api

    scene = bpy.context.scene
    material = user_material()
    mesh_object("A", material)
    with pytest.raises(api.AtmosError, match="camera"):
        api.enable(scene)
    assert not scene.atmos.enabled and not materials.is_injected(material)
    report = orchestrator.enable_effect(scene)
    assert report.managed == ["User"] and materials.is_injected(material)
    orchestrator.disable_effect(scene)
    assert not materials.is_injected(material)
