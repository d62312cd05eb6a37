# SPDX-License-Identifier: GPL-3.0-or-later
"""The terms of the aerial perspective as nodes, shared by every group that evaluates them: the feature set,
the transmittance powers, the phase functions and the layered-dome scattering terms (Hoffman & Preetham 2002,
eq. 16-19; the group that puts them together is :mod:`.aerial_perspective`, whose docstring derives them).

The Precise level (:mod:`.precise`), the sky (:mod:`.sky`, :mod:`.sky_lighting`),
the Per Pixel compositor group (:mod:`.per_pixel`) and In-Render mode (:mod:`.in_render`) call these functions
with their own builder, so every one of them evaluates the very same equations.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..physics.phase import HG_DENOMINATOR_FLOOR
from . import parameters
from .graph import GraphBuilder, Socket



#: Quality levels the group can be built for: the paper's constant density, or the frame's baked table
#: (:mod:`.precise`). No Balanced level (densities falling along the curved ray in closed form): against the
#: complete reference it is no more accurate than Fast at Precise's cost (docs/quality.md).
LEVELS = ("fast", "precise")


@dataclass(frozen=True)
class AerialFeatures:
    """What the group contains: Mie scattering (the HG phase), Mie absorption, the quality ``level`` and, at the
    Precise level, ``blend``: each lookup blends two key tiles (a camera or sun that moves over time,
    ``physics.precise.key_tiles``)."""

    mie: bool = True
    absorption: bool = True
    level: str = "fast"
    blend: bool = False

    def __post_init__(self) -> None:
        if self.level not in LEVELS:
            raise ValueError(f"AerialFeatures.level must be one of {LEVELS}; got {self.level!r}")
        if self.blend and self.level != "precise":
            raise ValueError(f"AerialFeatures.blend needs the precise level; got {self.level!r}")

    @classmethod
    def from_key(cls, key: str) -> "AerialFeatures":
        """The features a :attr:`key` names (a stamped group's, to rebuild it as it was)."""
        tokens = set(str(key).split("+"))
        level = next((level for level in LEVELS if level in tokens), "fast")
        return cls(mie="mie" in tokens, absorption="abs" in tokens, level=level,
                   blend=level == "precise" and "blend" in tokens)

    @property
    def key(self) -> str:
        """A stable short name, stamped on the tree: "rayleigh", "rayleigh+mie", "rayleigh+mie+abs+precise",
        "rayleigh+mie+abs+precise+blend"..."""
        return ("rayleigh" + ("+mie" if self.mie else "") + ("+abs" if self.absorption else "")
                + ("" if self.level == "fast" else f"+{self.level}") + ("+blend" if self.blend else ""))


# -- the quantities ------------------------------------------------------------------------------------


def distance_m(g: GraphBuilder, source: str = "VIEW") -> Socket:
    """s in m: scene units times metres per unit, from the camera (``"VIEW"``: Camera Data > View Distance) or
    along the ray segment that reached the shading point (``"RAY"``: Light Path > Ray Length; for a camera ray
    the distance from its origin, for a reflected or refracted ray the distance from the surface it left;
    Cycles keeps measuring from that origin across volume boundaries).
    """
    if source == "RAY":
        length = g.shading_input("ray_length", label="Light Path")
    else:
        length = g.shading_input("view_distance", label="Camera Data")
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
    """exp(-beta x) = b^(k x) per channel for a length x in m: one Gamma node
    (:meth:`~.graph.GraphBuilder.power_per_channel`).

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
