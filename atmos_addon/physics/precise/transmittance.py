# SPDX-License-Identifier: GPL-3.0-or-later
"""What the air takes out of a beam: the local extinction coefficient, and the sun's transmittance to any point.

beta_ex(h) = beta_R n_R + (beta_M,sc + beta_M,abs) n_M + beta_O3 n_O3(h) (:func:`local_extinction`): the two
exponential layers, n_i = exp(-max(h, 0) / H_i), and where the atmosphere has ozone its absorbing tent 10-40 km up.

Sun transmittance (:class:`SunTransmittanceTable`): the optical depth to space of each exponential layer is
tau_i = beta_i H_i exp(-h / H_i) Ch(r / H_i, chi), with Chapman's grazing-incidence function Ch (:mod:`..optical_depth`)
interpolated in log from a table in (altitude, position between the local horizon and the zenith), 0.02 % of tau
against direct quadrature; plus the ozone's beta_O3 times its slant column from the same grid. The ground is
transparent to the tables: a radius below it is read at the ground, so terrain below the scene's ground level keeps
its haze; T_sun is 0 where the ray to the sun meets the planet (its shadow).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..atmosphere import Atmosphere
from ..optical_depth import chapman, ozone_slant_column
from .interpolation import bilinear

#: The sun table's samples: altitudes h_j = top (j / (n - 1))^2, and positions w_k = (k / (m - 1))^2 of the way from
#: the local horizon to the zenith.
SUN_TABLE_ALTITUDES = 96
SUN_TABLE_COSINES = 256


def local_extinction(atm: Atmosphere, n_rayleigh: np.ndarray, n_mie: np.ndarray, altitude_m: np.ndarray) -> np.ndarray:
    """beta_R n_R + (beta_M,sc + beta_M,abs) n_M + beta_O3 n_O3(h), 1/m, (..., 3), from the relative densities of the
    two exponential layers (..., 1) and the altitude (...) where the ozone's tent is read (none when there is none).
    """
    beta_ex = atm.rayleigh_scattering * n_rayleigh + atm.mie_extinction * n_mie
    return beta_ex + atm.ozone_absorption_at(altitude_m) if atm.ozone_column_du > 0.0 else beta_ex


#: The grids of the last :class:`SunTransmittanceTable` geometries, keyed by what they depend on
#: (:func:`_sun_geometry`).
_SUN_GEOMETRY: dict[tuple, tuple[np.ndarray, np.ndarray | None]] = {}


def _sun_geometry(atm: Atmosphere) -> tuple[np.ndarray, np.ndarray | None]:
    """The grids of :class:`SunTransmittanceTable` (its docstring), read-only: log Ch of each layer (n, m, 2) and,
    where the atmosphere has ozone, the ozone's slant column (n, m, 1), m. Geometry only (the planet's radius, the
    top, the scale heights): kept for the last four, so an edit of a coefficient, a colour or the ozone's amount
    reuses them (0.28 s of an atmosphere's bake)."""
    key = (float(atm.planet_radius), float(atm.atmosphere_height), float(atm.rayleigh_scale_height),
           float(atm.mie_scale_height), bool(atm.ozone_column_du > 0.0))
    if key in _SUN_GEOMETRY:
        return _SUN_GEOMETRY[key]
    altitude = atm.atmosphere_height * np.linspace(0.0, 1.0, SUN_TABLE_ALTITUDES) ** 2
    w = np.linspace(0.0, 1.0, SUN_TABLE_COSINES) ** 2
    radius = atm.planet_radius + altitude[:, None]
    mu_h = -np.sqrt(np.maximum(1.0 - (atm.planet_radius / radius) ** 2, 0.0))
    mu = np.clip(mu_h + (1.0 - mu_h) * w[None, :], -1.0, 1.0)
    zenith = np.arccos(mu)
    log_ch = np.stack([np.log(chapman(radius / h, zenith))
                       for h in (atm.rayleigh_scale_height, atm.mie_scale_height)], axis=-1)
    column = ozone_slant_column(altitude[:, None], mu, atm)[..., None] if key[4] else None
    for array in (log_ch, column):
        if array is not None:
            array.setflags(write=False)
    while len(_SUN_GEOMETRY) >= 4:
        del _SUN_GEOMETRY[next(iter(_SUN_GEOMETRY))]
    _SUN_GEOMETRY[key] = (log_ch, column)
    return log_ch, column


class SunTransmittanceTable:
    """exp(-tau to space toward the sun) from any radius r and sun zenith cosine mu, per channel.

    log Ch of each layer is tabulated at altitudes h_j = top (j / (n - 1))^2 and at w_k = (k / (m - 1))^2 of
    the way from the local horizon mu_h(r) = -sqrt(1 - R^2 / r^2) to the zenith, and interpolated bilinearly;
    the factor beta H exp(-h / H) is exact. The ozone's slant column (:func:`ozone_slant_column`), where there is
    ozone, on the same grid, interpolated linearly. Below mu_h the ray meets the planet: 0. A radius below the
    ground is taken at the ground (the table's transparent ground, as its densities are).
    """

    def __init__(self, atm: Atmosphere) -> None:
        self.atm = atm
        self.n_alt, self.n_mu = SUN_TABLE_ALTITUDES, SUN_TABLE_COSINES
        #: log Ch per layer (n, m, 2) and the ozone's slant column (n, m, 1) m, or None without ozone (read-only)
        self.log_ch, self.ozone_column = _sun_geometry(atm)

    def __call__(self, radius_m: ArrayLike, cos_zenith: ArrayLike) -> np.ndarray:
        """exp(-tau) to space, (..., 3), at radii and sun zenith cosines that broadcast: what depends on the radius
        alone is computed at the radii's own shape (a ray's samples under several suns or azimuths share it)."""
        atm = self.atm
        radius = np.clip(np.asarray(radius_m, dtype=np.float64), atm.planet_radius,
                         atm.planet_radius + atm.atmosphere_height)
        mu = np.clip(np.asarray(cos_zenith, dtype=np.float64), -1.0, 1.0)
        mu_h = -np.sqrt(np.maximum(1.0 - (atm.planet_radius / radius) ** 2, 0.0))
        lit = mu >= mu_h
        w = np.clip((mu - mu_h) / (1.0 - mu_h), 0.0, 1.0)
        altitude = radius - atm.planet_radius
        i = np.sqrt(altitude / atm.atmosphere_height) * (self.n_alt - 1)
        k = np.sqrt(w) * (self.n_mu - 1)
        slant = np.exp(bilinear(self.log_ch, i, k))                                # (..., 2): both layers
        tau = np.zeros(np.broadcast_shapes(radius.shape, mu.shape) + (3,))
        for layer, beta, height in ((0, atm.rayleigh_scattering, atm.rayleigh_scale_height),
                                    (1, atm.mie_extinction, atm.mie_scale_height)):
            tau += beta * (height * np.exp(-altitude / height) * slant[..., layer])[..., None]
        if self.ozone_column is not None:
            tau += atm.ozone_absorption * bilinear(self.ozone_column, i, k)
        return np.where(lit[..., None], np.exp(-tau), 0.0)
