# SPDX-License-Identifier: GPL-3.0-or-later
"""A terrain valley: procedural ridges from 1 km to 45 km (up to 6.5 km high), a lake, a few foreground objects, a sun.

One Blender unit is one metre. The camera stands 2 m above the lake shore looking north (+Y); each
ridge is a height-field strip at a fixed distance, wide enough to fill the view, so the render
shows the same ground at many distances: the case aerial perspective is for.
Run: ``./run python -m atmos_addon.sample_scenes.valley --output valley.blend`` (with the pip ``bpy`` module), or
``blender --command atmos render valley ...`` with the extension installed.
"""

from __future__ import annotations

import math

import bpy
import numpy as np

from . import write_scene

#: (distance from the camera in m, ridge height in m, colour) for each ridge, near to far.
RIDGES = (
    (1_000.0, 50.0, (0.10, 0.16, 0.06)),
    (3_000.0, 220.0, (0.12, 0.15, 0.07)),
    (8_000.0, 800.0, (0.14, 0.13, 0.09)),
    (18_000.0, 2_200.0, (0.15, 0.13, 0.10)),
    (45_000.0, 6_500.0, (0.20, 0.19, 0.18)),
)
CAMERA_HEIGHT_M = 2.0
SUN_ELEVATION_DEG = 25.0
SUN_AZIMUTH_DEG = 60.0  # clockwise from north (+Y): ahead-right, just out of frame: its glow shows on the right


def material(name: str, colour: tuple[float, float, float], roughness: float = 0.8) -> bpy.types.Material:
    material = bpy.data.materials.new(name)
    material.use_nodes = True
    bsdf = material.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*colour, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    return material


def grid_object(name: str, xs: np.ndarray, ys: np.ndarray, heights: np.ndarray,
                 material: bpy.types.Material) -> bpy.types.Object:
    """A height-field mesh over the grid ``xs`` x ``ys`` (metres), heights[j, i] at (xs[i], ys[j])."""
    nx, ny = len(xs), len(ys)
    gx, gy = np.meshgrid(xs, ys)
    vertices = np.stack([gx.ravel(), gy.ravel(), heights.ravel()], axis=1)
    index = np.arange(nx * ny).reshape(ny, nx)
    quads = np.stack([index[:-1, :-1], index[:-1, 1:], index[1:, 1:], index[1:, :-1]], axis=-1).reshape(-1, 4)
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(vertices.tolist(), [], quads.tolist())
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _ridge(index: int, distance_m: float, height_m: float, colour: tuple[float, float, float],
           rng: np.random.Generator, half_fov_rad: float) -> bpy.types.Object:
    half_width = distance_m * math.tan(half_fov_rad) * 1.6 + 200.0
    depth = max(distance_m * 0.35, 300.0)
    xs = np.linspace(-half_width, half_width, 160)
    ys = np.linspace(distance_m, distance_m + depth, 24)
    phases = rng.uniform(0, 2 * math.pi, 4)
    u = xs / half_width
    crest = height_m * (0.75 + 0.15 * np.sin(3.1 * u + phases[0]) + 0.1 * np.sin(7.3 * u + phases[1])
                        + 0.05 * np.sin(17.0 * u + phases[2]))
    profile = np.sin(np.linspace(0.0, math.pi, len(ys))) ** 0.7  # rises from the valley floor and falls back
    heights = profile[:, None] * crest[None, :]
    return grid_object(f"Ridge {index + 1} ({distance_m / 1000:g} km)", xs, ys, heights,
                        material(f"Ridge {index + 1}", colour))


def new_scene(name: str, resolution: tuple[int, int]) -> bpy.types.Scene:
    """Empty the file and return its scene set up for the samples: Cycles, 32 samples, AgX view (Blender's default)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.name = name
    scene.render.resolution_x, scene.render.resolution_y = resolution
    scene.render.resolution_percentage = 100
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 32
    scene.cycles.use_denoising = False
    scene.view_settings.view_transform = "AgX"
    return scene


def add_camera(scene: bpy.types.Scene, lens_mm: float, height_m: float, pitch_deg: float) -> bpy.types.Object:
    """The scene camera at (0, 0, height) looking along +Y, pitched ``pitch_deg`` from straight down."""
    camera_data = bpy.data.cameras.new("Camera")
    camera_data.lens = lens_mm
    camera_data.clip_start = 0.1
    camera_data.clip_end = 200_000.0
    camera = bpy.data.objects.new("Camera", camera_data)
    camera.location = (0.0, 0.0, height_m)
    camera.rotation_euler = (math.radians(pitch_deg), 0.0, 0.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    return camera


def build(resolution: tuple[int, int] = (480, 270)) -> bpy.types.Scene:
    """Replace the current file's contents with the valley scene and return its scene."""
    scene = new_scene("Valley", resolution)
    rng = np.random.default_rng(7)
    camera = add_camera(scene, lens_mm=50.0, height_m=CAMERA_HEIGHT_M, pitch_deg=93.0)  # looking north, slightly up
    camera_data = camera.data
    half_fov = camera_data.angle_x / 2

    for index, (distance, height, colour) in enumerate(RIDGES):
        _ridge(index, distance, height, colour, rng, half_fov)

    # Valley floor (meadow) from the shore to the first ridge, and a calm lake in the foreground.
    floor = grid_object("Valley floor", np.linspace(-3000, 3000, 2), np.linspace(120, 2000, 2),
                         np.zeros((2, 2)), material("Meadow", (0.09, 0.14, 0.05), roughness=1.0))
    floor.location.z = -0.5
    lake = grid_object("Lake", np.linspace(-400, 400, 2), np.linspace(-5, 120, 2), np.zeros((2, 2)),
                        material("Lake water", (0.02, 0.04, 0.05), roughness=0.05))
    lake.location.z = -0.3

    rock_material = material("Rock", (0.25, 0.24, 0.22))
    tree_material = material("Pine", (0.03, 0.08, 0.03))
    for i, (x, y, size) in enumerate(((-9.0, 28.0, 1.6), (7.0, 45.0, 2.2), (14.0, 160.0, 6.0))):
        mesh = bpy.data.meshes.new(f"Rock {i + 1}")
        bm_verts = rng.normal(size=(40, 3))
        bm_verts /= np.linalg.norm(bm_verts, axis=1, keepdims=True)
        _convex_hull_mesh(mesh, bm_verts * size * np.array([1.0, 1.0, 0.6]))
        mesh.materials.append(rock_material)
        rock = bpy.data.objects.new(f"Rock {i + 1}", mesh)
        rock.location = (x, y, 0.0)
        scene.collection.objects.link(rock)
    for i in range(12):
        x, y = rng.uniform(-160, 160), rng.uniform(260, 900)
        height = rng.uniform(12, 25)
        mesh = bpy.data.meshes.new(f"Pine {i + 1}")
        ring = [(math.cos(a) * height * 0.25, math.sin(a) * height * 0.25, 0.0)
                for a in np.linspace(0, 2 * math.pi, 8, endpoint=False)]
        mesh.from_pydata(ring + [(0.0, 0.0, height)], [], [(k, (k + 1) % 8, 8) for k in range(8)]
                         + [tuple(range(7, -1, -1))])
        mesh.materials.append(tree_material)
        tree = bpy.data.objects.new(f"Pine {i + 1}", mesh)
        tree.location = (x, y, 0.0)
        scene.collection.objects.link(tree)

    place_sun(scene, SUN_ELEVATION_DEG, SUN_AZIMUTH_DEG, strength=4.0)

    plain_world(scene, "Valley sky", (0.35, 0.5, 0.8), 1.0)
    return scene


def plain_world(scene: bpy.types.Scene, name: str, colour: tuple[float, float, float],
                strength: float) -> bpy.types.World:
    """A new world of one background colour for ``scene``: what the scene shows with the effect off."""
    world = bpy.data.worlds.new(name)
    world.use_nodes = True
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (*colour, 1.0)
    background.inputs["Strength"].default_value = strength
    scene.world = world
    return world


def place_sun(scene: bpy.types.Scene, elevation_deg: float, azimuth_deg: float, strength: float) -> bpy.types.Object:
    """Add a sun lamp whose +Z axis (a sun lamp shines along its -Z) points at the sun.

    The direction to the sun is (cos e sin A, cos e cos A, sin e) for elevation e and azimuth A
    clockwise from +Y (north).
    """
    sun_data = bpy.data.lights.new("Sun", type="SUN")
    sun_data.energy = strength
    sun_data.angle = math.radians(0.533)
    sun = bpy.data.objects.new("Sun", sun_data)
    elevation, azimuth = math.radians(elevation_deg), math.radians(azimuth_deg)
    sun.rotation_euler = (math.pi / 2 - elevation, 0.0, math.pi - azimuth)
    sun.location = (0.0, 0.0, 50.0)
    scene.collection.objects.link(sun)
    return sun


def _convex_hull_mesh(mesh: bpy.types.Mesh, points: np.ndarray) -> None:
    import bmesh

    bm = bmesh.new()
    for point in points:
        bm.verts.new(point.tolist())
    bmesh.ops.convex_hull(bm, input=bm.verts)
    bm.to_mesh(mesh)
    bm.free()


if __name__ == "__main__":
    write_scene(build, "Build the Atmos valley sample scene.")
