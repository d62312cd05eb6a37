# SPDX-License-Identifier: GPL-3.0-or-later
"""The "Atmos Sky Lighting" world group: the dome sky from a per-atmosphere table, for the rays that light the scene.

Cycles evaluates the world shader for every camera ray that misses the scene, but also for every light sample it
takes of the world and every ray that escapes after a bounce: several times per camera sample in an outdoor
scene, where the analytic "Atmos Sky" (:mod:`.sky`, some seventy nodes per evaluation) was measured to be most of
Atmos's render cost. This group computes the same sky (without the sun's disk, which only camera rays see) as

    L = E_sun [A_R(u) Phi_R(mu) + A_M(u) Phi_HG(mu, g)] + (v_z < 0) albedo E_sun max(l_z, 0) / pi F_ex(u)
    u = sqrt(max(v_z, 0)),   mu = v . l

where A_R, A_M, F_ex are colours tabulated per atmosphere by ``atmos_addon.physics.sky_table`` (which
derives the factorisation) and held in three RGB Curves nodes (:data:`TABLE_NODES`; the curves' points are the
table, so it lives in the .blend and a farm renders it without the add-on). The phase functions are the aerial
group's own nodes, exact for any g. Per evaluation: eleven nodes and three curve lookups beside the view
direction and mu. The sun moves nothing in the table (mu, l_z and E_sun stay in the shader), so an animated sun
needs no re-bake; a change of the atmosphere rewrites the curves' values (:func:`write_sky_table`), never the
tree.

The world (:mod:`atmos_addon.blender.apply.world`) mixes the two skies on Light Path > Is Camera Ray: Cycles skips the
closure branch whose mix weight is 0, with its own nodes, so camera rays run the analytic sky and every
other ray runs this one. The table holds the analytic sky to 1.2e-4 between its samples
(``tests/physics/test_sky_table.py``). The group belongs to one world (its table is that world's atmosphere);
each world that shows the Atmos sky gets its own copy.
"""

from __future__ import annotations

from typing import Sequence

import bpy
import numpy as np

from . import parameters
from .terms import phase_henyey_greenstein, phase_rayleigh
from .graph import GraphBuilder, Socket
from . import stamps
from .sky import SkyFeatures, finish_radiance_group, ground, start_radiance_graph

#: Name of a new lighting group (Blender numbers further copies: one per world).
SKY_LIGHTING_GROUP_NAME = stamps.SKY_LIGHTING.name
#: The RGB Curves nodes holding the table, by name: A_R, A_M, F_ex (``physics.sky_table.SkyLightingTable``).
TABLE_NODES = ("Atmos table A_R", "Atmos table A_M", "Atmos table F_ex")
#: Custom property on the tree: which atmosphere its table holds (absent: the curves are not filled yet).
TABLE_KEY = "atmos_table_key"


def table_lookup(g: GraphBuilder, u: Socket, name: str, *, label: str) -> Socket:
    """The table colour at u: an RGB Curves node named ``name`` fed the grey (u, u, u), one curve per channel."""
    node = g.node("ShaderNodeRGBCurve", label=label)
    g._feed(node, node.inputs["Color"], u)
    depth = g._depth.pop(node.name)  # the builder keys its layout on node names
    node.name = name
    g._depth[node.name] = depth
    return node.outputs["Color"]


def build_sky_lighting(tree: bpy.types.ShaderNodeTree, features: SkyFeatures) -> None:
    """Clear ``tree``'s nodes and build the table sky for ``features`` (interface kept; the table is emptied)."""
    g, ray = start_radiance_graph(tree, "Sky radiance along the ray from the table (sky and ground, no sun disk)")
    view_z, sun, mu = ray.view_z, ray.sun, ray.mu
    u = g.sqrt(g.max(view_z, 0.0), label="u = sqrt(max(v_z, 0))")
    light = g.scale(table_lookup(g, u, TABLE_NODES[0], label="A_R(u)"), phase_rayleigh(g, mu), label="A_R Phi_R")
    if features.mie:
        phase_m = phase_henyey_greenstein(g, mu, g.attribute(parameters.MIE_G))
        light = g.multiply_add(table_lookup(g, u, TABLE_NODES[1], label="A_M(u)"), phase_m, light,
                               label="A_R Phi_R + A_M Phi_HG")
    radiance = g.mul(light, g.attribute(parameters.SUN_IRRADIANCE), label="L_sky")
    if features.ground == "ALBEDO":
        _, _, sun_z = g.separate(sun, label="l")
        f_ex = table_lookup(g, u, TABLE_NODES[2], label="F_ex(u)")
        below = g.less_than(view_z, 0.0, label="below horizon")
        radiance = g.add(radiance, ground(g, below, sun_z, f_ex), label="sky + ground")
    finish_radiance_group(g, radiance, stamps.SKY_LIGHTING, features.dome)
    if TABLE_KEY in tree:
        del tree[TABLE_KEY]


def is_current(tree: bpy.types.NodeTree, features: SkyFeatures) -> bool:
    """True if ``tree`` was built by this version for ``features`` (their dome terms: the level is not used)."""
    return stamps.is_current(tree, stamps.SKY_LIGHTING, features.dome.key)


def new_sky_lighting_group(features: SkyFeatures) -> bpy.types.ShaderNodeTree:
    """A new lighting group for one world (its table still empty: :func:`write_sky_table` fills it)."""
    tree = bpy.data.node_groups.new(SKY_LIGHTING_GROUP_NAME, "ShaderNodeTree")
    build_sky_lighting(tree, features)
    return tree


def ensure_current(tree: bpy.types.ShaderNodeTree, features: SkyFeatures) -> bool:
    """Rebuild ``tree`` in place if stale for ``features``; True when it was rebuilt (the table must be written)."""
    if is_current(tree, features):
        return False
    build_sky_lighting(tree, features)
    return True


def is_sky_lighting_group(tree: bpy.types.NodeTree | None) -> bool:
    """True for a group :func:`new_sky_lighting_group` made."""
    return stamps.kind_of(tree) == stamps.SKY_LIGHTING


def write_sky_table(tree: bpy.types.ShaderNodeTree, coordinate: Sequence[float],
                    columns: Sequence[np.ndarray], key: str) -> None:
    """Put the table into the curves: ``columns`` are A_R, A_M, F_ex as (N, 3) arrays at u = ``coordinate`` (N,).

    Each channel's curve gets N points with straight (vector) handles through the samples; the combined curve
    stays the identity. Only values change (the points are created once), so a parameter edit never rebuilds
    the tree. ``key`` names the atmosphere (stored on the tree, so an unchanged atmosphere is not rewritten).
    """
    u = np.asarray(coordinate, dtype=np.float32)
    count = len(u)
    for name, values in zip(TABLE_NODES, columns):
        node = tree.nodes.get(name)
        if node is None:
            continue
        values = np.clip(np.asarray(values, dtype=np.float32), 0.0, 1.0)
        mapping = node.mapping
        for channel in range(3):
            points = mapping.curves[channel].points
            created = len(points) != count
            while len(points) < count:
                points.new(0.0, 0.0)
            while len(points) > count:
                points.remove(points[len(points) - 1])
            points.foreach_set("location", np.stack([u, values[:, channel]], axis=1).ravel())
            if created:
                for point in points:
                    point.handle_type = "VECTOR"
        mapping.update()
    tree[TABLE_KEY] = key


#: Nodes in the lighting group per feature key for this :data:`.stamps.SKY_LIGHTING` (group output included).
SKY_LIGHTING_NODE_COUNTS = {"rayleigh": 18, "rayleigh+ground": 30, "rayleigh+abs": 18, "rayleigh+abs+ground": 30,
                            "rayleigh+mie": 40, "rayleigh+mie+ground": 52, "rayleigh+mie+abs": 40,
                            "rayleigh+mie+abs+ground": 52}
