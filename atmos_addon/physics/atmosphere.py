# SPDX-License-Identifier: GPL-3.0-or-later
"""The atmosphere: two exponential layers of scatterers (molecules and aerosols) over a spherical planet.

Every coefficient is a sea-level value per colour channel (R, G, B), in 1/m; the density of each
species falls as exp(-h / H) with altitude h (Hoffman & Preetham 2002, section "Applying the Theory";
Bruneton & Neyret 2008 for the two-layer model). Molecules (Rayleigh) only scatter; aerosols (Mie)
scatter and absorb, so the extinction coefficient is beta_ex = beta_R + beta_M,sc + beta_M,abs.

Default: a clear Earth sky.

* Rayleigh coefficients from :func:`~atmos_addon.physics.rayleigh.rayleigh_coefficients` at the
  default wavelengths for 288.15 K and 101325 Pa; scale height H_R = k T / (m g) = 8434 m so that
  beta_R H_R is the hydrostatic column optical depth of Bodhaine et al. 1999. The wavelengths, 648.1,
  547.4 and 443.1 nm, are those that stand for Blender's Rec.709 channels under sunlight: where air's
  coefficient equals its mean over the channel's band (:func:`~atmos_addon.physics.spectrum.channel_wavelengths_nm`;
  the seed's 680 / 550 / 440 nm make the sky 25-31 % too blue).
* A light continental haze: grey Mie scattering 3.3e-5 1/m and absorption 3.3e-6 1/m (single-scattering
  albedo 0.91), scale height 1200 m, Henyey-Greenstein g = 0.76 (Bruneton & Neyret 2008). Vertical aerosol
  optical depth 0.044; with the Rayleigh term and the haze's absorption the 550 nm extinction is 4.8e-5 1/m, a
  meteorological visibility 3.912 / beta_ex of about 82 km (Koschmieder).
* No ozone (``ozone_column_du`` = 0): the seed's atmosphere. The product's Earth presets carry 300 DU, the
  Earth's mean column, in a tent-shaped layer between 10 and 40 km (:meth:`Atmosphere.ozone_density`, the
  profile of Bruneton 2017). Ozone absorbs and does not scatter; its cross-section per channel is the
  Daumont-Brion-Malicet spectrum averaged over the channel's sunlit band (R 4.93e-25, G 3.19e-25, B 0 m^2
  per molecule, :data:`~atmos_addon.physics.spectrum.OZONE_CHANNEL_CROSS_SECTION_M2`), so it takes red and green
  from light that crosses the layer at a slant: the blue of the twilight zenith.
* ``sun_irradiance_top``: luminance 4.5 W/m^2 in the solar spectrum's colour, (4.94, 4.40, 4.24). Blender's sun
  strength is a render unit, not the solar constant (1361 W/m^2): daylight at film exposure 0 uses a sun
  strength of about 3-5. With 4.5 above the atmosphere the clear-sky ground sun has a luminance-weighted
  strength of about 3.9 at the zenith and 3.8 at 60 deg elevation. The colour is the ASTM G173 spectrum's in
  linear Rec.709 without chromatic adaptation (:data:`~atmos_addon.physics.spectrum.SUN_TOP_RGB`), slightly
  warm, as Blender's own sky renders the sun; the seed's sun was white (4.5 per channel).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .rayleigh import rayleigh_coefficients, rayleigh_column_scale_height
from .spectrum import (CHANNEL_WAVELENGTHS_NM, DEFAULT_OZONE_PEAK_ALTITUDE_M, OZONE_CHANNEL_CROSS_SECTION_M2,
                       SUN_TOP_RGB, ozone_number_density_per_m3, ozone_tent)

#: Default colour-channel wavelengths (R, G, B), nm: the wavelengths that stand for Blender's Rec.709 channels
#: under sunlight, 648.1, 547.4, 443.1 (:data:`~atmos_addon.physics.spectrum.CHANNEL_WAVELENGTHS_NM`).
DEFAULT_WAVELENGTHS_NM = tuple(float(value) for value in CHANNEL_WAVELENGTHS_NM)
#: The seed's wavelengths, nm (Bruneton 2008's and Hillaire 2020's choice): the former default, which a file saved
#: under it keeps (``blender.migration``).
SEED_WAVELENGTHS_NM = (680.0, 550.0, 440.0)
#: Sea-level scale height of the Rayleigh layer, m (column-consistent, see module docstring).
DEFAULT_RAYLEIGH_SCALE_HEIGHT_M = rayleigh_column_scale_height()
#: Sea-level Mie scattering coefficient of a light haze, 1/m (grey).
DEFAULT_MIE_SCATTERING_PER_M = 3.3e-5
#: Sea-level Mie absorption coefficient, 1/m (10 % of the scattering: single-scattering albedo 0.91).
DEFAULT_MIE_ABSORPTION_PER_M = 3.3e-6
#: Henyey-Greenstein anisotropy of the haze (positive: forward scattering).
DEFAULT_MIE_G = 0.76
#: Scale height of the aerosol layer, m.
DEFAULT_MIE_SCALE_HEIGHT_M = 1200.0
#: Mean radius of the Earth used by Bruneton & Neyret 2008, m.
DEFAULT_PLANET_RADIUS_M = 6_360_000.0
#: Height of the top of the atmosphere above the ground, m.
DEFAULT_ATMOSPHERE_HEIGHT_M = 100_000.0
#: Luminance of the sun above the atmosphere, W/m^2 in Blender's sun-strength unit (see module docstring).
DEFAULT_SUN_LUMINANCE_TOP = 4.5
#: Sun irradiance above the atmosphere per channel, W/m^2 in Blender's sun-strength unit: the solar spectrum's
#: colour in linear Rec.709 at luminance 4.5, (4.94, 4.40, 4.24) (see module docstring).
DEFAULT_SUN_IRRADIANCE_TOP = tuple(float(value) for value in DEFAULT_SUN_LUMINANCE_TOP * SUN_TOP_RGB)
#: The seed's sun above the atmosphere (white, 4.5 per channel): the former default, which a file saved under it
#: keeps (``blender.migration``).
SEED_SUN_IRRADIANCE_TOP = 4.5

_CHANNELS = 3
_RGB_FIELDS = ("rayleigh_scattering", "mie_scattering", "mie_absorption", "mie_g", "sun_irradiance_top",
               "wavelengths_nm")
_LENGTH_FIELDS = ("rayleigh_scale_height", "mie_scale_height", "planet_radius", "atmosphere_height")


def _rgb(name: str, value: ArrayLike) -> np.ndarray:
    """A per-channel value as a read-only float64 array of length 3 (a scalar is broadcast)."""
    array = np.asarray(value, dtype=np.float64)
    if array.ndim == 0:
        array = np.full(_CHANNELS, float(array))
    if array.shape != (_CHANNELS,):
        raise ValueError(f"Atmosphere.{name} must be a scalar or have 3 values (R, G, B); got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"Atmosphere.{name} must be finite; got {array.tolist()}")
    array = array.copy()
    array.flags.writeable = False
    return array


def _nonnegative(name: str, array: np.ndarray) -> None:
    """Reject negative coefficients: a medium cannot emit energy by scattering or absorbing."""
    if np.any(array < 0.0):
        raise ValueError(f"Atmosphere.{name} must be >= 0 (1/m); got {array.tolist()}")


def _positive_length(name: str, value: Any) -> float:
    """A length in metres, checked finite and strictly positive."""
    try:
        length = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"Atmosphere.{name} must be a number of metres; got {value!r}") from None
    if not np.isfinite(length) or length <= 0.0:
        raise ValueError(f"Atmosphere.{name} must be a finite length > 0 m; got {value!r}")
    return length


@dataclass(frozen=True, eq=False)
class Atmosphere:
    """Optical properties of a planetary atmosphere at sea level, per colour channel (R, G, B).

    ``rayleigh_scattering=None`` (the default) computes the molecular coefficients from
    ``wavelengths_nm`` for standard sea-level air. Scalars are broadcast to the three channels;
    arrays are stored read-only. Units: coefficients 1/m, lengths m, irradiance W/m^2 (Blender
    sun strength), wavelengths nm, ozone Dobson units (the whole column; 0: none); ``mie_g`` is dimensionless with
    positive values scattering forward. Ozone adds only absorption: :attr:`extinction_coefficient` is the sea-level
    value, where the layer is empty; :meth:`ozone_absorption_at` gives it at altitude.
    """

    rayleigh_scattering: ArrayLike | None = None
    mie_scattering: ArrayLike = DEFAULT_MIE_SCATTERING_PER_M
    mie_absorption: ArrayLike = DEFAULT_MIE_ABSORPTION_PER_M
    mie_g: ArrayLike = DEFAULT_MIE_G
    rayleigh_scale_height: float = DEFAULT_RAYLEIGH_SCALE_HEIGHT_M
    mie_scale_height: float = DEFAULT_MIE_SCALE_HEIGHT_M
    planet_radius: float = DEFAULT_PLANET_RADIUS_M
    atmosphere_height: float = DEFAULT_ATMOSPHERE_HEIGHT_M
    sun_irradiance_top: ArrayLike = DEFAULT_SUN_IRRADIANCE_TOP
    wavelengths_nm: ArrayLike = field(default=DEFAULT_WAVELENGTHS_NM)
    ozone_column_du: float = 0.0

    def __post_init__(self) -> None:
        wavelengths = _rgb("wavelengths_nm", self.wavelengths_nm)
        if np.any(wavelengths <= 0.0):
            raise ValueError(f"Atmosphere.wavelengths_nm must be > 0 nm; got {wavelengths.tolist()}")
        object.__setattr__(self, "wavelengths_nm", wavelengths)
        if self.rayleigh_scattering is None:
            object.__setattr__(self, "rayleigh_scattering", rayleigh_coefficients(wavelengths))
        for name in ("rayleigh_scattering", "mie_scattering", "mie_absorption", "sun_irradiance_top"):
            array = _rgb(name, getattr(self, name))
            _nonnegative(name, array)
            object.__setattr__(self, name, array)
        g = _rgb("mie_g", self.mie_g)
        if np.any(np.abs(g) >= 1.0):
            raise ValueError(f"Atmosphere.mie_g must satisfy -1 < g < 1 (Henyey-Greenstein anisotropy); "
                             f"got {g.tolist()}")
        object.__setattr__(self, "mie_g", g)
        for name in _LENGTH_FIELDS:
            object.__setattr__(self, name, _positive_length(name, getattr(self, name)))
        try:
            ozone = float(self.ozone_column_du)
        except (TypeError, ValueError):
            raise ValueError(f"Atmosphere.ozone_column_du must be a number of Dobson units; "
                             f"got {self.ozone_column_du!r}") from None
        if not np.isfinite(ozone) or ozone < 0.0:
            raise ValueError(f"Atmosphere.ozone_column_du must be finite and >= 0 (Dobson units); got {ozone!r}")
        object.__setattr__(self, "ozone_column_du", ozone)

    @property
    def ozone_absorption(self) -> np.ndarray:
        """Ozone absorption coefficient at the peak of its layer per channel, 1/m: the cross-section averaged over
        each Rec.709 channel under sunlight (:data:`~atmos_addon.physics.spectrum.OZONE_CHANNEL_CROSS_SECTION_M2`;
        ``wavelengths_nm`` do not enter) times the peak number density that holds ``ozone_column_du``
        (:func:`~atmos_addon.physics.spectrum.ozone_number_density_per_m3`).
        """
        peak_per_m3 = float(ozone_number_density_per_m3(DEFAULT_OZONE_PEAK_ALTITUDE_M, self.ozone_column_du))
        return OZONE_CHANNEL_CROSS_SECTION_M2 * peak_per_m3

    @staticmethod
    def ozone_density(altitude_m: ArrayLike) -> np.ndarray:
        """Ozone density relative to its peak at ``altitude_m`` (m above the ground), dimensionless in [0, 1]:
        the tent max(0, 1 - |h - 25 km| / 15 km) of Bruneton 2017, whose vertical integral is 15 km."""
        return ozone_tent(altitude_m)

    def ozone_absorption_at(self, altitude_m: ArrayLike) -> np.ndarray:
        """Ozone absorption coefficient at ``altitude_m`` per channel, 1/m, shape altitude.shape + (3,)."""
        return self.ozone_density(altitude_m)[..., np.newaxis] * self.ozone_absorption

    @property
    def scattering_coefficient(self) -> np.ndarray:
        """Total sea-level scattering coefficient beta_sc = beta_R + beta_M,sc per channel, 1/m."""
        return self.rayleigh_scattering + self.mie_scattering

    @property
    def mie_extinction(self) -> np.ndarray:
        """Sea-level aerosol extinction beta_M,sc + beta_M,abs per channel, 1/m."""
        return self.mie_scattering + self.mie_absorption

    @property
    def extinction_coefficient(self) -> np.ndarray:
        """Total sea-level extinction coefficient beta_ex = beta_R + beta_M,sc + beta_M,abs per channel, 1/m."""
        return self.rayleigh_scattering + self.mie_scattering + self.mie_absorption

    def replace(self, **changes: Any) -> "Atmosphere":
        """A copy with the given fields changed, validated again (``dataclasses.replace``).

        The Rayleigh coefficients are not recomputed when only ``wavelengths_nm`` changes; pass
        ``rayleigh_scattering=None`` as well to recompute them for the new wavelengths.
        """
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, list[float] | float]:
        """Plain lists and floats (JSON-ready), one entry per field; inverse of :meth:`from_dict`."""
        return {f.name: (getattr(self, f.name).tolist() if f.name in _RGB_FIELDS else getattr(self, f.name))
                for f in dataclasses.fields(self)}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "Atmosphere":
        """Build an atmosphere from :meth:`to_dict` output; missing fields take their defaults."""
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ValueError(f"Atmosphere.from_dict: unknown field(s) {unknown}; expected some of {sorted(known)}")
        return cls(**data)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Atmosphere):
            return NotImplemented
        return self.to_dict() == other.to_dict()

    def __hash__(self) -> int:
        return hash(tuple((k, tuple(v) if isinstance(v, list) else v) for k, v in self.to_dict().items()))
