# SPDX-License-Identifier: GPL-3.0-or-later
"""The Balanced quality level as nodes: densities that fall exponentially along the curved view ray.

The numpy reference is ``atmos_addon.physics.balanced`` (``extinction_balanced``, ``inscattering_balanced`` with
``sun_optical_depths``); its docstring derives every step. Per shading point, with s the camera distance (m),
v the unit view direction, c = v_z, h_P the shading point's altitude and h0 = h_P - c s the camera's (m):

    k      = (1 - c^2) / (2 (R_p + h0))                      the ray's altitude is h0 + c t + k t^2
    l      = s / N,  t_j = j l,  h_j = h0 + t_j (c + k t_j) - k l^2 / 6      ends of N straight pieces (sag-lowered)
    n_i,j  = exp(-max(h_j, 0) / H_i)                          relative density of species i at end j
    D_i    = l n_lo phi1(rise_i),  rise_i = |max(h_b,0) - max(h_a,0)| / H_i,  n_lo = max(n_a, n_b)
           = l |n_a - n_b| / rise_i  where rise_i >= 1e-3 (the same closed form, one exp per end, shared by
             the two pieces meeting there), else l n_lo (1 - rise/2 + rise^2/6)
    tau_j  = beta_R D_R + beta_M,ex D_M                       per channel
    E_j    = E_sun exp(min(tau_sun,R (1 - n_R,lo) + tau_sun,M (1 - n_M,lo), 50))   the sun at the piece's lower end
    L_in   = sum_j T_<j E_j (beta_R Phi_R(mu) D_R + beta_M Phi_HG(mu, g) D_M) phi1(tau_j),  T_<j = prod_<j exp(-tau)
    F_ex   = prod_j exp(-tau_j)

Both species run as the x and y components of one vector (as in :mod:`.dome`), so each exp, each phi1 and
each branch is one pass for the two. The shading point's altitude is ``atmos_origin_altitude`` (m, the
altitude of the world origin) plus its world z times metres per unit; no Python runs at render time, so an
animated camera renders the same on a farm. The sun's ground optical depths tau_sun,R and tau_sun,M (per
channel, capped at 50) are parameters the add-on writes per sun position (``physics.balanced.
sun_optical_depths_ground``, given the ground sun), keyed with the sun when it is animated. Those depths are
scaled so that E_sun exp(tau_sun) <= E_top: the exo-atmospheric cap of the numpy ``sun_irradiance_at_altitude``
is never reached, so it has no node.

Limits (measured, ``tests/blender/test_node_groups.py``): the graph matches the float32 core to 0.1 % up to
about 6e5 m and 0.4 % at 2e6 m; beyond, the phi1 blend a + c (b - a) cancels when the series branch grows
(12 % at 6e6 m), and rays running past the atmosphere's top keep drawing chords through it (the numpy model
does the same). Both were fixed in a trial graph, which Eevee then compiled in 130 s instead of 2 s under
Mesa's software OpenGL (LLVM's ScalarEvolution on the AOV loops; the CI renders this way): every variant of
this graph tried, 306 to 369 nodes, compiled that slowly inside the add-on's AOV material, so this one stays.
"""

from __future__ import annotations

from ..physics import balanced as physics_balanced
from ..physics.aerial_perspective import SMALL_OPTICAL_DEPTH
from . import parameters
from .dome import cos_theta_to_sun, sun_direction
from .graph import GraphBuilder, Socket
from .terms import mie_extinction_coefficient, scattering_per_length

#: Straight pieces the curved ray is cut into, the core's.
PIECES = physics_balanced.CURVATURE_PIECES
#: The Per Pixel variant (compositor): pieces and where each sees the sun.
PER_PIXEL_PIECES = physics_balanced.PER_PIXEL_PIECES
PER_PIXEL_SUN_AT = physics_balanced.PER_PIXEL_SUN_AT
#: Cap on the sun's gain exponent.
MAX_SUN_GAIN = physics_balanced.MAX_SUN_OPTICAL_DEPTH


def exp_xy(g: GraphBuilder, vector: Socket, *, label: str) -> Socket:
    """(exp(x), exp(y), 1): the exponential of the two species' components (z unused)."""
    x, y, _ = g.separate(vector)
    return g.combine(g.exp(x), g.exp(y), 1.0, label=label)


def branch_large(g: GraphBuilder, x: Socket, threshold: float) -> Socket:
    """Per component, 1 where x >= ``threshold`` and 0 below (x >= 0): min(floor(x / threshold), 1)."""
    return g.min(g.floor(g.scale(x, 1.0 / threshold)), (1.0, 1.0, 1.0), label=f"x >= {threshold:g}")


def phi1_vector(g: GraphBuilder, x: Socket, exp_minus_x: Socket, *, label: str) -> Socket:
    """phi1(x) = (1 - exp(-x)) / x per component, the series 1 - x/2 + x^2/6 below 1e-3 (x >= 0)."""
    series = g.multiply_add(x, g.multiply_add(x, (1.0 / 6.0,) * 3, (-0.5,) * 3), (1.0, 1.0, 1.0),
                            label="1 - x/2 + x^2/6")
    quotient = g.div(g.sub((1.0, 1.0, 1.0), exp_minus_x), g.max(x, (SMALL_OPTICAL_DEPTH,) * 3),
                     label="(1 - e^-x) / x")
    large = branch_large(g, x, SMALL_OPTICAL_DEPTH)
    return g.multiply_add(large, g.sub(quotient, series), series, label=label)


def exp_per_channel(g: GraphBuilder, vector: Socket, *, label: str) -> Socket:
    """exp of each of the three components."""
    return g.per_channel(g.exp, vector, label=label)


def ray_geometry(g: GraphBuilder, s: Socket, view: Socket, camera_altitude: Socket | None = None
                 ) -> tuple[Socket, Socket, Socket]:
    """(h0, c, k): the camera's altitude (m, >= 0), the view ray's zenith cosine and its curvature k (1/m).

    h0 is ``camera_altitude`` where the caller has it (the per-pixel compositor group), else h_P - c s from the
    shading point's position (the shader group).
    """
    _, _, c = g.separate(view, label="v")
    if camera_altitude is None:
        _, _, z = g.separate(g.shading_input("position", label="Geometry (position)"), label="P")
        metres = g.attribute(parameters.METRES_PER_UNIT, output="Fac")
        h_point = g.multiply_add(z, metres, g.attribute(parameters.ORIGIN_ALTITUDE, output="Fac"), label="h_P (m)")
        h0 = g.max(g.multiply_add(c, g.neg(s), h_point), 0.0, label="h0 = h_P - c s")
    else:
        h0 = camera_altitude
    planet = g.attribute(parameters.PLANET_RADIUS, output="Fac", label="R_p")
    one_minus_c2 = g.mul(g.sub(1.0, c), g.add(1.0, c), label="1 - c^2")
    k = g.div(one_minus_c2, g.mul(g.add(planet, h0), 2.0), label="k = (1 - c^2) / (2 (R_p + h0))")
    return h0, c, k


def piece_ends(g: GraphBuilder, h0: Socket, c: Socket, k: Socket, s: Socket, pieces: int
               ) -> tuple[list[Socket], Socket]:
    """Altitudes h_j (m) of the pieces' ends on the parabola, lowered by the mean sag k l^2 / 6, and l (m)."""
    length = g.mul(s, 1.0 / pieces, label="l = s / N")
    sag = g.mul(g.mul(k, g.mul(length, length)), 1.0 / 6.0, label="sag = k l^2 / 6")
    ends = [g.sub(h0, sag, label="h_0")]
    for j in range(1, pieces + 1):
        t = g.mul(s, j / pieces, label=f"t_{j}")
        ends.append(g.sub(g.multiply_add(t, g.multiply_add(t, k, c), h0), sag, label=f"h_{j}"))
    return ends, length


def relative_densities(g: GraphBuilder, altitude: Socket, inverse_heights: Socket, j: int) -> tuple[Socket, Socket]:
    """(max(h, 0), (n_R, n_M, 1)) at one end: n_i = exp(-max(h, 0) / H_i)."""
    ground = g.max(altitude, 0.0, label=f"max(h_{j}, 0)")
    return ground, exp_xy(g, g.scale(inverse_heights, g.neg(ground)), label=f"n_{j}")


def piece_columns(g: GraphBuilder, end_a: tuple[Socket, Socket], end_b: tuple[Socket, Socket],
                  inverse_heights: Socket, length: Socket, j: int) -> tuple[Socket, Socket]:
    """((D_R, D_M, .), (n_R, n_M, .) at the lower end): the piece's density columns in m."""
    (h_a, n_a), (h_b, n_b) = end_a, end_b
    rise = g.scale(inverse_heights, g.abs(g.sub(h_b, h_a)), label=f"rise_{j} = |dh| / H")
    n_low = g.max(n_a, n_b, label=f"n_lo,{j}")
    quotient = g.div(g.abs(g.sub(n_a, n_b)), g.max(rise, (SMALL_OPTICAL_DEPTH,) * 3), label="|n_a - n_b| / rise")
    series = g.mul(n_low, g.multiply_add(rise, g.multiply_add(rise, (1.0 / 6.0,) * 3, (-0.5,) * 3), (1.0, 1.0, 1.0)),
                   label="n_lo (1 - r/2 + r^2/6)")
    large = branch_large(g, rise, SMALL_OPTICAL_DEPTH)
    columns = g.scale(g.multiply_add(large, g.sub(quotient, series), series), length, label=f"D_{j} (m)")
    return columns, n_low


def balanced_terms(g: GraphBuilder, features, s: Socket, view: Socket, pieces: int = PIECES,
                   camera_altitude: Socket | None = None, sun_at: str = "lower_end") -> tuple[Socket, Socket]:
    """(F_ex, L_in) of the Balanced model for a shading point at distance ``s`` (m) along ``view``, seen from a
    camera at ``camera_altitude`` (m, >= 0; None: from the shading point's position, :func:`ray_geometry`).
    Each piece sees the sun at its lower end, or with ``sun_at="middle"`` at the mean of its ends' altitudes
    (the Per Pixel variant: ``physics.balanced``'s docstring).

    ``features`` is an :class:`~.terms.AerialFeatures`: without Mie scattering there is no phase
    function for the haze, without Mie scattering or absorption no haze column in the optical depth.
    """

    mu = cos_theta_to_sun(g, view, sun_direction(g))
    h0, c, k = ray_geometry(g, s, view, camera_altitude)
    heights = g.attribute(parameters.SCALE_HEIGHTS, output="Vector", label="(H_R, H_M, 0)")
    inverse_heights = g.div((1.0, 1.0, 1.0), heights, label="1 / H")  # Vector Math divide: 0 for the z component
    altitudes, length = piece_ends(g, h0, c, k, s, pieces)
    ends = [relative_densities(g, h, inverse_heights, j) for j, h in enumerate(altitudes)]
    beta_rayleigh = g.attribute(parameters.BETA_RAYLEIGH)
    beta_mie = g.attribute(parameters.BETA_MIE) if features.mie else None
    beta_mie_ex = mie_extinction_coefficient(g, features, beta_mie)
    sigma_rayleigh, sigma_mie = scattering_per_length(g, features, mu, beta_rayleigh, beta_mie)
    sun_irradiance = g.attribute(parameters.SUN_IRRADIANCE)
    sun_depth_rayleigh = g.attribute(parameters.SUN_OPTICAL_DEPTH_RAYLEIGH, label="tau_sun,R")
    sun_depth_mie = g.attribute(parameters.SUN_OPTICAL_DEPTH_MIE, label="tau_sun,M")
    transmittance = None
    radiance = None
    for j in range(pieces):
        columns, n_low = piece_columns(g, ends[j], ends[j + 1], inverse_heights, length, j)
        d_rayleigh, d_mie, _ = g.separate(columns, label=f"D_R, D_M ({j})")
        tau = g.scale(beta_rayleigh, d_rayleigh, label=f"beta_R D_R ({j})")
        if beta_mie_ex is not None:
            tau = g.multiply_add(beta_mie_ex, d_mie, tau, label=f"tau_{j}")
        piece_transmittance = exp_per_channel(g, g.neg(tau), label=f"exp(-tau_{j})")
        scattered = g.scale(sigma_rayleigh, d_rayleigh, label=f"sigma_R D_R ({j})")
        if sigma_mie is not None:
            scattered = g.multiply_add(sigma_mie, d_mie, scattered, label=f"sigma_R D_R + sigma_M D_M ({j})")
        if sun_at == "middle":
            middle = g.max(g.mul(g.add(altitudes[j], altitudes[j + 1]), 0.5), 0.0, label=f"h_mid,{j}")
            n_low = exp_xy(g, g.scale(inverse_heights, g.neg(middle)), label=f"n_mid,{j}")
        thinned_r, thinned_m, _ = g.separate(g.sub((1.0, 1.0, 1.0), n_low), label=f"1 - n_sun ({j})")
        gain = g.scale(sun_depth_rayleigh, thinned_r)
        gain = g.multiply_add(sun_depth_mie, thinned_m, gain, label=f"sun gain ({j})")
        sun = g.mul(sun_irradiance, exp_per_channel(g, g.min(gain, (MAX_SUN_GAIN,) * 3), label="exp(gain)"),
                    label=f"E_sun,{j}")
        term = g.mul(g.mul(scattered, phi1_vector(g, tau, piece_transmittance, label=f"phi1(tau_{j})")), sun,
                     label=f"L_{j}")
        if transmittance is None:
            radiance, transmittance = term, piece_transmittance
        else:
            radiance = g.multiply_add(transmittance, term, radiance, label=f"L_in to piece {j}")
            transmittance = g.mul(transmittance, piece_transmittance, label=f"T to piece {j}")
    return transmittance, radiance
