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
    phi1(x) = (1 - exp(-x)) / x, or 1 - x/2 + x^2/6 for x < 1e-3 (no 0/0 at zero depth)

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

Every step follows ``atmos_addon.physics`` (its float32 evaluation is what the tests compare against).
Vector Math does the per-channel products and sums (exact per component); exp, sqrt, sign and the
branch of phi1 have no Vector Math form in Blender 4.2, so they run channel by channel on Math nodes.
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
NODE_GROUP_VERSION = 3  # 2: lengths clamped to the virtual sky dome; 3: the layered dome
#: Optical depth below which phi1 uses its series (the physics core's ``SMALL_OPTICAL_DEPTH``).
SMALL_OPTICAL_DEPTH = 1.0e-3
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


def optical_depth(g: GraphBuilder, beta_rayleigh: Socket, beta_mie_ex: Socket | None, s_rayleigh: Socket,
                  s_mie: Socket) -> Socket:
    """tau = beta_R s_R + beta_M,ex s_M per channel, dimensionless."""
    tau = g.scale(beta_rayleigh, s_rayleigh, label="beta_R s_R")
    if beta_mie_ex is None:
        return tau
    return g.multiply_add(beta_mie_ex, s_mie, tau, label="tau")


def transmittance(g: GraphBuilder, tau: Socket) -> Socket:
    """F_ex = exp(-tau) per channel."""
    return g.per_channel(g.exp, g.neg(tau), label="F_ex")


def one_minus_exp_over_x(g: GraphBuilder, x: Socket, exp_minus_x: Socket) -> Socket:
    """phi1(x) = (1 - exp(-x)) / x per channel, by its series 1 - x/2 + x^2/6 where x < 1e-3.

    ``exp_minus_x`` is exp(-x) (the transmittance, already computed); the quotient uses max(x, 1e-3)
    so the unused branch never divides by zero, and the branch is picked exactly (see ``select``).
    """
    series = g.add(g.sub(1.0, g.mul(x, 0.5)), g.mul(g.mul(x, x), 1.0 / 6.0), label="1 - x/2 + x^2/6")
    quotient = g.div(g.sub(1.0, exp_minus_x), g.max(x, SMALL_OPTICAL_DEPTH), label="(1 - e^-x) / x")

    def pick(x_c: Socket, series_c: Socket, quotient_c: Socket) -> Socket:
        return g.select(g.less_than(x_c, SMALL_OPTICAL_DEPTH), series_c, quotient_c)

    return g.per_channel(pick, x, series, quotient, label="phi1")


def phase_rayleigh(g: GraphBuilder, mu: Socket) -> Socket:
    """Phi_R(mu) = 3 / (16 pi) (1 + mu^2), 1/sr (eq. 17)."""
    return g.mul(g.multiply_add(mu, mu, 1.0), 3.0 / (16.0 * math.pi), label="Phi_R")


def phase_henyey_greenstein(g: GraphBuilder, mu: Socket, anisotropy: Socket) -> Socket:
    """Phi_HG(mu, g) = (1 - g^2) / (4 pi (1 + g^2 - 2 g mu)^(3/2)) per channel, 1/sr (eq. 18, normalised).

    The base is written (1 - |g|)^2 + 2 |g| (1 - sign(g) mu), two non-negative terms, so it does not
    cancel near the peak as |g| -> 1, and is floored at 1e-12.
    """
    abs_g = g.abs(anisotropy, label="|g|")
    sign_g = g.per_channel(g.sign, anisotropy, label="sign(g)")
    one_minus_sign_mu = g.multiply_add(sign_g, g.neg(mu), 1.0, label="1 - sign(g) mu")
    one_minus_abs_g = g.sub(1.0, abs_g)
    base = g.multiply_add(g.mul(abs_g, 2.0), one_minus_sign_mu, g.mul(one_minus_abs_g, one_minus_abs_g),
                          label="1 + g^2 - 2 g mu")
    base = g.max(base, HG_DENOMINATOR_FLOOR)
    base_to_three_halves = g.mul(base, g.per_channel(g.sqrt, base), label="base^1.5")
    one_minus_g2 = g.mul(g.sub(1.0, anisotropy), g.add(1.0, anisotropy), label="1 - g^2")
    return g.div(one_minus_g2, g.mul(base_to_three_halves, 4.0 * math.pi), label="Phi_HG")


def scattering_per_length(g: GraphBuilder, features: AerialFeatures, mu: Socket, beta_rayleigh: Socket,
                          beta_mie: Socket | None) -> tuple[Socket, Socket | None]:
    """(beta_R Phi_R(mu), beta_M Phi_HG(mu, g)) per channel, 1/(m sr): the species' scattering per unit length."""
    rayleigh = g.scale(beta_rayleigh, phase_rayleigh(g, mu), label="beta_R Phi_R")
    if not features.mie:
        return rayleigh, None
    anisotropy = g.attribute(parameters.MIE_G)
    return rayleigh, g.mul(beta_mie, phase_henyey_greenstein(g, mu, anisotropy), label="beta_M Phi_HG")


def slab(g: GraphBuilder, sigma_rayleigh: Socket, sigma_mie: Socket | None, beta_rayleigh: Socket,
         beta_mie_ex: Socket | None, length_rayleigh: Socket, length_mie: Socket | None, name: str
         ) -> tuple[Socket, Socket]:
    """(T, L / E_sun) of one slab with a length per species: exp(-tau) and (sigma_R x_R + sigma_M x_M) phi1(tau).

    tau = beta_R x_R + beta_M,ex x_M; exact for species in fixed proportion and for one species alone
    (``physics.sky.inscattering_two_species`` without E_sun).
    """
    tau = optical_depth(g, beta_rayleigh, beta_mie_ex, length_rayleigh, length_mie)
    f_ex = transmittance(g, tau)
    scattered = g.scale(sigma_rayleigh, length_rayleigh, label=f"sigma_R x_R ({name})")
    if sigma_mie is not None:
        scattered = g.multiply_add(sigma_mie, length_mie, scattered, label=f"sigma_R x_R + sigma_M x_M ({name})")
    return f_ex, g.mul(scattered, one_minus_exp_over_x(g, tau, f_ex), label=f"L / E_sun ({name})")


def scattering_terms(g: GraphBuilder, features: AerialFeatures, s_rayleigh: Socket, s_mie: Socket | None,
                     mu: Socket) -> tuple[Socket, Socket]:
    """(F_ex, L_in) of the layered dome for per-species lengths b_R, b_M: shared by the aerial and sky groups.

    a = min(b_R, b_M) holds both species, the tail t_i = b_i - a (one of them 0) the longer one alone:
    L_in = E_sun [L(a, a) + T(a, a) L(t_R, t_M)], F_ex = T(a, a) T(t_R, t_M) (``physics.sky.inscattering_layered``).
    With neither Mie scattering nor absorption (``s_mie`` None) there is one species and one slab of length b_R.
    """
    beta_rayleigh = g.attribute(parameters.BETA_RAYLEIGH)
    beta_mie = g.attribute(parameters.BETA_MIE) if features.mie else None
    beta_mie_ex = mie_extinction_coefficient(g, features, beta_mie)
    sigma_rayleigh, sigma_mie = scattering_per_length(g, features, mu, beta_rayleigh, beta_mie)
    sun_irradiance = g.attribute(parameters.SUN_IRRADIANCE)
    if s_mie is None:
        f_ex, light = slab(g, sigma_rayleigh, None, beta_rayleigh, None, s_rayleigh, None, "b_R")
        return f_ex, g.mul(light, sun_irradiance, label="L_in")
    shared = g.min(s_rayleigh, s_mie, label="a = min(b_R, b_M)")
    tail_rayleigh = g.sub(s_rayleigh, shared, label="t_R = b_R - a")
    tail_mie = g.sub(s_mie, shared, label="t_M = b_M - a")
    f_near, l_near = slab(g, sigma_rayleigh, sigma_mie, beta_rayleigh, beta_mie_ex, shared, shared, "a")
    f_far, l_far = slab(g, sigma_rayleigh, sigma_mie, beta_rayleigh, beta_mie_ex, tail_rayleigh, tail_mie, "tail")
    light = g.multiply_add(f_near, l_far, l_near, label="L(a) + T(a) L(tail)")
    return g.mul(f_near, f_far, label="F_ex"), g.mul(light, sun_irradiance, label="L_in")


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
NODE_COUNTS = {"rayleigh": 73, "rayleigh+abs": 115, "rayleigh+mie": 143, "rayleigh+mie+abs": 145,
               "rayleigh+balanced": 295, "rayleigh+abs+balanced": 300, "rayleigh+mie+balanced": 330,
               "rayleigh+mie+abs+balanced": 332, "rayleigh+precise": 153, "rayleigh+abs+precise": 153,
               "rayleigh+mie+precise": 225, "rayleigh+mie+abs+precise": 225}
