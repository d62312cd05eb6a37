# SPDX-License-Identifier: GPL-3.0-or-later
"""Cycles in-render mode: the aerial perspective applied per ray segment, exactly, inside the render.

Three pieces, all reading the scene-property parameters of :mod:`.parameters`:

- the dome material (:func:`build_dome_volume`): for the closed dome mesh of one species
  (``atmos_addon.physics.dome_mesh``), a homogeneous Volume Absorption of coefficient sigma = beta_R
  (molecules) or beta_M + beta_M,abs (aerosols), per channel, in 1/scene unit. Cycles integrates a homogeneous
  absorber in closed form, so every camera, glossy and transmission ray loses exactly exp(-sigma l) over its
  length l inside dome i; for a ray from the camera l = b_i = min(s, R_i(v)), the extinction F_ex of the
  aerial group (:mod:`.aerial_perspective`). Its surface is a Transparent filter (:func:`dome_filter`) that
  makes a ray from anywhere else lose what a camera ray along the same direction would;
- the surface emission (:data:`SURFACE_GROUP_NAME`): each managed material adds, on camera, glossy and
  transmission rays only, an emission L_in / F_ex of the segment the ray just travelled (the "Ray Segment"
  aerial group: s = Light Path > Ray Length, v = -Incoming), weighted by the surface's opacity. The dome
  attenuates it by the same F_ex, so the eye receives F_ex L_0 + L_in per segment, and a reflected or
  refracted segment composes with the one before it: F_1 (F_2 L_0 + L_2) + L_1;
- the sky compensation (:data:`SKY_GROUP_NAME`): a sky ray leaves the domes attenuated by
  exp(-tau_dome(v)) (the dome filters see to that for rays that do not start at the camera), the sky's own
  extinction; on camera, glossy and transmission rays the world radiance is multiplied by
  exp(min(tau_dome, :data:`MAX_COMPENSATED_OPTICAL_DEPTH`)) so every such ray sees the sky the camera sees.

Diffuse and shadow rays see neither the domes (ray visibility off) nor the emission: the sun lamp carries the
ground-level sunlight, and the haze must not light the scene. Nothing here runs Python at render time, so a
.blend renders the same without the add-on.
"""

from __future__ import annotations

import math

import bpy

from . import parameters, stamps
from .aerial_perspective import ensure_aerial_perspective_group
from .dome import dome_distances, view_direction
from .graph import GraphBuilder, Socket
from .terms import AerialFeatures

SURFACE_GROUP_NAME = stamps.IN_RENDER_SURFACE.name
SKY_GROUP_NAME = stamps.IN_RENDER_SKY.name
#: The compensation exp(tau) is capped here: exp(60) = 1.1e26 keeps a bright sky (1e5 W/(m^2 sr), the sun's
#: disk) times the factor below float32's 3.4e38, and exp(-60) = 8.8e-27 above its smallest normal 1.2e-38.
#: Where the real depth is larger (the horizon in thick haze) the in-render sky is darker than the sky.
MAX_COMPENSATED_OPTICAL_DEPTH = 60.0
#: Smallest F_ex the surface emission divides by: exp(-60), for the same reason.
MIN_TRANSMITTANCE = math.exp(-MAX_COMPENSATED_OPTICAL_DEPTH)
SPECIES = ("MOLECULES", "AEROSOLS")


def _ray_mask(g: GraphBuilder) -> Socket:
    """1 on camera, glossy and transmission rays, 0 on diffuse, shadow and light-sampling evaluations."""
    path = g.node("ShaderNodeLightPath", label="Light Path")
    camera_or_glossy = g.max(path.outputs["Is Camera Ray"], path.outputs["Is Glossy Ray"])
    return g.max(camera_or_glossy, path.outputs["Is Transmission Ray"], label="camera | glossy | transmission")


def _socket(tree, name: str, in_out: str, socket_type: str, description: str, default=None):
    socket = tree.interface.new_socket(name, in_out=in_out, socket_type=socket_type)
    socket.description = description
    if default is not None:
        socket.default_value = default
        socket.min_value, socket.max_value = 0.0, 1.0
    return socket


# -- the surface emission -------------------------------------------------------------------------------


def build_surface_group(tree: bpy.types.ShaderNodeTree, segment_group: bpy.types.ShaderNodeTree) -> None:
    """Surface + Emission(L_in / max(F_ex, exp(-60)) * alpha * ray mask), alpha = Opacity (1 - Transparency)."""
    tree.nodes.clear()
    tree.interface.clear()
    _socket(tree, "Surface", "INPUT", "NodeSocketShader", "The material's own surface shader")
    _socket(tree, "Opacity", "INPUT", "NodeSocketFloat", "Surface opacity (Principled Alpha)", 1.0)
    _socket(tree, "Transparency", "INPUT", "NodeSocketFloat", "Transparent share of a Mix Shader", 0.0)
    _socket(tree, "Shader", "OUTPUT", "NodeSocketShader", "Surface plus the segment's in-scattering")
    g = GraphBuilder(tree)
    group_in = g.node("NodeGroupInput", label="Group Input")
    aerial = g.node("ShaderNodeGroup", label="Atmos Aerial Perspective (Ray Segment)", node_tree=segment_group)
    f_ex = g.max(aerial.outputs["Transmittance"], (MIN_TRANSMITTANCE,) * 3, label="max(F_ex, exp(-60))")
    radiance = g.div(aerial.outputs["Inscattering"], f_ex, label="L_in / F_ex")
    alpha = g.mul(group_in.outputs["Opacity"], g.sub(1.0, group_in.outputs["Transparency"]), label="alpha")
    weight = g.mul(alpha, _ray_mask(g), label="alpha * ray mask")
    emission = g.node("ShaderNodeEmission", label="In-scattering")
    g._feed(emission, emission.inputs["Color"], g.scale(radiance, weight, label="emitted"))
    emission.inputs["Strength"].default_value = 1.0
    add = g.node("ShaderNodeAddShader", label="Surface + in-scattering")
    g._feed(add, add.inputs[0], group_in.outputs["Surface"])
    g._feed(add, add.inputs[1], emission.outputs["Emission"])
    output = g.node("NodeGroupOutput", label="Group Output")
    tree.links.new(add.outputs["Shader"], output.inputs["Shader"])
    g.set_depth(output, g.max_depth + 1)
    g.layout()
    stamps.stamp(tree, stamps.IN_RENDER_SURFACE, segment_group.get(stamps.FEATURES_KEY, ""))


def ensure_surface_group(features: AerialFeatures) -> bpy.types.ShaderNodeTree:
    """Get or (re)build the "Atmos In-Render Surface" group (and the Ray Segment aerial group inside it)."""
    segment_group = ensure_aerial_perspective_group(features, distance="RAY")
    tree = stamps.group(stamps.IN_RENDER_SURFACE)
    if not (stamps.is_current(tree, stamps.IN_RENDER_SURFACE, features.key)
            and any(n.bl_idname == "ShaderNodeGroup" and n.node_tree == segment_group for n in tree.nodes)):
        build_surface_group(tree, segment_group)
    return tree


# -- the sky compensation -------------------------------------------------------------------------------


def dome_optical_depth(g: GraphBuilder, features: AerialFeatures, view_z: Socket) -> Socket:
    """tau_dome = beta_R R_R + beta_M,ex R_M per channel (only the terms ``features`` keep)."""
    r_rayleigh, r_mie = dome_distances(g, view_z)
    tau = g.scale(g.attribute(parameters.BETA_RAYLEIGH), r_rayleigh, label="beta_R R_R")
    mie_terms = ([parameters.BETA_MIE] if features.mie else []) + \
        ([parameters.BETA_MIE_ABSORPTION] if features.absorption else [])
    for name in mie_terms:
        tau = g.multiply_add(g.attribute(name), r_mie, tau, label=f"+ {name} R_M")
    return tau


def build_sky_group(tree: bpy.types.ShaderNodeTree, features: AerialFeatures) -> None:
    """Color * exp(min(tau_dome, 60)) on camera, glossy and transmission rays; Color unchanged on others."""
    tree.nodes.clear()
    tree.interface.clear()
    _socket(tree, "Color", "INPUT", "NodeSocketColor", "The world's radiance (the sky)")
    _socket(tree, "Color", "OUTPUT", "NodeSocketColor", "The radiance to emit so that the camera sees Color")
    g = GraphBuilder(tree)
    group_in = g.node("NodeGroupInput", label="Group Input")
    _, _, view_z = g.separate(view_direction(g), label="v")
    tau = g.min(dome_optical_depth(g, features, view_z), (MAX_COMPENSATED_OPTICAL_DEPTH,) * 3, label="min(tau, 60)")
    factor = g.per_channel(g.exp, tau, label="exp(tau)")
    gain = g.multiply_add(g.sub(factor, (1.0, 1.0, 1.0)), _ray_mask(g), (1.0, 1.0, 1.0),
                          label="compensation 1 + mask (exp(tau) - 1)")
    output = g.node("NodeGroupOutput", label="Group Output")
    tree.links.new(g.mul(group_in.outputs["Color"], gain, label="Color * compensation"), output.inputs["Color"])
    g.set_depth(output, g.max_depth + 1)
    g.layout()
    stamps.stamp(tree, stamps.IN_RENDER_SKY, features.key)


def ensure_sky_group(features: AerialFeatures) -> bpy.types.ShaderNodeTree:
    """Get or (re)build the "Atmos In-Render Sky" compensation group."""
    tree = stamps.group(stamps.IN_RENDER_SKY)
    if not stamps.is_current(tree, stamps.IN_RENDER_SKY, features.key):
        build_sky_group(tree, features)
    return tree


# -- the dome volume ------------------------------------------------------------------------------------


def dome_filter(g: GraphBuilder, species: str, sigma_per_unit: Socket) -> Socket:
    """The dome surface's Transparent colour: exp(sigma L - tau_i(v)) leaving, exp(-sigma L) entering, per channel.

    L = Light Path > Ray Length, the distance from the ray's origin p (the camera, or the surface a reflected or
    refracted ray left; Cycles keeps p across transparent surfaces); tau_i(v) = beta_i R_i(v), the depth of
    dome i from the camera along the ray's direction v, by which the world multiplies the sky. Along any ray
    segment the dome's absorption times these filters is exp(-tau_i(v)) once the ray has left the dome,
    wherever p is (the cases are worked through in ``docs/in_render.md``), so the sky a reflection sees is the
    sky the camera sees, and a surface beyond the dome gets the model's F_ex of b_i = R_i(v). For a camera
    ray the exit filter only cancels the mesh's facet error. The exponent is capped at
    :data:`MAX_COMPENSATED_OPTICAL_DEPTH` like the world's.
    """
    path = g.node("ShaderNodeLightPath", label="Light Path")
    geometry = g.node("ShaderNodeNewGeometry", label="Geometry")
    _, _, view_z = g.separate(view_direction(g), label="v")
    r_rayleigh, r_mie = dome_distances(g, view_z)
    if species == "MOLECULES":
        tau = g.scale(g.attribute(parameters.BETA_RAYLEIGH), r_rayleigh, label="tau_R = beta_R R_R")
    else:
        beta = g.add(g.attribute(parameters.BETA_MIE), g.attribute(parameters.BETA_MIE_ABSORPTION),
                     label="beta_M + beta_M,abs")
        tau = g.scale(beta, r_mie, label="tau_M = beta_M,ex R_M")
    depth = g.scale(sigma_per_unit, path.outputs["Ray Length"], label="sigma L")
    leaving = g.min(g.sub(depth, tau), (MAX_COMPENSATED_OPTICAL_DEPTH,) * 3, label="min(sigma L - tau, 60)")
    entering = g.neg(depth, label="-sigma L")
    exponent = g.multiply_add(g.sub(leaving, entering), geometry.outputs["Backfacing"], entering,
                              label="leaving (backfacing) or entering")
    return g.per_channel(g.exp, exponent, label="dome filter")


def build_dome_volume(tree: bpy.types.ShaderNodeTree, species: str) -> None:
    """A material tree: Volume Absorption with density max_c(sigma) and colour 1 - sigma / density; the surface
    a Transparent BSDF coloured by :func:`dome_filter`.

    Cycles' absorption coefficient is density * (1 - colour) per channel, so this is sigma exactly, in
    1/scene unit: sigma (1/m) times metres per unit. Uniform inputs only (view-layer attributes), so Cycles
    treats the volume as homogeneous and integrates it in closed form.
    """
    if species not in SPECIES:
        raise ValueError(f"species must be one of {SPECIES}; got {species!r}")
    tree.nodes.clear()
    g = GraphBuilder(tree)
    if species == "MOLECULES":
        sigma = g.attribute(parameters.BETA_RAYLEIGH)
    else:
        sigma = g.add(g.attribute(parameters.BETA_MIE), g.attribute(parameters.BETA_MIE_ABSORPTION),
                      label="beta_M + beta_M,abs")
    sigma = g.scale(sigma, g.attribute(parameters.METRES_PER_UNIT, output="Fac"), label="sigma (1/unit)")
    r, gr, b = g.separate(sigma, label="sigma")
    density = g.max(g.max(r, gr), b, label="density = max sigma")
    colour = g.sub((1.0, 1.0, 1.0), g.div(sigma, g.combine(density, density, density)), label="1 - sigma / density")
    absorption = g.node("ShaderNodeVolumeAbsorption", label="Dome absorption")
    g._feed(absorption, absorption.inputs["Color"], colour)
    g._feed(absorption, absorption.inputs["Density"], density)
    output = g.node("ShaderNodeOutputMaterial", label="Material Output")
    output.target = "CYCLES"
    tree.links.new(absorption.outputs["Volume"], output.inputs["Volume"])
    crossing = g.node("ShaderNodeBsdfTransparent", label="Dome filter")
    g._feed(crossing, crossing.inputs["Color"], dome_filter(g, species, sigma))
    tree.links.new(crossing.outputs["BSDF"], output.inputs["Surface"])
    g.set_depth(output, g.max_depth + 1)
    g.layout()
    stamps.stamp(tree, stamps.DOME_VOLUME, species)
