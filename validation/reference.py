# SPDX-License-Identifier: GPL-3.0-or-later
"""Brute-force yardsticks: numerical integration of eq. 15 of Hoffman & Preetham 2002 (single scattering).

Nothing here shares code with the closed forms it checks (no Chapman function, no phi1): optical depths
are Simpson sums of the layer densities along straight rays over a spherical planet, so agreement with
:mod:`~atmos_addon.physics.optical_depth` and :mod:`~atmos_addon.physics.aerial_perspective` is evidence,
not tautology. Geometry: z up, the camera at (0, 0, h), the planet's centre at (0, 0, -R); the atmosphere
ends at radius R + ``atm.atmosphere_height``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from atmos_addon.physics.atmosphere import Atmosphere
from atmos_addon.physics.phase import phase_hg, phase_rayleigh


def _simpson(values: np.ndarray, step: ArrayLike, axis: int = -1) -> np.ndarray:
    """Composite Simpson sum of equally spaced samples along ``axis`` (odd sample count)."""
    values = np.moveaxis(values, axis, -1)
    if values.shape[-1] % 2 == 0 or values.shape[-1] < 3:
        raise ValueError("Simpson's rule needs an odd number (>= 3) of samples")
    total = values[..., 0] + values[..., -1] + 4.0 * values[..., 1:-1:2].sum(-1) + 2.0 * values[..., 2:-1:2].sum(-1)
    return np.asarray(step) / 3.0 * total


def _odd(n: int, name: str) -> int:
    """A sample count, checked odd and >= 3 (Simpson's rule)."""
    if int(n) != n or n < 3 or n % 2 == 0:
        raise ValueError(f"{name} must be an odd integer >= 3; got {n!r}")
    return int(n)


def _unit(vector: ArrayLike, name: str) -> np.ndarray:
    """A direction as a unit 3-vector."""
    v = np.asarray(vector, dtype=np.float64)
    norm = np.linalg.norm(v)
    if v.shape != (3,) or not norm > 0.0:
        raise ValueError(f"{name} must be a non-zero 3-vector; got {vector!r}")
    return v / norm


def _layer_extinction(altitude_m: np.ndarray, atm: Atmosphere) -> np.ndarray:
    """Local extinction coefficient beta_R exp(-h/H_R) + beta_M,ex exp(-h/H_M) (+ the ozone's absorption in its
    layer), 1/m, shape (..., 3)."""
    rayleigh = np.exp(-altitude_m / atm.rayleigh_scale_height)[..., np.newaxis]
    mie = np.exp(-altitude_m / atm.mie_scale_height)[..., np.newaxis]
    extinction = atm.rayleigh_scattering * rayleigh + atm.mie_extinction * mie
    return extinction + atm.ozone_absorption_at(altitude_m) if atm.ozone_column_du > 0.0 else extinction


def distance_to_top(radius_m: np.ndarray, cos_zenith: np.ndarray, atm: Atmosphere) -> np.ndarray:
    """Distance along a ray from radius r with local zenith cosine mu to the top sphere, m (0 if outside)."""
    top = atm.planet_radius + atm.atmosphere_height
    discriminant = np.maximum(radius_m ** 2 * (cos_zenith ** 2 - 1.0) + top ** 2, 0.0)
    return np.maximum(-radius_m * cos_zenith + np.sqrt(discriminant), 0.0)


def _hits_planet(radius_m: np.ndarray, cos_zenith: np.ndarray, atm: Atmosphere) -> np.ndarray:
    """True where a ray descends and its perigee lies inside the planet."""
    return (cos_zenith < 0.0) & (radius_m ** 2 * (1.0 - cos_zenith ** 2) < atm.planet_radius ** 2)


def _optical_depth_segment(radius_m: np.ndarray, cos_zenith: np.ndarray, start_m: np.ndarray, end_m: np.ndarray,
                           atm: Atmosphere, n_steps: int) -> np.ndarray:
    """Simpson optical depth of the ray segment [start, end] (m along the ray), shape (..., 3)."""
    t = start_m[..., np.newaxis] + (end_m - start_m)[..., np.newaxis] * np.linspace(0.0, 1.0, n_steps)
    r0, mu0 = radius_m[..., np.newaxis], cos_zenith[..., np.newaxis]
    altitude = np.sqrt(np.maximum(r0 * r0 + t * t + 2.0 * r0 * t * mu0, 0.0)) - atm.planet_radius
    beta = _layer_extinction(altitude, atm)
    return _simpson(beta, ((end_m - start_m) / (n_steps - 1))[..., np.newaxis], axis=-2)


def optical_depth_numerical(altitude_m: float, zenith_rad: float, atm: Atmosphere, n_steps: int = 20001
                            ) -> np.ndarray:
    """Optical depth from ``altitude_m`` to the top of the atmosphere along zenith angle ``zenith_rad``, (3,).

    Simpson's rule on ``n_steps`` equally spaced samples of the local extinction coefficient, split at the
    perigee for descending rays; ``inf`` where the ray meets the planet.
    """
    n = _odd(n_steps, "n_steps")
    radius = np.asarray(atm.planet_radius + float(altitude_m))
    mu = np.asarray(np.cos(float(zenith_rad)))
    if _hits_planet(radius, mu, atm):
        return np.full(3, np.inf)
    end = distance_to_top(radius, mu, atm)
    perigee = np.clip(-radius * mu, 0.0, end)
    zero = np.zeros_like(end)
    return (_optical_depth_segment(radius, mu, zero, perigee, atm, n)
            + _optical_depth_segment(radius, mu, perigee, end, atm, n))


def sun_transmittance_numerical(points_m: np.ndarray, sun_dir: np.ndarray, atm: Atmosphere, n_steps: int
                                ) -> np.ndarray:
    """Transmittance toward the sun from each point (..., 3 coordinates), shape (..., 3 channels).

    Zero in the planet's shadow (the ray to the sun meets the ground); otherwise exp of the Simpson
    optical depth to the top of the atmosphere, split at the perigee.
    """
    centre = np.array([0.0, 0.0, -atm.planet_radius])
    offset = points_m - centre
    radius = np.linalg.norm(offset, axis=-1)
    mu = np.einsum("...i,i->...", offset, sun_dir) / radius
    shadow = _hits_planet(radius, mu, atm)
    end = np.where(shadow, 0.0, distance_to_top(radius, mu, atm))  # shadowed rays are not integrated
    perigee = np.clip(-radius * mu, 0.0, end)
    tau = (_optical_depth_segment(radius, mu, np.zeros_like(end), perigee, atm, n_steps)
           + _optical_depth_segment(radius, mu, perigee, end, atm, n_steps))
    return np.where(shadow[..., np.newaxis], 0.0, np.exp(-tau))


def single_scattering(camera_altitude_m: float, view_dir: ArrayLike, distance_m: float, sun_dir: ArrayLike,
                      atm: Atmosphere, sun_irradiance_top: ArrayLike | None = None, n_steps: int = 2001,
                      n_sun_steps: int = 513) -> tuple[np.ndarray, np.ndarray]:
    """Transmittance F_ex and single-scattered in-scattering L_in along a view ray, each (3,).

    Integrates eq. 15 of Hoffman & Preetham 2002 with single scattering of the direct sun:

        F_ex = exp(-integral_0^d beta_ex(p(t)) dt)
        L_in = integral_0^d sum_k beta_sc,k(p) Phi_k(mu) E_sun0 T_sun(p) T_view(0, p) dt

    over the species k (Rayleigh, Mie), with exponential densities over the spherical planet, T_sun the
    transmittance from p to the top of the atmosphere toward the sun (0 in the planet's shadow) and
    mu = view_dir . sun_dir. The view ray starts at the camera (0, 0, ``camera_altitude_m``) and runs
    ``distance_m`` along ``view_dir`` (need not be unit length). ``sun_irradiance_top`` defaults to
    ``atm.sun_irradiance_top``. Simpson's rule on ``n_steps`` view samples (cumulative trapezoid for
    T_view) and ``n_sun_steps`` samples per sun-ray segment; both odd.
    """
    n_view, n_sun = _odd(n_steps, "n_steps"), _odd(n_sun_steps, "n_sun_steps")
    view, sun = _unit(view_dir, "view_dir"), _unit(sun_dir, "sun_dir")
    e_top = atm.sun_irradiance_top if sun_irradiance_top is None else np.asarray(sun_irradiance_top, np.float64)
    distance = max(float(distance_m), 0.0)
    t = np.linspace(0.0, distance, n_view)
    step = distance / (n_view - 1)
    points = np.array([0.0, 0.0, float(camera_altitude_m)]) + t[:, np.newaxis] * view
    altitude = np.linalg.norm(points - np.array([0.0, 0.0, -atm.planet_radius]), axis=-1) - atm.planet_radius
    beta_ex = _layer_extinction(altitude, atm)
    tau_view = np.concatenate([np.zeros((1, 3)), np.cumsum(0.5 * step * (beta_ex[1:] + beta_ex[:-1]), axis=0)])
    mu = float(np.dot(view, sun))
    scattering = (atm.rayleigh_scattering * np.exp(-altitude / atm.rayleigh_scale_height)[:, np.newaxis]
                  * phase_rayleigh(mu)
                  + atm.mie_scattering * np.exp(-altitude / atm.mie_scale_height)[:, np.newaxis]
                  * phase_hg(mu, atm.mie_g))
    integrand = scattering * e_top * sun_transmittance_numerical(points, sun, atm, n_sun) * np.exp(-tau_view)
    return np.exp(-tau_view[-1]), _simpson(integrand, step, axis=0)


def sun_irradiance_numerical(elevation_rad: float, atm: Atmosphere, altitude_m: float = 0.0,
                             angular_radius_rad: float = float(np.radians(0.2666)), limb_darkening: float = 0.6,
                             n_rows: int = 201, n_columns: int = 201, n_steps: int = 4001) -> np.ndarray:
    """Ground irradiance of the sun's disk, per channel (3,), by brute force over the disk, units of E_sun0.

    E = E_sun0 * integral over the visible disk of I(x, y) T(elevation + rho y) dx dy / integral over the whole
    disk of I dx dy, with I = 1 - u (1 - sqrt(1 - x^2 - y^2)) (linear limb darkening, flat disk of radius rho,
    x and y in units of rho), T the transmittance toward the point (:func:`optical_depth_numerical`, straight rays,
    0 below the geometric horizon seen from ``altitude_m``). Simpson's rule on ``n_rows`` heights y and
    ``n_columns`` points across each chord (both odd). Shares nothing with :mod:`~atmos_addon.physics.sun` but the
    geometry.
    """
    rows, columns = _odd(n_rows, "n_rows"), _odd(n_columns, "n_columns")
    radius = atm.planet_radius + max(float(altitude_m), 0.0)
    horizon = -float(np.arccos(np.clip(atm.planet_radius / radius, -1.0, 1.0)))
    y = np.linspace(-1.0, 1.0, rows)
    x_unit = np.linspace(-1.0, 1.0, columns)
    u = float(limb_darkening)
    chord_flux = np.empty(rows)
    for index, height in enumerate(y):
        half = np.sqrt(max(1.0 - height * height, 0.0))
        x = half * x_unit
        intensity = 1.0 - u * (1.0 - np.sqrt(np.maximum(1.0 - x * x - height * height, 0.0)))
        chord_flux[index] = _simpson(intensity, half * 2.0 / (columns - 1)) if half > 0.0 else 0.0
    transmittance = np.zeros((rows, 3))
    for index, height in enumerate(y):
        point_elevation = float(elevation_rad) + angular_radius_rad * height
        if point_elevation >= horizon:
            tau = optical_depth_numerical(altitude_m, 0.5 * np.pi - point_elevation, atm, n_steps)
            transmittance[index] = np.exp(-tau)
    step = 2.0 / (rows - 1)
    total = _simpson(chord_flux, step)
    return atm.sun_irradiance_top * _simpson(chord_flux[:, np.newaxis] * transmittance, step, axis=0) / total
