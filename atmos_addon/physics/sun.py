# SPDX-License-Identifier: GPL-3.0-or-later
"""Sunlight at the ground: the sun's irradiance above the atmosphere, dimmed and reddened on its way down.

E_sun(elevation) = E_sun0 * <exp(-tau(chi))>_disk * f_visible        (Hoffman & Preetham 2002,
"Applying the Theory - Sunlight": the extinction factor of eq. 15 along the slant path to the sun)

* tau(chi) is the optical depth to space along the ray toward a point of the sun's disk, from the
  Chapman function over the curved planet (:func:`~atmos_addon.physics.optical_depth.optical_depth_to_space`).
* The sun is a uniform disk of angular radius rho (limb darkening and refraction neglected). Near the
  horizon only the part above the geometric horizon is seen: f_visible is the area fraction of the disk
  above the horizon line, and the transmittance is averaged over that visible part. Every point of the
  visible part sees space, so the average is finite, and E_sun falls smoothly to exactly 0 as the disk's
  upper limb sets (elevation = horizon - rho).
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
#: Gauss-Legendre nodes across the visible part of the disk.
DISK_QUADRATURE_NODES = 12

_DISK_NODES, _DISK_WEIGHTS = np.polynomial.legendre.leggauss(DISK_QUADRATURE_NODES)


def horizon_dip_rad(altitude_m: ArrayLike, planet_radius_m: float) -> np.ndarray:
    """Elevation of the geometric horizon seen from ``altitude_m``: -arccos(R / (R + h)), rad (<= 0)."""
    radius = planet_radius_m + np.maximum(np.asarray(altitude_m, dtype=np.float64), 0.0)
    return -np.arccos(np.clip(planet_radius_m / radius, -1.0, 1.0))


def visible_disk_fraction(elevation_above_horizon_rad: ArrayLike, angular_radius_rad: float) -> np.ndarray:
    """Area fraction of a uniform disk above a straight horizon line, dimensionless in [0, 1].

    With u = (elevation of the disk centre above the line) / rho clamped to [-1, 1], the circular-segment
    area gives f = 1/2 + (u sqrt(1 - u^2) + arcsin u) / pi: 0 at u = -1, 1/2 at u = 0, 1 at u = 1, with
    zero slope at both ends (the chord shrinks to a point).
    """
    u = np.clip(np.asarray(elevation_above_horizon_rad, dtype=np.float64) / angular_radius_rad, -1.0, 1.0)
    return 0.5 + (u * np.sqrt(1.0 - u * u) + np.arcsin(u)) / np.pi


def _check_angular_radius(sun_angular_radius_rad: float) -> float:
    """The sun's angular radius in rad, checked to be a small positive angle."""
    radius = float(sun_angular_radius_rad)
    if not 0.0 < radius < 0.5 * np.pi:
        raise ValueError(f"sun_angular_radius_rad must lie in (0, pi/2) rad; got {sun_angular_radius_rad!r}")
    return radius


def sun_irradiance_ground(elevation_rad: ArrayLike, atm: Atmosphere, altitude_m: float = 0.0,
                          sun_angular_radius_rad: float = SUN_ANGULAR_RADIUS_RAD) -> np.ndarray:
    """Sun irradiance at ``altitude_m`` on a surface facing the sun, per channel, shape (..., 3).

    E_sun = E_sun0 * (mean transmittance exp(-tau) over the visible part of the disk) * (visible area
    fraction); units of ``atm.sun_irradiance_top`` (W/m^2). ``elevation_rad`` is the elevation of the
    disk centre above the astronomical horizon, rad. Continuous and never NaN over -pi/2..pi/2; exactly 0
    once the whole disk is below the geometric horizon. The transmittance average uses Gauss-Legendre
    nodes in psi across the visible part (height y = -cos psi on the disk, area element 2 sin^2 psi dpsi).
    """
    rho = _check_angular_radius(sun_angular_radius_rad)
    elevation = np.asarray(elevation_rad, dtype=np.float64)
    horizon = horizon_dip_rad(altitude_m, atm.planet_radius)
    u = np.clip((elevation - horizon) / rho, -1.0, 1.0)
    fraction = visible_disk_fraction(elevation - horizon, rho)
    # Visible heights y in [-u, 1] (units of rho from the disk centre), y = -cos psi, psi in [arccos u, pi].
    psi_low = np.arccos(u)[..., np.newaxis]
    psi = psi_low + (np.pi - psi_low) * 0.5 * (_DISK_NODES + 1.0)
    weight = _DISK_WEIGHTS * np.sin(psi) ** 2
    node_elevation = np.maximum(elevation[..., np.newaxis] - rho * np.cos(psi), horizon)
    zenith = np.clip(0.5 * np.pi - node_elevation, 0.0, np.pi)
    transmittance = np.exp(-optical_depth_to_space(altitude_m, zenith, atm))
    weight_sum = np.sum(weight, axis=-1, keepdims=True)
    mean_transmittance = np.sum(weight[..., np.newaxis] * transmittance, axis=-2) / np.maximum(
        weight_sum, np.finfo(np.float64).tiny)
    return atm.sun_irradiance_top * mean_transmittance * fraction[..., np.newaxis]


def sun_color_and_strength(elevation_rad: ArrayLike, atm: Atmosphere, altitude_m: float = 0.0,
                           sun_angular_radius_rad: float = SUN_ANGULAR_RADIUS_RAD
                           ) -> tuple[np.ndarray, np.ndarray]:
    """Split the ground sun irradiance into a colour and a strength for a Blender sun lamp.

    strength = Y(E_sun) = 0.2126 E_R + 0.7152 E_G + 0.0722 E_B (Rec. 709 luminance weights, W/m^2) and
    colour = E_sun / strength, so colour * strength == E_sun and the colour has unit luminance (a
    channel may exceed 1 for a low, red sun). Where the sun is set (strength 0) the colour is white
    (1, 1, 1). Returns (colour (..., 3), strength (...)).
    """
    irradiance = sun_irradiance_ground(elevation_rad, atm, altitude_m, sun_angular_radius_rad)
    strength = irradiance @ LUMINANCE_WEIGHTS
    lit = strength > 0.0
    colour = np.where(lit[..., np.newaxis], irradiance / np.where(lit, strength, 1.0)[..., np.newaxis], 1.0)
    return colour, strength
