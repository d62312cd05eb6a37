# SPDX-License-Identifier: GPL-3.0-or-later
"""Surfaces whose material no object's slot lists: a Geometry Nodes *Set Material*, the objects of a collection
instanced from outside the scene, a background set's objects, a view layer's Material Override. Until December 2026
Atmos looked only at the slots of the scene's objects, so these rendered with no haze at all (a scatter of rocks, an
instanced asset, a set scene, a clay render), and an object coloured by its Geometry Nodes was reported as having no
material.

Each scene starts from an empty factory file: a camera 2 m up looking north with a 20 degree field of view, a sun
behind it, three emissive targets (radiance 0.5) 3 km away side by side. The expectation is the same scene with a
slot material on every target: the same pixels, through the API, the CLI's ``render`` and ``apply`` then a process
that never imports the add-on; ``disable`` strips every material it added nodes to.
"""

from __future__ import annotations

import math

import bpy
import numpy as np
import pytest

from atmos_addon import api, cli
from atmos_addon.blender.apply import materials
from exr_file import composite_rgb
import render_utils as ru

pytestmark = pytest.mark.usefixtures("addon")

WIDTH, HEIGHT, COLUMNS = 15, 6, 5   # three targets of 3 pixels, one-pixel gaps of sky between them
OPTIONS = {"preset": "clear", "sun_elevation_deg": 30.0, "sun_azimuth_deg": 180.0}
CLI_OPTIONS = ["--preset", "clear", "--sun-elevation", "30", "--sun-azimuth", "180", "--engine", "cycles"]


def _corners(index: int) -> list:
    """The quad 3 km north that covers columns COLUMNS * index + 1 .. + 3 of the image."""
    half = math.tan(math.radians(10.0))
    left = (COLUMNS * index + 1 - WIDTH / 2.0) / (WIDTH / 2.0) * half
    right = (COLUMNS * index + 4 - WIDTH / 2.0) / (WIDTH / 2.0) * half
    return [(3000.0 * left, 3000.0, -400.0), (3000.0 * right, 3000.0, -400.0),
            (3000.0 * right, 3000.0, 400.0), (3000.0 * left, 3000.0, 400.0)]


def _set_material_tree(material) -> bpy.types.NodeTree:
    """A Geometry Nodes tree that gives its geometry ``material`` (Set Material)."""
    tree = bpy.data.node_groups.new("Set Grey", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    group_input, group_output = tree.nodes.new("NodeGroupInput"), tree.nodes.new("NodeGroupOutput")
    setter = tree.nodes.new("GeometryNodeSetMaterial")
    setter.inputs["Material"].default_value = material
    tree.links.new(group_input.outputs[0], setter.inputs["Geometry"])
    tree.links.new(setter.outputs["Geometry"], group_output.inputs[0])
    return tree


def _scene(kind: str, library=None):
    """``slots``: a slot material on each target; ``instanced``: the first by its slot, the second by a Geometry
    Nodes modifier (no slot), the third in a collection the scene does not hold, instanced by an empty;
    ``set``: the first by its slot, the other two in the scene's background set; ``override``: no target has a
    material, the view layer overrides them all."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    ru.make_camera(scene, location=(0.0, 0.0, 2.0), rotation_euler=(math.pi / 2.0, 0.0, 0.0),
                   fov_rad=math.radians(20.0), clip_start=0.1, clip_end=10_000.0)
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    scene.collection.objects.link(sun)
    ru.set_engine(scene, "CYCLES", width=WIDTH, height=HEIGHT)
    grey = [ru.emission_material(f"Grey {index}", (0.5, 0.5, 0.5)) for index in range(3)]
    if kind == "slots":
        for index in range(3):
            ru.make_plane(scene, f"Target {index}", _corners(index), grey[index])
    elif kind == "instanced":
        ru.make_plane(scene, "Target 0", _corners(0), grey[0])
        shaped = ru.make_plane(scene, "Target 1", _corners(1), None)
        shaped.modifiers.new("Set Grey", "NODES").node_group = _set_material_tree(grey[1])
        assets = bpy.data.collections.new("Assets")   # not linked to the scene
        asset = ru.make_plane(scene, "Target 2", _corners(2), grey[2])
        scene.collection.objects.unlink(asset)
        assets.objects.link(asset)
        instancer = bpy.data.objects.new("Assets instance", None)
        instancer.instance_type, instancer.instance_collection = "COLLECTION", assets
        scene.collection.objects.link(instancer)
    elif kind == "set":
        ru.make_plane(scene, "Target 0", _corners(0), grey[0])
        backdrop = bpy.data.scenes.new("Backdrop")
        for index in (1, 2):
            backdrop.collection.objects.link(ru.make_plane(scene, f"Target {index}", _corners(index), grey[index]))
            scene.collection.objects.unlink(backdrop.objects[f"Target {index}"])
        scene.background_set = backdrop
    elif kind == "linked":   # the collection "Assets" of ``library`` (:func:`_library`), instanced by an empty
        ru.make_plane(scene, "Target 0", _corners(0), grey[0])
        with bpy.data.libraries.load(str(library), link=True) as (_, data):
            data.collections = ["Assets"]
        instancer = bpy.data.objects.new("Assets instance", None)
        instancer.instance_type, instancer.instance_collection = "COLLECTION", data.collections[0]
        scene.collection.objects.link(instancer)
    elif kind == "override":
        for index in range(3):
            ru.make_plane(scene, f"Target {index}", _corners(index), None)
        bpy.context.view_layer.material_override = grey[0]
    else:
        raise ValueError(kind)
    return scene


def _middles(image: np.ndarray) -> np.ndarray:
    """The middle pixel (RGB) of each target, (3, 3)."""
    return image[HEIGHT // 2, [COLUMNS * index + 2 for index in range(3)], :3]


_REFERENCE: list = []


@pytest.fixture
def reference(addon):
    """The targets with slot materials, through the API: their middle pixels (rendered once per module)."""
    if not _REFERENCE:
        scene = _scene("slots")
        api.enable(scene, **OPTIONS)
        pixels = _middles(ru.render_to_array(scene))
        assert np.all(np.max(np.abs(pixels - 0.5), axis=-1) > 0.01), pixels   # hazed: not the bare 0.5
        _REFERENCE.append(pixels)
    return _REFERENCE[0]


@pytest.mark.parametrize("kind", ["instanced", "set", "override"])
def test_surfaces_no_slot_lists_are_hazed_like_slot_materials(kind, reference):
    scene = _scene(kind)
    report = api.enable(scene, **OPTIONS)
    names = {"override": {"Grey 0"}}.get(kind, {"Grey 0", "Grey 1", "Grey 2"})
    assert names <= set(report.managed)
    assert report.objects_without_material == []
    assert all(materials.is_injected(bpy.data.materials[name]) for name in names)
    pixels = _middles(ru.render_to_array(scene))
    assert np.max(np.abs(pixels - reference)) <= 1e-4, (pixels, reference)
    api.disable(scene)
    assert not any(materials.is_injected(material) for material in bpy.data.materials)


def test_an_object_without_material_is_still_reported():
    """The Geometry Nodes and override rules do not hide an object that renders with no material."""
    scene = _scene("instanced")
    ru.make_plane(scene, "Bare", [(0.0, -10.0, 0.0), (0.5, -10.0, 0.0), (0.5, -10.0, 0.5), (0.0, -10.0, 0.5)], None)
    assert api.enable(scene, **OPTIONS).objects_without_material == ["Bare"]


def test_a_material_override_set_after_enabling_is_picked_up():
    """The depsgraph handler's cheap check notices a view layer's new Material Override."""
    scene = _scene("override")
    view_layer = bpy.context.view_layer
    override = view_layer.material_override
    view_layer.material_override = None
    api.enable(scene, **OPTIONS)
    assert not materials.is_injected(override)
    view_layer.material_override = override
    view_layer.update()
    assert materials.is_injected(override)




def test_cli_render_and_apply_then_a_farm_haze_them_too(tmp_path, reference):
    farm_args = []
    for kind in ("instanced", "override"):
        source = tmp_path / f"{kind}.blend"
        _scene(kind)
        bpy.ops.wm.save_as_mainfile(filepath=str(source))
        out = tmp_path / f"{kind}.exr"
        assert cli.main(["render", str(source), *CLI_OPTIONS, "--output", str(out)]) == 0
        assert np.max(np.abs(_middles(composite_rgb(out)) - reference)) <= 1e-4, kind
        applied = tmp_path / f"{kind}_applied.blend"
        assert cli.main(["apply", str(source), *CLI_OPTIONS, "--output", str(applied)]) == 0
        farm_args += [str(applied), str(tmp_path / f"{kind}_farm")]
    assert ru.run_farm(tmp_path, farm_args) == {"addon_loaded": False}
    for kind in ("instanced", "override"):
        farm = np.load(str(tmp_path / f"{kind}_farm.npy"))
        assert np.max(np.abs(_middles(farm) - reference)) <= 1e-4, kind


def _library(path, *, atmos: bool, render_mode: str = "PER_PIXEL") -> None:
    """A library file: targets 1 and 2 in its collection "Assets", their materials "Asset 1" and "Asset 2"; with
    ``atmos``, saved with Atmos on in ``render_mode`` (so its materials carry the Atmos nodes)."""
    scene = _scene("slots")
    assets = bpy.data.collections.new("Assets")
    scene.collection.children.link(assets)
    for index in (1, 2):
        target = bpy.data.objects[f"Target {index}"]
        target.data.materials[0].name = f"Asset {index}"
        scene.collection.objects.unlink(target)
        assets.objects.link(target)
    if atmos:
        api.enable(scene, **OPTIONS, render_mode=render_mode)
    bpy.ops.wm.save_as_mainfile(filepath=str(path))


def test_linked_assets_from_a_file_with_atmos_on_are_hazed(tmp_path, reference):
    """A linked material cannot be edited, but one linked from a file saved with Atmos on carries the Atmos nodes,
    which write the view layer's AOVs by name: it is counted as managed, hazed as a local one, and Atmos builds its
    own groups beside the library's (a plain lookup by name returned the library's, which Atmos would have edited)."""
    from atmos_addon.node_groups import stamps

    library = tmp_path / "assets.blend"
    _library(library, atmos=True)
    scene = _scene("linked", library)
    report = api.enable(scene, **OPTIONS)
    assert {"Asset 1", "Asset 2"} <= set(report.managed) and report.skipped == [], report.skipped
    linked = [tree for tree in bpy.data.node_groups if tree.library is not None]
    assert linked and all(stamps.local(bpy.data.node_groups, tree.name) is not None for tree in linked)
    material_group = bpy.data.materials["Grey 0"].node_tree.nodes
    assert all(node.node_tree.library is None for node in material_group if node.bl_idname == "ShaderNodeGroup")
    pixels = _middles(ru.render_to_array(scene))
    assert np.max(np.abs(pixels - reference)) <= 1e-4, (pixels, reference)
    api.disable(scene)
    assert not materials.is_injected(bpy.data.materials["Grey 0"])


def test_linked_assets_without_the_nodes_are_reported_with_what_to_do(tmp_path):
    """From a file without Atmos: skipped, the report says to make it local or turn Atmos on in that file; from a file
    whose Atmos nodes write another mode's AOVs: skipped, and the report says which mode to switch to."""
    plain = tmp_path / "plain.blend"
    _library(plain, atmos=False)
    report = api.enable(_scene("linked", plain), **OPTIONS)
    reasons = dict(report.skipped)
    assert set(reasons) == {"Asset 1", "Asset 2"}
    assert all("make it local, or turn Atmos on in that file" in reason for reason in reasons.values())
    per_pixel = tmp_path / "per_pixel.blend"
    _library(per_pixel, atmos=True)
    report = api.enable(_scene("linked", per_pixel), **OPTIONS, render_mode="COMPOSITOR")
    reasons = dict(report.skipped)
    assert set(reasons) == {"Asset 1", "Asset 2"}
    assert all("Atmos nodes of another mode (no atmos_inscattering, atmos_transmittance, atmos_transmittance2, atmos_transmittance3)" in reason
               for reason in reasons.values()), reasons
