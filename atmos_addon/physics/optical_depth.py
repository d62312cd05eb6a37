# SPDX-License-Identifier: GPL-3.0-or-later
"""Optical depth along slant paths through exponential layers over a spherical planet: the Chapman function.

A layer of density n(h) = n0 exp(-h / H) seen from radius r = R + h0 along a ray with zenith angle chi
has optical depth to space tau = beta0 H exp(-h0 / H) Ch(x, chi), x = r / H, where the Chapman
grazing-incidence function (Chapman 1931; Huestis 2001, J. Quant. Spectrosc. Radiat. Transfer 69, 709)

    Ch(x, chi) = integral_0^inf exp(x - sqrt(x^2 + s^2 + 2 x s cos chi)) ds        (s in units of H)

is the slant column relative to the vertical one (Ch(x, 0) = 1, Ch(x, 90 deg) ~ sqrt(pi x / 2)).
For chi <= 90 deg the integrand falls monotonically; the integral is cut where the ray has climbed
:data:`CHAPMAN_CUTOFF_SCALE_HEIGHTS` scale heights (relative error e^-40) and evaluated by Gauss-Legendre
quadrature in s. The cut point has the closed form s_max = sqrt(x^2 cos^2 chi + 2 x L + L^2) - x cos chi.
Beyond 90 deg the ray passes its perigee p = x sin chi, and (Huestis 2001, eq. 5)

    Ch(x, chi) = 2 exp(x - p) Ch(p, 90 deg) - Ch(x, 180 deg - chi).

Accuracy: better than 1e-6 relative for x >= 30 (every planet and layer of interest has x > 100).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .atmosphere import Atmosphere
from .spectrum import DEFAULT_OZONE_HALF_WIDTH_M, DEFAULT_OZONE_PEAK_ALTITUDE_M

#: Altitude gain, in scale heights, at which the Chapman integral is truncated (neglects e^-40).
CHAPMAN_CUTOFF_SCALE_HEIGHTS = 40.0
#: Gauss-Legendre nodes of the Chapman quadrature.
CHAPMAN_QUADRATURE_NODES = 64

_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(CHAPMAN_QUADRATURE_NODES)
_UNIT_NODES = 0.5 * (_GL_NODES + 1.0)
_UNIT_WEIGHTS = 0.5 * _GL_WEIGHTS


def _chapman_rising(x: np.ndarray, cos_chi: np.ndarray) -> np.ndarray:
    """Ch(x, chi) for a ray that never descends (0 <= cos chi <= 1), by Gauss-Legendre quadrature in s."""
    cut = CHAPMAN_CUTOFF_SCALE_HEIGHTS
    c = x * cos_chi
    s_max = (2.0 * x * cut + cut * cut) / (c + np.sqrt(c * c + 2.0 * x * cut + cut * cut))
    s = s_max[..., np.newaxis] * _UNIT_NODES
    xs, cs = x[..., np.newaxis], cos_chi[..., np.newaxis]
    rise = (s * s + 2.0 * xs * s * cs) / (np.sqrt(xs * xs + s * s + 2.0 * xs * s * cs) + xs)
    return s_max * np.sum(_UNIT_WEIGHTS * np.exp(-rise), axis=-1)


def chapman(x: ArrayLike, zenith_rad: ArrayLike) -> np.ndarray:
    """Chapman grazing-incidence function Ch(x, chi), dimensionless (Chapman 1931; Huestis 2001).

    ``x`` = (R + h) / H (radius of the start point in scale heights, > 0), ``zenith_rad`` = chi in
    [0, pi]; they broadcast together. The function ignores the planet: beyond the horizon it follows
    the ray through the perigee (see :func:`optical_depth_to_space` for the solid ground). Rays far
    below the horizon meet densities up to exp(x) times the start's and overflow to ``inf``.
    """
    x, chi = np.broadcast_arrays(np.asarray(x, dtype=np.float64), np.asarray(zenith_rad, dtype=np.float64))
    if np.any(~(x > 0.0)):
        raise ValueError("chapman: x = (R + h) / H must be > 0")
    cos_chi = np.clip(np.cos(chi), -1.0, 1.0)
    sin_chi = np.sqrt(np.maximum(1.0 - cos_chi * cos_chi, 0.0))
    rising = _chapman_rising(x, np.abs(cos_chi))
    descending = cos_chi < 0.0
    if not np.any(descending):
        return rising
    perigee = x * sin_chi
    # x - p = x (1 - sin chi) = x cos^2 chi / (1 + sin chi), free of cancellation near the horizon.
    density_gain = x * cos_chi * cos_chi / (1.0 + sin_chi)
    with np.errstate(over="ignore"):
        through_perigee = 2.0 * np.exp(density_gain) * _chapman_rising(np.maximum(perigee, 1e-300),
                                                                      np.zeros_like(perigee)) - rising
    return np.where(descending, through_perigee, rising)


def ray_hits_planet(altitude_m: ArrayLike, zenith_rad: ArrayLike, planet_radius_m: float) -> np.ndarray:
    """True where a ray from ``altitude_m`` with zenith angle ``zenith_rad`` meets the solid planet.

    It does when it descends (cos chi < 0) and its perigee radius (R + h) sin chi lies below R.
    A ray exactly tangent to the ground does not (its optical depth is finite).
    """
    altitude, chi = np.broadcast_arrays(np.asarray(altitude_m, dtype=np.float64),
                                        np.asarray(zenith_rad, dtype=np.float64))
    radius = planet_radius_m + np.maximum(altitude, 0.0)
    return (np.cos(chi) < 0.0) & (radius * np.sin(chi) < planet_radius_m)


def layer_optical_depth(altitude_m: ArrayLike, zenith_rad: ArrayLike, beta_sea_per_m: ArrayLike,
                        scale_height_m: float, planet_radius_m: float) -> np.ndarray:
    """Optical depth to space of one exponential layer, tau = beta0 H exp(-h / H) Ch((R + h) / H, chi).

    ``beta_sea_per_m`` is the sea-level coefficient per channel (3,), 1/m; result (..., 3), ignoring
    the solid planet (see :func:`optical_depth_to_space`).
    """
    altitude = np.maximum(np.asarray(altitude_m, dtype=np.float64), 0.0)
    column = scale_height_m * np.exp(-altitude / scale_height_m)
    slant = chapman((planet_radius_m + altitude) / scale_height_m, zenith_rad)
    with np.errstate(invalid="ignore"):
        return np.asarray(beta_sea_per_m, dtype=np.float64) * (column * slant)[..., np.newaxis]


def optical_depth_to_space(altitude_m: ArrayLike, zenith_rad: ArrayLike, atm: Atmosphere) -> np.ndarray:
    """Optical depth from a point to the top of the atmosphere per channel, dimensionless, shape (..., 3).

    tau = beta_R H_R exp(-h / H_R) Ch((R + h) / H_R, chi)
        + (beta_M,sc + beta_M,abs) H_M exp(-h / H_M) Ch((R + h) / H_M, chi)

    + beta_O3 * (slant column of the ozone's tent, :func:`ozone_slant_column`)

    (Chapman 1931; Hoffman & Preetham 2002, "Applying the Theory - Sunlight"). ``altitude_m`` (m,
    clamped at 0) and ``zenith_rad`` broadcast together. Rays that meet the ground never reach space:
    their optical depth is ``inf`` (transmittance exp(-tau) = 0), also in vacuum. The layers extend to
    infinity; cutting them at ``atm.atmosphere_height`` changes tau by less than exp(-top / H).
    """
    altitude, chi = np.broadcast_arrays(np.maximum(np.asarray(altitude_m, dtype=np.float64), 0.0),
                                        np.asarray(zenith_rad, dtype=np.float64))
    hits = ray_hits_planet(altitude, chi, atm.planet_radius)
    chi_missing = np.where(hits, 0.5 * np.pi, chi)
    tau = (layer_optical_depth(altitude, chi_missing, atm.rayleigh_scattering, atm.rayleigh_scale_height,
                               atm.planet_radius)
           + layer_optical_depth(altitude, chi_missing, atm.mie_extinction, atm.mie_scale_height,
                                 atm.planet_radius))
    if atm.ozone_column_du > 0.0:
        tau = tau + atm.ozone_absorption * ozone_slant_column(altitude, np.cos(chi_missing), atm)[..., np.newaxis]
    return np.where(hits[..., np.newaxis], np.inf, tau)


#: Gauss-Legendre nodes per piece of the ozone slant column (the tent is linear in altitude between its kinks).
OZONE_QUADRATURE_NODES = 8
_OZ_NODES, _OZ_WEIGHTS = np.polynomial.legendre.leggauss(OZONE_QUADRATURE_NODES)


def ozone_slant_column(altitude_m: ArrayLike, cos_zenith: ArrayLike, atm: Atmosphere) -> np.ndarray:
    """Integral of the ozone's relative density (:meth:`Atmosphere.ozone_density`) along a ray to the top of the
    atmosphere, m; times :attr:`Atmosphere.ozone_absorption` it is the ozone's optical depth. Straight up from the
    ground it is the tent's vertical integral, 15 km.

    The ray r(s)^2 = r0^2 + 2 r0 mu s + s^2 is cut where it crosses the radii of the tent's kinks (R + 10, 25 and
    40 km, both roots) and at its perigee s = -r0 mu; on each piece the density is a smooth function of s and
    :data:`OZONE_QUADRATURE_NODES` Gauss-Legendre nodes integrate it. The solid planet is ignored (the callers mask
    the rays that meet it); ``altitude_m`` is clamped at 0 and may lie above the top (0 upward).
    """
    altitude, mu = np.broadcast_arrays(np.maximum(np.asarray(altitude_m, dtype=np.float64), 0.0),
                                       np.clip(np.asarray(cos_zenith, dtype=np.float64), -1.0, 1.0))
    r0 = atm.planet_radius + altitude
    r_top = atm.planet_radius + max(atm.atmosphere_height, float(np.max(altitude, initial=0.0)))
    b = r0 * mu
    c0 = r0 * r0 * (mu * mu - 1.0)                                   # r(s)^2 = (s + b)^2 - c0
    s_top = -b + np.sqrt(np.maximum(b * b - r0 * r0 + r_top * r_top, 0.0))
    cuts = [np.zeros_like(r0), s_top, -b]
    for kink_m in (DEFAULT_OZONE_PEAK_ALTITUDE_M - DEFAULT_OZONE_HALF_WIDTH_M, DEFAULT_OZONE_PEAK_ALTITUDE_M,
                   DEFAULT_OZONE_PEAK_ALTITUDE_M + DEFAULT_OZONE_HALF_WIDTH_M):
        r_k = atm.planet_radius + kink_m
        disc = r_k * r_k + c0                                     # r(s) = r_k at s = -b +- sqrt(disc)
        root = np.sqrt(np.maximum(disc, 0.0))
        for s in (-b - root, -b + root):
            cuts.append(np.where(disc > 0.0, s, 0.0))
    edges = np.sort(np.clip(np.stack(cuts, axis=-1), 0.0, s_top[..., None]), axis=-1)     # (..., 9)
    lo, width = edges[..., :-1], np.diff(edges, axis=-1)                                   # (..., 8)
    s = lo[..., None] + width[..., None] * 0.5 * (_OZ_NODES + 1.0)                          # (..., 8, n)
    radius = np.sqrt(np.maximum(r0[..., None, None] ** 2 + 2.0 * b[..., None, None] * s + s * s, 0.0))
    density = Atmosphere.ozone_density(radius - atm.planet_radius)
    return np.sum(0.5 * width * np.sum(_OZ_WEIGHTS * density, axis=-1), axis=-1)


def relative_air_mass(zenith_rad: ArrayLike, atm: Atmosphere) -> np.ndarray:
    """Relative optical air mass of the Rayleigh layer seen from the ground, tau(chi) / tau(0), dimensionless.

    Equal to Ch(R / H_R, chi) (1 at the zenith, about 34 at the horizon for Earth). Without refraction,
    so about 9 % below Kasten & Young 1989 at the horizon and within 1 % of it up to 80 deg. ``inf``
    below the horizon.
    """
    x = atm.planet_radius / atm.rayleigh_scale_height
    chi = np.asarray(zenith_rad, dtype=np.float64)
    hits = ray_hits_planet(0.0, chi, atm.planet_radius)
    ratio = chapman(x, np.where(hits, 0.5 * np.pi, chi)) / chapman(x, 0.0)
    return np.where(hits, np.inf, ratio)
