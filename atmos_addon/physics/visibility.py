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


def koschmieder_contrast(distance_m: ArrayLike, visibility: float) -> np.ndarray:
    """exp(-3.912 d / V): a black target's contrast in the homogeneous atmosphere of visibility ``visibility`` m."""
    return np.exp(-KOSCHMIEDER_CONSTANT * np.asarray(distance_m, dtype=np.float64) / float(visibility))
