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

import numpy as np
from numpy.typing import ArrayLike

from .atmosphere import Atmosphere
from .optical_depth import optical_depth_to_space

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
    rho = _check_angular_radius(sun_angular_radius_rad)
    u = float(limb_darkening)
    if not 0.0 <= u <= 1.0:
        raise ValueError(f"limb_darkening must lie in [0, 1]; got {limb_darkening!r}")
    elevation = np.asarray(elevation_rad, dtype=np.float64)
    horizon = horizon_dip_rad(altitude_m, atm.planet_radius)
    h = np.clip((elevation - horizon) / rho, -1.0, 1.0)
    fraction = visible_disk_fraction(elevation - horizon, rho, u)
    # Visible heights y in [-h, 1] (units of rho from the disk centre), y = -cos psi, psi in [arccos h, pi].
    psi_low = np.arccos(h)[..., np.newaxis]
    psi = psi_low + (np.pi - psi_low) * 0.5 * (_DISK_NODES + 1.0)
    chord = np.sin(psi)
    weight = _DISK_WEIGHTS * chord * (2.0 * (1.0 - u) * chord + 0.5 * np.pi * u * chord * chord)
    node_elevation = np.maximum(elevation[..., np.newaxis] - rho * np.cos(psi), horizon)
    zenith = np.clip(0.5 * np.pi - node_elevation, 0.0, np.pi)
    transmittance = np.exp(-optical_depth_to_space(altitude_m, zenith, atm))
    weight_sum = np.sum(weight, axis=-1, keepdims=True)
    mean_transmittance = np.sum(weight[..., np.newaxis] * transmittance, axis=-2) / np.maximum(
        weight_sum, np.finfo(np.float64).tiny)
    return atm.sun_irradiance_top * mean_transmittance * fraction[..., np.newaxis]


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
