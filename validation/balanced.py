# SPDX-License-Identifier: GPL-3.0-or-later
"""The Balanced quality level: aerial perspective with densities that fall exponentially along the view ray.

The Fast model (:mod:`~atmos_addon.physics.aerial_perspective`, Hoffman & Preetham 2002, eq. 19) takes
the sea-level density everywhere. That is right for a camera and a target near the ground, wrong for a
drone at 2 km, an aircraft at 10 km or a mountain range 150 km away. Balanced keeps the paper's
structure (one transmittance, one in-scattering term, E_sun constant along the ray) and integrates the
real density profiles n_i(h) = exp(-h / H_i) along the ray in closed form.

Optical depth of one straight piece (plane-parallel)
    A piece of length l (m) whose altitude runs linearly from h_a to h_b (m) has, per species i,

        tau_i = beta_i integral_0^l exp(-h(t) / H_i) dt = beta_i H_i |exp(-h_a/H_i) - exp(-h_b/H_i)| / |cos|
              = beta_i l exp(-h_lo / H_i) phi1(|h_b - h_a| / H_i),      h_lo = min(h_a, h_b),

    with |cos| = |h_b - h_a| / l and phi1(x) = (1 - exp(-x)) / x
    (:func:`~atmos_addon.physics.aerial_perspective.one_minus_exp_over_x`). Factoring the *lower* end out
    makes every exponent <= 0: a ray looking down (density growing along it) cannot overflow, a horizontal
    piece (h_a = h_b) is phi1(0) = 1 without a 0/0, and the expression is symmetric in the two ends.
    Endpoints below the ground are taken at the ground (:func:`above_ground`).

Curvature
    Over a sphere of radius R a straight ray from altitude h0 with zenith cosine c has altitude
    h(t) = sqrt(r0^2 + 2 r0 c t + t^2) - R, r0 = R + h0, i.e. h(t) = h0 + c t + (1 - c^2) t^2 / (2 r0) to second
    order (third-order term below 40 m at 360 km). A horizontal ray rises s^2 / (2 R) = 1.8 km in 150 km,
    1.5 haze scale heights: the plane-parallel form alone overestimates that path's haze optical depth by
    about 30 %, and an aircraft looking at the horizon would see its ray end 10 km below the ground. So
    Balanced follows the parabola, taken as :data:`CURVATURE_PIECES` straight pieces between points of
    it (the square root of the exact form loses every digit in float32 for r0 ~ 6e6 m; the parabola
    does not). A chord lies above the arc it spans by (1 - c^2)/(2 r0) (t - t_a)(t_b - t) <= k l^2 / 4,
    so each piece is lowered by the mean of that sag, k l^2 / 6 (exact to first order in sag / H for a
    nearly level piece), before its optical depth is taken. Against numerical quadrature: below 0.01 %
    for ground views to 30 km and for the drone, 0.5 % (haze) at 150 km, 5 % (haze) on an aircraft's
    tangent ray to the horizon, where the transmittance is below 1e-3 and the in-scattering saturated.

In-scattering (two species with different profiles)
    Single scattering with E_sun constant along the ray is L_in = E_sun integral sum_i beta_sc,i Phi_i(mu)
    n_i(t) exp(-tau(t)) dt. With columns D_i = integral n_i dt (m) and tau = sum_i beta_ex,i D_i, the closed
    form used here (the same as the sky dome's, :mod:`~atmos_addon.physics.sky`) is

        L_in = E_sun (sum_i beta_sc,i Phi_i(mu) D_i) phi1(tau)
             = E_sun (sum_i beta_sc,i Phi_i D_i) (1 - exp(-tau)) / tau.

    It is exact when the profiles are proportional along the ray (then the scattering per unit optical
    depth is the constant sum_i beta_sc,i Phi_i D_i / tau and d(1 - exp(-tau)) integrates it), so exact for
    one species: L_in = E_sun beta_sc/beta_ex Phi (1 - exp(-tau)). With H_R != H_M it spreads each
    species' scatterers evenly over the optical depth. With H -> infinity (D_i = s) it is eq. 19, the
    Fast model, exactly.

Sun at altitude (optional)
    The slides use the ground-level E_sun. A scatterer at altitude h sees the sun through less air:
    tau_sun,i(h) ~ tau_sun,i(0) exp(-h / H_i) (the slant path to the sun keeps its shape, the column above
    shrinks). :func:`sun_irradiance_at_altitude` applies that at the lower end of each piece (the mid-point
    was measured too: 4.6 % pixel error for mountains at 150 km against 0.8 %, 3.0 % against 7.3 % on
    an aircraft's ray to the horizon). Without it the drone's in-scattering is 11 % low and the aircraft's 30 %.

In-scattering is summed piece by piece (each piece's term attenuated by the pieces before it), which keeps
the two species' scatterers where they are along the ray instead of spreading them over the whole of it.

The Per Pixel variant
    Per sample, the graph's size is what Eevee can compile (module ``atmos_addon.node_groups.balanced``), so the shader keeps
    4 pieces and the sun at each piece's lower end. Evaluated once per pixel in the compositor, nodes are cheap:
    :data:`PER_PIXEL_PIECES` = 8 pieces with the sun at each piece's middle altitude (``sun_at="middle"``).
    Against brute-force single scattering (``tools/bench_accuracy.py``, "balanced, per pixel"): the aircraft's
    ray to the horizon 0.6 % instead of 7.3 %, every other case except the sunsets within 1.3 %. (With 4 pieces
    the middle is worse at 150 km, 4.6 %, as measured above; with 8 the lower end still leaves 3.3 % on the
    aircraft; 16 pieces at the lower end 1.9 %.)

Units: lengths m, coefficients 1/m, radiance in the units of E_sun per steradian. Every step is cast to
``dtype`` so the float32 results are what a shader node tree computes; no step overflows in float32.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

from atmos_addon.physics.aerial_perspective import nonnegative_distance, one_minus_exp_over_x
from atmos_addon.physics.atmosphere import Atmosphere
from atmos_addon.physics.optical_depth import layer_optical_depth, ray_hits_planet
from atmos_addon.physics.phase import clamp_cosine, phase_hg, phase_rayleigh

#: Straight pieces the curved ray is cut into (their ends lie on the parabola h0 + c t + k t^2).
CURVATURE_PIECES = 4
#: Where a piece sees the sun: its lower end, or its middle altitude (the mean of its ends').
SUN_AT = ("lower_end", "middle")
#: The Per Pixel variant (module docstring): pieces, and where each sees the sun.
PER_PIXEL_PIECES = 8
PER_PIXEL_SUN_AT = "middle"
#: Cap on the ground sun optical depth and on the sun's gain exponent at altitude (exp(50) fits float32).
MAX_SUN_OPTICAL_DEPTH = 50.0


def above_ground(altitude_m: ArrayLike, dtype: DTypeLike = np.float64) -> np.ndarray:
    """Altitude in m clamped at the ground (0): the exponential profiles are not continued underground."""
    dt = np.dtype(dtype).type
    return np.maximum(np.asarray(altitude_m, dtype=dt), dt(0.0))


def cos_zenith_of(view_dir_or_cos_zenith: ArrayLike, dtype: DTypeLike = np.float64) -> np.ndarray:
    """The view ray's zenith cosine c in [-1, 1]: a scalar/array of cosines, or directions (..., 3) (z up).

    Directions need not be unit length; a zero vector counts as horizontal.
    """
    dt = np.dtype(dtype).type
    value = np.asarray(view_dir_or_cos_zenith, dtype=np.float64)
    if value.ndim >= 1 and value.shape[-1] == 3:
        norm = np.linalg.norm(value, axis=-1)
        value = value[..., 2] / np.where(norm > 0.0, norm, 1.0)
    return clamp_cosine(value, dt)


def curvature_coefficient(h0_m: ArrayLike, cos_zenith: ArrayLike, planet_radius_m: float,
                          dtype: DTypeLike = np.float64) -> np.ndarray:
    """k = (1 - c^2) / (2 (R + h0)), 1/m: the ray's altitude is h0 + c t + k t^2 to second order in t / R."""
    dt = np.dtype(dtype).type
    c = clamp_cosine(cos_zenith, dt)
    radius = dt(planet_radius_m) + above_ground(h0_m, dt)
    return (dt(1.0) - c) * (dt(1.0) + c) / (dt(2.0) * radius)


def _piece_column(h_a: np.ndarray, h_b: np.ndarray, length: np.ndarray, scale_height: float, dt: type
                  ) -> np.ndarray:
    """integral of exp(-h/H) over a straight piece of ``length`` m from altitude h_a to h_b: l e^{-h_lo/H} phi1."""
    h_lo = above_ground(np.minimum(h_a, h_b), dt)
    rise = np.abs(above_ground(h_b, dt) - above_ground(h_a, dt)) / dt(scale_height)
    return length * np.exp(-h_lo / dt(scale_height)) * one_minus_exp_over_x(rise, dt)


def _ray_pieces(h0_m: ArrayLike, view_dir_or_cos_zenith: ArrayLike, distance_m: ArrayLike, atm: Atmosphere,
                dt: type, curvature: bool, pieces: int) -> tuple[list[np.ndarray], np.ndarray]:
    """Altitudes (m) of the ends of the ray's straight pieces, each lowered by the piece's mean sag, and the
    piece length (m). Plane-parallel (``curvature=False``): the straight line h0 + c t in one piece."""
    if int(pieces) != pieces or pieces < 1:
        raise ValueError(f"pieces must be an integer >= 1; got {pieces!r}")
    h0 = above_ground(h0_m, dt)
    c = cos_zenith_of(view_dir_or_cos_zenith, dt)
    s = nonnegative_distance(distance_m, dt)
    h0, c, s = np.broadcast_arrays(h0, c, s)
    if not curvature:
        return [h0, h0 + c * s], s
    n = int(pieces)
    k = curvature_coefficient(h0, c, atm.planet_radius, dt)
    length = s / dt(n)
    sag = k * length * length * dt(1.0 / 6.0)
    ends = []
    for j in range(n + 1):
        t = s * dt(j / n)
        ends.append(h0 + t * (c + t * k) - sag)
    return ends, length


def piece_columns(h0_m: ArrayLike, view_dir_or_cos_zenith: ArrayLike, distance_m: ArrayLike, atm: Atmosphere,
                  dtype: DTypeLike = np.float64, curvature: bool = True, pieces: int = CURVATURE_PIECES
                  ) -> tuple[list[tuple[np.ndarray, np.ndarray]], list[np.ndarray]]:
    """Per piece of the ray, the relative-density columns (D_R, D_M) in m and the piece's lower end altitude in m.

    A list of (D_R, D_M) and a list of altitudes, one entry per piece (see :func:`density_columns`). The lower
    end is where the sun is evaluated (:func:`inscattering_balanced`): the light that reaches the camera
    comes mostly from the denser, lower part of a piece.
    """
    dt = np.dtype(dtype).type
    ends, length = _ray_pieces(h0_m, view_dir_or_cos_zenith, distance_m, atm, dt, curvature, pieces)
    columns = [tuple(_piece_column(a, b, length, height, dt)
                     for height in (atm.rayleigh_scale_height, atm.mie_scale_height))
               for a, b in zip(ends[:-1], ends[1:])]
    lows = [above_ground(np.minimum(a, b), dt) for a, b in zip(ends[:-1], ends[1:])]
    return columns, lows


def density_columns(h0_m: ArrayLike, view_dir_or_cos_zenith: ArrayLike, distance_m: ArrayLike, atm: Atmosphere,
                    dtype: DTypeLike = np.float64, curvature: bool = True, pieces: int = CURVATURE_PIECES
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Relative-density columns (D_R, D_M) = integral of exp(-h/H_i) dt along the ray, m, each of shape (...).

    ``curvature=False`` is the plane-parallel straight segment h(t) = h0 + c t, exact in one piece.
    Otherwise the parabola h0 + c t + k t^2 in ``pieces`` straight pieces, each lowered by its mean sag
    k l^2 / 6 (module docstring). D_i / s is the mean relative density; D_i = s when H_i -> infinity.
    """
    columns, _ = piece_columns(h0_m, view_dir_or_cos_zenith, distance_m, atm, dtype, curvature, pieces)
    d_r, d_m = columns[0]
    for piece_r, piece_m in columns[1:]:
        d_r, d_m = d_r + piece_r, d_m + piece_m
    return d_r, d_m


def _optical_depth(d_r: np.ndarray, d_m: np.ndarray, atm: Atmosphere, dt: type) -> np.ndarray:
    """tau = beta_R D_R + beta_M,ex D_M per channel, shape (..., 3)."""
    return (atm.rayleigh_scattering.astype(dt) * d_r[..., np.newaxis]
            + atm.mie_extinction.astype(dt) * d_m[..., np.newaxis])


def optical_depth_segment(h0_m: ArrayLike, cos_zenith: ArrayLike, distance_m: ArrayLike, atm: Atmosphere,
                          dtype: DTypeLike = np.float64, curvature: bool = True, pieces: int = CURVATURE_PIECES
                          ) -> np.ndarray:
    """Optical depth of the view ray from altitude ``h0_m`` over ``distance_m`` with zenith cosine c, (..., 3).

    tau = sum_i beta_ex,i D_i with the columns of :func:`density_columns`; plane-parallel closed form
    beta H |e^{-h0/H} - e^{-h1/H}| / |c| when ``curvature=False``. Dimensionless, >= 0.
    ``cos_zenith`` may also be a direction (..., 3).
    """
    dt = np.dtype(dtype).type
    d_r, d_m = density_columns(h0_m, cos_zenith, distance_m, atm, dt, curvature, pieces)
    return _optical_depth(d_r, d_m, atm, dt)


def extinction_balanced(h0_m: ArrayLike, view_dir_or_cos_zenith: ArrayLike, distance_m: ArrayLike,
                        atm: Atmosphere, dtype: DTypeLike = np.float64, curvature: bool = True,
                        pieces: int = CURVATURE_PIECES) -> np.ndarray:
    """Transmittance F_ex = exp(-tau) along the view ray, in [0, 1], shape (..., 3)."""
    dt = np.dtype(dtype).type
    return np.exp(-optical_depth_segment(h0_m, view_dir_or_cos_zenith, distance_m, atm, dt, curvature, pieces))


def sun_optical_depths_ground(sun_elevation_rad: ArrayLike, atm: Atmosphere,
                              sun_irradiance_ground: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Optical depths (tau_R, tau_M) from the ground to space toward the sun's centre, each (..., 3).

    Chapman function over the curved planet, capped at :data:`MAX_SUN_OPTICAL_DEPTH` (the sun behind the
    planet would be ``inf``). Computed once per frame on the CPU and fed to the shader.

    With the ground sun ``sun_irradiance_ground`` (W/m^2, per channel) both depths are scaled down, per channel,
    where E_ground exp(tau_R + tau_M) would exceed the sun above the atmosphere: the sun brightened to any altitude
    (:func:`sun_irradiance_at_altitude`) then never passes E_top, so the shader needs no cap of its own. The ground
    sun averages the limb-darkened disk, whose upper limb is dimmed less than the centre: near the horizon
    E_ground exp(tau_centre) exceeds E_top by up to 12 % (the overcast preset at 4 deg).
    """
    zenith = 0.5 * np.pi - np.asarray(sun_elevation_rad, dtype=np.float64)
    zenith = np.where(ray_hits_planet(0.0, zenith, atm.planet_radius), 0.5 * np.pi, zenith)
    taus = (layer_optical_depth(0.0, zenith, atm.rayleigh_scattering, atm.rayleigh_scale_height, atm.planet_radius),
            layer_optical_depth(0.0, zenith, atm.mie_extinction, atm.mie_scale_height, atm.planet_radius))
    taus = tuple(np.minimum(tau, MAX_SUN_OPTICAL_DEPTH) for tau in taus)
    if sun_irradiance_ground is None:
        return taus
    ground = np.asarray(sun_irradiance_ground, dtype=np.float64)
    with np.errstate(divide="ignore"):
        headroom = np.log(atm.sun_irradiance_top / np.maximum(ground, 1e-300))   # ln(E_top / E_ground)
    total = taus[0] + taus[1]
    scale = np.where(total > headroom, np.maximum(headroom, 0.0) / np.maximum(total, 1e-300), 1.0)
    return tuple(tau * scale for tau in taus)


def sun_irradiance_at_altitude(sun_irradiance_ground: ArrayLike, altitude_m: ArrayLike,
                               sun_optical_depths: tuple[ArrayLike, ArrayLike], atm: Atmosphere,
                               dtype: DTypeLike = np.float64) -> np.ndarray:
    """E_sun(h) = E_sun(0) exp(sum_i tau_sun,i (1 - exp(-h / H_i))), capped at the sun above the atmosphere.

    The air between the ground and h no longer dims the sun: each species' slant optical depth toward the
    sun keeps its ground value's shape and loses the fraction 1 - exp(-h/H_i) below h. Shape (..., 3).
    """
    dt = np.dtype(dtype).type
    h = above_ground(altitude_m, dt)[..., np.newaxis]
    gain = dt(0.0)
    for tau, height in zip(sun_optical_depths, (atm.rayleigh_scale_height, atm.mie_scale_height)):
        tau = np.minimum(np.asarray(tau, dtype=dt), dt(MAX_SUN_OPTICAL_DEPTH))
        gain = gain + tau * -np.expm1(-h / dt(height))
    gain = np.minimum(gain, dt(MAX_SUN_OPTICAL_DEPTH))
    e_ground = np.maximum(np.asarray(sun_irradiance_ground, dtype=dt), dt(0.0))
    return np.minimum(e_ground * np.exp(gain), atm.sun_irradiance_top.astype(dt))


def inscattering_balanced(h0_m: ArrayLike, view_dir_or_cos_zenith: ArrayLike, distance_m: ArrayLike,
                          cos_theta: ArrayLike, atm: Atmosphere, sun_irradiance: ArrayLike,
                          dtype: DTypeLike = np.float64, curvature: bool = True,
                          sun_optical_depths: tuple[ArrayLike, ArrayLike] | None = None,
                          pieces: int = CURVATURE_PIECES, sun_at: str = "lower_end") -> np.ndarray:
    """In-scattered sunlight along the ray, summed over its pieces j (module docstring), shape (..., 3):

        L_in = sum_j exp(-tau_<j) E_sun,j (beta_R Phi_R D_R,j + beta_M,sc Phi_HG D_M,j) phi1(tau_j)

    with tau_<j the optical depth from the camera to piece j. Each term is exact when the two profiles are
    proportional within its piece; for one species the sum telescopes to E beta_sc/beta_ex Phi (1 - e^-tau).
    ``cos_theta`` = mu, the cosine between the view ray and the direction to the sun; ``sun_irradiance``
    the ground sun E_sun per channel ((3,) or (..., 3)). With ``sun_optical_depths`` (from
    :func:`sun_optical_depths_ground`) E_sun,j is E_sun raised to its value at the altitude of the
    piece's lower end, or with ``sun_at="middle"`` of the mean of its ends' altitudes
    (:func:`sun_irradiance_at_altitude`; the Per Pixel variant, module docstring); otherwise E_sun,j = E_sun.
    Radiance in the units of E_sun per steradian, never negative.
    """
    if sun_at not in SUN_AT:
        raise ValueError(f"sun_at must be one of {SUN_AT}; got {sun_at!r}")
    dt = np.dtype(dtype).type
    columns, lows = piece_columns(h0_m, view_dir_or_cos_zenith, distance_m, atm, dt, curvature, pieces)
    if sun_at == "middle":
        ends, _ = _ray_pieces(h0_m, view_dir_or_cos_zenith, distance_m, atm, dt, curvature, pieces)
        lows = [dt(0.5) * (a + b) for a, b in zip(ends[:-1], ends[1:])]   # clamped at the ground below
    mu = clamp_cosine(cos_theta, dt)
    mu = np.broadcast_to(mu, np.broadcast_shapes(mu.shape, columns[0][0].shape))
    phase_r = atm.rayleigh_scattering.astype(dt) * phase_rayleigh(mu, dt)[..., np.newaxis]
    phase_m = atm.mie_scattering.astype(dt) * phase_hg(mu, atm.mie_g, dt)
    e_ground = np.maximum(np.asarray(sun_irradiance, dtype=dt), dt(0.0))
    total = dt(0.0)
    transmittance = dt(1.0)
    for (d_r, d_m), low in zip(columns, lows):
        tau = _optical_depth(d_r, d_m, atm, dt)
        e_sun = e_ground if sun_optical_depths is None else sun_irradiance_at_altitude(
            e_ground, low, sun_optical_depths, atm, dt)
        scattering_column = phase_r * d_r[..., np.newaxis] + phase_m * d_m[..., np.newaxis]
        total = total + transmittance * e_sun * scattering_column * one_minus_exp_over_x(tau, dt)
        transmittance = transmittance * np.exp(-tau)
    return np.broadcast_to(total, np.broadcast_shapes(np.shape(total), mu.shape + (3,))).astype(dt)
