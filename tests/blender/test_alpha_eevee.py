# SPDX-License-Identifier: GPL-3.0-or-later
"""Eevee and alpha cut-outs: a leaf card's transparent parts show the atmosphere of the surface behind them.

Eevee renders a material's alpha by dithering (``surface_render_method = "DITHERED"``, the default): a
sample where the alpha is 0 is discarded, AOV outputs included, so the AOVs of the hole come from the
surface behind. The card here has a 2 x 2 checker alpha of exactly 0 and 1 (Principled BSDF Alpha), so
one sample per pixel decides each pixel with no noise. The composited pixel of a hole must equal the far
wall's L0 F_ex + L_in at the wall's distance, an opaque cell the card's own, within 1 % (the tolerance of
the Eevee parity test in test_aerial_application.py; measured here about 1e-3).

The Cycles counterpart is ``test_cutout_does_not_catch_its_own_atmosphere_in_cycles``.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import bpy
import numpy as np
import pytest
from mathutils import Vector

from atmos_addon.blender import orchestrator
from render_utils import fast_segment, render_exr

EEVEE = "BLENDER_EEVEE" if bpy.app.version >= (5, 0, 0) else "BLENDER_EEVEE_NEXT"
WIDTH, HEIGHT, FOV = 32, 16, math.radians(20.0)
CARD_DISTANCE, CARD_RADIANCE = 300.0, (0.2, 0.2, 0.2)
WALL_DISTANCE, WALL_RADIANCE = 3000.0, (0.8, 0.8, 0.8)
TOLERANCE = 1e-2


pytestmark = pytest.mark.usefixtures("addon")


def _use_nodes(idblock) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        idblock.use_nodes = True


def _direction(column: int, row: int) -> Vector:
    """World direction of a pixel centre (camera at the origin looking along +Y, Z up; row 0 at the bottom)."""
    half = math.tan(FOV / 2.0)
    x = (column + 0.5 - WIDTH / 2.0) / (WIDTH / 2.0) * half
    z = (row + 0.5 - HEIGHT / 2.0) / (WIDTH / 2.0) * half
    return Vector((x, 1.0, z)).normalized()


def _square(name: str, material, half_size: float, distance: float):
    """A square facing the camera, perpendicular to +Y at ``distance``; local +x is world +x, local +y world +z."""
    mesh = bpy.data.meshes.new(name)
    h = half_size
    mesh.from_pydata([(-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0)], [], [(0, 1, 2, 3)])
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    obj.location = (0.0, distance, 0.0)
    obj.rotation_euler = (math.pi / 2.0, 0.0, 0.0)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _emissive_wall():
    material = bpy.data.materials.new("Wall")
    _use_nodes(material)
    tree = material.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    emission = tree.nodes.new("ShaderNodeEmission")
    emission.inputs["Color"].default_value = (*WALL_RADIANCE, 1.0)
    tree.links.new(emission.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    return _square("Wall", material, WALL_DISTANCE * math.tan(FOV / 2.0) * 1.5, WALL_DISTANCE)


def _checker_card():
    """Principled card, emissive, alpha = (x > 0.5) xor (z > 0.5) in its generated coordinates.

    Seen from the camera: bottom-left and top-right quarters are holes, the other two opaque.
    """
    material = bpy.data.materials.new("Leaf card")
    _use_nodes(material)
    material.surface_render_method = "DITHERED"
    tree = material.node_tree
    coords = tree.nodes.new("ShaderNodeTexCoord")
    split = tree.nodes.new("ShaderNodeSeparateXYZ")
    tree.links.new(coords.outputs["Generated"], split.inputs[0])
    halves = []
    for axis in ("X", "Y"):
        half = tree.nodes.new("ShaderNodeMath")
        half.operation = "GREATER_THAN"
        half.inputs[1].default_value = 0.5
        tree.links.new(split.outputs[axis], half.inputs[0])
        halves.append(half)
    differ = tree.nodes.new("ShaderNodeMath")
    differ.operation = "SUBTRACT"
    tree.links.new(halves[0].outputs[0], differ.inputs[0])
    tree.links.new(halves[1].outputs[0], differ.inputs[1])
    alpha = tree.nodes.new("ShaderNodeMath")
    alpha.operation = "ABSOLUTE"
    tree.links.new(differ.outputs[0], alpha.inputs[0])
    principled = tree.nodes["Principled BSDF"]
    principled.inputs["Base Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    principled.inputs["Specular IOR Level"].default_value = 0.0
    principled.inputs["Emission Color"].default_value = (*CARD_RADIANCE, 1.0)
    principled.inputs["Emission Strength"].default_value = 1.0
    tree.links.new(alpha.outputs[0], principled.inputs["Alpha"])
    return _square("Leaf card", material, CARD_DISTANCE * math.tan(FOV / 2.0) * 0.75, CARD_DISTANCE)


def _scene():
    scene = bpy.context.scene
    scene.render.engine = EEVEE
    scene.render.resolution_x, scene.render.resolution_y = WIDTH, HEIGHT
    scene.render.resolution_percentage = 100
    scene.render.filter_size = 0.0
    scene.eevee.taa_render_samples = 1
    scene.view_settings.view_transform = "Standard"
    scene.atmos.quality = "FAST"   # the expectations are the Fast equations (the default is Precise)
    world = bpy.data.worlds.new("World")
    scene.world = world
    _use_nodes(world)
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.05, 0.1, 0.2, 1.0)
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.data.sensor_fit = "HORIZONTAL"
    camera.data.angle = FOV
    camera.data.clip_start = 1.0
    camera.data.clip_end = 10_000.0
    camera.rotation_euler = (math.pi / 2.0, 0.0, 0.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.rotation_euler = (math.radians(50.0), 0.0, 0.5)
    scene.collection.objects.link(sun)
    return scene


_render = render_exr  # the composited image, linear RGB, row 0 at the bottom


def _expected(scene, radiance, plane_distance: float, column: int, row: int) -> np.ndarray:
    """L0 F_ex + L_in for the plane y = plane_distance seen through pixel (column, row)."""
    direction = _direction(column, row)
    transmittance, inscattered = fast_segment(scene, direction, plane_distance / direction.y)
    return np.asarray(radiance) * transmittance + inscattered


def test_eevee_checker_cutout_shows_the_far_wall_atmosphere_in_its_holes(tmp_path: Path) -> None:
    scene = _scene()
    _emissive_wall()
    _checker_card()
    scene.atmos.sky_enabled = False
    orchestrator.enable_effect(scene)
    pixels = _render(scene, tmp_path / "eevee_checker.exr")
    # the card spans columns 4-27 and rows 0-15 (its half size is 0.75 of the half view width); cell centres:
    holes = [(10, 4), (21, 11)]   # bottom-left and top-right quarters
    opaque = [(21, 4), (10, 11)]  # bottom-right and top-left quarters
    worst = 0.0
    for (column, row), radiance, distance in (
        [(p, WALL_RADIANCE, WALL_DISTANCE) for p in holes] + [(p, CARD_RADIANCE, CARD_DISTANCE) for p in opaque]
    ):
        expected = _expected(scene, radiance, distance, column, row)
        got = pixels[row, column]
        error = float(np.max(np.abs(got / expected - 1.0)))
        worst = max(worst, error)
        assert error <= TOLERANCE, (column, row, got, expected)
    wall_seen_bare = _expected(scene, WALL_RADIANCE, WALL_DISTANCE, *holes[0])
    card_atmosphere = _expected(scene, CARD_RADIANCE, CARD_DISTANCE, *opaque[0])
    assert not np.allclose(wall_seen_bare, card_atmosphere, rtol=0.05)  # the two cases are far apart
    print(f"eevee checker cut-out: max relative error {worst:.2e} (limit {TOLERANCE:g})")
