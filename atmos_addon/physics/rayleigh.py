# SPDX-License-Identifier: GPL-3.0-or-later
"""Rayleigh scattering coefficient of dry air from physical constants.

The volume scattering coefficient of air molecules is (Bodhaine et al. 1999, eq. 2 and 13)

    beta_R(lambda) = N(p, T) * sigma(lambda),
    sigma(lambda)  = 24 pi^3 (n_s^2 - 1)^2 / (lambda^4 N_s^2 (n_s^2 + 2)^2) * F_air(lambda)     [m^2]

with ``n_s`` the refractive index of standard air (Peck & Reeder 1972, corrected for CO2 after
Edlen 1966), ``N_s`` the molecular number density of the same standard air (288.15 K, 101325 Pa),
and ``F_air`` the King correction factor for molecular anisotropy (Bates 1984, as tabulated by
Bodhaine et al. 1999, eqs. 23-25). The cross-section is evaluated at the standard state because
(n^2 - 1) / (N (n^2 + 2)) is independent of density (Lorentz-Lorenz); the number density of the
requested state ``N = p / (k T)`` multiplies it to give the coefficient in 1/m.

The optical depth of the whole column is ``sigma * p / (m_air g)`` (hydrostatic equilibrium), so an
exponential layer that reproduces both the sea-level coefficient and the column must have the scale
height ``H = k T / (m_air g)`` (about 8.43 km at 288.15 K): see :func:`rayleigh_column_scale_height`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

#: Boltzmann constant, J/K (exact, SI 2019).
BOLTZMANN_J_PER_K = 1.380649e-23
#: Avogadro constant, 1/mol (exact, SI 2019).
AVOGADRO_PER_MOL = 6.02214076e23
#: Standard gravity, m/s^2.
STANDARD_GRAVITY_M_S2 = 9.80665
#: Standard sea-level pressure, Pa.
STANDARD_PRESSURE_PA = 101325.0
#: Standard temperature of the Peck & Reeder refractive-index formula, K (15 degC).
STANDARD_TEMPERATURE_K = 288.15
#: CO2 concentration assumed by the Bodhaine et al. 1999 reference optical depths, ppm by volume.
DEFAULT_CO2_PPM = 360.0
#: Volume percentages of the main constituents of dry air (Bodhaine et al. 1999, section 4).
_N2_PERCENT, _O2_PERCENT, _AR_PERCENT = 78.084, 20.946, 0.934


def _wavenumber_per_um(wavelengths_nm: np.ndarray) -> np.ndarray:
    """Vacuum wavenumber sigma = 1 / lambda in 1/um, the variable of the dispersion formulas."""
    return 1.0e3 / wavelengths_nm


def refractive_index_standard_air(wavelengths_nm: ArrayLike, co2_ppm: float = DEFAULT_CO2_PPM) -> np.ndarray:
    """Refractive index n_s of standard dry air (288.15 K, 101325 Pa) at the given wavelengths.

    Peck & Reeder 1972 (J. Opt. Soc. Am. 62, 958) for 300 ppm CO2,

        (n_300 - 1) 1e8 = 8060.51 + 2480990 / (132.274 - sigma^2) + 17455.7 / (39.32957 - sigma^2),

    sigma in 1/um, scaled to the CO2 content C (volume fraction) by Edlen 1966:
    (n - 1) = (n_300 - 1) (1 + 0.54 (C - 0.0003)) (Bodhaine et al. 1999, eq. 19). Dimensionless.
    """
    sigma2 = _wavenumber_per_um(_positive_wavelengths(wavelengths_nm)) ** 2
    n300_minus_1 = (8060.51 + 2480990.0 / (132.274 - sigma2) + 17455.7 / (39.32957 - sigma2)) * 1.0e-8
    return 1.0 + n300_minus_1 * (1.0 + 0.54 * (co2_ppm * 1.0e-6 - 0.0003))


def king_factor_air(wavelengths_nm: ArrayLike, co2_ppm: float = DEFAULT_CO2_PPM) -> np.ndarray:
    """King correction factor F_air(lambda) of dry air (dimensionless, about 1.05).

    Bates 1984 fits as given by Bodhaine et al. 1999 (eqs. 23-25), lambda in um:
    F_N2 = 1.034 + 3.17e-4 / lambda^2, F_O2 = 1.096 + 1.385e-3 / lambda^2 + 1.448e-4 / lambda^4,
    F_Ar = 1.00, F_CO2 = 1.15, averaged with the volume percentages of the constituents.
    """
    inv_lambda2 = _wavenumber_per_um(_positive_wavelengths(wavelengths_nm)) ** 2
    f_n2 = 1.034 + 3.17e-4 * inv_lambda2
    f_o2 = 1.096 + 1.385e-3 * inv_lambda2 + 1.448e-4 * inv_lambda2 ** 2
    co2_percent = co2_ppm * 1.0e-4
    numerator = _N2_PERCENT * f_n2 + _O2_PERCENT * f_o2 + _AR_PERCENT * 1.00 + co2_percent * 1.15
    return numerator / (_N2_PERCENT + _O2_PERCENT + _AR_PERCENT + co2_percent)


def number_density_per_m3(pressure_pa: float = STANDARD_PRESSURE_PA,
                          temperature_k: float = STANDARD_TEMPERATURE_K) -> float:
    """Molecular number density N = p / (k T) of an ideal gas, 1/m^3 (2.5469e25 at 288.15 K, 101325 Pa)."""
    if not pressure_pa > 0.0 or not temperature_k > 0.0:
        raise ValueError(f"pressure_pa and temperature_k must be positive (got {pressure_pa}, {temperature_k})")
    return pressure_pa / (BOLTZMANN_J_PER_K * temperature_k)


def rayleigh_cross_section_m2(wavelengths_nm: ArrayLike, king_factor: ArrayLike | None = None,
                              co2_ppm: float = DEFAULT_CO2_PPM) -> np.ndarray:
    """Rayleigh scattering cross-section of one air molecule, m^2 (Bodhaine et al. 1999, eq. 13).

    sigma = 24 pi^3 (n_s^2 - 1)^2 / (lambda^4 N_s^2 (n_s^2 + 2)^2) F_air, with n_s and N_s of standard
    air; ``king_factor=None`` uses :func:`king_factor_air`. About 4.5e-31 m^2 at 550 nm.
    """
    wavelengths = _positive_wavelengths(wavelengths_nm)
    n2 = refractive_index_standard_air(wavelengths, co2_ppm) ** 2
    n_standard = number_density_per_m3(STANDARD_PRESSURE_PA, STANDARD_TEMPERATURE_K)
    lambda_m = wavelengths * 1.0e-9
    f_king = king_factor_air(wavelengths, co2_ppm) if king_factor is None else np.asarray(king_factor, np.float64)
    return 24.0 * np.pi ** 3 * (n2 - 1.0) ** 2 / (lambda_m ** 4 * n_standard ** 2 * (n2 + 2.0) ** 2) * f_king


def rayleigh_coefficients(wavelengths_nm: ArrayLike, pressure_pa: float = STANDARD_PRESSURE_PA,
                          temperature_k: float = STANDARD_TEMPERATURE_K, king_factor: ArrayLike | None = None,
                          co2_ppm: float = DEFAULT_CO2_PPM) -> np.ndarray:
    """Rayleigh volume scattering coefficient beta_R of dry air per wavelength, 1/m.

    beta_R = N(p, T) sigma(lambda) (Bodhaine et al. 1999, eqs. 2 and 13), with N from the ideal-gas
    law and sigma from :func:`rayleigh_cross_section_m2`. At sea level (288.15 K, 101325 Pa) this is
    about 4.9e-6, 1.15e-5 and 2.9e-5 1/m at 680, 550 and 440 nm.
    """
    return number_density_per_m3(pressure_pa, temperature_k) * rayleigh_cross_section_m2(
        wavelengths_nm, king_factor, co2_ppm)


def rayleigh_column_scale_height(temperature_k: float = STANDARD_TEMPERATURE_K,
                                 gravity_m_s2: float = STANDARD_GRAVITY_M_S2,
                                 co2_ppm: float = DEFAULT_CO2_PPM) -> float:
    """Scale height H = k T / (m_air g) of the exponential layer with the true air column, m.

    Hydrostatic equilibrium gives the column number density p / (m_air g); dividing by the sea-level
    density p / (k T) gives the height of an exponential layer holding the same column: 8434 m at
    288.15 K. ``beta_R(sea level) * H`` is then the Rayleigh optical depth of Bodhaine et al. 1999.
    The molar mass of dry air is 28.9595 + 15.0556 C_CO2 g/mol (Bodhaine et al. 1999, eq. 17).
    """
    molar_mass_kg = (28.9595 + 15.0556 * co2_ppm * 1.0e-6) * 1.0e-3
    molecule_mass_kg = molar_mass_kg / AVOGADRO_PER_MOL
    return BOLTZMANN_J_PER_K * temperature_k / (molecule_mass_kg * gravity_m_s2)


def _positive_wavelengths(wavelengths_nm: ArrayLike) -> np.ndarray:
    """Wavelengths as float64 nm, checked to lie in the range of the dispersion formula (230-2000 nm)."""
    wavelengths = np.asarray(wavelengths_nm, dtype=np.float64)
    if not np.all(np.isfinite(wavelengths)) or np.any(wavelengths < 230.0) or np.any(wavelengths > 2000.0):
        raise ValueError(f"wavelengths_nm must lie in 230..2000 nm, the range of the air dispersion formula "
                         f"(got {wavelengths_nm!r})")
    return wavelengths
