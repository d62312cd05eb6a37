# SPDX-License-Identifier: GPL-3.0-or-later
"""The sky and the sun's disk with the "virtual sky dome" of Hoffman & Preetham (GDC 2002 slides, "Implementation").

The aerial perspective of :mod:`~atmos_addon.physics.aerial_perspective` takes the density constant along
the ray. A sky ray runs to the top of the atmosphere through densities that fall as exp(-h / H), so the
slides replace the real atmosphere, for each direction, by a homogeneous one that ends at the distance
R(direction) where it holds the same amount of matter: "Each distance R is defined so that R times the
constant density of our constant density model equals the integrated density from the real sky density
distribution." The sky is then the in-scattering of the homogeneous model out to R, which makes the sky
and the aerial perspective one model: a surface at the dome (or beyond it) melts into the sky.

The two species (molecules, aerosols) have different scale heights, so each has its own dome,

    R_i(elevation) n_i(h) = integral over the ray of n_i(h(l)) dl
    R_i = H_i Ch((R_p + h) / H_i, chi) - H_i exp(-(h_top - h) / H_i) Ch((R_p + h_top) / H_i, chi_top)

with n_i(h) = exp(-h / H_i) the density relative to sea level, h the camera altitude, chi = pi/2 - elevation
the zenith angle of the view ray, Ch the Chapman function (:func:`~atmos_addon.physics.optical_depth.chapman`)
and the second term removing the matter above the top of the atmosphere (h_top = ``atm.atmosphere_height``),
where the ray leaves it with zenith angle chi_top, sin chi_top = (R_p + h) sin chi / (R_p + h_top).
At the zenith of a ground camera R_i = H_i (1 - exp(-h_top / H_i)) ~ H_i; at the horizon R_i ~ H_i sqrt(pi x / 2)
(about 290 km for Earth's molecules, 110 km for its haze).

Lengths ``R_i`` are real metres for the constant-density atmosphere *at the camera's altitude*
(:func:`atmosphere_at_altitude`; the sea-level one for a camera on the ground). Rays that meet the ground take
the dome of the ray grazing the ground (the horizon; elevation clamped to the geometric horizon, which lies
at 0 for a ground camera): the sky behind the ground is hidden, and the world background below the horizon
is a distant ground seen through the horizon's aerial perspective (see :func:`sky_radiance`).

Sky radiance and aerial perspective: the layered dome. Per channel, with per-species lengths
b_R = min(s, R_R), b_M = min(s, R_M) (a surface at distance s; s -> infinity for the sky), the two species share
the first stretch of the ray and only the species with the longer dome fills the rest: the haze (smaller scale
height, normally the shorter dome) sits near the camera, the molecules reach on. Along the ray,

    segment 1 = [0, a],  a = min(b_R, b_M):   both species (an even mixture)
    segment 2 = [a, b],  b = max(b_R, b_M):   the longer species alone, t_R = b_R - a, t_M = b_M - a (one is 0)

and single scattering of a homogeneous slab of length l and coefficients (beta_sc Phi, beta_ex) is
S l phi1(beta_ex l) E_sun (S the scattering per unit length, phi1(x) = (1 - exp(-x)) / x), so

    L_in = L_2sp(a, a) + T_2sp(a, a) L_2sp(t_R, t_M)
    F_ex = T_2sp(a, a) T_2sp(t_R, t_M) = exp(-(beta_R b_R + beta_M,ex b_M))
    L_2sp(x_R, x_M) = (beta_R Phi_R(mu) x_R + beta_M,sc Phi_HG(mu, g) x_M) E_sun phi1(beta_R x_R + beta_M,ex x_M)
    T_2sp(x_R, x_M) = exp(-(beta_R x_R + beta_M,ex x_M))

L_2sp (:func:`inscattering_two_species`) is exact for a slab whose species are mixed in fixed proportion; in the
tail one of t_R, t_M is 0, so it is the one-species slab there and the order of the two tails never matters. A
black surface's L_in is therefore non-decreasing in s (growing s only adds a slab behind the ones already seen),
equals eq. 19 of the paper (the core's ``inscattering``) while s <= min(R_R, R_M), and equals the sky
(:func:`sky_radiance`, the same formula with b_i = R_i) for s >= max(R_R, R_M): no surface outshines the sky behind
it (:func:`inscattering_layered`, :func:`extinction_layered`). The earlier even mixture over the whole ray,
L_2sp(b_R, b_M), let the molecular depth added beyond the haze dome dim the haze's light, so a black wall between
the domes toward the sun came out up to 24 % brighter than the sky behind it. E_sun is the sun's irradiance at
the ground (the slides' choice), so the sky goes black exactly when the sun has set: with E_sun = 0 single
scattering gives L = 0, and twilight (light scattered from the still-lit upper atmosphere, and multiple
scattering) needs a model beyond this one.

Units: lengths m, coefficients 1/m, angles rad, radiance in the units of E_sun per steradian. Directions use
Blender's world axes (z up). Numpy only.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

from .aerial_perspective import nonnegative_distance, one_minus_exp_over_x
from .atmosphere import Atmosphere
from .optical_depth import chapman
from .phase import clamp_cosine, phase_hg, phase_rayleigh
from .sun import SUN_ANGULAR_RADIUS_RAD, SUN_LIMB_DARKENING, horizon_dip_rad, sun_irradiance_ground

#: Shape parameter p of the closed-form Chapman approximation (:func:`chapman_approx`), fitted minimax over
#: x in [300, 6400] and elevations 0..90 deg: maximum relative error 0.40 %.
CHAPMAN_APPROX_P = 0.653
#: Gauss-Legendre nodes of the limb-darkening normalisation over the disk.
LIMB_QUADRATURE_NODES = 16

#: A dome: (elevation_rad, atm, altitude_m) -> (R_rayleigh, R_mie) in m, like :func:`dome_distance`.
DomeFunction = Callable[..., tuple[np.ndarray, np.ndarray]]

_LIMB_NODES, _LIMB_WEIGHTS = np.polynomial.legendre.leggauss(LIMB_QUADRATURE_NODES)


def _camera_altitude(altitude_m: ArrayLike, atm: Atmosphere) -> np.ndarray:
    """The camera altitude in m clamped to the atmosphere, [0, atm.atmosphere_height] (the dome is inside it)."""
    return np.clip(np.asarray(altitude_m, dtype=np.float64), 0.0, atm.atmosphere_height)


def relative_density(altitude_m: ArrayLike, scale_height_m: float) -> np.ndarray:
    """Density of an exponential layer relative to sea level, n(h) = exp(-h / H), dimensionless."""
    return np.exp(-np.maximum(np.asarray(altitude_m, dtype=np.float64), 0.0) / scale_height_m)


def atmosphere_at_altitude(atm: Atmosphere, altitude_m: float) -> Atmosphere:
    """The constant-density atmosphere at the camera: every coefficient scaled by its species' n_i(h).

    beta_R(h) = beta_R exp(-h / H_R), beta_M(h) = beta_M exp(-h / H_M) (scattering and absorption alike).
    The aerial perspective of a camera at ``altitude_m`` (m) and the dome distances of :func:`dome_distance`
    refer to this atmosphere; at h = 0 it is ``atm`` itself.
    """
    h = float(_camera_altitude(altitude_m, atm))
    if h == 0.0:
        return atm
    n_r = float(relative_density(h, atm.rayleigh_scale_height))
    n_m = float(relative_density(h, atm.mie_scale_height))
    return atm.replace(rayleigh_scattering=atm.rayleigh_scattering * n_r, mie_scattering=atm.mie_scattering * n_m,
                       mie_absorption=atm.mie_absorption * n_m)


def elevation_of(direction: ArrayLike) -> np.ndarray:
    """Elevation above the astronomical horizon of a direction (..., 3) with z up, rad in [-pi/2, pi/2]."""
    d = np.asarray(direction, dtype=np.float64)
    norm = np.linalg.norm(d, axis=-1)
    return np.arcsin(np.clip(d[..., 2] / np.where(norm > 0.0, norm, 1.0), -1.0, 1.0))


def _dome_elevation(elevation_rad: ArrayLike, altitude_m: np.ndarray, atm: Atmosphere) -> np.ndarray:
    """Elevation clamped to [geometric horizon, pi/2]: rays meeting the ground take the grazing ray's dome."""
    elevation = np.asarray(elevation_rad, dtype=np.float64)
    return np.clip(elevation, horizon_dip_rad(altitude_m, atm.planet_radius), 0.5 * np.pi)


def _dome_one_species(elevation: np.ndarray, altitude: np.ndarray, scale_height_m: float,
                      atm: Atmosphere) -> np.ndarray:
    """R_i = H Ch(x, chi) - H exp(-(h_top - h) / H) Ch(x_top, chi_top) in m (module docstring)."""
    radius = atm.planet_radius + altitude
    top = atm.planet_radius + atm.atmosphere_height
    chi = 0.5 * np.pi - elevation
    sin_chi_top = np.clip(radius * np.cos(elevation) / top, 0.0, 1.0)
    chi_top = np.arcsin(sin_chi_top)
    to_infinity = scale_height_m * chapman(radius / scale_height_m, chi)
    above_top = (scale_height_m * np.exp(-(atm.atmosphere_height - altitude) / scale_height_m)
                 * chapman(top / scale_height_m, chi_top))
    return np.maximum(to_infinity - above_top, 0.0)


def dome_distance(elevation_rad: ArrayLike, atm: Atmosphere, altitude_m: ArrayLike = 0.0
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Distances to the virtual sky dome of molecules and of aerosols, (R_rayleigh, R_mie) in m, float64.

    R_i n_i(h) equals the integrated density of species i along the real ray from the camera at ``altitude_m``
    (m, clamped to [0, top]) with elevation ``elevation_rad`` to the top of the atmosphere (module docstring;
    GDC 2002 slides, "Virtual sky dome"). Chapman function by quadrature, better than 1e-6 relative. For an
    elevated camera, rays between the geometric horizon and 0 pass their perigee and gather more matter than
    the horizontal ray; rays meeting the ground take the value of the ray grazing it. Shapes broadcast.
    """
    altitude = _camera_altitude(altitude_m, atm)
    elevation, altitude = np.broadcast_arrays(_dome_elevation(elevation_rad, altitude, atm), altitude)
    return (_dome_one_species(elevation, altitude, atm.rayleigh_scale_height, atm),
            _dome_one_species(elevation, altitude, atm.mie_scale_height, atm))


def chapman_approx(x: ArrayLike, cos_zenith: ArrayLike, dtype: DTypeLike = np.float64) -> np.ndarray:
    """Closed-form Chapman function for rays at or above the horizon, dimensionless, in ``dtype`` arithmetic.

        Ch(x, chi) ~ c / (p c mu + sqrt(((1 - p) c mu)^2 + 1)),   c = sqrt(pi x / 2),  mu = max(cos chi, 0)

    From Chapman's large-x asymptote Ch ~ c erfcx(sqrt(x / 2) mu) with the rational-root form
    erfcx(y) ~ 1 / (sqrt(pi) p y + sqrt(pi (1 - p)^2 y^2 + 1)), which is exact at y = 0 and for y -> inf
    for any p; p = :data:`CHAPMAN_APPROX_P` is fitted (p = 1/2 is the classical upper bound of erfcx, 5.8 %
    off). Maximum relative error 0.40 % for x in [300, 6400] over elevations 0..90 deg (Earth's molecules
    x = 754 and haze x = 5300, Mars x = 305). Schueler's (2012) c / ((c - 1) mu + 1) is 14-15 % off near
    2 deg for the same x. Seven Math nodes per species with c a constant.
    """
    dt = np.dtype(dtype).type
    c = np.sqrt(dt(0.5 * np.pi) * np.asarray(x, dtype=dt))
    mu = np.maximum(np.asarray(cos_zenith, dtype=dt), dt(0.0))
    c_mu = c * mu
    tail = dt(1.0 - CHAPMAN_APPROX_P) * c_mu
    return c / (dt(CHAPMAN_APPROX_P) * c_mu + np.sqrt(tail * tail + dt(1.0)))


def dome_distance_approx(elevation_rad: ArrayLike, atm: Atmosphere, altitude_m: float = 0.0,
                         dtype: DTypeLike = np.float64) -> tuple[np.ndarray, np.ndarray]:
    """Cheap dome distances (R_rayleigh, R_mie), m: R_i ~ H_i Ch_approx((R_p + h) / H_i, sin(elevation)).

    What the shader nodes evaluate (:func:`chapman_approx`, in ``dtype`` arithmetic); the matter above the top
    of the atmosphere is not removed (a relative exp(-(h_top - h) / H), 7e-6 for Earth's molecules, 1e-4 for
    Mars). The elevation is clamped at 0: below the horizon the horizontal dome is used, also for an elevated
    camera whose real rays between the geometric horizon and 0 gather more matter (:func:`dome_distance`).
    Maximum relative error against :func:`dome_distance` for a ground camera: 0.4 %.
    """
    dt = np.dtype(dtype).type
    altitude = float(_camera_altitude(altitude_m, atm))
    mu = np.sin(np.clip(np.asarray(elevation_rad, dtype=dt), dt(0.0), dt(0.5 * np.pi)))
    radius = atm.planet_radius + altitude
    return tuple(dt(h) * chapman_approx(radius / h, mu, dt)  # type: ignore[return-value]
                 for h in (atm.rayleigh_scale_height, atm.mie_scale_height))


def extinction_two_species(s_rayleigh_m: ArrayLike, s_mie_m: ArrayLike, atm: Atmosphere,
                           dtype: DTypeLike = np.float64) -> np.ndarray:
    """Transmittance of one slab, exp(-(beta_R s_R + (beta_M,sc + beta_M,abs) s_M)) per channel, shape (..., 3).

    The extinction of :func:`~atmos_addon.physics.aerial_perspective.extinction` with a path length per
    species (m, clamped at 0); equal to it when s_R = s_M.
    """
    dt = np.dtype(dtype).type
    s_r, s_m = np.broadcast_arrays(nonnegative_distance(s_rayleigh_m, dt), nonnegative_distance(s_mie_m, dt))
    return np.exp(-_optical_depth(s_r, s_m, atm, dt))


def _optical_depth(s_r: np.ndarray, s_m: np.ndarray, atm: Atmosphere, dt: type) -> np.ndarray:
    """tau = beta_R s_R + (beta_M,sc + beta_M,abs) s_M per channel, (..., 3)."""
    return (atm.rayleigh_scattering.astype(dt) * s_r[..., np.newaxis]
            + atm.mie_extinction.astype(dt) * s_m[..., np.newaxis])


def inscattering_two_species(s_rayleigh_m: ArrayLike, s_mie_m: ArrayLike, cos_theta: ArrayLike, atm: Atmosphere,
                             sun_irradiance: ArrayLike, dtype: DTypeLike = np.float64) -> np.ndarray:
    """In-scattered radiance of one slab with a path length per species (an even mixture), shape (..., 3):

        L_2sp = (beta_R Phi_R(mu) s_R + beta_M,sc Phi_HG(mu, g) s_M) E_sun phi1(beta_R s_R + beta_M,ex s_M)

    Exact when the species are mixed in fixed proportion along the slab, and for one species alone (s_R or s_M
    0): the building block of :func:`inscattering_layered`, which is what the sky and the aerial perspective use.
    Eq. 19 of Hoffman & Preetham 2002 (:func:`~atmos_addon.physics.aerial_perspective.inscattering`) when
    s_R = s_M. ``s_rayleigh_m``, ``s_mie_m`` (m) and ``cos_theta`` (view direction . sun direction) broadcast
    together; ``sun_irradiance`` is per channel, (3,) or (..., 3). Stable as tau -> 0 (phi1's series).
    """
    dt = np.dtype(dtype).type
    s_r, s_m, mu = np.broadcast_arrays(nonnegative_distance(s_rayleigh_m, dt), nonnegative_distance(s_mie_m, dt),
                                       clamp_cosine(cos_theta, dt))
    scattered = (atm.rayleigh_scattering.astype(dt) * (phase_rayleigh(mu, dt) * s_r)[..., np.newaxis]
                 + atm.mie_scattering.astype(dt) * phase_hg(mu, atm.mie_g, dt) * s_m[..., np.newaxis])
    e_sun = np.maximum(np.asarray(sun_irradiance, dtype=dt), dt(0.0))
    return scattered * e_sun * one_minus_exp_over_x(_optical_depth(s_r, s_m, atm, dt), dt)


def _layered_segments(s_r: np.ndarray, s_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(a, t_R, t_M): the shared segment a = min(b_R, b_M) and the tails b_i - a (one of them 0), same dtype."""
    a = np.minimum(s_r, s_m)
    return a, s_r - a, s_m - a


def _layered(seg_r: np.ndarray, seg_m: np.ndarray, tail_r: np.ndarray, tail_m: np.ndarray, mu: np.ndarray,
             atm: Atmosphere, sun_irradiance: ArrayLike, dt: type) -> tuple[np.ndarray, np.ndarray]:
    """(L_in, F_ex) of the layered dome from the segment's and the tails' lengths per species (module docstring).

    ``seg_r``, ``seg_m`` are the shared segment's lengths in ``atm``'s coefficients (equal in real metres; they
    differ only as sea-level-equivalent lengths of an elevated camera, see :func:`sky_radiance`).
    """
    near = inscattering_two_species(seg_r, seg_m, mu, atm, sun_irradiance, dt)
    far = inscattering_two_species(tail_r, tail_m, mu, atm, sun_irradiance, dt)
    t_near = extinction_two_species(seg_r, seg_m, atm, dt)
    return near + t_near * far, t_near * extinction_two_species(tail_r, tail_m, atm, dt)


def inscattering_layered(s_rayleigh_m: ArrayLike, s_mie_m: ArrayLike, cos_theta: ArrayLike, atm: Atmosphere,
                         sun_irradiance: ArrayLike, dtype: DTypeLike = np.float64) -> np.ndarray:
    """In-scattered radiance of the layered dome, shape (..., 3) (module docstring):

        L_in = L_2sp(a, a) + T_2sp(a, a) L_2sp(b_R - a, b_M - a),   a = min(b_R, b_M)

    ``s_rayleigh_m``, ``s_mie_m`` are the per-species lengths b_i = min(s, R_i) of
    :func:`aerial_distance_clamped` (m, clamped at 0; s -> infinity gives the sky), ``cos_theta`` the view
    direction . sun direction; all broadcast together. ``sun_irradiance`` is per channel, (3,) or (..., 3).
    Non-decreasing in s for fixed domes; equal to the core's ``inscattering`` (eq. 19) when b_R = b_M = s.
    """
    dt = np.dtype(dtype).type
    s_r, s_m, mu = np.broadcast_arrays(nonnegative_distance(s_rayleigh_m, dt), nonnegative_distance(s_mie_m, dt),
                                       clamp_cosine(cos_theta, dt))
    a, tail_r, tail_m = _layered_segments(s_r, s_m)
    return _layered(a, a, tail_r, tail_m, mu, atm, sun_irradiance, dt)[0]


def extinction_layered(s_rayleigh_m: ArrayLike, s_mie_m: ArrayLike, atm: Atmosphere,
                       dtype: DTypeLike = np.float64) -> np.ndarray:
    """Transmittance of the layered dome, T_2sp(a, a) T_2sp(b_R - a, b_M - a), per channel, shape (..., 3).

    The product of the two segments' transmittances (as the shader nodes form it); mathematically
    exp(-(beta_R b_R + beta_M,ex b_M)), :func:`extinction_two_species` of the same lengths.
    """
    dt = np.dtype(dtype).type
    s_r, s_m = np.broadcast_arrays(nonnegative_distance(s_rayleigh_m, dt), nonnegative_distance(s_mie_m, dt))
    a, tail_r, tail_m = _layered_segments(s_r, s_m)
    return extinction_two_species(a, a, atm, dt) * extinction_two_species(tail_r, tail_m, atm, dt)


def aerial_distance_clamped(distance_m: ArrayLike, elevation_rad: ArrayLike, atm: Atmosphere,
                            altitude_m: float = 0.0, dome: DomeFunction = dome_distance
                            ) -> tuple[np.ndarray, np.ndarray]:
    """Per-species aerial-perspective lengths (min(s, R_R), min(s, R_M)), m: the "seamless horizon".

    A surface at ``distance_m`` along a ray of elevation ``elevation_rad`` gets the aerial perspective of
    :func:`inscattering_layered` / :func:`extinction_layered` with these lengths in
    :func:`atmosphere_at_altitude` (``atm``, ``altitude_m``): a black surface's in-scattering grows with its
    distance and never passes the sky behind it, which it reaches exactly beyond both domes.
    """
    s = nonnegative_distance(distance_m)
    r_rayleigh, r_mie = dome(elevation_rad, atm, altitude_m)
    return np.minimum(s, r_rayleigh), np.minimum(s, r_mie)


def ground_radiance(sun_dir: ArrayLike, sun_irradiance: ArrayLike, ground_albedo: ArrayLike) -> np.ndarray:
    """Radiance of a flat Lambertian ground lit by the sun alone, albedo E_sun max(sin(sun elevation), 0) / pi."""
    sun_sin = np.sin(elevation_of(sun_dir))
    return (np.asarray(ground_albedo, dtype=np.float64) * np.asarray(sun_irradiance, dtype=np.float64)
            * np.maximum(sun_sin, 0.0)[..., np.newaxis] / np.pi)


def _unit_vectors(vectors: ArrayLike, name: str) -> np.ndarray:
    """Directions (..., 3) normalised, float64; zero vectors are an error."""
    v = np.asarray(vectors, dtype=np.float64)
    if v.shape[-1:] != (3,):
        raise ValueError(f"{name} must have 3 components (x, y, z) on its last axis; got shape {v.shape}")
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    if np.any(~(norm > 0.0)):
        raise ValueError(f"{name} must be non-zero directions")
    return v / norm


def sky_radiance(view_dir: ArrayLike, sun_dir: ArrayLike, atm: Atmosphere, sun_irradiance: ArrayLike,
                 altitude_m: float = 0.0, dome: DomeFunction = dome_distance, ground_albedo: ArrayLike = 0.0,
                 dtype: DTypeLike = np.float64) -> np.ndarray:
    """Sky radiance in the directions ``view_dir`` (..., 3), z up: single scattering out to the dome, (..., 3).

        L_sky = L_in(R_R, R_M, mu)                                        above the geometric horizon
        L_sky = L_ground exp(-tau(R_R, R_M)) + L_in(R_R, R_M, mu)         below it (rays meeting the ground)

    with L_in and tau of the layered dome (:func:`inscattering_layered`, the lengths b_i = R_i: s -> infinity)
    in :func:`atmosphere_at_altitude`, (R_R, R_M) from ``dome``
    (:func:`dome_distance` or :func:`dome_distance_approx`) at the view elevation, mu = view . sun.
    Below the horizon the dome is the horizon's, so the ground counts as distant: the world background's ground
    is what lies beyond the scene's own geometry, and the horizon stays seamless. L_ground is
    :func:`ground_radiance` (direct sun only; the default albedo 0 leaves the horizon's haze). ``sun_irradiance``
    is E_sun at the ground per channel (:func:`~atmos_addon.physics.sun.sun_irradiance_ground`), (3,) or
    (..., 3). The domes are evaluated in float64; the scattering in ``dtype``.
    """
    dt = np.dtype(dtype).type
    view = _unit_vectors(view_dir, "view_dir")
    sun = _unit_vectors(sun_dir, "sun_dir")
    altitude = float(_camera_altitude(altitude_m, atm))
    elevation = elevation_of(view)
    r_rayleigh, r_mie = dome(elevation, atm, altitude)
    # The layered segments in real metres (a = min(R_R, R_M), tails R_i - a), then as sea-level-equivalent
    # lengths x n_i(h) with the sea-level coefficients: the same optical depths as in the camera's atmosphere,
    # bounded for any camera height.
    r_rayleigh, r_mie = np.broadcast_arrays(np.asarray(r_rayleigh, dtype=np.float64),
                                            np.asarray(r_mie, dtype=np.float64))
    a, tail_r, tail_m = _layered_segments(r_rayleigh, r_mie)
    n_r = relative_density(altitude, atm.rayleigh_scale_height)
    n_m = relative_density(altitude, atm.mie_scale_height)
    mu = clamp_cosine(np.sum(view * sun, axis=-1), dt)
    radiance, transmittance = _layered(*(np.asarray(x, dtype=dt) for x in (a * n_r, a * n_m, tail_r * n_r,
                                                                          tail_m * n_m)), mu, atm, sun_irradiance, dt)
    if np.any(np.asarray(ground_albedo) != 0.0):
        below = (elevation < horizon_dip_rad(altitude, atm.planet_radius))[..., np.newaxis]
        ground = ground_radiance(sun, sun_irradiance, ground_albedo).astype(dt)
        radiance = radiance + np.where(below, ground * transmittance, dt(0.0))
    return radiance.astype(dt)


def sun_disk_solid_angle(angular_radius_rad: float = SUN_ANGULAR_RADIUS_RAD) -> float:
    """Solid angle of a disk of angular radius r, Omega = 2 pi (1 - cos r) = 4 pi sin^2(r / 2), sr."""
    return float(4.0 * np.pi * np.sin(0.5 * angular_radius_rad) ** 2)


def limb_darkening_factor(offset_rad: ArrayLike, angular_radius_rad: float = SUN_ANGULAR_RADIUS_RAD,
                          limb_darkening: float = SUN_LIMB_DARKENING) -> np.ndarray:
    """Radiance across the disk relative to its mean, I(offset) / <I>, dimensionless (0 outside the disk).

    Linear law I(mu) / I(1) = 1 - u (1 - mu), mu = cos of the emission angle on the sun's sphere, with
    mu = sqrt(1 - (sin t / sin r)^2) at angular offset t from the disk centre. <I> is the solid-angle mean,
    Omega^-1 2 pi integral_0^r I sin t dt (Gauss-Legendre in mu; 1 - u / 3 in the flat-disk limit), so
    the disk's irradiance is unchanged by the darkening.
    """
    u = float(limb_darkening)
    if not 0.0 <= u <= 1.0:
        raise ValueError(f"limb_darkening must lie in [0, 1]; got {limb_darkening!r}")
    sin_r = np.sin(angular_radius_rad)
    # sin t dt = sin^2 r mu dmu / sqrt(1 - (1 - mu^2) sin^2 r): smooth in mu on [0, 1].
    mu_nodes = 0.5 * (_LIMB_NODES + 1.0)
    weight = 0.5 * _LIMB_WEIGHTS * sin_r ** 2 * mu_nodes / np.sqrt(1.0 - (1.0 - mu_nodes ** 2) * sin_r ** 2)
    mean = 2.0 * np.pi * np.sum(weight * (1.0 - u * (1.0 - mu_nodes))) / sun_disk_solid_angle(angular_radius_rad)
    t = np.abs(np.asarray(offset_rad, dtype=np.float64))
    rho = np.sin(np.minimum(t, 0.5 * np.pi)) / sin_r
    mu = np.sqrt(np.maximum(1.0 - rho * rho, 0.0))
    return np.where(t <= angular_radius_rad, (1.0 - u * (1.0 - mu)) / mean, 0.0)


def sun_disk_radiance(atm: Atmosphere, elevation_rad: ArrayLike,
                      angular_radius_rad: float = SUN_ANGULAR_RADIUS_RAD, altitude_m: float = 0.0,
                      offset_rad: ArrayLike | None = None, limb_darkening: float = SUN_LIMB_DARKENING
                      ) -> np.ndarray:
    """Radiance of the sun's disk seen through the atmosphere, per channel, (..., 3), units of E_sun per sr.

    Without ``offset_rad``: the disk's mean radiance L = E_sun / Omega, Omega = 2 pi (1 - cos r), so that
    radiance x solid angle = the line-of-sight irradiance E_sun of
    :func:`~atmos_addon.physics.sun.sun_irradiance_ground` (which already averages the extinction over the
    disk and counts only its part above the horizon: a setting sun's mean radiance falls with it). With
    ``offset_rad`` (angle from the disk centre, broadcast with ``elevation_rad``): that mean times
    :func:`limb_darkening_factor` (linear law, coefficient ``limb_darkening``; 0 gives a uniform disk), whose
    integral over the disk is again E_sun; 0 outside the disk.
    """
    radius = float(angular_radius_rad)
    e_sun = sun_irradiance_ground(elevation_rad, atm, altitude_m, radius, limb_darkening)
    mean = e_sun / sun_disk_solid_angle(radius)
    if offset_rad is None:
        return mean
    return mean * limb_darkening_factor(offset_rad, radius, limb_darkening)[..., np.newaxis]
