# SPDX-License-Identifier: GPL-3.0-or-later
"""Aerial perspective applied to a scene: material injection, compositor insertion, and render parity.

Render tests use tiny images (32 x 16 px) of emissive planes whose radiance L0 is known, so the
composited pixel must equal L0 F_ex + L_in from :mod:`atmos_addon.physics` (Hoffman & Preetham
2002, eq. 16). Cycles is held to 0.2 %, Eevee to 1 %.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import bpy
import numpy as np
import pytest
from mathutils import Vector

from atmos_addon import plan
from atmos_addon.node_groups import parts, surface
from atmos_addon.blender.apply import compositor, materials
from atmos_addon.blender import orchestrator, scene_reading, settings_io
from render_utils import emission_material, fast_segment, parity_world_camera_sun, render_exr, \
    set_use_nodes, user_compositor, view_direction

IS_5 = bpy.app.version >= (5, 0, 0)
EEVEE = "BLENDER_EEVEE" if IS_5 else "BLENDER_EEVEE_NEXT"
WORLD_COLOUR = (0.05, 0.1, 0.2)
WIDTH, HEIGHT, FOV = 32, 16, math.radians(20.0)


pytestmark = pytest.mark.usefixtures("addon")


def _quiet(function, *args):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        return function(*args)


def snapshot(tree) -> tuple:
    """Node names/types/values and links of a tree, for before/after comparisons."""
    nodes = []
    for node in tree.nodes:
        values = tuple(
            (s.identifier, tuple(s.default_value) if hasattr(s.default_value, "__len__") else s.default_value)
            for s in node.inputs if hasattr(s, "default_value")
        )
        nodes.append((node.name, node.bl_idname, tuple(node.location), values))
    links = sorted(
        (link.from_node.name, link.from_socket.identifier, link.to_node.name, link.to_socket.identifier)
        for link in tree.links
    )
    return sorted(nodes), links


def user_material(name: str = "User"):
    """A material with a few user nodes: noise -> colour ramp -> principled, plus a loose math node."""
    material = bpy.data.materials.new(name)
    set_use_nodes(material, True)
    tree = material.node_tree
    noise = tree.nodes.new("ShaderNodeTexNoise")
    ramp = tree.nodes.new("ShaderNodeValToRGB")
    loose = tree.nodes.new("ShaderNodeMath")
    loose.inputs[0].default_value = 0.25
    tree.links.new(noise.outputs["Fac"], ramp.inputs["Fac"])
    tree.links.new(ramp.outputs["Color"], tree.nodes["Principled BSDF"].inputs["Base Color"])
    return material


def mesh_object(name: str, *mats, half_size: float | None = None):
    """A mesh object linked to the scene: a triangle, or a square of ``half_size`` in its XY plane."""
    mesh = bpy.data.meshes.new(name)
    if half_size is None:
        mesh.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
    else:
        h = half_size
        mesh.from_pydata([(-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0)], [], [(0, 1, 2, 3)])
    for material in mats:
        mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


# -- material injection ------------------------------------------------------------------------


#: The AOVs each mode's materials write, in the order the view layer declares them.
MODE_AOVS = {mode: plan.material_aovs(mode) for mode in plan.AOV_MODES}


@pytest.mark.parametrize("mode", ["PER_PIXEL", "COMPOSITOR"])
def test_enable_disable_restores_the_user_material_exactly(mode) -> None:
    material = user_material()
    mesh_object("A", material)
    before = snapshot(material.node_tree)
    bpy.context.scene.atmos.render_mode = mode
    report = orchestrator.enable_effect(bpy.context.scene)
    assert report.managed == ["User"]
    added = materials.atmos_nodes(material)
    assert len(added) == 1 and added[0].node_tree.name == materials.SURFACE_GROUP
    assert len(material.node_tree.nodes) == len(before[0]) + 1
    assert surface.aov_names(added[0].node_tree) == set(MODE_AOVS[mode])
    user_part = [n for n in snapshot(material.node_tree)[0] if n[0] != added[0].name]
    assert user_part == before[0], "injection must not move or change the user's nodes"
    orchestrator.disable_effect(bpy.context.scene)
    assert snapshot(material.node_tree) == before


def _no_stand_in_left() -> bool:
    return not any(surface.STAND_IN_KEY in group for group in bpy.data.node_groups)


@pytest.mark.parametrize("mode", ["PER_PIXEL", "COMPOSITOR"])
def test_a_bulk_pass_detaches_the_outputs_and_attaches_them_once(mode) -> None:
    """Over :data:`materials.BULK_THRESHOLD` materials, enable, a mode switch and disable edit them while the material
    group is detached from its outputs (``surface.detached``): afterwards every material has the group node, the
    group instances the outputs group (one attach, counted), the materials' own nodes are untouched, and no stand-in
    is left; disable strips them all and leaves no Atmos group behind."""
    scene = bpy.context.scene
    scene.atmos.render_mode = mode
    count = materials.BULK_THRESHOLD + 4
    users = [user_material(f"User {index}") for index in range(count)]
    for index, material in enumerate(users):
        mesh_object(f"Object {index}", material)
    before = [snapshot(material.node_tree) for material in users]
    attaches = []
    real_detached = surface.detached

    def counting(tree, outputs_group=None):
        attaches.append(tree.name)
        return real_detached(tree, outputs_group)

    surface.detached = counting
    try:
        orchestrator.enable_effect(scene)
        group = bpy.data.node_groups[materials.SURFACE_GROUP]
        assert attaches == [group.name, group.name]   # building its outputs, then the materials' pass
        assert surface.outputs_node(group).node_tree == bpy.data.node_groups[surface.OUTPUTS_GROUP]
        assert surface.aov_names(group) == set(MODE_AOVS[mode]) and _no_stand_in_left()
        for material, shot in zip(users, before):
            (node,) = materials.atmos_nodes(material)
            assert node.node_tree == group
            assert [n for n in snapshot(material.node_tree)[0] if n[0] != node.name] == shot[0]
        other = "COMPOSITOR" if mode == "PER_PIXEL" else "PER_PIXEL"
        attaches.clear()
        scene.atmos.render_mode = other   # the outputs rebuilt while detached; the materials not edited
        assert attaches == [group.name]
        assert surface.aov_names(group) == set(MODE_AOVS[other]) and _no_stand_in_left()
        assert all(materials.atmos_nodes(material)[0].node_tree == group for material in users)
        orchestrator.disable_effect(scene)
    finally:
        surface.detached = real_detached
    assert [snapshot(material.node_tree) for material in users] == before
    assert _no_stand_in_left()
    assert not [g.name for g in bpy.data.node_groups if g.name.startswith("Atmos")]


def test_a_pass_that_fails_midway_leaves_the_material_group_attached() -> None:
    """An error inside a detached pass (a material that cannot be edited, say) must not leave the material group on
    its empty stand-in: every material would then render without the atmosphere, silently."""
    scene = bpy.context.scene
    material = user_material()
    mesh_object("A", material)
    orchestrator.enable_effect(scene)
    group = bpy.data.node_groups[materials.SURFACE_GROUP]
    outputs = bpy.data.node_groups[surface.OUTPUTS_GROUP]
    with pytest.raises(RuntimeError, match="midway"):
        with surface.detached(group):
            assert surface.outputs_node(group).node_tree != outputs
            raise RuntimeError("midway")
    assert surface.outputs_node(group).node_tree == outputs and _no_stand_in_left()
    assert surface.aov_names(group) == set(MODE_AOVS[scene.atmos.render_mode])


def test_a_material_group_of_the_older_layout_is_rebuilt_in_place_around_an_outputs_group() -> None:
    """A file saved before the outputs group (the AOV outputs inside "Atmos Surface AOVs" itself, its version 3): the
    next enable rebuilds that group in place as one node of "Atmos AOV Outputs"; the materials keep their group node
    and its links, write the same AOVs, and the aerial group is reused, not copied."""
    from atmos_addon.node_groups import stamps

    scene = bpy.context.scene
    scene.atmos.render_mode = "COMPOSITOR"
    material = user_material()
    tree = material.node_tree
    tree.links.new(tree.nodes["Color Ramp"].outputs["Alpha"], tree.nodes["Principled BSDF"].inputs["Alpha"])
    mesh_object("A", material)
    orchestrator.enable_effect(scene)
    group = bpy.data.node_groups[materials.SURFACE_GROUP]
    aerial = bpy.data.node_groups["Atmos Aerial Perspective"]
    bpy.data.node_groups.remove(bpy.data.node_groups[surface.OUTPUTS_GROUP])
    surface.build_outputs_group(group, aerial, ("COMPOSITOR",))   # the older layout, stamped as it was
    stamps.stamp(group, stamps.SURFACE, "COMPOSITOR")
    group[stamps.VERSION_KEY] = 3
    (node,) = materials.atmos_nodes(material)
    linked = [(link.from_socket.identifier, link.to_socket.identifier) for link in material.node_tree.links
              if link.to_node == node]
    assert linked == [("Alpha", "Socket_0")]   # the ramp's alpha into the group's Opacity
    orchestrator.enable_effect(scene)
    assert bpy.data.node_groups[materials.SURFACE_GROUP] == group and group[stamps.VERSION_KEY] == 4
    assert [n.bl_idname for n in group.nodes] == ["NodeGroupInput", "ShaderNodeGroup"]
    outputs = bpy.data.node_groups[surface.OUTPUTS_GROUP]
    assert surface.outputs_node(group).node_tree == outputs
    assert surface.aov_names(group) == set(MODE_AOVS["COMPOSITOR"])
    assert materials.atmos_nodes(material) == [node] and node.node_tree == group
    assert [(link.from_socket.identifier, link.to_socket.identifier) for link in material.node_tree.links
            if link.to_node == node] == linked
    assert bpy.data.node_groups["Atmos Aerial Perspective"] == aerial and aerial.users == 1
    assert _no_stand_in_left() and not any(g.name.endswith(".001") for g in bpy.data.node_groups)


def test_shared_material_once_and_multiple_slots() -> None:
    shared, second = user_material("Shared"), user_material("Second")
    for index in range(5):
        mesh_object(f"Obj{index}", shared)
    mesh_object("TwoSlots", shared, second)
    report = orchestrator.enable_effect(bpy.context.scene)
    assert sorted(report.managed) == ["Second", "Shared"]
    for material in (shared, second):
        groups = [n for n in material.node_tree.nodes if n.bl_idname == "ShaderNodeGroup"]
        assert len(groups) == 1


def test_skipped_materials_and_bare_objects_are_reported(tmp_path: Path) -> None:
    plain = bpy.data.materials.new("NoNodes")
    set_use_nodes(plain, False)
    library_path = tmp_path / "library.blend"
    linked_source = user_material("Linked")
    bpy.data.libraries.write(str(library_path), {linked_source})
    bpy.data.materials.remove(linked_source)
    with bpy.data.libraries.load(str(library_path), link=True) as (data_from, data_to):
        data_to.materials = ["Linked"]
    linked = data_to.materials[0]
    mesh_object("Plain", plain)
    mesh_object("UsesLinked", linked)
    mesh_object("Bare")
    report = orchestrator.enable_effect(bpy.context.scene)
    reasons = dict(report.skipped)
    uses_nodes = _quiet(getattr, plain, "use_nodes")  # Blender 5.0 materials always use nodes
    assert uses_nodes or "use nodes" in reasons["NoNodes"].lower()
    assert "linked" in reasons["Linked"]
    assert report.objects_without_material == ["Bare"]
    assert any("without material" in m for m in report.messages)
    skipped = {"Linked"} if uses_nodes else {"NoNodes", "Linked"}
    assert {item.name for item in bpy.context.scene.atmos.skipped_materials} == skipped
    assert uses_nodes or not materials.is_injected(plain)


@pytest.mark.parametrize("mode", ["PER_PIXEL", "COMPOSITOR"])
def test_enable_disable_enable_is_idempotent(mode) -> None:
    material = user_material()
    mesh_object("A", material)
    scene = bpy.context.scene
    scene.atmos.render_mode = mode
    orchestrator.enable_effect(scene)
    bpy.context.view_layer.update()   # Per Pixel: the group node's driven inputs hold their values once evaluated
    first = snapshot(material.node_tree), snapshot(compositor.current_tree(scene))
    orchestrator.enable_effect(scene)
    bpy.context.view_layer.update()
    assert (snapshot(material.node_tree), snapshot(compositor.current_tree(scene))) == first
    orchestrator.disable_effect(scene)
    orchestrator.enable_effect(scene)
    assert snapshot(material.node_tree)[1] == first[0][1]
    assert {n[0] for n in snapshot(material.node_tree)[0]} == {n[0] for n in first[0][0]}
    assert [a.name for a in scene.view_layers[0].aovs] == [name for name, _ in plan.AOVS[mode]]


def test_material_added_after_enabling_is_picked_up() -> None:
    scene = bpy.context.scene
    mesh_object("A", user_material("First"))
    orchestrator.enable_effect(scene)
    late = user_material("Late")
    mesh_object("B", late)
    bpy.context.view_layer.update()  # runs depsgraph_update_post
    assert materials.is_injected(late)


def test_sun_direction_follows_the_lamp() -> None:
    scene = bpy.context.scene
    direction, status = scene_reading.sun_direction(scene)
    assert direction[2] == pytest.approx(math.sqrt(0.5)) and "default" in status
    lamp = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    scene.collection.objects.link(lamp)
    lamp.rotation_euler = (math.radians(60.0), 0.0, 0.0)  # tilts local +Z towards -Y, 30 deg elevation
    bpy.context.view_layer.update()
    direction, status = scene_reading.sun_direction(scene)
    np.testing.assert_allclose(direction, (0.0, -math.sin(math.radians(60)), math.cos(math.radians(60))), atol=1e-6)
    assert "'Sun'" in status


# -- compositor --------------------------------------------------------------------------------


_user_compositor = user_compositor


def _compositor_state(scene) -> tuple:
    if IS_5:
        tree = compositor.current_tree(scene)
        effects = [(e.name, e.node_group) for e in scene.compositor_effects] if compositor.EFFECT_STACK else None
        return (tree.name if tree else None, snapshot(tree) if tree else None, scene.render.use_compositing, effects)
    return (_quiet(getattr, scene, "use_nodes"), snapshot(scene.node_tree) if scene.node_tree else None,
            scene.render.use_compositing)


def test_user_compositor_is_kept_and_restored_exactly() -> None:
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    mesh_object("A", user_material())
    tree = _user_compositor(scene)
    before = _compositor_state(scene)
    orchestrator.enable_effect(scene)
    glare = next(n for n in tree.nodes if n.bl_idname == "CompositorNodeGlare")
    feeding = glare.inputs["Image"].links[0].from_node
    assert feeding.name == compositor.COMPOSITE_NODE, "the Glare must now read the atmosphere-composited image"
    orchestrator.enable_effect(scene)
    assert len([n for n in tree.nodes if n.name.startswith(compositor.COMPOSITE_NODE)]) == 1
    orchestrator.disable_effect(scene)
    assert _compositor_state(scene) == before
    assert len(scene.view_layers[0].aovs) == 0
    assert compositor.STATE_KEY not in scene


def test_missing_compositor_is_created_and_removed() -> None:
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    mesh_object("A", user_material())
    before = _compositor_state(scene)
    orchestrator.enable_effect(scene)
    tree = compositor.current_tree(scene)
    assert tree is not None and compositor.COMPOSITE_NODE in tree.nodes
    orchestrator.disable_effect(scene)
    after = _compositor_state(scene)
    if IS_5:
        assert after == before
        assert compositor.CREATED_TREE_NAME not in bpy.data.node_groups
    else:  # 4.5 keeps the (now empty) embedded tree that use_nodes created
        assert after[0] == before[0] and after[2] == before[2] and after[1] in (None, ([], []))
    assert compositor.GROUP_NAME not in bpy.data.node_groups


# -- renders -----------------------------------------------------------------------------------


def _pixel_direction(column: int, row: int) -> Vector:
    """World direction of a pixel centre for the test camera (at the origin, looking along +Y, Z up)."""
    return view_direction(column, row, WIDTH, HEIGHT, FOV)


def _emissive_plane(name: str, radiance, distance: float, column: int, row: int):
    material = emission_material(name, radiance)
    direction = _pixel_direction(column, row)
    obj = mesh_object(name, material, half_size=distance * 3.0 * math.tan(FOV / 2.0) / (WIDTH / 2.0))  # ~3 px
    obj.location = direction * distance
    obj.rotation_euler = (-direction).to_track_quat("Z", "Y").to_euler()  # faces the camera
    return obj


def _render_scene(engine: str):
    scene = bpy.context.scene
    scene.render.engine = engine
    scene.render.resolution_x, scene.render.resolution_y = WIDTH, HEIGHT
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = "Standard"
    scene.render.filter_size = 0.0
    if engine == "CYCLES":
        scene.cycles.samples = 4
        scene.cycles.use_denoising = False
        scene.cycles.device = "CPU"
        scene.cycles.filter_width = 0.01  # sample the pixel centre, where the expected value is computed
    else:
        scene.eevee.taa_render_samples = 1
    sun = parity_world_camera_sun(scene, WORLD_COLOUR, FOV)
    scene.atmos.quality = "FAST"   # these renders check the Fast equations (the default is Precise)
    return scene, sun


PLANES = (  # name, L0, distance (m), pixel column, row
    ("Near", (0.2, 0.5, 0.8), 300.0, 6, 8),
    ("Middle", (0.6, 0.4, 0.3), 3000.0, 16, 8),
    ("Far", (0.5, 0.5, 0.5), 20000.0, 26, 8),
)
SKY_PIXEL = (16, 1)


def _render(scene, tmp_path: Path, name: str) -> np.ndarray:
    return render_exr(scene, tmp_path / f"{name}.exr")  # RGB, row 0 at the bottom


def _expected(scene, radiance, distance: float, column: int, row: int) -> np.ndarray:
    transmittance, inscattered = fast_segment(scene, _pixel_direction(column, row), distance)
    return np.asarray(radiance) * transmittance + inscattered


def _show_pass(scene, socket_name: str | None) -> None:
    """Route a Render Layers output (or, for None, our composite) to the final output."""
    tree = compositor.current_tree(scene)
    combine = tree.nodes[compositor.COMPOSITE_NODE]
    output = next(n for n in tree.nodes if n.bl_idname in ("NodeGroupOutput", "CompositorNodeComposite"))
    target = output.inputs[0]
    layers = combine.inputs["Image"].links[0].from_node
    source = combine.outputs["Image"] if socket_name is None else layers.outputs[socket_name]
    tree.links.new(source, target)


def _assert_planes_composite_the_physics(scene, pixels: np.ndarray, tolerance: float, what: str) -> None:
    """Each of :data:`PLANES` is the physics core's L0 F_ex + L_in within ``tolerance``; the sky pixel untouched."""
    for name, radiance, distance, column, row in PLANES:
        expected = _expected(scene, radiance, distance, column, row)
        got = pixels[row, column]
        print(f"{what} {name}: max relative error {np.max(np.abs(got / expected - 1)):.2e}")
        assert np.allclose(got, expected, rtol=tolerance, atol=0), (what, name, got, expected)
    np.testing.assert_allclose(pixels[SKY_PIXEL[1], SKY_PIXEL[0]], WORLD_COLOUR, rtol=2e-3)


def _parity(engine: str, tolerance: float, tmp_path: Path) -> dict:
    scene, sun = _render_scene(engine)
    for name, radiance, distance, column, row in PLANES:
        _emissive_plane(name, radiance, distance, column, row)
    scene.atmos.sky_enabled = False  # the user's plain world must pass through untouched (the sky: test_sky_sun)
    scene.atmos.render_mode = "COMPOSITOR"   # its per-sample passes (Per Pixel: test_per_pixel_mode_composites...)
    orchestrator.enable_effect(scene)
    aovs = {}
    for label, rotation in (("high", (math.radians(30), 0, math.radians(40))), ("low", (math.radians(80), 0, 2.5))):
        sun.rotation_euler = rotation
        bpy.context.view_layer.update()  # the depsgraph handler re-syncs the sun
        _assert_planes_composite_the_physics(scene, _render(scene, tmp_path, f"{engine}_{label}"), tolerance,
                                             f"parity {engine} sun={label}")
    for socket_name in ("atmos_transmittance", "atmos_inscattering"):
        _show_pass(scene, socket_name)
        pixels = _render(scene, tmp_path, f"{engine}_{socket_name}")
        aovs[socket_name] = np.array([pixels[row, column] for *_, column, row in PLANES])
    _show_pass(scene, None)
    return aovs


@pytest.fixture(scope="module")
def aov_results() -> dict:
    return {}


def test_cycles_parity_with_the_physics(tmp_path: Path, aov_results: dict) -> None:
    aov_results["CYCLES"] = _parity("CYCLES", 2e-3, tmp_path)


def test_eevee_parity_with_the_physics(tmp_path: Path, aov_results: dict) -> None:
    aov_results["EEVEE"] = _parity(EEVEE, 1e-2, tmp_path)
    if "CYCLES" in aov_results:
        for name in aov_results["CYCLES"]:
            ratio = np.max(np.abs(aov_results["EEVEE"][name] / aov_results["CYCLES"][name] - 1))
            print(f"engines {name}: max relative difference {ratio:.2e}")
            np.testing.assert_allclose(aov_results["EEVEE"][name], aov_results["CYCLES"][name], rtol=1e-2)


def _cutout_card(kind: str, distance: float, radiance: float):
    """A card whose left half is fully transparent: Principled Alpha or Mix Shader with Transparent BSDF."""
    material = bpy.data.materials.new(f"Card {kind}")
    set_use_nodes(material, True)
    tree = material.node_tree
    coords = tree.nodes.new("ShaderNodeTexCoord")
    split = tree.nodes.new("ShaderNodeSeparateXYZ")
    mask = tree.nodes.new("ShaderNodeMath")
    mask.operation = "GREATER_THAN"
    mask.inputs[1].default_value = 0.5
    tree.links.new(coords.outputs["Generated"], split.inputs[0])
    tree.links.new(split.outputs["X"], mask.inputs[0])
    principled = tree.nodes["Principled BSDF"]
    if kind == "mix":
        tree.nodes.remove(principled)
        emission = tree.nodes.new("ShaderNodeEmission")
        emission.inputs["Color"].default_value = (radiance, radiance, radiance, 1.0)
        transparent = tree.nodes.new("ShaderNodeBsdfTransparent")
        mix = tree.nodes.new("ShaderNodeMixShader")
        tree.links.new(mask.outputs[0], mix.inputs[0])
        tree.links.new(transparent.outputs[0], mix.inputs[1])
        tree.links.new(emission.outputs[0], mix.inputs[2])
        tree.links.new(mix.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    else:
        principled.inputs["Base Color"].default_value = (0.0, 0.0, 0.0, 1.0)
        principled.inputs["Specular IOR Level"].default_value = 0.0
        principled.inputs["Emission Color"].default_value = (radiance, radiance, radiance, 1.0)
        principled.inputs["Emission Strength"].default_value = 1.0
        tree.links.new(mask.outputs[0], principled.inputs["Alpha"])
    obj = mesh_object(f"Card {kind}", material, half_size=distance * math.tan(FOV / 2.0) * 0.6)
    obj.location = (0.0, distance, 0.0)
    obj.rotation_euler = (math.pi / 2.0, 0.0, 0.0)
    return obj


@pytest.mark.parametrize("kind", ["mix", "principled"])
def test_cutout_does_not_catch_its_own_atmosphere_in_cycles(kind: str, tmp_path: Path) -> None:
    scene, sun = _render_scene("CYCLES")
    scene.cycles.samples = 8
    sun.rotation_euler = (math.radians(50), 0.0, 0.5)
    far = _emissive_plane("Far wall", (0.8, 0.8, 0.8), 3000.0, 16, 8)
    far.scale = (12.0, 12.0, 1.0)
    _cutout_card(kind, 300.0, 0.2)
    orchestrator.enable_effect(scene)
    pixels = _render(scene, tmp_path, f"cutout_{kind}")
    hole, card = (10, 8), (22, 8)  # left half of the card is transparent
    expected_far = _expected(scene, (0.8, 0.8, 0.8), 3000.0 / _pixel_direction(*hole)[1], *hole)
    expected_card = _expected(scene, (0.2, 0.2, 0.2), 300.0 / _pixel_direction(*card)[1], *card)
    np.testing.assert_allclose(pixels[hole[1], hole[0]], expected_far, rtol=3e-3)
    np.testing.assert_allclose(pixels[card[1], card[0]], expected_card, rtol=3e-3)


@pytest.mark.parametrize("engine, tolerance", [("CYCLES", 2e-3), (EEVEE, 1e-2)])
def test_per_pixel_mode_composites_the_physics(engine: str, tolerance: float, tmp_path: Path) -> None:
    """Per Pixel mode: the compositor evaluates the Fast level from the distance and view AOVs, and the pixels are
    the physics core's L0 F_ex + L_in (sun high and low), the sky untouched, the parameters driven live."""
    scene, sun = _render_scene(engine)
    for name, radiance, distance, column, row in PLANES:
        _emissive_plane(name, radiance, distance, column, row)
    scene.atmos.sky_enabled = False
    scene.atmos.quality = "FAST"
    scene.atmos.render_mode = "PER_PIXEL"
    orchestrator.enable_effect(scene)
    assert scene.atmos.status_built.startswith("Fast, ") and "per pixel" in scene.atmos.status_built
    layer_aovs = {aov.name for aov in scene.view_layers[0].aovs}
    assert layer_aovs == {name for name, _ in plan.AOVS["PER_PIXEL"]}
    for label, rotation in (("high", (math.radians(30), 0, math.radians(40))), ("low", (math.radians(80), 0, 2.5))):
        sun.rotation_euler = rotation
        bpy.context.view_layer.update()
        _assert_planes_composite_the_physics(scene, _render(scene, tmp_path, f"{engine}_per_pixel_{label}"),
                                             tolerance, f"per pixel {engine} sun={label}")


def test_per_pixel_names_agree_between_the_materials_and_the_compositor_group() -> None:
    from atmos_addon.node_groups import parameters, per_pixel, surface

    assert (surface.AOV_DISTANCE, surface.AOV_VIEW) == (per_pixel.AOV_DISTANCE, per_pixel.AOV_VIEW)
    assert surface.DISTANCE_AOV_UNIT_M == per_pixel.DISTANCE_AOV_UNIT_M
    assert surface.METRES_PER_UNIT == parameters.METRES_PER_UNIT
    assert sorted(aov for name, aov, _ in per_pixel.IMAGE_INPUTS if name not in ("Image", "Alpha", "Environment")) == sorted(
        name for name, _ in plan.AOVS["PER_PIXEL"])   # Image, Alpha and Environment are the render's own passes


def test_per_pixel_declares_its_colour_aovs_first_and_reorders_a_file_that_did_not() -> None:
    """Eevee writes 0 into a Value AOV that a colour AOV follows in the view layer (measured with bpy 5.2.3; with
    the coverage first, Per Pixel rendered as if the effect were off). The colour AOVs come first, and Refresh
    reinstalls a file saved with another order (or without this version's AOVs), restoring the user's compositor
    links."""
    scene = bpy.context.scene
    mesh_object("Thing", user_material())
    scene.atmos.render_mode = "PER_PIXEL"
    orchestrator.enable_effect(scene)
    layer = scene.view_layers[0]
    assert [(aov.name, aov.type) for aov in layer.aovs] == list(plan.AOVS["PER_PIXEL"])
    kinds = [aov.type for aov in layer.aovs]
    assert kinds == sorted(kinds, key=lambda kind: kind == "VALUE")   # every colour AOV before every value AOV
    assert not compositor.aovs_out_of_order(scene, scene[compositor.STATE_KEY].to_dict(), plan.AOVS["PER_PIXEL"])
    view = layer.aovs["atmos_view"]   # what an earlier version declared: coverage, distance, view
    layer.aovs.remove(view)
    view = layer.aovs.add()
    view.name, view.type = "atmos_view", "COLOR"
    assert compositor.aovs_out_of_order(scene, scene[compositor.STATE_KEY].to_dict(), plan.AOVS["PER_PIXEL"])
    orchestrator.refresh_effect(scene)
    assert [(aov.name, aov.type) for aov in layer.aovs] == list(plan.AOVS["PER_PIXEL"])
    tree = compositor.current_tree(scene)
    node = tree.nodes[compositor.COMPOSITE_NODE]
    linked = {link.to_socket.name: link.from_socket.name for link in tree.links if link.to_node == node}
    assert linked == {"Image": "Image", "Coverage": "atmos_coverage", "Distance": "atmos_distance",
                      "View": "atmos_view", "Alpha": "Alpha", "Moments": "atmos_moments",
                      "Environment": compositor.layer_output(linked_layers(node), "Environment").name}
    orchestrator.disable_effect(scene)
    assert len(layer.aovs) == 0 and not layer.use_pass_environment


def linked_layers(node):
    """The Render Layers node that feeds ``node``'s Image."""
    return node.inputs["Image"].links[0].from_node


def test_per_pixel_mode_swaps_with_the_compositor_mode_and_disables_cleanly() -> None:
    """Compositor <-> Per Pixel swaps the AOVs and the inserted group without touching the materials; disabling
    removes the drivers, the groups and the AOVs."""
    scene = bpy.context.scene
    scene.atmos.quality = "FAST"   # the driver count below is the Fast level's
    scene.atmos.render_mode = "COMPOSITOR"
    user = user_material()
    mesh_object("Thing", user)
    before = _compositor_state(scene)
    orchestrator.enable_effect(scene)
    material_nodes = snapshot(user.node_tree)
    scene.atmos.render_mode = "PER_PIXEL"   # the update callback re-enables
    tree = compositor.current_tree(scene)
    node = tree.nodes[compositor.COMPOSITE_NODE]
    assert node.node_tree.name == "Atmos Aerial Composite (Per Pixel)"
    assert compositor.installed_evaluation(scene) == "PER_PIXEL"
    drivers = [curve for curve in tree.animation_data.drivers if curve.data_path.startswith('nodes["Atmos Aerial')]
    assert len(drivers) == 3 * 7 + 2 + 1   # 7 colour/vector parameters, 2 scalars, Film Transparent
    assert snapshot(user.node_tree) == material_nodes
    assert {aov.name for aov in scene.view_layers[0].aovs} == {name for name, _ in plan.AOVS["PER_PIXEL"]}
    group = bpy.data.node_groups[materials.SURFACE_GROUP]   # its outputs rebuilt in place: only this mode's
    assert surface.aov_names(group) == set(plan.material_aovs("PER_PIXEL"))
    outputs = bpy.data.node_groups[surface.OUTPUTS_GROUP]
    assert surface.outputs_node(group).node_tree == outputs
    assert not any(n.bl_idname == "ShaderNodeGroup" for n in outputs.nodes)
    assert "Atmos Aerial Perspective" not in bpy.data.node_groups   # nothing uses the shader group: none is kept
    other = bpy.data.scenes.new("Other")   # a second enabled scene in the Compositor mode: the group holds both
    other.camera = scene.camera
    other.collection.objects.link(bpy.data.objects["Thing"])
    other.atmos.render_mode = "COMPOSITOR"
    orchestrator.enable_effect(other)
    assert surface.aov_names(group) == set(plan.material_aovs("PER_PIXEL")) | set(plan.material_aovs("COMPOSITOR"))
    assert bpy.data.node_groups["Atmos Aerial Perspective"].users == 1
    orchestrator.disable_effect(other)
    bpy.data.scenes.remove(other)
    scene["atmos_mie_g"] = (0.1, 0.2, 0.3)   # what sync writes; the driver reads it
    scene.frame_set(scene.frame_current)
    assert tuple(round(v, 6) for v in node.inputs["Mie Anisotropy g"].default_value) == (0.1, 0.2, 0.3)
    # E_sun is itself driven by the sun lamp: the group's input follows it through the scene's property
    assert tuple(node.inputs["Sun Irradiance (W/m^2)"].default_value) == pytest.approx(
        tuple(scene["atmos_sun_irradiance"]), rel=1e-6)
    scene.atmos.render_mode = "COMPOSITOR"
    node = compositor.current_tree(scene).nodes[compositor.COMPOSITE_NODE]
    assert node.node_tree.name == compositor.GROUP_NAME
    assert {aov.name for aov in scene.view_layers[0].aovs} == {name for name, _ in plan.AOVS["COMPOSITOR"]}
    animation = compositor.current_tree(scene).animation_data   # the Compositor mode's node: Film Transparent alone
    assert [curve.data_path for curve in animation.drivers] == [
        node.inputs[compositor.FILM_TRANSPARENT].path_from_id("default_value")]
    assert "Atmos Aerial Composite (Per Pixel)" not in bpy.data.node_groups   # unused now: not left in the file
    scene.atmos.render_mode = "PER_PIXEL"
    orchestrator.disable_effect(scene)
    assert _compositor_state(scene) == before or not compositor.GROUP_API
    assert "Atmos Aerial Composite (Per Pixel)" not in bpy.data.node_groups
    tree = compositor.current_tree(scene)
    assert tree is None or tree.animation_data is None or not tree.animation_data.drivers
    assert not list(scene.view_layers[0].aovs)


def test_a_per_pixel_group_of_an_older_version_is_rebuilt_and_its_node_driven_again() -> None:
    """A file saved by the first Per Pixel version (stop 18: eight parameter inputs, Fast only): the next sync
    rebuilds the group in place with today's inputs, and the group node gets a valid driver on every one."""
    from atmos_addon.node_groups import per_pixel, stamps

    scene = bpy.context.scene
    mesh_object("Thing", user_material())
    scene.camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(scene.camera)
    scene.atmos.render_mode = "PER_PIXEL"
    scene.atmos.quality = "FAST"
    orchestrator.enable_effect(scene)
    tree = compositor.current_tree(scene)
    group = bpy.data.node_groups[per_pixel.GROUP_NAME]
    old_inputs = 4 + 8   # Image, Coverage, Distance, View and the eight parameters of the first version
    for item in [i for i in group.interface.items_tree if i.item_type == "SOCKET" and i.in_out == "INPUT"][old_inputs:]:
        group.interface.remove(item)
    for curve in [c for c in tree.animation_data.drivers if int(c.data_path.split("inputs[")[1].split("]")[0])
                  >= old_inputs]:
        tree.animation_data.drivers.remove(curve)
    group[stamps.VERSION_KEY] = 1
    orchestrator.update(scene)
    assert group[stamps.VERSION_KEY] == stamps.PER_PIXEL.version and bpy.data.node_groups[per_pixel.GROUP_NAME] == group
    node = tree.nodes[compositor.COMPOSITE_NODE]
    drivers = [c for c in tree.animation_data.drivers if c.data_path.startswith(f'nodes["{node.name}"]')]
    assert len(drivers) == 3 * 7 + 2 + 1 and all(c.driver.is_valid for c in drivers)   # 7 vectors, 2 numbers, film
    linked = {link.to_socket.name for link in tree.links if link.to_node == node}
    assert linked == {name for name, _, _ in per_pixel.IMAGE_INPUTS}   # the render passes stay wired


def test_a_per_pixel_group_saved_with_balanced_inputs_keeps_its_links_and_drops_their_drivers() -> None:
    """A Per Pixel group saved while Balanced existed had a camera-z input and three Balanced parameters (retired
    December 2026): rebuilt, those inputs and their drivers go, the render passes stay linked, every driver is
    valid and each parameter input reads its own scene property."""
    from atmos_addon.node_groups import per_pixel, stamps

    scene = bpy.context.scene
    mesh_object("Thing", user_material())
    scene.camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(scene.camera)
    scene.atmos.render_mode = "PER_PIXEL"
    scene.atmos.quality = "FAST"
    orchestrator.enable_effect(scene)
    tree = compositor.current_tree(scene)
    group = bpy.data.node_groups[per_pixel.GROUP_NAME]
    node = tree.nodes[compositor.COMPOSITE_NODE]
    inputs = [i for i in group.interface.items_tree if i.item_type == "SOCKET" and i.in_out == "INPUT"]
    for position, (name, socket_type) in enumerate((("Origin Altitude (m)", "NodeSocketFloat"),
                                                    ("Sun Optical Depth, Rayleigh", "NodeSocketVector"),
                                                    ("Sun Optical Depth, Mie", "NodeSocketVector"),
                                                    ("Camera z (units)", "NodeSocketFloat"))):
        item = group.interface.new_socket(name, in_out="INPUT", socket_type=socket_type)
        group.interface.move(item, inputs[len(per_pixel.IMAGE_INPUTS) + 9].position + position)
    for socket in node.inputs[len(per_pixel.IMAGE_INPUTS):]:   # the drivers of then, by input index
        for index in range(3 if socket.type == "VECTOR" else 1):
            socket.driver_add("default_value", index) if socket.type == "VECTOR" else socket.driver_add("default_value")
    group[stamps.VERSION_KEY] = 1
    orchestrator.update(scene)
    assert [s.name for s in node.inputs if s.name in ("Camera z (units)", "Origin Altitude (m)")] == []
    drivers = [c for c in tree.animation_data.drivers if c.data_path.startswith(f'nodes["{node.name}"]')]
    assert len(drivers) == 3 * 7 + 2 + 1 and all(c.driver.is_valid for c in drivers)   # and Film Transparent
    for curve in drivers:
        socket = tree.path_resolve(curve.data_path.rsplit(".", 1)[0])
        if socket.name == compositor.FILM_TRANSPARENT:
            assert curve.driver.variables[0].targets[0].data_path == "render.film_transparent"
            continue
        name = next(prop for prop, socket_name, _ in per_pixel.PARAMETER_SOCKETS if socket_name == socket.name)
        assert curve.driver.variables[0].targets[0].data_path.startswith(f'["{name}"]'), (socket.name, curve)
    linked = {link.to_socket.name for link in tree.links if link.to_node == node}
    assert linked == {name for name, _, _ in per_pixel.IMAGE_INPUTS}


def _aircraft_planes(engine: str, quality: str, mode: str):
    """The planes seen from 3 km up (origin altitude 2.5 km, the camera and the planes raised 500 m), the sun at
    60 deg from the zenith, the effect enabled at ``quality`` in ``mode``, no Atmos sky; the scene."""
    scene, sun = _render_scene(engine)
    for name, radiance, distance, column, row in PLANES:
        _emissive_plane(name, radiance, distance, column, row)
    for obj in scene.objects:
        if obj.type != "LIGHT":
            obj.location.z += 500.0
    scene.atmos.sky_enabled = False
    scene.atmos.quality = quality
    scene.atmos.render_mode = mode
    scene.atmos.origin_altitude = 2500.0
    sun.rotation_euler = (math.radians(30), 0, math.radians(40))
    bpy.context.view_layer.update()   # the sun's matrix, which the Precise bake reads
    orchestrator.enable_effect(scene)
    group = "Atmos Aerial Composite (Per Pixel)" if mode == "PER_PIXEL" else "Atmos Aerial Perspective"
    assert bpy.data.node_groups[group]["atmos_features"].endswith(f"+{quality.lower()}")
    return scene


def _assert_planes_match(pixels: np.ndarray, expected_of, tolerance: float, what: str) -> None:
    """Each of :data:`PLANES` is ``expected_of(radiance, distance, column, row)`` within ``tolerance``."""
    for name, radiance, distance, column, row in PLANES:
        expected = expected_of(radiance, distance, column, row)
        got = pixels[row, column]
        print(f"{what} {name}: max relative error {np.max(np.abs(got / expected - 1)):.2e}")
        assert np.allclose(got, expected, rtol=tolerance, atol=0), (what, name, got, expected)


def _expected_precise(scene, radiance, distance: float, column: int, row: int) -> np.ndarray:
    """L0 F_ex + L_in sampled from the scene's Precise table as ``physics.precise.evaluate`` samples it (the tile
    baked again here for the scene's camera and sun, multiple scattering off as by default)."""
    from atmos_addon.physics.precise import bake_tile, evaluate

    atmosphere = settings_io.atmosphere_from_settings(scene.atmos)
    sun_dir, _ = scene_reading.sun_direction(scene)
    altitude = scene.atmos.origin_altitude + scene.camera.location.z * scene_reading.metres_per_unit(scene)
    tile = bake_tile(atmosphere, altitude, math.asin(sun_dir[2]), ground_albedo=tuple(scene.atmos.ground_albedo),
                     multiple_scattering=bool(scene.atmos.multiple_scattering))
    view = np.array(_pixel_direction(column, row))
    f_ex, l_in = evaluate(tile, view, sun_dir, distance * scene_reading.metres_per_unit(scene), atmosphere, np.float64)
    return np.asarray(radiance) * f_ex + l_in


@pytest.mark.parametrize("mode", ["COMPOSITOR", "PER_PIXEL"])
@pytest.mark.parametrize("engine, tolerance", [("CYCLES", 2e-3), (EEVEE, 1e-2)])
def test_precise_level_composites_the_physics(engine: str, tolerance: float, mode: str, tmp_path: Path) -> None:
    """The Precise level end to end from 3 km up: the composited pixels are the baked table sampled by
    ``physics.precise.evaluate``. In Per Pixel mode the compositor fetches the texels with Map UV nodes from the
    packed table image, its tile parameters driven from the scene."""
    scene = _aircraft_planes(engine, "PRECISE", mode)
    if mode == "PER_PIXEL":
        per_pixel = bpy.data.node_groups["Atmos Aerial Composite (Per Pixel)"]
        assert any(n.bl_idname == "CompositorNodeImage" and n.image is not None and n.image.packed_file
                   for tree in parts.used_parts(per_pixel) for n in tree.nodes)   # in its table-sample part
    pixels = _render(scene, tmp_path, f"{engine}_{mode}_precise")
    _assert_planes_match(pixels, lambda *plane: _expected_precise(scene, *plane), tolerance,
                         f"precise {engine} {mode}")
