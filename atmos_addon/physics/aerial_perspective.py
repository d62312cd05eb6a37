# SPDX-License-Identifier: GPL-3.0-or-later
"""Aerial perspective in a homogeneous atmosphere: the closed form of Hoffman & Preetham 2002, eq. 19.

For a camera and a target low in the atmosphere the densities are taken constant (their sea-level
values) and the sun's irradiance E_sun constant along the ray. Eq. 15 then integrates to

    L(s, theta) = L0 F_ex(s) + L_in(s, theta)                                         (eq. 16, 19)
    F_ex(s)        = exp(-beta_ex s)
    L_in(s, theta) = (beta_R Phi_R(mu) + beta_M Phi_HG(mu, g)) E_sun (1 - exp(-beta_ex s)) / beta_ex
                   = (beta_R Phi_R(mu) + beta_M Phi_HG(mu, g)) E_sun s phi1(beta_ex s)

with s the distance in m, mu = cos(theta) the cosine of the angle between the view ray (camera to
target) and the direction to the sun, phi1(x) = (1 - exp(-x)) / x, and beta_ex = beta_R + beta_M,sc +
beta_M,abs. The paper has beta_ex = beta_R + beta_M; aerosol absorption is added here to the
extinction but not to the in-scattering. Radiance units are those of E_sun per steradian.

These functions describe what Blender's shader nodes compute, in float32 when asked: every step is
cast to ``dtype`` before it is taken, and phi1 uses the same branch and series as the node tree.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

from .atmosphere import Atmosphere
from .phase import clamp_cosine, phase_hg, phase_rayleigh

#: Optical depth below which phi1(x) = (1 - exp(-x)) / x is evaluated by its Taylor series.
SMALL_OPTICAL_DEPTH = 1.0e-3


def one_minus_exp_over_x(x: ArrayLike, dtype: DTypeLike = np.float64) -> np.ndarray:
    """phi1(x) = (1 - exp(-x)) / x for optical depth x >= 0, dimensionless, in ``dtype`` arithmetic.

    For x < :data:`SMALL_OPTICAL_DEPTH` the series 1 - x/2 + x^2/6 (truncation error x^3/24 < 5e-11)
    replaces the quotient, whose numerator cancels catastrophically as x -> 0 and is 0/0 at x = 0.
    phi1 decreases from 1 at x = 0 to 1/x for large x. Negative x is clamped to 0.
    """
    dt = np.dtype(dtype).type
    x = np.maximum(np.asarray(x, dtype=dt), dt(0.0))
    series = dt(1.0) - x * dt(0.5) + x * x * dt(1.0 / 6.0)
    x_large = np.maximum(x, dt(SMALL_OPTICAL_DEPTH))
    quotient = (dt(1.0) - np.exp(-x_large)) / x_large
    return np.where(x < dt(SMALL_OPTICAL_DEPTH), series, quotient).astype(dt)


def nonnegative_distance(distance_m: ArrayLike, dtype: DTypeLike = np.float64) -> np.ndarray:
    """A distance along the ray in m as an array of ``dtype``, clamped at 0 (no light travels backwards)."""
    dt = np.dtype(dtype).type
    return np.maximum(np.asarray(distance_m, dtype=dt), dt(0.0))


def extinction(distance_m: ArrayLike, atm: Atmosphere, dtype: DTypeLike = np.float64) -> np.ndarray:
    """Transmittance F_ex = exp(-beta_ex s) over ``distance_m`` (Hoffman & Preetham 2002, eq. 19).

    Dimensionless, in [0, 1], shape (..., 3) for ``distance_m`` of shape (...).
    """
    dt = np.dtype(dtype).type
    s = nonnegative_distance(distance_m, dt)[..., np.newaxis]
    return np.exp(-(atm.extinction_coefficient.astype(dt) * s))


def inscattering(distance_m: ArrayLike, cos_theta: ArrayLike, atm: Atmosphere, sun_irradiance: ArrayLike,
                 dtype: DTypeLike = np.float64) -> np.ndarray:
    """Single-scattered sunlight added along the ray, L_in (Hoffman & Preetham 2002, eq. 19).

    L_in = (beta_R Phi_R(mu) + beta_M,sc Phi_HG(mu, g)) E_sun s phi1(beta_ex s), radiance in the units of
    ``sun_irradiance`` per steradian (W/(m^2 sr) for E_sun in W/m^2). ``distance_m`` (m) and
    ``cos_theta`` broadcast together to (...); ``sun_irradiance`` is per channel, (3,) or (..., 3); the
    result has shape (..., 3) and is never negative.
    """
    dt = np.dtype(dtype).type
    s = nonnegative_distance(distance_m, dt)
    mu = clamp_cosine(cos_theta, dt)
    s, mu = np.broadcast_arrays(s, mu)
    s = s[..., np.newaxis]
    beta_r = atm.rayleigh_scattering.astype(dt)
    beta_m = atm.mie_scattering.astype(dt)
    beta_ex = atm.extinction_coefficient.astype(dt)
    angular = beta_r * phase_rayleigh(mu, dt)[..., np.newaxis] + beta_m * phase_hg(mu, atm.mie_g, dt)
    e_sun = np.maximum(np.asarray(sun_irradiance, dtype=dt), dt(0.0))
    return angular * e_sun * (s * one_minus_exp_over_x(beta_ex * s, dt))


def aerial_perspective(l0: ArrayLike, distance_m: ArrayLike, cos_theta: ArrayLike, atm: Atmosphere,
                       sun_irradiance: ArrayLike, dtype: DTypeLike = np.float64) -> np.ndarray:
    """Radiance reaching the camera, L = L0 F_ex(s) + L_in(s, theta) (Hoffman & Preetham 2002, eq. 16 and 19).

    ``l0`` is the radiance leaving the target toward the camera, per channel ((3,) or (..., 3)), in the
    units of ``sun_irradiance`` per steradian. Shape (..., 3).
    """
    dt = np.dtype(dtype).type
    l0 = np.asarray(l0, dtype=dt)
    return l0 * extinction(distance_m, atm, dt) + inscattering(distance_m, cos_theta, atm, sun_irradiance, dt)
