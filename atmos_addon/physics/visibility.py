# SPDX-License-Identifier: GPL-3.0-or-later
"""Meteorological visibility: what the haze setting promises and what the atmosphere gives.

Koschmieder (1924; the WMO's definition of meteorological optical range, WMO-No. 8): in a homogeneous atmosphere
under a horizontally uniform light field, a black target at distance d seen against the horizon sky behind it has
the apparent contrast

    C(d) = (L_sky - L_target) / L_sky = exp(-beta_ex d),

so contrast falls to the eye's threshold of 2 % at the visibility V = -ln(0.02) / beta_ex = 3.912 / beta_ex
(beta_ex at 550 nm). Atmos's Haze setting is V at the ground (``blender/simple_controls.py``).

The real atmosphere is not homogeneous along a horizontal view: the ray climbs away from the curved ground, the
haze (scale height about 1 km) thins, and the horizon sky is the light of the whole path, not of an endless layer
at sea-level density. For a black target, L_target is exactly the in-scattering L_in(d) in front of it, so

    C(d) = 1 - L_in(d) / L_sky.

The complete reference evaluates it by Monte Carlo over every scattering order, and each quality level as it
renders it (``validation/visibility.py``, docs/visibility.md).
Lengths m, angles rad unless named _deg. Numpy only.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from .atmosphere import Atmosphere
from .rayleigh import rayleigh_coefficients
from .spectrum import channel_value_at

#: The contrast threshold of Koschmieder's visibility (WMO: 0.05 for the meteorological optical range; the
#: haze setting and the presets use Koschmieder's 0.02).
CONTRAST_THRESHOLD = 0.02
#: -ln(CONTRAST_THRESHOLD) = 3.912: V = KOSCHMIEDER_CONSTANT / beta_ex(550 nm).
KOSCHMIEDER_CONSTANT = -math.log(CONTRAST_THRESHOLD)
#: The channel nearest 550 nm (G).
GREEN = 1
#: Wavelength at which visibility is defined, nm.
VISIBILITY_WAVELENGTH_NM = 550.0


def extinction_at_550(channel_wavelengths_nm: ArrayLike, *species: ArrayLike) -> float:
    """The sum of per-channel coefficients (any one unit), each species read at 550 nm from its channels
    (:func:`~atmos_addon.physics.spectrum.channel_value_at`; the G channel stands for 547.4 nm)."""
    return sum(channel_value_at(VISIBILITY_WAVELENGTH_NM, channel_wavelengths_nm, values) for values in species)


def extinction_550_per_m(atm: Atmosphere) -> float:
    """Sea-level extinction coefficient of ``atm`` at 550 nm, 1/m (:func:`extinction_at_550` of its Rayleigh
    scattering, aerosol scattering and aerosol absorption)."""
    return extinction_at_550(atm.wavelengths_nm, atm.rayleigh_scattering, atm.mie_scattering, atm.mie_absorption)


def visibility_m(atm: Atmosphere) -> float:
    """Koschmieder's visibility 3.912 / beta_ex(550 nm) of ``atm`` at sea level, m."""
    return KOSCHMIEDER_CONSTANT / extinction_550_per_m(atm)


#: Absorption / scattering ratio given to haze that has none to copy (the clear default: albedo 0.91).
DEFAULT_HAZE_ABSORPTION_RATIO = 0.1


def haze_absorption_ratio(scattering: ArrayLike, absorption: ArrayLike) -> np.ndarray:
    """Each channel's haze absorption / scattering, (3,): a channel without scattering takes the mean ratio, a haze
    without any scattering :data:`DEFAULT_HAZE_ABSORPTION_RATIO` (or 0 when it absorbs)."""
    scattering = np.asarray(scattering, dtype=np.float64)
    absorption = np.asarray(absorption, dtype=np.float64)
    if np.all(scattering <= 0.0):
        return np.full(3, DEFAULT_HAZE_ABSORPTION_RATIO if np.all(absorption <= 0.0) else 0.0)
    fallback = float(np.sum(absorption) / max(np.sum(scattering), 1e-30))
    return np.where(scattering > 0.0, absorption / np.where(scattering > 0.0, scattering, 1.0), fallback)


def haze_colour_of(scattering: ArrayLike) -> np.ndarray:
    """The haze's colour: its scattering per channel over its largest channel, (3,); white where there is no haze."""
    scattering = np.asarray(scattering, dtype=np.float64)
    peak = float(scattering.max())
    return np.ones(3) if peak <= 0.0 else scattering / peak


def haze_extinction_for_visibility(visibility: float, channel_wavelengths_nm: ArrayLike,
                                   rayleigh_per_m: ArrayLike) -> float:
    """The haze's sea-level extinction at 550 nm, 1/m, that gives the visibility ``visibility`` m over the air
    ``rayleigh_per_m``: 3.912 / V - beta_R(550), not below 0 (a visibility longer than clean air allows gets no
    haze)."""
    rayleigh_550 = channel_value_at(VISIBILITY_WAVELENGTH_NM, channel_wavelengths_nm, rayleigh_per_m)
    return max(KOSCHMIEDER_CONSTANT / max(float(visibility), 1e-9) - rayleigh_550, 0.0)


def haze_for_extinction(haze_extinction_550_per_m: float, channel_wavelengths_nm: ArrayLike, shape: ArrayLike,
                        absorption_ratio: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """The haze's scattering and absorption per channel, 1/m, of colour ``shape`` (scattering proportional to it)
    with absorption / scattering ``absorption_ratio`` per channel, whose extinction at 550 nm is
    ``haze_extinction_550_per_m``: the split of one visibility into the haze's coefficients.

    Scattering s shape_c and absorption s shape_c a_c, with s chosen so that (shape + shape a) read at 550 nm
    (:func:`extinction_at_550`) times s is the extinction asked for; a shape without extinction gives no haze.
    """
    shape = np.asarray(shape, dtype=np.float64)
    ratio = np.asarray(absorption_ratio, dtype=np.float64)
    unit_550 = extinction_at_550(channel_wavelengths_nm, shape, shape * ratio)
    scale = float(haze_extinction_550_per_m) / unit_550 if unit_550 > 0.0 else 0.0
    return shape * scale, shape * ratio * scale


def relative_air_density(channel_wavelengths_nm: ArrayLike, rayleigh_per_m: ArrayLike) -> float:
    """Air density relative to standard sea-level air (288.15 K, 101325 Pa; Bodhaine et al. 1999): the Rayleigh
    coefficient at 550 nm over standard air's at the same channel wavelengths (1 = Earth at sea level)."""
    standard = channel_value_at(VISIBILITY_WAVELENGTH_NM, channel_wavelengths_nm,
                                rayleigh_coefficients(np.asarray(channel_wavelengths_nm, dtype=np.float64)))
    return channel_value_at(VISIBILITY_WAVELENGTH_NM, channel_wavelengths_nm, rayleigh_per_m) / standard


def koschmieder_contrast(distance_m: ArrayLike, visibility: float) -> np.ndarray:
    """exp(-3.912 d / V): a black target's contrast in the homogeneous atmosphere of visibility ``visibility`` m."""
    return np.exp(-KOSCHMIEDER_CONSTANT * np.asarray(distance_m, dtype=np.float64) / float(visibility))
