# SPDX-License-Identifier: GPL-3.0-or-later
"""The "Atmos Sky View" world group: the Precise sky Cycles' camera rays see above the horizon, from two lookups.

The camera's Precise sky of "Atmos Sky" (:mod:`.sky`: the frame's table at the length of the whole ray, ten texel
fetches and some 240 nodes) was measured to cost as much as Blender's whole Sky Texture on the sample valley (0.85 s
against 0.88 s of a 3.6 s Per Pixel render, ``tools/bench_quality_cost.py --decompose``): Cycles evaluates it for
every camera sample that misses the scene. This group reads the same sky from the tile's camera sky view
(``physics.precise.camera_sky_view``: the sky's Rayleigh term and its Mie term without the phase function, by
elevation and azimuth from the sun) with two Linear lookups, multiplies the Mie term by the exact Henyey-Greenstein
phase (the sun's aureole keeps its shape) and adds the sun's disk:

    L = image_R(row, column) + Phi_HG(mu, g) image_M(row, column) + L_disk
    row = (N - 1) sqrt(max(e - e_h, 0) / (pi/2 - e_h)),   column = azimuth from the sun (N_s - 1) / pi

It also outputs the weight of the table's own sky, 1 up to :data:`EXACT_BELOW_DEG` above the horizon, falling
linearly to 0 at :data:`VIEW_ABOVE_DEG`. The world (:mod:`atmos_addon.blender.apply.world`) mixes the two skies with
it in a Mix Shader, which Cycles skips a branch of where the weight is 0 or 1: the sky at and below the horizon (where
a 2 m camera's ground path shrinks from 5 km to 1 km within 0.05 deg, and where a far surface's haze must meet the
sky behind it, the seamless horizon) is the table's as before, the rest costs two lookups. Measured against the
table's sky above the band (``tests/physics/test_precise.py``): 0.05-0.10 % mean luminance difference, 0.2-1.0 %
at the 99th percentile, over four presets; the table's sky is about 1 % from the brute-force sky. Eevee keeps the
table's sky everywhere (its world output is the "All" one; its Linear lookups filter with mipmaps).
"""

from __future__ import annotations

import dataclasses
import math

import bpy
import numpy as np

from . import stamps
from .graph import ArrayBuilder, GraphBuilder, Socket
from .precise import camera_sky_view
from .sky import OUTPUT_RADIANCE, SkyFeatures, ensure_radiance_output, sky_ray, sun_disk

#: The table's own sky, all of it, up to this elevation above the horizon, deg.
EXACT_BELOW_DEG = 1.0
#: The sky view alone from this elevation above the horizon, deg (between the two a linear blend of both).
VIEW_ABOVE_DEG = 2.0
OUTPUT_EXACT = "Exact"


def sky_view_key(features: SkyFeatures) -> str:
    """What the group is built for: the sky's key without its ground, which the view never shows (the table's sky
    does, below the horizon); :meth:`SkyFeatures.from_key` reads it back."""
    return dataclasses.replace(features, ground="BLACK").key


def camera_sky(g: GraphBuilder, features: SkyFeatures) -> tuple[Socket, Socket]:
    """(radiance, weight of the table's sky) on any builder: the camera sky view plus the sun's disk, and the band
    weight clamp((VIEW_ABOVE - (e - e_h)) / (VIEW_ABOVE - EXACT_BELOW), 0, 1)."""
    ray = sky_ray(g)
    radiance, above = camera_sky_view(g, ray.view, ray.sun, ray.mu, blend=features.blend)
    radiance = g.add(radiance, sun_disk(g, ray.view, ray.view_z, ray.sun, ray.mu), label="sky view + disk")
    band = math.radians(VIEW_ABOVE_DEG - EXACT_BELOW_DEG)
    exact = g.clamp(g.mul(g.sub(math.radians(VIEW_ABOVE_DEG), above), 1.0 / band), 0.0, 1.0,
                    label="the table's sky (horizon band)")
    return radiance, exact


def build_sky_view(tree: bpy.types.ShaderNodeTree, features: SkyFeatures) -> None:
    """Clear ``tree``'s nodes and build the camera sky view for ``features`` (interface kept)."""
    tree.nodes.clear()
    ensure_radiance_output(tree, "Sky radiance for camera rays above the horizon band (sky view and sun disk)")
    if OUTPUT_EXACT not in {item.name for item in tree.interface.items_tree
                            if item.item_type == "SOCKET" and item.in_out == "OUTPUT"}:
        socket = tree.interface.new_socket(OUTPUT_EXACT, in_out="OUTPUT", socket_type="NodeSocketFloat")
        socket.description = ("Weight of the Precise table's own sky: 1 near and below the horizon, 0 above "
                              f"{VIEW_ABOVE_DEG:g} deg over it")
    g = GraphBuilder(tree)
    radiance, exact = camera_sky(g, features)
    output = g.node("NodeGroupOutput", label="Group Output")
    tree.links.new(radiance, output.inputs[OUTPUT_RADIANCE])
    tree.links.new(exact, output.inputs[OUTPUT_EXACT])
    g.set_depth(output, g.max_depth + 1)
    g.layout()
    stamps.stamp(tree, stamps.SKY_VIEW, sky_view_key(features))


def evaluate(features: SkyFeatures, parameter_values, *, view_direction, images):
    """What the group computes, in numpy float32: (radiance (N, 3), weight of the table's sky (N,)) along the unit
    ``view_direction`` (N, 3) of camera rays; ``parameter_values`` as :func:`.sky.evaluate`, ``images`` the table's
    pixels by image name."""
    direction = np.asarray(view_direction, dtype=np.float64)
    camera = np.ones(direction.shape[:-1], np.float32)
    g = ArrayBuilder(parameter_values, {"incoming": -direction, "is_camera_ray": camera}, images)
    radiance, exact = camera_sky(g, features)
    return (np.broadcast_to(g.array(radiance), direction.shape),
            np.broadcast_to(g.array(exact), direction.shape[:-1]))


def ensure_sky_view_group(features: SkyFeatures) -> bpy.types.ShaderNodeTree:
    """Get or create the "Atmos Sky View" group, rebuilt in place only if stale (worlds keep their links)."""
    tree = stamps.group(stamps.SKY_VIEW)
    if not stamps.is_current(tree, stamps.SKY_VIEW, sky_view_key(features)):
        build_sky_view(tree, features)
    return tree
