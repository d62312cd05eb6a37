# SPDX-License-Identifier: GPL-3.0-or-later
"""A Mars scene: a crater rim and a dune field under dusty light, one Blender unit = one metre.

The camera stands 1.7 m above a dune crest looking across a crater 16 km wide whose far rim is
28 km away, with higher terrain 40 km out; materials are dusty ochres and basalt greys. The Mars
preset (``atmos_addon/presets/builtin/mars.toml``) gives the atmosphere.
Run: ``./run python -m atmos_addon.sample_scenes.mars --output mars.blend`` (with the pip ``bpy`` module), or
``blender --command atmos render mars ...`` with the extension installed.
"""

from __future__ import annotations

import math

import bpy
import numpy as np

from . import write_scene
from .valley import add_camera, grid_object, material, new_scene, place_sun, plain_world

CAMERA_HEIGHT_M = 1.7
SUN_ELEVATION_DEG = 25.0
SUN_AZIMUTH_DEG = 165.0  # clockwise from +Y: low behind-right of the camera, raking across the dunes


def _dunes(rng: np.random.Generator) -> bpy.types.Object:
    """Transverse dunes from 5 m to 2.5 km: crests 3-7 m high, 60 m apart, running across the view."""
    xs = np.linspace(-1500.0, 1500.0, 241)
    ys = np.linspace(5.0, 2500.0, 201)
    gx, gy = np.meshgrid(xs, ys)
    phase = rng.uniform(0, 2 * math.pi)
    crest = 5.0 + 2.0 * np.sin(gx / 170.0 + phase)
    heights = crest * np.abs(np.sin(gy / 60.0 * math.pi + 0.25 * np.sin(gx / 90.0))) ** 1.5 - 1.0
    return grid_object("Dunes", xs, ys, heights, material("Dune sand", (0.42, 0.22, 0.10), roughness=0.95))


def _crater(rng: np.random.Generator) -> bpy.types.Object:
    """A crater 16 km across, centred 20 km ahead: a raised rim (300 m) around a bowl 600 m deep."""
    xs = np.linspace(-24000.0, 24000.0, 241)
    ys = np.linspace(2000.0, 34000.0, 161)
    gx, gy = np.meshgrid(xs, ys)
    r = np.hypot(gx, gy - 20000.0) / 8000.0  # radius in crater radii
    rim = 300.0 * np.exp(-((r - 1.0) / 0.18) ** 2)
    bowl = np.where(r < 1.0, -600.0 * (1.0 - r ** 2), 0.0)
    ejecta = 60.0 * np.exp(-np.maximum(r - 1.0, 0.0) * 2.0) * (r > 1.0)
    roughness = 25.0 * np.sin(gx / 700.0 + rng.uniform(0, 6)) * np.sin(gy / 900.0)
    return grid_object("Crater", xs, ys, rim + bowl + ejecta + roughness - 5.0,
                       material("Crater regolith", (0.36, 0.19, 0.10), roughness=0.9))


def _highlands() -> bpy.types.Object:
    """Higher terrain 40 km away, up to 3.3 km high, to show the dust's aerial perspective."""
    xs = np.linspace(-60000.0, 60000.0, 121)
    ys = np.linspace(38000.0, 52000.0, 15)
    u = xs / 60000.0
    crest = 2300.0 + 700.0 * np.sin(4.0 * u + 1.0) + 300.0 * np.sin(11.0 * u)
    profile = np.sin(np.linspace(0.0, math.pi, len(ys))) ** 0.8
    return grid_object("Highlands", xs, ys, profile[:, None] * crest[None, :],
                       material("Basalt", (0.16, 0.11, 0.09), roughness=0.9))


def build(resolution: tuple[int, int] = (480, 270)) -> bpy.types.Scene:
    """Replace the current file's contents with the Mars scene and return its scene."""
    scene = new_scene("Mars", resolution)
    # Mars gets 43 % of Earth's sunlight and its dust dims it further: expose for it, as a rover camera does.
    scene.view_settings.exposure = 2.5
    rng = np.random.default_rng(11)
    add_camera(scene, lens_mm=40.0, height_m=CAMERA_HEIGHT_M + 6.0, pitch_deg=91.5)  # standing on a dune crest

    _dunes(rng)
    _crater(rng)
    _highlands()
    boulder_material = material("Basalt boulder", (0.12, 0.09, 0.08), roughness=0.8)
    for i, (x, y, size) in enumerate(((-6.0, 22.0, 1.6), (5.0, 35.0, 1.2), (-30.0, 90.0, 3.5))):
        bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=2, radius=size, location=(x, y, 4.0))
        boulder = bpy.context.active_object
        boulder.name = f"Boulder {i + 1}"
        boulder.scale = (1.0, 0.8, 0.55)
        boulder.data.materials.append(boulder_material)

    place_sun(scene, SUN_ELEVATION_DEG, SUN_AZIMUTH_DEG, strength=1.8)
    plain_world(scene, "Mars sky", (0.55, 0.40, 0.28), 0.3)
    return scene


if __name__ == "__main__":
    write_scene(build, "Build the Atmos Mars sample scene.")
