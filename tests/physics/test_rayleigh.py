# SPDX-License-Identifier: GPL-3.0-or-later
"""Rayleigh coefficients from physical constants against published optical depths."""

import numpy as np
import pytest

from atmos_addon.physics import Atmosphere, rayleigh_coefficients
from atmos_addon.physics.rayleigh import (king_factor_air, rayleigh_column_scale_height,
                                          rayleigh_cross_section_m2)

# Sea-level Rayleigh optical depths of Bodhaine et al. 1999 (Table 3; Bucholtz 1995 agrees to < 1 %).
BODHAINE_OPTICAL_DEPTH = {440.0: 0.2428, 550.0: 0.0972, 680.0: 0.0410}


@pytest.mark.parametrize("wavelength_nm, expected", sorted(BODHAINE_OPTICAL_DEPTH.items()))
def test_sea_level_optical_depth_matches_bodhaine(wavelength_nm, expected):
    # Column = p / (m g) = N_sea * H with H = k T / (m g): beta_sea * H is the column optical depth.
    tau = rayleigh_coefficients([wavelength_nm])[0] * rayleigh_column_scale_height()
    assert tau == pytest.approx(expected, rel=0.03)


def test_cross_section_and_king_factor_at_550nm():
    # Bodhaine et al. 1999, Table 2: sigma(550 nm) = 4.513e-27 cm^2, F_air(550 nm) = 1.0494 (at 360 ppm CO2).
    assert rayleigh_cross_section_m2([550.0])[0] == pytest.approx(4.513e-31, rel=5e-3)
    assert king_factor_air([550.0])[0] == pytest.approx(1.0494, abs=2e-3)


def test_coefficients_scale_with_number_density_and_lambda_minus_four():
    base = rayleigh_coefficients([550.0])[0]
    assert rayleigh_coefficients([550.0], pressure_pa=50662.5)[0] == pytest.approx(0.5 * base, rel=1e-12)
    assert rayleigh_coefficients([550.0], temperature_k=2 * 288.15)[0] == pytest.approx(0.5 * base, rel=1e-12)
    ratio = rayleigh_coefficients([440.0])[0] / base
    assert 1.05 * (550 / 440) ** 4 > ratio > (550 / 440) ** 4  # dispersion and King factor steepen lambda^-4


def test_default_atmosphere_uses_column_consistent_scale_height():
    atm = Atmosphere()
    assert atm.rayleigh_scale_height == pytest.approx(8434.5, abs=1.0)
    np.testing.assert_allclose(atm.rayleigh_scattering, rayleigh_coefficients([648.1, 547.4, 443.1]))


def test_wavelength_outside_dispersion_range_is_rejected():
    with pytest.raises(ValueError, match="wavelengths_nm"):
        rayleigh_coefficients([100.0])
