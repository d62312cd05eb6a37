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
(:class:`AerialFeatures`), and is rebuilt only when those or :data:`NODE_GROUP_VERSION` change.

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
import math
from dataclasses import dataclass
from typing import Sequence

import bpy

from . import parameters
from .balanced import balanced_terms
from .dome import cos_theta_to_sun, dome_distances, sun_direction, view_direction
from .graph import GraphBuilder, Socket
from .precise import precise_terms

#: Name of the node group in ``bpy.data.node_groups``.
GROUP_NAME = "Atmos Aerial Perspective"
#: The same graph with s the length of the ray segment just travelled (Cycles in-render mode, :mod:`.in_render`).
SEGMENT_GROUP_NAME = "Atmos Aerial Perspective (Ray Segment)"
#: Where s comes from: the camera's view distance (the AOV path) or Light Path > Ray Length (per ray segment).
DISTANCE_SOURCES = ("VIEW", "RAY")
#: Bump when the tree a given feature set builds changes; stale trees are rebuilt in place.
NODE_GROUP_VERSION = 5  # 2: lengths clamped to the virtual sky dome; 3: the layered dome; 4: powers, no phi1;
#                          5: Precise distances taken at most to the top of the atmosphere
#: Floor of the Henyey-Greenstein denominator base (the physics core's ``HG_DENOMINATOR_FLOOR``).
HG_DENOMINATOR_FLOOR = 1.0e-12

OUTPUT_TRANSMITTANCE = "Transmittance"
OUTPUT_INSCATTERING = "Inscattering"
_VERSION_KEY = "atmos_version"
_FEATURES_KEY = "atmos_features"


#: Quality levels the group can be built for: the paper's constant density, or densities falling with altitude
#: along the curved ray (:mod:`.balanced`), or the frame's baked table (:mod:`.precise`).
LEVELS = ("fast", "balanced", "precise")


@dataclass(frozen=True)
class AerialFeatures:
    """What the group contains: Mie scattering (the HG phase), Mie absorption, and the quality ``level``."""

    mie: bool = True
    absorption: bool = True
    level: str = "fast"

    def __post_init__(self) -> None:
        if self.level not in LEVELS:
            raise ValueError(f"AerialFeatures.level must be one of {LEVELS}; got {self.level!r}")

    @classmethod
    def from_coefficients(cls, beta_mie: Sequence[float], beta_mie_absorption: Sequence[float]) -> "AerialFeatures":
        """The smallest feature set that represents these coefficients (a term is kept if any channel > 0)."""
        return cls(mie=any(float(b) > 0.0 for b in beta_mie),
                   absorption=any(float(b) > 0.0 for b in beta_mie_absorption))

    @property
    def key(self) -> str:
        """A stable short name, stamped on the tree: "rayleigh", "rayleigh+mie", "rayleigh+mie+abs+balanced"..."""
        return ("rayleigh" + ("+mie" if self.mie else "") + ("+abs" if self.absorption else "")
                + ("" if self.level == "fast" else f"+{self.level}"))


# -- the quantities ------------------------------------------------------------------------------------


def distance_m(g: GraphBuilder, source: str = "VIEW") -> Socket:
    """s in m: scene units times metres per unit, from the camera (``"VIEW"``: Camera Data > View Distance) or
    along the ray segment that reached the shading point (``"RAY"``: Light Path > Ray Length; for a camera ray
    the distance from its origin, for a reflected or refracted ray the distance from the surface it left;
    Cycles keeps measuring from that origin across volume boundaries).
    """
    if source == "RAY":
        length = g.node("ShaderNodeLightPath", label="Light Path").outputs["Ray Length"]
    else:
        length = g.node("ShaderNodeCameraData", label="Camera Data").outputs["View Distance"]
    metres_per_unit = g.attribute(parameters.METRES_PER_UNIT, output="Fac")
    return g.mul(length, metres_per_unit, label="s (m)")


def mie_extinction_coefficient(g: GraphBuilder, features: AerialFeatures, beta_mie: Socket | None) -> Socket | None:
    """beta_M,ex = beta_M + beta_M,abs, 1/m (only the terms the features keep; None when neither is)."""
    if features.mie and features.absorption:
        return g.add(beta_mie, g.attribute(parameters.BETA_MIE_ABSORPTION), label="beta_M,ex")
    if features.absorption:
        return g.attribute(parameters.BETA_MIE_ABSORPTION)
    return beta_mie if features.mie else None


def exponent_unit(g: GraphBuilder, beta_rayleigh: Socket, beta_mie_ex: Socket | None) -> Socket:
    """k = max over the channels of beta_R + beta_M,ex, 1/m: optical depths are written as k x (parameters only)."""
    total = beta_rayleigh if beta_mie_ex is None else g.add(beta_rayleigh, beta_mie_ex, label="beta_ex")
    red, green, blue = g.separate(total)
    return g.max(g.max(red, green), blue, label="k = max beta_ex")


def transmittance_base(g: GraphBuilder, beta: Socket, k: Socket, *, label: str) -> Socket:
    """b = exp(-beta / k) per channel, in [1/e, 1]: the transmittance over the length 1/k (parameters only).

    With every coefficient 0, k = 0 and Blender's divide gives 0: b = 1, no extinction.
    """
    return g.per_channel(g.exp, g.neg(g.div(beta, k)), label=label)


def transmittance(g: GraphBuilder, base: Socket, length: Socket, k: Socket, *, label: str) -> Socket:
    """exp(-beta x) = b^(k x) per channel for a length x in m: one Gamma node (:meth:`~.graph.GraphBuilder.power_per_channel`).

    k x is the largest channel's optical depth; b >= 1/e keeps every channel's base far from float32's
    underflow, and b^0 = 1 at zero length.
    """
    return g.power_per_channel(base, g.mul(length, k, label=f"k x ({label})"), label=label)


def one_minus(g: GraphBuilder, colour: Socket, *, label: str = "") -> Socket:
    """1 - colour per channel."""
    return g.sub((1.0, 1.0, 1.0), colour, label=label)


def phase_rayleigh(g: GraphBuilder, mu: Socket) -> Socket:
    """Phi_R(mu) = 3 / (16 pi) (1 + mu^2), 1/sr (eq. 17)."""
    return g.mul(g.multiply_add(mu, mu, 1.0), 3.0 / (16.0 * math.pi), label="Phi_R")


def phase_henyey_greenstein(g: GraphBuilder, mu: Socket, anisotropy: Socket) -> Socket:
    """Phi_HG(mu, g) = (1 - g^2) / (4 pi (1 + g^2 - 2 g mu)^(3/2)) per channel, 1/sr (eq. 18, normalised).

    The base is written (1 - |g|)^2 + 2 |g| (1 - sign(g) mu), two non-negative terms, so it does not
    cancel near the peak as |g| -> 1, and is floored at 1e-12; base^(-3/2) is one Gamma node. Only the
    three nodes that involve mu run per shading point: the rest reads parameters alone (Cycles folds it).
    """
    abs_g = g.abs(anisotropy, label="|g|")
    minus_sign_g = g.neg(g.per_channel(g.sign, anisotropy), label="-sign(g)")
    one_minus_sign_mu = g.multiply_add(minus_sign_g, mu, (1.0, 1.0, 1.0), label="1 - sign(g) mu")
    one_minus_abs_g = g.sub((1.0, 1.0, 1.0), abs_g)
    base = g.multiply_add(g.scale(abs_g, 2.0), one_minus_sign_mu, g.mul(one_minus_abs_g, one_minus_abs_g),
                          label="1 + g^2 - 2 g mu")
    base = g.max(base, (HG_DENOMINATOR_FLOOR,) * 3)
    one_minus_g2 = g.mul(g.sub((1.0, 1.0, 1.0), anisotropy), g.add((1.0, 1.0, 1.0), anisotropy), label="1 - g^2")
    return g.mul(g.power_per_channel(base, -1.5, label="base^-1.5"), g.scale(one_minus_g2, 1.0 / (4.0 * math.pi)),
                 label="Phi_HG")


def scattering_per_length(g: GraphBuilder, features: AerialFeatures, mu: Socket, beta_rayleigh: Socket,
                          beta_mie: Socket | None) -> tuple[Socket, Socket | None]:
    """(beta_R Phi_R(mu), beta_M Phi_HG(mu, g)) per channel, 1/(m sr): the species' scattering per unit length."""
    rayleigh = g.scale(beta_rayleigh, phase_rayleigh(g, mu), label="beta_R Phi_R")
    if not features.mie:
        return rayleigh, None
    anisotropy = g.attribute(parameters.MIE_G)
    return rayleigh, g.mul(beta_mie, phase_henyey_greenstein(g, mu, anisotropy), label="beta_M Phi_HG")


def scattering_terms(g: GraphBuilder, features: AerialFeatures, s_rayleigh: Socket, s_mie: Socket | None,
                     mu: Socket) -> tuple[Socket, Socket]:
    """(F_ex, L_in) of the layered dome for per-species lengths b_R, b_M: shared by the aerial and sky groups.

    a = min(b_R, b_M) holds both species, the tail t_i = b_i - a (one of them 0) the longer one alone
    (``physics.sky.inscattering_layered``). A slab's L = (sigma_R x_R + sigma_M x_M) phi1(tau) becomes, for
    the shared segment (x_R = x_M = a, tau = beta_ex a), (beta_R Phi_R + beta_M Phi_HG) / beta_ex (1 - T(a)),
    and for a tail of one species beta_i Phi_i / beta_i,ex (1 - T_i(t_i)); so

        L_in = E_sun [(1 - T(a)) (r_R Phi_R + r_M Phi_HG) + T(a) (Phi_R (1 - T_R(t_R)) + w_M Phi_HG (1 - T_M(t_M)))]
        F_ex = T(a) T_R(t_R) T_M(t_M),   T(a) = T_R(a) T_M(a)

    with the parameter-only ratios r_R = beta_R / beta_ex, r_M = beta_M / beta_ex, w_M = beta_M / beta_M,ex
    (0 where a denominator is 0, and so is its numerator) and every T a power b^(k x) (:func:`transmittance`).
    No quotient by tau and no series branch at small depths: the shading point runs about thirty Vector Math
    and Gamma nodes, the per-channel ratios and bases fold to constants in Cycles. 1 - T rounds to 6e-8 in
    float32, so for tau < 1e-3 the in-scattering keeps an absolute error of 6e-8 E_sun Phi (a surface a few
    metres away, whose in-scattering is that small). Without Mie scattering or absorption (``s_mie`` None)
    there is one species: L_in = E_sun Phi_R (1 - T_R(b_R)), F_ex = T_R(b_R).
    """
    beta_rayleigh = g.attribute(parameters.BETA_RAYLEIGH)
    beta_mie = g.attribute(parameters.BETA_MIE) if features.mie else None
    beta_mie_ex = mie_extinction_coefficient(g, features, beta_mie) if s_mie is not None else None
    sun_irradiance = g.attribute(parameters.SUN_IRRADIANCE)
    phase_r = phase_rayleigh(g, mu)
    k = exponent_unit(g, beta_rayleigh, beta_mie_ex)
    base_rayleigh = transmittance_base(g, beta_rayleigh, k, label="b_R")
    if s_mie is None:
        f_ex = transmittance(g, base_rayleigh, s_rayleigh, k, label="F_ex")
        light = g.scale(one_minus(g, f_ex, label="1 - F_ex"), phase_r, label="L / E_sun")
        return f_ex, g.mul(light, sun_irradiance, label="L_in")
    base_mie = transmittance_base(g, beta_mie_ex, k, label="b_M")
    shared = g.min(s_rayleigh, s_mie, label="a = min(b_R, b_M)")
    tail_rayleigh = g.sub(s_rayleigh, shared, label="t_R = b_R - a")
    tail_mie = g.sub(s_mie, shared, label="t_M = b_M - a")
    t_shared = transmittance(g, g.mul(base_rayleigh, base_mie, label="b_R b_M"), shared, k, label="T(a)")
    t_rayleigh = transmittance(g, base_rayleigh, tail_rayleigh, k, label="T_R(t_R)")
    t_mie = transmittance(g, base_mie, tail_mie, k, label="T_M(t_M)")
    beta_ex = g.add(beta_rayleigh, beta_mie_ex, label="beta_ex")
    shared_phase = g.scale(g.div(beta_rayleigh, beta_ex, label="r_R"), phase_r, label="r_R Phi_R")
    tail = g.scale(one_minus(g, t_rayleigh, label="1 - T_R"), phase_r, label="Phi_R (1 - T_R)")
    if features.mie:
        phase_m = phase_henyey_greenstein(g, mu, g.attribute(parameters.MIE_G))
        shared_phase = g.multiply_add(g.div(beta_mie, beta_ex, label="r_M"), phase_m, shared_phase,
                                      label="r_R Phi_R + r_M Phi_HG")
        albedo_phase = g.mul(g.div(beta_mie, beta_mie_ex, label="w_M"), phase_m, label="w_M Phi_HG")
        tail = g.multiply_add(albedo_phase, one_minus(g, t_mie, label="1 - T_M"), tail, label="tail L / E_sun")
    shared_light = g.mul(one_minus(g, t_shared, label="1 - T(a)"), shared_phase, label="shared L / E_sun")
    light = g.multiply_add(t_shared, tail, shared_light, label="L(a) + T(a) L(tail)")
    f_ex = g.mul(t_shared, g.mul(t_rayleigh, t_mie, label="T_R T_M"), label="F_ex")
    return f_ex, g.mul(light, sun_irradiance, label="L_in")


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


def build_aerial_perspective(tree: bpy.types.ShaderNodeTree, features: AerialFeatures, distance: str = "VIEW"
                             ) -> None:
    """Clear ``tree``'s nodes and build the aerial-perspective graph for ``features`` (interface kept);
    ``distance`` is one of :data:`DISTANCE_SOURCES` (see :func:`distance_m`)."""
    tree.nodes.clear()
    _ensure_interface(tree)
    g = GraphBuilder(tree)
    s = distance_m(g, distance)
    view = view_direction(g)
    if features.level == "balanced":
        f_ex, l_in = balanced_terms(g, features, s, view)
    elif features.level == "precise":
        f_ex, l_in = precise_terms(g, features, s, view)
    else:
        r_rayleigh, r_mie = dome_distances(g, g.separate(view, label="v")[2])
        s_rayleigh = g.min(s, r_rayleigh, label="s_R = min(s, R_R)")
        s_mie = g.min(s, r_mie, label="s_M = min(s, R_M)") if features.mie or features.absorption else None
        f_ex, l_in = scattering_terms(g, features, s_rayleigh, s_mie, cos_theta_to_sun(g, view, sun_direction(g)))
    output = g.node("NodeGroupOutput", label="Group Output")
    tree.links.new(f_ex, output.inputs[OUTPUT_TRANSMITTANCE])
    tree.links.new(l_in, output.inputs[OUTPUT_INSCATTERING])
    g.set_depth(output, g.max_depth + 1)
    g.layout()
    tree[_VERSION_KEY] = NODE_GROUP_VERSION
    tree[_FEATURES_KEY] = features.key


def is_current(tree: bpy.types.NodeTree, features: AerialFeatures) -> bool:
    """True if ``tree`` was built by this version for ``features``."""
    return tree.get(_VERSION_KEY) == NODE_GROUP_VERSION and tree.get(_FEATURES_KEY) == features.key


def ensure_aerial_perspective_group(features: AerialFeatures = AerialFeatures(), distance: str = "VIEW"
                                    ) -> bpy.types.ShaderNodeTree:
    """Get or create the "Atmos Aerial Perspective" group, rebuilt in place only if stale.

    With ``distance="RAY"`` it is the "Atmos Aerial Perspective (Ray Segment)" group: the same graph with s the
    length of the ray segment (:func:`distance_m`), for Cycles' in-render mode.

    A tree stamped with the current :data:`NODE_GROUP_VERSION` and ``features`` is returned untouched.
    A stale one keeps its identity and interface (group nodes in materials keep their links) and gets
    new nodes. A data-block of that name that is not a shader tree is an error the user must resolve.
    """
    if distance not in DISTANCE_SOURCES:
        raise ValueError(f"distance source must be one of {DISTANCE_SOURCES}; got {distance!r}")
    if distance == "RAY":
        # A ray segment may start anywhere (a mirror, a dome crossing), not at the camera: the Balanced graph's
        # camera altitude h_P - c s would be wrong there, so the in-render segments use the constant density.
        features = dataclasses.replace(features, level="fast")
    name = SEGMENT_GROUP_NAME if distance == "RAY" else GROUP_NAME
    tree = bpy.data.node_groups.get(name)
    if tree is None:
        tree = bpy.data.node_groups.new(name, "ShaderNodeTree")
    elif tree.bl_idname != "ShaderNodeTree":
        raise TypeError(f'Node group "{name}" exists but is a {tree.bl_idname}, not a shader node group; '
                        f"rename or delete it, then apply Atmos again")
    if not is_current(tree, features):
        build_aerial_perspective(tree, features, distance)
    return tree


def node_count(tree: bpy.types.NodeTree) -> int:
    """Number of nodes in ``tree`` (the group output included)."""
    return len(tree.nodes)


def describe_features(features: AerialFeatures) -> str:
    """One line for the panel, e.g. "Rayleigh + Mie + absorption: 81 nodes".

    Reads :data:`NODE_COUNTS` (a test checks it against built trees), so it is safe in a panel's draw.
    """
    parts = ["Rayleigh"] + (["Mie"] if features.mie else []) + (["absorption"] if features.absorption else [])
    return f"{features.level.capitalize()}, {' + '.join(parts)}: {NODE_COUNTS[features.key]} nodes"


#: Nodes in the group per feature key for this :data:`NODE_GROUP_VERSION` (group output included).
NODE_COUNTS = {"rayleigh": 47, "rayleigh+abs": 73, "rayleigh+mie": 99, "rayleigh+mie+abs": 101,
               "rayleigh+balanced": 295, "rayleigh+abs+balanced": 300, "rayleigh+mie+balanced": 325,
               "rayleigh+mie+abs+balanced": 327, "rayleigh+precise": 174, "rayleigh+abs+precise": 174,
               "rayleigh+mie+precise": 241, "rayleigh+mie+abs+precise": 241}
