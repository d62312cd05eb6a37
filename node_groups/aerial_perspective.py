# SPDX-License-Identifier: GPL-3.0-or-later
"""The "Atmos Aerial Perspective" shader node group: Hoffman & Preetham 2002, eq. 19, as nodes.

Per colour channel, for a shading point at distance s (m) from the camera, seen along the unit view
direction v, with the unit direction to the sun l and mu = v . l:

    b_R, b_M = min(s, R_R(v)), min(s, R_M(v))                   per-species lengths clamped to the sky dome
    a        = min(b_R, b_M),  t_R = b_R - a,  t_M = b_M - a    shared segment; the longer species' tail
    tau(x_R, x_M) = beta_R x_R + (beta_M + beta_M,abs) x_M     optical depth of a slab
    L(x_R, x_M)   = (beta_R Phi_R(mu) x_R + beta_M Phi_HG(mu, g) x_M) phi1(tau(x_R, x_M))
    F_ex    = exp(-tau(a, a)) exp(-tau(t_R, t_M))               "Transmittance"
    L_in    = E_sun [L(a, a) + exp(-tau(a, a)) L(t_R, t_M)]     "Inscattering"
    Phi_R   = 3 / (16 pi) (1 + mu^2)
    Phi_HG  = (1 - g^2) / (4 pi (1 + g^2 - 2 g mu)^(3/2))       (normalised; g > 0 scatters forward)
    phi1(x) = (1 - exp(-x)) / x

which is eq. 19 when s is nearer than both domes (t_R = t_M = 0). Beyond the shorter dome (the haze's, normally)
only the longer species' slab is added behind the mixed one: the layered dome of ``physics.sky`` (one of t_R,
t_M is 0, so one L(t_R, t_M) covers either order). R_R, R_M are the virtual-dome distances of :mod:`.dome` (the
very nodes the "Atmos Sky" world group evaluates), so a black surface's in-scattering grows with s and reaches
exactly the sky behind it beyond both domes, never more ("seamless horizon";
``physics.sky.inscattering_layered``).
s is Camera Data > View Distance times the ``atmos_metres_per_unit`` parameter; v is -(Geometry >
Incoming). Mie absorption adds to extinction only. The other parameters are read from scene custom
properties (see :mod:`.parameters`), so the tree depends only on which terms are present
(:class:`AerialFeatures`), and is rebuilt only when those or its version (:data:`.stamps.AERIAL`) change.

How the nodes evaluate it (:func:`scattering_terms`): phi1 cancels against the slab's length, so L(a, a) is
(beta_R Phi_R + beta_M Phi_HG) / beta_ex (1 - exp(-tau)); every exp(-beta x) is b^(k x), a per-channel power
of the parameter-only base b = exp(-beta / k) (one Gamma node), and Phi_HG's base^(-3/2) is a Gamma node too.
Cycles resolves the parameters (View Layer attributes) to constants and folds every node that reads only
them, so what runs per shading point is about thirty Vector Math and Gamma nodes: no per-channel exp, no
division by tau, no series branch.
Every quantity is the one ``atmos_addon.physics`` computes (its float32 evaluation is what the tests compare
against, within 2e-3 in Cycles). Vector Math does the per-channel products and sums (exact per component);
exp and sign of the parameters run channel by channel on Math nodes, folded to constants by Cycles.
"""

from __future__ import annotations

import dataclasses

import bpy
import numpy as np

from .dome import cos_theta_to_sun, dome_distances, sun_direction, view_direction
from . import parts, stamps
from .graph import ArrayBuilder, GraphBuilder
from .precise import precise_terms
from .terms import HG_DENOMINATOR_FLOOR, LEVELS, AerialFeatures, distance_m, scattering_terms  # noqa: F401

#: Name of the node group in ``bpy.data.node_groups``.
GROUP_NAME = stamps.AERIAL.name
#: The same graph with s the length of the ray segment just travelled (Cycles in-render mode, :mod:`.in_render`).
SEGMENT_GROUP_NAME = stamps.AERIAL_SEGMENT.name
#: Where s comes from: the camera's view distance (the AOV path) or Light Path > Ray Length (per ray segment).
DISTANCE_SOURCES = ("VIEW", "RAY")

OUTPUT_TRANSMITTANCE = "Transmittance"
OUTPUT_INSCATTERING = "Inscattering"


# -- the group ---------------------------------------------------------------------------------------


def _ensure_interface(tree: bpy.types.ShaderNodeTree) -> None:
    """Add the group's output sockets if missing (existing sockets, and the links to them, are kept)."""
    present = {item.name for item in tree.interface.items_tree
               if item.item_type == "SOCKET" and item.in_out == "OUTPUT"}
    for name, description in ((OUTPUT_TRANSMITTANCE, "F_ex = exp(-beta_ex s): multiply the surface radiance"),
                              (OUTPUT_INSCATTERING, "L_in: sunlight scattered toward the camera; add it")):
        if name not in present:
            socket = tree.interface.new_socket(name, in_out="OUTPUT", socket_type="NodeSocketColor")
            socket.description = description


def aerial_terms(g: GraphBuilder, features: AerialFeatures, distance: str = "VIEW"):
    """(F_ex, L_in) of the group for ``features``, on any builder: the nodes of the group, or their values
    (:func:`evaluate`). ``distance`` is one of :data:`DISTANCE_SOURCES` (see :func:`distance_m`)."""
    s = distance_m(g, distance)
    view = view_direction(g)
    if features.level == "precise":
        return precise_terms(g, features, s, view)
    r_rayleigh, r_mie = dome_distances(g, g.separate(view, label="v")[2])
    s_rayleigh = g.min(s, r_rayleigh, label="s_R = min(s, R_R)")
    s_mie = g.min(s, r_mie, label="s_M = min(s, R_M)") if features.mie or features.absorption else None
    return scattering_terms(g, features, s_rayleigh, s_mie, cos_theta_to_sun(g, view, sun_direction(g)))


def evaluate(features: AerialFeatures, parameter_values, *, distance_units, view_direction, position=None,
             images=None):
    """What the group computes, in numpy float32: (F_ex, L_in), each (N, 3), for shading points at
    ``distance_units`` (N,) scene units from the camera along the unit ``view_direction`` (N, 3); ``position``
    (N, 3) scene units is the shading point (the graph's Geometry > Position), ``images`` the Precise table's pixels
    by image name. ``parameter_values`` are :func:`~.parameters.shader_parameter_values`."""
    direction = np.asarray(view_direction, dtype=np.float64)
    inputs = {"view_distance": distance_units, "incoming": -direction,
              "position": direction * 0.0 if position is None else position}
    g = ArrayBuilder(parameter_values, inputs, images)
    f_ex, l_in = aerial_terms(g, features)
    shape = np.shape(distance_units) + (3,)
    return np.broadcast_to(g.array(f_ex), shape), np.broadcast_to(g.array(l_in), shape)


def build_aerial_perspective(tree: bpy.types.ShaderNodeTree, features: AerialFeatures, distance: str = "VIEW"
                             ) -> None:
    """Clear ``tree``'s nodes and build the aerial-perspective graph for ``features`` (interface kept);
    ``distance`` is one of :data:`DISTANCE_SOURCES` (see :func:`distance_m`)."""
    tree.nodes.clear()
    _ensure_interface(tree)
    g = GraphBuilder(tree)
    f_ex, l_in = aerial_terms(g, features, distance)
    output = g.node("NodeGroupOutput", label="Group Output")
    tree.links.new(f_ex, output.inputs[OUTPUT_TRANSMITTANCE])
    tree.links.new(l_in, output.inputs[OUTPUT_INSCATTERING])
    g.set_depth(output, g.max_depth + 1)
    g.layout()
    stamps.stamp(tree, stamps.AERIAL_SEGMENT if distance == "RAY" else stamps.AERIAL, features.key)


def is_current(tree: bpy.types.NodeTree, features: AerialFeatures, distance: str = "VIEW") -> bool:
    """True if ``tree`` was built by this version for ``features``."""
    return stamps.is_current(tree, stamps.AERIAL_SEGMENT if distance == "RAY" else stamps.AERIAL, features.key)


def ensure_aerial_perspective_group(features: AerialFeatures = AerialFeatures(), distance: str = "VIEW"
                                    ) -> bpy.types.ShaderNodeTree:
    """Get or create the "Atmos Aerial Perspective" group, rebuilt in place only if stale.

    With ``distance="RAY"`` it is the "Atmos Aerial Perspective (Ray Segment)" group: the same graph with s the
    length of the ray segment (:func:`distance_m`), for Cycles' in-render mode.

    A tree stamped with the current version (:mod:`.stamps`) and ``features`` is returned untouched.
    A stale one keeps its identity and interface (group nodes in materials keep their links) and gets
    new nodes. A data-block of that name that is not a shader tree is an error the user must resolve.
    """
    if distance not in DISTANCE_SOURCES:
        raise ValueError(f"distance source must be one of {DISTANCE_SOURCES}; got {distance!r}")
    if distance == "RAY":
        # A ray segment may start anywhere (a mirror, a dome crossing), not at the camera: the Precise table is
        # camera-centred and would be wrong there, so the in-render segments use the constant density.
        features = dataclasses.replace(features, level="fast")
    tree = stamps.group(stamps.AERIAL_SEGMENT if distance == "RAY" else stamps.AERIAL)
    if not is_current(tree, features, distance):
        build_aerial_perspective(tree, features, distance)
    return tree


def node_count(tree: bpy.types.NodeTree) -> int:
    """Number of nodes ``tree`` evaluates (the group output included), its parts' counted as if inlined
    (:func:`.parts.inline_count`)."""
    return parts.inline_count(tree)


def describe_features(features: AerialFeatures) -> str:
    """One line for the panel, e.g. "Rayleigh + Mie + absorption: 81 nodes".

    Reads :data:`NODE_COUNTS` (a test checks it against built trees), so it is safe in a panel's draw.
    """
    parts = ["Rayleigh"] + (["Mie"] if features.mie else []) + (["absorption"] if features.absorption else [])
    return f"{features.level.capitalize()}, {' + '.join(parts)}: {NODE_COUNTS[features.key]} nodes"


#: Nodes in the group per feature key for this version (:data:`.stamps.AERIAL`; group output included).
NODE_COUNTS = {"rayleigh": 47, "rayleigh+abs": 73, "rayleigh+mie": 99, "rayleigh+mie+abs": 101,
               "rayleigh+precise": 188, "rayleigh+abs+precise": 188,
               "rayleigh+mie+precise": 255, "rayleigh+mie+abs+precise": 255,
               # key tiles blended (an animated camera or sun): a second texel and a blend per lookup
               "rayleigh+precise+blend": 242, "rayleigh+abs+precise+blend": 242, "rayleigh+mie+precise+blend": 341,
               "rayleigh+mie+abs+precise+blend": 341}
