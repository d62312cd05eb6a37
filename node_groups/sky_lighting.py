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

At the Precise level the sky varies with the azimuth from the sun beyond the phase functions (the planet's shadow,
the multiple scattering by direction), so it does not factor into curves of the elevation; there the group is the
frame's **sky view** instead (:func:`precise_lighting_radiance`, ``physics.precise.sky_view``): the Precise sky
tabulated per tile over the view's zenith (rows crowded at the horizon on both sides of it) and its azimuth from the
sun, one Linear image lookup in the baked table image, plus the lit ground through its tabulated transmittance.
Some fifty nodes and two lookups where the camera's Precise sky has about 240 nodes and ten texel fetches; the
floor it lights within 1 % of the floor the Precise sky itself lights (``tests/blender/test_sky_sun.py``).

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

from . import parameters, stamps
from .dome import sun_direction, view_direction
from .graph import ArrayBuilder, GraphBuilder, Socket
from .precise import sky_view
from .terms import phase_henyey_greenstein, phase_rayleigh
from .sky import SkyFeatures, ensure_radiance_output, finish_radiance_group, ground, start_radiance_graph

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


def lighting_key(features: SkyFeatures) -> str:
    """What the lighting group is built for: the dome terms (the curves' factorisation), or at the Precise level
    the frame's sky view (its graph reads the scattering from the table, so only the ground term varies it)."""
    return features.key if features.level == "precise" else features.dome.key


def precise_lighting_radiance(g: GraphBuilder, features: SkyFeatures) -> Socket:
    """The Precise level's lighting sky on any builder: the frame's sky view (``nodes.precise.sky_view``: one
    filtered lookup) plus, with ``ground="ALBEDO"``, the lit ground albedo E_sun max(l_z, 0) / pi seen through its
    tabulated transmittance (0 where the ray misses the ground). ``physics.precise.lighting_from_tile``."""
    sun = sun_direction(g)
    radiance, ground_transmittance = sky_view(g, view_direction(g), sun, blend=features.blend)
    if features.ground == "ALBEDO":
        _, _, sun_z = g.separate(sun, label="l")
        radiance = g.add(radiance, ground(g, 1.0, sun_z, ground_transmittance), label="sky view + ground")
    return radiance


def evaluate_precise(features: SkyFeatures, parameter_values, *, view_direction, images):
    """What the Precise lighting group computes, in numpy float32: the radiance (N, 3) along the unit
    ``view_direction`` (N, 3); ``parameter_values`` as :func:`.sky.evaluate`, ``images`` the table's pixels by name."""
    direction = np.asarray(view_direction, dtype=np.float64)
    g = ArrayBuilder(parameter_values, {"incoming": -direction}, images)
    return np.broadcast_to(g.array(precise_lighting_radiance(g, features)), direction.shape)


def build_sky_lighting(tree: bpy.types.ShaderNodeTree, features: SkyFeatures) -> None:
    """Clear ``tree``'s nodes and build the table sky for ``features`` (interface kept; the table is emptied)."""
    if features.level == "precise":
        tree.nodes.clear()
        ensure_radiance_output(tree, "Sky radiance along the ray from the Precise sky view (no sun disk)")
        g = GraphBuilder(tree)
        finish_radiance_group(g, precise_lighting_radiance(g, features), stamps.SKY_LIGHTING,
                              SkyFeatures.from_key(lighting_key(features)))
        if TABLE_KEY in tree:
            del tree[TABLE_KEY]
        return
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
    """True if ``tree`` was built by this version for ``features`` (:func:`lighting_key`)."""
    return stamps.is_current(tree, stamps.SKY_LIGHTING, lighting_key(features))


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
                            "rayleigh+mie+abs+ground": 52,
                            # the Precise sky view's graph: the same for every scattering term
                            **{f"{terms}+precise{blend}{ground}": (64 if ground else 54) + (14 if blend else 0)
                               for terms in ("rayleigh", "rayleigh+abs", "rayleigh+mie", "rayleigh+mie+abs")
                               for blend in ("", "+blend") for ground in ("", "+ground")}}
