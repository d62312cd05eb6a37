# SPDX-License-Identifier: GPL-3.0-or-later
"""Sunlight at the ground: the sun's irradiance above the atmosphere, dimmed and reddened on its way down.

E_sun(elevation) = E_sun0 * <exp(-tau(chi))>_disk * f_visible        (Hoffman & Preetham 2002,
"Applying the Theory - Sunlight": the extinction factor of eq. 15 along the slant path to the sun)

* tau(chi) is the optical depth to space along the ray toward a point of the sun's disk, from the
  Chapman function over the curved planet (:func:`~atmos_addon.physics.optical_depth.optical_depth_to_space`).
* The sun is a disk of angular radius rho with linear limb darkening, I(mu) / I(1) = 1 - u (1 - mu) (the
  same law the sky draws the disk with, :func:`~atmos_addon.physics.sky.limb_darkening_factor`); refraction
  is neglected. Near the horizon only the part above the geometric horizon is seen: f_visible is the fraction
  of the disk's flux above the horizon line, and the transmittance is averaged over that visible part,
  weighted by the disk's radiance. Every point of the visible part sees space, so the average is finite, and
  E_sun falls smoothly to exactly 0 as the disk's upper limb sets (elevation = horizon - rho).
* Why the disk and not its centre: exp(-tau) is convex across the disk, so a low sun's disk average exceeds the
  transmittance toward its centre (clear preset, 2 deg: 2.2 % in blue; the Atmosphere() default: 1.5 %). A
  point-sun brute force is therefore not the reference; ``tests/physics/test_sun.py`` integrates the
  limb-darkened disk by brute force (Simpson optical depths, 2-D quadrature over the disk) instead.
* The horizon seen from altitude h dips below the astronomical horizon by arccos(R / (R + h)).

Irradiance is per colour channel, on a surface perpendicular to the sun, in the units of E_sun0
(W/m^2 in Blender's sun-strength sense).
"""

from __future__ import annotations

import functools

import numpy as np
from numpy.typing import ArrayLike

from .atmosphere import Atmosphere
from .optical_depth import layer_optical_depth, optical_depth_to_space, ozone_slant_column

#: Mean angular radius of the solar disk seen from the Earth, rad (16 arcmin).
SUN_ANGULAR_RADIUS_RAD = float(np.radians(0.2666))
#: Rec. 709 / sRGB luminance weights of linear R, G, B (the working space of Blender's default scene).
LUMINANCE_WEIGHTS = np.array([0.2126, 0.7152, 0.0722])
#: Linear limb-darkening coefficient of the sun in the visible, I(mu) / I(1) = 1 - u (1 - mu) (about 0.6 at
#: 550 nm; Neckel & Labs 1994 give 0.5 in the red to 0.7 in the blue).
SUN_LIMB_DARKENING = 0.6
#: Gauss-Legendre nodes across the visible part of the disk.
DISK_QUADRATURE_NODES = 12

_DISK_NODES, _DISK_WEIGHTS = np.polynomial.legendre.leggauss(DISK_QUADRATURE_NODES)


def horizon_dip_rad(altitude_m: ArrayLike, planet_radius_m: float) -> np.ndarray:
    """Elevation of the geometric horizon seen from ``altitude_m``: -arccos(R / (R + h)), rad (<= 0)."""
    radius = planet_radius_m + np.maximum(np.asarray(altitude_m, dtype=np.float64), 0.0)
    return -np.arccos(np.clip(planet_radius_m / radius, -1.0, 1.0))


def visible_disk_fraction(elevation_above_horizon_rad: ArrayLike, angular_radius_rad: float,
                          limb_darkening: float = 0.0) -> np.ndarray:
    """Fraction of a disk's flux above a straight horizon line, dimensionless in [0, 1].

    With h = (elevation of the disk centre above the line) / rho clamped to [-1, 1], heights y in [-h, 1] (units
    of rho) are visible. A uniform disk (``limb_darkening`` u = 0) gives the circular-segment area
    f_0 = 1/2 + (h sqrt(1 - h^2) + arcsin h) / pi. Under linear limb darkening the chord at height y carries
    2 (1 - u) s + u (pi / 2) s^2, s = sqrt(1 - y^2) (the flat-disk limit, mu = sqrt(1 - x^2 - y^2)), so
    f = [(1 - u) pi f_0 + u (pi / 2) ((1 + h) - (1 + h^3) / 3)] / (pi (1 - u / 3)). 0 at h = -1, 1 at h = 1,
    with zero slope at both ends (the chord shrinks to a point).
    """
    u = float(limb_darkening)
    h = np.clip(np.asarray(elevation_above_horizon_rad, dtype=np.float64) / angular_radius_rad, -1.0, 1.0)
    area = 0.5 + (h * np.sqrt(1.0 - h * h) + np.arcsin(h)) / np.pi
    darkened = 0.5 * ((1.0 + h) - (1.0 + h ** 3) / 3.0)
    return ((1.0 - u) * area + u * darkened) / (1.0 - u / 3.0)


def _check_angular_radius(sun_angular_radius_rad: float) -> float:
    """The sun's angular radius in rad, checked to be a small positive angle."""
    radius = float(sun_angular_radius_rad)
    if not 0.0 < radius < 0.5 * np.pi:
        raise ValueError(f"sun_angular_radius_rad must lie in (0, pi/2) rad; got {sun_angular_radius_rad!r}")
    return radius


def sun_irradiance_ground(elevation_rad: ArrayLike, atm: Atmosphere, altitude_m: float = 0.0,
                          sun_angular_radius_rad: float = SUN_ANGULAR_RADIUS_RAD,
                          limb_darkening: float = SUN_LIMB_DARKENING) -> np.ndarray:
    """Sun irradiance at ``altitude_m`` on a surface facing the sun, per channel, shape (..., 3).

    E_sun = E_sun0 * (mean transmittance exp(-tau) over the visible part of the disk, weighted by the disk's
    radiance) * (visible flux fraction); units of ``atm.sun_irradiance_top`` (W/m^2). ``elevation_rad`` is the
    elevation of the disk centre above the astronomical horizon, rad; ``limb_darkening`` the linear coefficient u
    in [0, 1] (0: a uniform disk). Continuous and never NaN over -pi/2..pi/2; exactly 0 once the whole disk is
    below the geometric horizon. The transmittance average uses Gauss-Legendre nodes in psi across the visible
    part (height y = -cos psi on the disk, dy = sin psi dpsi), each weighted by the radiance along its chord,
    2 (1 - u) sin psi + u (pi / 2) sin^2 psi (see :func:`visible_disk_fraction`).
    """
    weight, zenith, fraction = _visible_disk(elevation_rad, horizon_dip_rad(altitude_m, atm.planet_radius),
                                             sun_angular_radius_rad, limb_darkening)
    return _disk_mean(weight, optical_depth_to_space(altitude_m, zenith, atm), fraction, atm)


def _visible_disk(elevation_rad: ArrayLike, horizon_rad: float, sun_angular_radius_rad: float,
                  limb_darkening: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The geometry of :func:`sun_irradiance_ground`'s disk average: per elevation, the Gauss-Legendre points' weights
    normalised to sum to 1 (..., n, 1), their zenith angles (..., n) and the visible flux fraction (..., 1)."""
    rho = _check_angular_radius(sun_angular_radius_rad)
    u = float(limb_darkening)
    if not 0.0 <= u <= 1.0:
        raise ValueError(f"limb_darkening must lie in [0, 1]; got {limb_darkening!r}")
    elevation = np.asarray(elevation_rad, dtype=np.float64)
    h = np.clip((elevation - horizon_rad) / rho, -1.0, 1.0)
    fraction = visible_disk_fraction(elevation - horizon_rad, rho, u)
    # Visible heights y in [-h, 1] (units of rho from the disk centre), y = -cos psi, psi in [arccos h, pi].
    psi_low = np.arccos(h)[..., np.newaxis]
    psi = psi_low + (np.pi - psi_low) * 0.5 * (_DISK_NODES + 1.0)
    chord = np.sin(psi)
    weight = _DISK_WEIGHTS * chord * (2.0 * (1.0 - u) * chord + 0.5 * np.pi * u * chord * chord)
    node_elevation = np.maximum(elevation[..., np.newaxis] - rho * np.cos(psi), horizon_rad)
    zenith = np.clip(0.5 * np.pi - node_elevation, 0.0, np.pi)
    weight = weight / np.maximum(np.sum(weight, axis=-1, keepdims=True), np.finfo(np.float64).tiny)
    return weight[..., np.newaxis], zenith, fraction[..., np.newaxis]


def _disk_mean(weight: np.ndarray, tau: np.ndarray, fraction: np.ndarray, atm: Atmosphere) -> np.ndarray:
    """E_top times the weighted mean transmittance over the visible disk times the visible fraction, (..., 3)."""
    return atm.sun_irradiance_top * np.sum(weight * np.exp(-tau), axis=-2) * fraction


def sun_color_and_strength(elevation_rad: ArrayLike, atm: Atmosphere, altitude_m: float = 0.0,
                           sun_angular_radius_rad: float = SUN_ANGULAR_RADIUS_RAD,
                           limb_darkening: float = SUN_LIMB_DARKENING) -> tuple[np.ndarray, np.ndarray]:
    """Split the ground sun irradiance into a colour and a strength for a Blender sun lamp.

    strength = Y(E_sun) = 0.2126 E_R + 0.7152 E_G + 0.0722 E_B (Rec. 709 luminance weights, W/m^2) and
    colour = E_sun / strength, so colour * strength == E_sun and the colour has unit luminance (a
    channel may exceed 1 for a low, red sun). Where the sun is set (strength 0) the colour is white
    (1, 1, 1). Returns (colour (..., 3), strength (...)).
    """
    irradiance = sun_irradiance_ground(elevation_rad, atm, altitude_m, sun_angular_radius_rad, limb_darkening)
    strength = irradiance @ LUMINANCE_WEIGHTS
    lit = strength > 0.0
    colour = np.where(lit[..., np.newaxis], irradiance / np.where(lit, strength, 1.0)[..., np.newaxis], 1.0)
    return colour, strength


#: Rows of :func:`sun_irradiance_table`: enough that linear interpolation stays within 0.2 % of E_sun above the
#: disk's setting (worst: sunset preset 0.153 %, overcast 0.135 %, clear 0.078 %, Mars 0.018 %; measured by
#: ``tests/physics/test_sun.py::test_the_sun_table_interpolates_e_sun``).
SUN_TABLE_ROWS = 1024


def sun_table_sines(sun_angular_radius_rad: float = SUN_ANGULAR_RADIUS_RAD, rows: int = SUN_TABLE_ROWS) -> np.ndarray:
    """The sines of the sun elevations :func:`sun_irradiance_table` samples, increasing: e_j = -rho + (pi/2 + rho)
    (j / (rows - 1))^2, dense at the horizon where E_sun changes fastest, from the elevation where the disk's upper
    limb sets (E_sun = 0) to the zenith."""
    rho = _check_angular_radius(sun_angular_radius_rad)
    fraction = np.linspace(0.0, 1.0, int(rows))
    return np.sin(-rho + (0.5 * np.pi + rho) * fraction * fraction)


@functools.lru_cache(maxsize=4)
def _table_geometry(planet_radius_m: float, rayleigh_scale_height_m: float, mie_scale_height_m: float,
                    atmosphere_height_m: float, sun_angular_radius_rad: float, limb_darkening: float,
                    rows: int) -> tuple[np.ndarray, ...]:
    """What :func:`sun_irradiance_table` keeps per geometry: (sines, the disk points' weights as rows (rows, 1, n),
    fractions (rows, 1), and the optical depths to space of every row's disk points per unit sea-level coefficient,
    (rows, n, 3): Rayleigh, haze, ozone), read-only."""
    sines = sun_table_sines(sun_angular_radius_rad, rows)
    weight, zenith, fraction = _visible_disk(np.arcsin(sines), 0.0, sun_angular_radius_rad, limb_darkening)
    shell = Atmosphere(planet_radius=planet_radius_m, atmosphere_height=atmosphere_height_m)   # the ozone's path
    depths = np.concatenate([layer_optical_depth(0.0, zenith, 1.0, rayleigh_scale_height_m, planet_radius_m),
                             layer_optical_depth(0.0, zenith, 1.0, mie_scale_height_m, planet_radius_m),
                             ozone_slant_column(0.0, np.cos(zenith), shell)[..., np.newaxis]], axis=-1)
    arrays = (sines, np.ascontiguousarray(np.swapaxes(weight, -1, -2)), fraction, depths)
    for array in arrays:
        array.setflags(write=False)
    return arrays


def sun_irradiance_table(atm: Atmosphere, sun_angular_radius_rad: float = SUN_ANGULAR_RADIUS_RAD,
                         limb_darkening: float = SUN_LIMB_DARKENING, rows: int = SUN_TABLE_ROWS
                         ) -> tuple[np.ndarray, np.ndarray]:
    """E_sun at the ground as a table of the sine of the sun's elevation: (sines (rows,), E_sun (rows, 3)).

    What Blender evaluates without Python as the sun lamp moves (:mod:`atmos_addon.blender.apply.sun_drivers`: a
    driver per channel whose F-curve holds these rows, read linearly in the sine, constant beyond the ends: 0
    below the first row, where the disk has set). :func:`interpolate_sun_irradiance` is the same lookup in numpy.

    Each row is :func:`sun_irradiance_ground` at the ground, every disk point seeing space. Optical depth is linear
    in the sea-level coefficients, tau = beta_R H_R Ch_R + beta_M,ex H_M Ch_M + beta_O3 X_O3, and the disk's points,
    weights and Chapman functions and ozone slant columns depend only on the geometry: they are computed once per
    geometry (:func:`_table_geometry`, 0.1 s, the last four kept), and an edit of the air, the haze or the ozone
    costs two matrix products and an exponential (0.4 ms, where the quadratures took 84 ms on every edit).
    """
    sines, weight_rows, fraction, depths = _table_geometry(
        float(atm.planet_radius), float(atm.rayleigh_scale_height), float(atm.mie_scale_height),
        float(atm.atmosphere_height), float(sun_angular_radius_rad), float(limb_darkening), int(rows))
    ozone = atm.ozone_absorption if atm.ozone_column_du > 0.0 else np.zeros(3)
    # tau and the disk's weighted mean as two matrix products: 0.4 ms where the broadcast sums took 0.9 ms (equal to
    # :func:`_disk_mean` but for the order of the sums: within 1e-15 relative)
    transmittance = depths @ -np.stack([atm.rayleigh_scattering, atm.mie_extinction, ozone])     # (rows, n, 3)
    np.exp(transmittance, out=transmittance)
    return sines, atm.sun_irradiance_top * (weight_rows @ transmittance)[:, 0, :] * fraction


def interpolate_sun_irradiance(table: tuple[np.ndarray, np.ndarray], sine_elevation: ArrayLike) -> np.ndarray:
    """E_sun per channel, shape (..., 3), read from :func:`sun_irradiance_table`'s rows linearly in the sine of the
    elevation, the end rows beyond the ends (the driver F-curves' lookup)."""
    sines, irradiance = table
    sine = np.asarray(sine_elevation, dtype=np.float64)
    return np.stack([np.interp(sine, sines, irradiance[:, channel]) for channel in range(3)], axis=-1)
