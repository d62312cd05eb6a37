# SPDX-License-Identifier: GPL-3.0-or-later
"""Artist controls that are views of the coefficients, not settings of their own: Visibility, Haze Colour and
Air Density.

* Visibility is the meteorological visibility V = 3.912 / beta_ex(550 nm) (Koschmieder 1924: the
  distance at which a black object keeps 2 % contrast against the horizon sky), with beta_ex the total
  extinction beta_R + beta_M,sc + beta_M,abs at sea level, shown in km. Setting it keeps the Rayleigh
  term and gives the haze the rest, keeping the haze's colour and each channel's absorption-to-scattering
  ratio (so soot stays soot, dust stays dust).
* Haze Colour is the haze's scattering per channel over its largest channel (the tint the haze adds to
  the light it scatters). Setting it keeps the visibility and each channel's absorption ratio.
* Air Density is the Rayleigh coefficient at 550 nm relative to standard sea-level air
  (288.15 K, 101325 Pa; Bodhaine et al. 1999) at the same wavelengths. Setting it scales the
  current Rayleigh coefficients, keeping their colour.

Both are read and written through ``get``/``set`` of ``scene.atmos`` properties, so the coefficients
stay the one source of truth and presets never need to know these controls exist.
"""

from __future__ import annotations

import numpy as np

from ..physics import rayleigh_coefficients
from ..physics.visibility import (KOSCHMIEDER_CONSTANT, extinction_at_550, haze_absorption_ratio, haze_colour_of,
                                  haze_extinction_for_visibility, haze_for_extinction, relative_air_density)

#: -ln(0.02) = 3.912: the 2 % contrast threshold of Koschmieder's visibility.
KOSCHMIEDER = KOSCHMIEDER_CONSTANT
#: Visibility reported when the air does not attenuate at all, m (a finite stand-in for infinity).
MAX_VISIBILITY_M = 1.0e9


def extinction_550_per_m(settings) -> float:
    """Sea-level extinction coefficient at 550 nm, 1/m (settings hold 1/km), each species read at 550 nm."""
    return extinction_at_550(settings.wavelengths_nm, settings.rayleigh_scattering_per_km,
                             settings.mie_scattering_per_km, settings.mie_absorption_per_km) / 1000.0


def visibility_m(settings) -> float:
    """Koschmieder visibility V = 3.912 / beta_ex(550 nm), metres."""
    beta = extinction_550_per_m(settings)
    return MAX_VISIBILITY_M if beta <= KOSCHMIEDER / MAX_VISIBILITY_M else KOSCHMIEDER / beta


def haze_coefficients(settings, visibility: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """Mie scattering of the haze's current colour and the matching absorption (1/km) that give ``visibility``
    metres.

    The haze's extinction at 550 nm is what the visibility needs beyond the Rayleigh term; it is
    split as s (1 + a_550) with a_c = absorption_c / scattering_c kept per channel. A visibility
    longer than clean air alone allows gives no haze at all (and a white Haze Colour after it).
    """
    return _haze_with_visibility(settings, haze_colour(settings), visibility)


def _absorption_ratio(settings) -> np.ndarray:
    """Each channel's haze absorption / scattering (:func:`~atmos_addon.physics.visibility.haze_absorption_ratio`)."""
    return haze_absorption_ratio(settings.mie_scattering_per_km, settings.mie_absorption_per_km)


def _haze_with_visibility(settings, shape, visibility: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """Mie scattering proportional to ``shape`` per channel and the matching absorption (1/km), scaled so that the
    total extinction at 550 nm gives ``visibility`` metres."""
    rayleigh_per_m = np.asarray(settings.rayleigh_scattering_per_km, dtype=float) / 1000.0
    extinction = haze_extinction_for_visibility(visibility, settings.wavelengths_nm, rayleigh_per_m)
    scattering, absorption = haze_for_extinction(extinction, settings.wavelengths_nm, shape,
                                                 _absorption_ratio(settings))
    return tuple((scattering * 1000.0).tolist()), tuple((absorption * 1000.0).tolist())


#: Smallest channel of a Haze Colour written to the coefficients (a black channel would make the haze opaque
#: nowhere and its visibility undefined).
MIN_HAZE_COLOUR = 1.0e-3


def haze_colour(settings) -> tuple[float, float, float]:
    """The haze's scattering per channel over its largest channel; white where there is no haze."""
    return tuple(haze_colour_of(settings.mie_scattering_per_km).tolist())


def haze_for_colour(settings, colour) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """Mie scattering and absorption (1/km) of the tint ``colour`` at the settings' current visibility."""
    shape = np.clip(np.asarray(colour, dtype=float), MIN_HAZE_COLOUR, None)
    return _haze_with_visibility(settings, shape, visibility_m(settings))


def standard_rayleigh_per_km(settings) -> np.ndarray:
    """Rayleigh coefficients of standard sea-level air at the settings' wavelengths, 1/km."""
    return rayleigh_coefficients(np.asarray(settings.wavelengths_nm, dtype=float)) * 1000.0


def air_density(settings) -> float:
    """Rayleigh scattering at 550 nm relative to standard sea-level air (1 = Earth, sea level)."""
    return relative_air_density(settings.wavelengths_nm,
                                np.asarray(settings.rayleigh_scattering_per_km, dtype=float) / 1000.0)


def rayleigh_for_density(settings, density: float) -> tuple[float, ...]:
    """Rayleigh coefficients (1/km) for ``density`` times standard air, keeping the current colour."""
    current = np.asarray(settings.rayleigh_scattering_per_km, dtype=float)
    old = air_density(settings)
    if old <= 0.0:
        return tuple((standard_rayleigh_per_km(settings) * density).tolist())
    return tuple((current * (density / old)).tolist())


# ``get``/``set`` callbacks of the scene.atmos properties (one update per write through orchestrator.batch).


def get_visibility_km(settings) -> float:
    return visibility_m(settings) / 1000.0


def set_visibility_km(settings, value: float) -> None:
    _write_haze(settings, haze_coefficients(settings, float(value) * 1000.0))


def get_haze_colour(settings) -> tuple[float, float, float]:
    return haze_colour(settings)


def set_haze_colour(settings, value) -> None:
    _write_haze(settings, haze_for_colour(settings, value))


def _write_haze(settings, coefficients) -> None:
    from . import orchestrator

    scattering, absorption = coefficients
    with orchestrator.batch(settings.id_data):
        settings.mie_scattering_per_km = scattering
        settings.mie_absorption_per_km = absorption


def get_air_density(settings) -> float:
    return air_density(settings)


def set_air_density(settings, value: float) -> None:
    from . import orchestrator

    rayleigh = rayleigh_for_density(settings, max(float(value), 0.0))
    with orchestrator.batch(settings.id_data):
        settings.rayleigh_scattering_per_km = rayleigh
