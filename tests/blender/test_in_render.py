# SPDX-License-Identifier: GPL-3.0-or-later
"""Cycles In-Render mode: exact aerial perspective on every ray segment, reflections included.

Renders are tiny (32 x 16 px) and use emissive planes of known radiance L0, as the Compositor-mode parity
test does, so every pixel has an expected value from :mod:`atmos_addon.physics`: F_ex L0 + L_in for a plane
seen directly, and F_1 (F_2 L0 + L_2) + L_1 for a plane seen in a perfect mirror (segment 1 camera -> mirror,
segment 2 mirror -> plane). In-Render mode is held to 0.2 % of those; the sky it shows to the same 0.5 % of
the Compositor-mode sky; its noise to 5 % of the same render without the orchestrator. Removal must give the
scene back exactly.
"""

from __future__ import annotations

import math
from pathlib import Path

import bpy
import numpy as np
import pytest
from mathutils import Vector

import atmos_addon
import atmos_addon.api
from atmos_addon.blender.apply import in_render, materials
from atmos_addon.blender import orchestrator, scene_reading, settings_io
from atmos_addon.physics import sun_irradiance_ground
from atmos_addon.physics.sky import aerial_distance_clamped, dome_distance_approx, extinction_layered, \
    inscattering_layered
from render_utils import emission_material, fast_segment, parity_world_camera_sun, render_exr, set_use_nodes, \
    view_direction

EEVEE = "BLENDER_EEVEE" if bpy.app.version >= (5, 0, 0) else "BLENDER_EEVEE_NEXT"
WORLD_COLOUR = (0.05, 0.1, 0.2)
WIDTH, HEIGHT, FOV = 32, 16, math.radians(20.0)
TOLERANCE = 2e-3


pytestmark = pytest.mark.usefixtures("addon")


def _pixel_direction(column: float, row: float) -> Vector:
    """World direction of a pixel centre for the test camera (at the origin, looking along +Y, Z up)."""
    return view_direction(column, row, WIDTH, HEIGHT, FOV)


def _quad(name: str, material, centre: Vector, normal: Vector, half_size: float):
    """A square of ``half_size`` centred at ``centre`` whose front faces along ``normal``."""
    mesh = bpy.data.meshes.new(name)
    h = half_size
    mesh.from_pydata([(-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0)], [], [(0, 1, 2, 3)])
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    obj.location = centre
    obj.rotation_euler = normal.to_track_quat("Z", "Y").to_euler()
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _mirror_material():
    material = bpy.data.materials.new("Mirror")
    set_use_nodes(material, True)
    tree = material.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    glossy = tree.nodes.new("ShaderNodeBsdfAnisotropic" if bpy.app.version < (4, 0, 0) else "ShaderNodeBsdfGlossy")
    glossy.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    glossy.inputs["Roughness"].default_value = 0.0
    tree.links.new(glossy.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    return material


def _scene(samples: int = 1):
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.render.resolution_x, scene.render.resolution_y = WIDTH, HEIGHT
    scene.render.resolution_percentage = 100
    scene.render.use_compositing = True
    scene.view_settings.view_transform = "Standard"
    cycles = scene.cycles
    cycles.samples = samples
    cycles.use_adaptive_sampling = False
    cycles.use_denoising = False
    cycles.device = "CPU"
    cycles.pixel_filter_type = "BOX"
    cycles.filter_width = 0.01  # sample the pixel centre, where the expected value is computed
    sun = parity_world_camera_sun(scene, WORLD_COLOUR, FOV)
    sun.rotation_euler = (math.radians(60), 0.0, math.radians(200))
    return scene, sun


def _render(scene, tmp_path: Path, name: str) -> np.ndarray:
    return render_exr(scene, tmp_path / f"{name}.exr")  # RGB, row 0 at the bottom


def _segment(scene, direction, distance: float) -> tuple[np.ndarray, np.ndarray]:
    """(F_ex, L_in) of a segment of ``distance`` scene units along unit ``direction`` (physics core, eq. 19)."""
    return fast_segment(scene, direction, distance)


DIRECT = (  # name, L0, distance (m), pixel column, row
    ("Near", (0.2, 0.5, 0.8), 300.0, 4, 9),
    ("Middle", (0.6, 0.4, 0.3), 3000.0, 10, 9),
    ("Far", (0.5, 0.5, 0.5), 20000.0, 16, 9),
)
MIRROR_PIXEL, MIRROR_DISTANCE, REFLECTED_DISTANCE = (25, 9), 300.0, 2000.0
REFLECTED_RADIANCE = (0.7, 0.5, 0.2)
SKY_PIXEL = (16, 14)


def _build_planes(scene):
    for name, radiance, distance, column, row in DIRECT:
        direction = _pixel_direction(column, row)
        half = distance * 2.0 * math.tan(FOV / 2.0) / (WIDTH / 2.0)  # about 2 px
        _quad(name, emission_material(name, radiance), direction * distance, -direction, half)
    # The mirror faces back along the view ray, turned 45 degrees about Z so it reflects the ray toward +X.
    view = _pixel_direction(*MIRROR_PIXEL)
    mirror_point = view * MIRROR_DISTANCE
    normal = Vector((1.0, -1.0, 0.0)).normalized()
    _quad("Mirror", _mirror_material(), mirror_point, normal, 40.0)
    reflected = view - 2.0 * view.dot(normal) * normal
    wall_centre = mirror_point + reflected * REFLECTED_DISTANCE
    _quad("Reflected", emission_material("Reflected", REFLECTED_RADIANCE), wall_centre, -reflected, 400.0)
    return view, mirror_point, normal, reflected


def test_in_render_parity_direct_and_mirrored(tmp_path: Path) -> None:
    scene, _sun = _scene()
    scene.cycles.max_bounces = scene.cycles.glossy_bounces = 2
    scene.atmos.sky_enabled = False
    scene.atmos.render_mode = "IN_RENDER"
    view, mirror_point, normal, reflected = _build_planes(scene)
    orchestrator.enable_effect(scene)
    assert in_render.is_installed(scene)
    pixels = _render(scene, tmp_path, "in_render")
    for name, radiance, distance, column, row in DIRECT:
        direction = _pixel_direction(column, row)
        f_ex, l_in = _segment(scene, direction, distance)
        expected = np.asarray(radiance) * f_ex + l_in
        got = pixels[row, column]
        print(f"in-render {name}: max relative error {np.max(np.abs(got / expected - 1)):.2e}")
        np.testing.assert_allclose(got, expected, rtol=TOLERANCE, atol=0)
    # Mirror: the exact hit points of the mirror pixel's centre ray.
    column, row = MIRROR_PIXEL
    view = _pixel_direction(column, row)
    s1 = mirror_point.dot(normal) / view.dot(normal)
    hit = view * s1
    out = view - 2.0 * view.dot(normal) * normal
    wall_centre = mirror_point + reflected * REFLECTED_DISTANCE
    s2 = (wall_centre - hit).dot(reflected) / out.dot(reflected)
    f1, l1 = _segment(scene, view, s1)
    f2, l2 = _segment(scene, out, s2)
    expected = f1 * (f2 * np.asarray(REFLECTED_RADIANCE) + l2) + l1
    got = pixels[row, column]
    print(f"in-render mirror (s1 {s1:.0f} m, s2 {s2:.0f} m): max relative error {np.max(np.abs(got / expected - 1)):.2e}")
    np.testing.assert_allclose(got, expected, rtol=TOLERANCE, atol=0)
    # The user's plain world is shown unchanged to the camera (the domes' attenuation is compensated).
    np.testing.assert_allclose(pixels[SKY_PIXEL[1], SKY_PIXEL[0]], WORLD_COLOUR, rtol=TOLERANCE)


def _dome_segment(scene, direction, distance: float) -> tuple[np.ndarray, np.ndarray]:
    """(F_ex, L_in) of a segment with the virtual-dome clamp b_i = min(s, R_i(v)) (the model both modes use)."""
    atmosphere = settings_io.atmosphere_from_settings(scene.atmos)
    sun_dir, _ = scene_reading.sun_direction(scene)
    e_sun = sun_irradiance_ground(math.asin(sun_dir[2]), atmosphere)
    v = np.asarray(direction, dtype=float)
    b_rayleigh, b_mie = aerial_distance_clamped(distance * scene_reading.metres_per_unit(scene), math.asin(v[2]), atmosphere,
                                                0.0, dome_distance_approx)
    return (extinction_layered(b_rayleigh, b_mie, atmosphere),
            inscattering_layered(b_rayleigh, b_mie, float(v @ sun_dir), atmosphere, e_sun))


def _mirror_towards(name: str, view: Vector, distance: float, out: Vector, half_size: float) -> None:
    """A perfect mirror where the camera ray ``view`` meets it at ``distance``, turned to reflect it along ``out``."""
    _quad(name, _mirror_material(), view * distance, (out - view).normalized(), half_size)


#: Mirrors anywhere in the domes, reflecting the sky: (pixel column, row, distance m, reflected elevation deg).
#: Rows 8, 5 and 2 look 0.3 deg up, 1.6 and 3.5 deg down, so the mirrors stand up to 2.8 km below the camera.
SKY_MIRRORS = tuple((column, row, distance, elevation)
                    for row, elevation in ((8, 0.5), (5, 3.0), (2, 10.0))
                    for column, distance in ((10, 300.0), (20, 20_000.0), (28, 45_000.0)))
#: Mirrors in the top row, 50 km away, beyond the aerosols' dome (R_M(4.7 deg) = 14 km): the reflected ray
#: enters that dome and leaves it again. (column, elevation of the reflected ray, its x direction)
BEYOND_MIRRORS = ((12, -3.0, -1.0), (28, -6.0, 1.0))


def test_reflections_anywhere_see_the_cameras_sky(tmp_path: Path) -> None:
    """A reflected ray leaves the camera-centred domes after its own length, not the camera's: the domes'
    transparent filters make up the difference, so a mirror 300 m to 50 km away, above or below the camera,
    inside or beyond a dome, shows the sky the camera sees (1 sample per pixel: no Russian roulette at the
    crossings either), and a near mirror shows a plane beyond the aerosols' dome with that dome's F_ex."""
    scene, _sun = _scene()
    scene.cycles.max_bounces = scene.cycles.glossy_bounces = 4
    scene.atmos.sky_enabled = False
    scene.atmos.render_mode = "IN_RENDER"
    cases = []
    for column, row, distance, elevation in SKY_MIRRORS:
        view = _pixel_direction(column, row)
        out = Vector((1.0, 0.0, math.tan(math.radians(elevation)))).normalized()
        _mirror_towards(f"Mirror {column} {row}", view, distance, out, distance * 0.004)
        cases.append((f"{distance / 1000:g} km, sky {elevation:g} deg", column, row, view, distance, None))
    for column, elevation, x in BEYOND_MIRRORS:
        view = _pixel_direction(column, 15)
        out = Vector((x, 0.3, math.tan(math.radians(elevation)))).normalized()
        _mirror_towards(f"Beyond {column}", view, 50_000.0, out, 300.0)
        cases.append((f"50 km beyond the aerosol dome, sky {elevation:g} deg", column, 15, view, 50_000.0, None))
    # A mirror 500 m away reflecting a plane 40 km further, 6 deg up: beyond the aerosols' dome there.
    view = _pixel_direction(4, 8)
    out = Vector((-1.0, 0.2, math.tan(math.radians(6.0)))).normalized()
    _mirror_towards("Near mirror", view, 500.0, out, 4.0)
    _quad("Far plane", emission_material("Far plane", REFLECTED_RADIANCE), view * 500.0 + out * 40_000.0, -out,
          2000.0)
    cases.append(("near mirror, plane 40 km beyond it", 4, 8, view, 500.0, (out, 40_000.0)))
    orchestrator.enable_effect(scene)
    assert in_render.is_installed(scene)
    pixels = _render(scene, tmp_path, "reflections")
    for name, column, row, view, distance, reflected in cases:
        f1, l1 = _dome_segment(scene, view, distance)
        if reflected is None:
            seen = np.asarray(WORLD_COLOUR)
        else:
            f2, l2 = _dome_segment(scene, *reflected)
            seen = f2 * np.asarray(REFLECTED_RADIANCE) + l2
        expected = f1 * seen + l1
        got = pixels[row, column]
        print(f"reflection, {name}: max relative error {np.max(np.abs(got / expected - 1)):.2e}")
        np.testing.assert_allclose(got, expected, rtol=TOLERANCE, atol=0, err_msg=name)


def test_in_render_sky_equals_the_compositor_sky(tmp_path: Path) -> None:
    """The Atmos sky seen directly: In-Render (attenuated by the domes, compensated) = Compositor within 0.5 %, at
    the level In-Render renders (Fast: at the default Precise the Compositor mode shows the Precise sky)."""
    scene, sun = _scene()
    scene.atmos.quality = "FAST"
    sun.rotation_euler = (math.radians(80.0), 0.0, math.radians(180.0))  # 10 degrees up, in front: the Mie halo
    scene.camera.rotation_euler = (math.radians(95.0), 0.0, 0.0)  # from the horizon up to 10 degrees
    orchestrator.enable_effect(scene)
    compositor_sky = _render(scene, tmp_path, "compositor_sky")
    scene.atmos.render_mode = "IN_RENDER"
    assert in_render.is_installed(scene)
    in_render_sky = _render(scene, tmp_path, "in_render_sky")
    relative = np.abs(in_render_sky / compositor_sky - 1.0)
    print(f"sky: In-Render vs Compositor, max relative difference {relative.max():.2e}, mean {relative.mean():.2e}")
    assert np.all(np.isfinite(in_render_sky))
    assert relative.max() < 5e-3


def _noise_scene():
    scene, _sun = _scene(samples=16)
    scene.render.resolution_x, scene.render.resolution_y = 48, 24
    scene.cycles.max_bounces = 4
    scene.cycles.seed = 7
    material = bpy.data.materials.new("Grey")
    set_use_nodes(material, True)
    material.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.3, 0.3, 0.3, 1.0)
    material.node_tree.nodes["Principled BSDF"].inputs["Roughness"].default_value = 0.6
    _quad("Wall", material, Vector((0.0, 1000.0, 0.0)), Vector((0.0, -1.0, 0.0)), 400.0)
    # A world that varies with direction (ground brown to sky blue), so Cycles importance-samples it with and
    # without the effect (a constant world is not light-sampled at all, and any shaded world would add noise).
    tree = scene.world.node_tree
    coordinates = tree.nodes.new("ShaderNodeTexCoord")
    split = tree.nodes.new("ShaderNodeSeparateXYZ")
    mix = tree.nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    mix.clamp_factor = True
    mix.inputs[6].default_value = (0.1, 0.08, 0.05, 1.0)
    mix.inputs[7].default_value = (*WORLD_COLOUR, 1.0)
    tree.links.new(coordinates.outputs["Generated"], split.inputs[0])
    tree.links.new(split.outputs["Z"], mix.inputs[0])
    tree.links.new(mix.outputs[2], tree.nodes["Background"].inputs["Color"])
    scene.atmos.sky_enabled = False  # the same world and sunlight with and without the effect
    scene.atmos.drive_sun_lamp = False
    return scene


def _noise(scene, tmp_path: Path, name: str) -> np.ndarray:
    """Per-channel pixel noise: the standard deviation of the difference of two seeds' renders, / sqrt(2).

    Differencing removes what every render shares (the wall's shading, the haze's variation across the view),
    leaving the sampling noise of one render.
    """
    scene.cycles.seed = 7
    first = _render(scene, tmp_path, f"{name}_7")
    scene.cycles.seed = 8
    second = _render(scene, tmp_path, f"{name}_8")
    return (first - second).std(axis=(0, 1)) / math.sqrt(2.0)


def test_in_render_adds_no_noise(tmp_path: Path) -> None:
    """Noise over the wall, divided by its F_ex, equals the noise of the render without the effect within 5 %."""
    scene = _noise_scene()
    plain = _noise(scene, tmp_path, "plain")
    scene.atmos.render_mode = "IN_RENDER"
    orchestrator.enable_effect(scene)
    f_ex, _ = _segment(scene, (0.0, 1.0, 0.0), 1000.0)
    hazed = _noise(scene, tmp_path, "hazed") / f_ex
    ratio = hazed / plain
    print(f"noise: without {plain}, with / F_ex {hazed}, ratio {ratio}")
    assert np.all(plain > 0.0)
    np.testing.assert_allclose(ratio, 1.0, atol=0.05)


def _tree_snapshot(tree) -> tuple:
    nodes = []
    for node in tree.nodes:
        values = tuple((s.identifier, tuple(s.default_value) if hasattr(s.default_value, "__len__") else s.default_value)
                       for s in node.inputs if hasattr(s, "default_value"))
        extra = (node.target, node.is_active_output) if hasattr(node, "target") else ()
        nodes.append((node.name, node.bl_idname, tuple(node.location), values, extra))
    links = sorted((l.from_node.name, l.from_socket.identifier, l.to_node.name, l.to_socket.identifier)
                   for l in tree.links)
    return sorted(nodes), links


def _file_snapshot(scene) -> tuple:
    return (
        {m.name: (_tree_snapshot(m.node_tree), m.cycles.emission_sampling) for m in bpy.data.materials},
        _tree_snapshot(scene.world.node_tree),
        sorted(o.name for o in bpy.data.objects), sorted(c.name for c in bpy.data.collections),
        sorted(g.name for g in bpy.data.node_groups), sorted(m.name for m in bpy.data.meshes),
        # Blender 4.x lists the add-on's own settings (the registered PropertyGroup) among the ID properties.
        scene.camera.data.clip_end, sorted(k for k in scene.keys() if k != "atmos"),
        scene.cycles.transparent_max_bounces, scene.cycles.min_transparent_bounces,
    )


def test_in_render_removal_restores_the_scene_exactly() -> None:
    scene, _sun = _scene()
    _build_planes(scene)
    cycles_only = emission_material("Cycles only", (0.1, 0.2, 0.3))  # a user output with target Cycles
    tree = cycles_only.node_tree
    extra = tree.nodes.new("ShaderNodeOutputMaterial")
    extra.target = "CYCLES"
    tree.links.new(tree.nodes["Emission"].outputs[0], extra.inputs["Surface"])
    _quad("Cycles only", cycles_only, Vector((0.0, 50.0, 0.0)), Vector((0.0, -1.0, 0.0)), 1.0)
    scene.camera.data.clip_end = 1000.0
    before = _file_snapshot(scene)
    scene.atmos.render_mode = "IN_RENDER"
    report = orchestrator.enable_effect(scene)
    assert in_render.is_installed(scene)
    assert len(report.managed) == 6
    domes = [o for o in bpy.data.objects if o.name.startswith("Atmos Dome")]
    assert len(domes) == 2 and all(o.hide_select and not o.visible_diffuse and not o.visible_shadow for o in domes)
    assert all(o.constraints[0].target == scene.camera for o in domes)
    assert scene.camera.data.clip_end > 290_000.0  # beyond the molecules' dome at the horizon
    assert scene.cycles.transparent_max_bounces == before[-2] + in_render.DOME_CROSSINGS
    assert scene.cycles.min_transparent_bounces == before[-1] + in_render.DOME_CROSSINGS
    assert bpy.data.materials["Mirror"].cycles.emission_sampling == "NONE"
    assert not any(n.get(materials.TAG) for m in bpy.data.materials if m.node_tree for n in m.node_tree.nodes
                   if n.bl_idname == "ShaderNodeOutputAOV")
    ours = next(n for n in tree.nodes if n.get(materials.TAG) == in_render.OUTPUT_TAG)
    assert ours.is_active_output and not extra.is_active_output
    assert any(n.get(materials.TAG) for n in scene.world.node_tree.nodes)
    orchestrator.disable_effect(scene)
    assert _file_snapshot(scene) == before


def test_switching_modes_and_engines() -> None:
    scene, _sun = _scene()
    _build_planes(scene)
    before = _file_snapshot(scene)
    orchestrator.enable_effect(scene)
    assert not in_render.is_installed(scene)
    scene.atmos.render_mode = "IN_RENDER"  # the update callback switches
    assert in_render.is_installed(scene)
    scene.render.engine = EEVEE  # Eevee renders with the Compositor mode: the depsgraph handler switches
    bpy.context.view_layer.update()
    assert not in_render.is_installed(scene) and scene.atmos.enabled
    assert any(n.bl_idname == "ShaderNodeGroup" and n.get(materials.TAG)
               for n in bpy.data.materials["Near"].node_tree.nodes)
    scene.render.engine = "CYCLES"
    bpy.context.view_layer.update()
    assert in_render.is_installed(scene)
    scene.atmos.render_mode = "COMPOSITOR"
    assert not in_render.is_installed(scene)
    orchestrator.disable_effect(scene)
    scene.render.engine = "CYCLES"
    assert _file_snapshot(scene) == before


def test_in_render_file_renders_the_same_without_the_addon(tmp_path: Path) -> None:
    scene, _sun = _scene()
    scene.cycles.max_bounces = scene.cycles.glossy_bounces = 2
    _build_planes(scene)
    scene.atmos.render_mode = "IN_RENDER"
    orchestrator.enable_effect(scene)
    with_addon = _render(scene, tmp_path, "with")
    path = tmp_path / "farm.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    atmos_addon.unregister()
    try:
        bpy.ops.wm.open_mainfile(filepath=str(path))
        without = _render(bpy.context.scene, tmp_path, "without")
    finally:
        atmos_addon.register()
    np.testing.assert_array_equal(without, with_addon)


def test_thick_haze_warns_where_the_sky_compensation_stops() -> None:
    scene, _sun = _scene()
    scene.atmos.render_mode = "IN_RENDER"
    report = atmos_addon.api.enable(scene, preset="overcast")
    assert any("optical depth (74)" in line for line in report.messages), report.messages
    report = atmos_addon.api.enable(scene, preset="clear")
    assert not any("optical depth" in line for line in report.messages)


def test_transparent_bounces_come_back_even_at_blenders_limit() -> None:
    """The dome crossings' budget is added and given back exactly, also where Blender clamps it (1024)."""
    scene, _sun = _scene()
    _build_planes(scene)
    scene.cycles.transparent_max_bounces, scene.cycles.min_transparent_bounces = 1022, 3
    scene.atmos.render_mode = "IN_RENDER"
    orchestrator.enable_effect(scene)
    assert (scene.cycles.transparent_max_bounces, scene.cycles.min_transparent_bounces) == \
        (1024, 3 + in_render.DOME_CROSSINGS)
    orchestrator.disable_effect(scene)
    assert (scene.cycles.transparent_max_bounces, scene.cycles.min_transparent_bounces) == (1022, 3)
