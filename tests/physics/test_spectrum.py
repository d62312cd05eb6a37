# SPDX-License-Identifier: GPL-3.0-or-later
"""Spectral tables and colour conversion against published colorimetric and atmospheric facts."""

import numpy as np
import pytest

from atmos_addon.physics import rayleigh_coefficients
from atmos_addon.physics.spectrum import (CHANNEL_WAVELENGTHS_NM, CIE_1931_XYZ_BAR, D65_WHITE_XYZ, DOBSON_UNIT_PER_M2,
                                          LINEAR_REC709_TO_XYZ, OZONE_CROSS_SECTION_M2,
                                          SOLAR_CONSTANT_ASTM_G173_W_M2, SOLAR_IRRADIANCE_TOP_W_M2_NM, SUN_TOP_RGB,
                                          WAVELENGTH_STEP_NM, WAVELENGTHS_NM, XYZ_TO_LINEAR_REC709,
                                          angstrom_spectrum, channel_response_weights, channel_value_at,
                                          chromaticity_xy, ozone_absorption_per_m,
                                          ozone_number_density_per_m3, ozone_vertical_optical_depth,
                                          rayleigh_spectrum_per_m, spectrum_to_linear_rec709, spectrum_to_xyz,
                                          xyz_to_linear_rec709)


def at(wavelength_nm):
    """Index of a grid wavelength."""
    return int(np.flatnonzero(WAVELENGTHS_NM == wavelength_nm)[0])


def test_grid_covers_the_visible_every_10nm():
    assert WAVELENGTHS_NM[0] == 360.0 and WAVELENGTHS_NM[-1] == 830.0
    np.testing.assert_array_equal(np.diff(WAVELENGTHS_NM), WAVELENGTH_STEP_NM)
    assert np.count_nonzero((WAVELENGTHS_NM >= 380.0) & (WAVELENGTHS_NM <= 780.0)) >= 16
    for table in (SOLAR_IRRADIANCE_TOP_W_M2_NM, OZONE_CROSS_SECTION_M2, CIE_1931_XYZ_BAR):
        assert table.shape[0] == WAVELENGTHS_NM.size and np.all(table >= 0.0)
        with pytest.raises(ValueError):
            table[0] = 1.0  # read-only


def test_cie_1931_matching_functions_peaks_and_area():
    xbar, ybar, zbar = CIE_1931_XYZ_BAR.T
    # CIE 1931 table: y_bar = 1 at 555 nm (0.99495 and 0.995 at 550 and 560), x_bar 1.0622 at 600 nm with a
    # secondary peak 0.34828 at 440 nm, z_bar 1.77211 at 450 nm.
    assert WAVELENGTHS_NM[np.argmax(ybar)] in (550.0, 560.0) and ybar.max() == pytest.approx(1.0, abs=0.01)
    assert WAVELENGTHS_NM[np.argmax(xbar)] == 600.0 and xbar.max() == pytest.approx(1.0622, abs=1e-4)
    blue = WAVELENGTHS_NM < 500.0
    assert WAVELENGTHS_NM[blue][np.argmax(xbar[blue])] == 440.0 and xbar[blue].max() == pytest.approx(0.34828)
    assert WAVELENGTHS_NM[np.argmax(zbar)] == 450.0 and zbar.max() == pytest.approx(1.77211)
    # The 1 nm table integrates to 106.857 for each function (equal-energy white has X = Y = Z).
    np.testing.assert_allclose(CIE_1931_XYZ_BAR.sum(axis=0) * WAVELENGTH_STEP_NM, 106.857, rtol=2e-3)


def test_equal_energy_spectrum_is_achromatic():
    xyz = spectrum_to_xyz(np.ones(WAVELENGTHS_NM.size))
    assert xyz[1] == pytest.approx(106.86, rel=2e-3)  # radiometric: no 683 lm/W
    np.testing.assert_allclose(chromaticity_xy(xyz), [1 / 3, 1 / 3], atol=1e-3)


def test_xyz_to_rec709_matrix_maps_d65_to_white_and_matches_iec_61966():
    np.testing.assert_allclose(XYZ_TO_LINEAR_REC709 @ [0.9505, 1.0, 1.089], [1.0, 1.0, 1.0], atol=1e-3)
    np.testing.assert_allclose(xyz_to_linear_rec709(D65_WHITE_XYZ), [1.0, 1.0, 1.0], atol=1e-12)
    iec = [[3.2406, -1.5372, -0.4986], [-0.9689, 1.8758, 0.0415], [0.0557, -0.2040, 1.0570]]  # 4-decimal print
    np.testing.assert_allclose(XYZ_TO_LINEAR_REC709, iec, atol=5e-4)
    primaries_xy = chromaticity_xy(LINEAR_REC709_TO_XYZ.T)  # rows: XYZ of R, G, B
    np.testing.assert_allclose(primaries_xy, [[0.64, 0.33], [0.30, 0.60], [0.15, 0.06]], atol=1e-12)
    assert LINEAR_REC709_TO_XYZ[1].sum() == pytest.approx(1.0)  # white has Y = 1


def test_conversions_follow_the_wavelength_axis_and_reject_wrong_lengths():
    spectra = np.stack([SOLAR_IRRADIANCE_TOP_W_M2_NM, np.ones(WAVELENGTHS_NM.size)], axis=1)  # (48, 2)
    xyz = spectrum_to_xyz(spectra, axis=0)
    assert xyz.shape == (2, 3)
    np.testing.assert_allclose(xyz[0], spectrum_to_xyz(SOLAR_IRRADIANCE_TOP_W_M2_NM))
    np.testing.assert_allclose(spectrum_to_linear_rec709(spectra, axis=0), xyz @ XYZ_TO_LINEAR_REC709.T)
    assert np.isnan(chromaticity_xy([0.0, 0.0, 0.0])).all()
    with pytest.raises(ValueError, match="48"):
        spectrum_to_xyz(np.ones(47))
    with pytest.raises(ValueError, match="last axis"):
        xyz_to_linear_rec709(np.ones(4))


def test_solar_spectrum_integral_peak_and_colour():
    band_w_m2 = SOLAR_IRRADIANCE_TOP_W_M2_NM.sum() * WAVELENGTH_STEP_NM  # 355-835 nm
    assert 700.0 < band_w_m2 < 800.0
    assert 0.5 < band_w_m2 / SOLAR_CONSTANT_ASTM_G173_W_M2 < 0.6
    assert 450.0 <= WAVELENGTHS_NM[np.argmax(SOLAR_IRRADIANCE_TOP_W_M2_NM)] <= 500.0
    assert SOLAR_IRRADIANCE_TOP_W_M2_NM[at(550)] == pytest.approx(1.87, rel=0.02)  # ASTM G173: 1.86 at 550 nm
    x, y = chromaticity_xy(spectrum_to_xyz(SOLAR_IRRADIANCE_TOP_W_M2_NM))
    assert 0.32 < x < 0.33 and 0.33 < y < 0.34  # about 5900 K, a little warmer than D65 (0.3127, 0.3290)
    rgb = spectrum_to_linear_rec709(SOLAR_IRRADIANCE_TOP_W_M2_NM)
    assert rgb[0] > rgb[1] > rgb[2] > 0.0 and rgb.max() / rgb.min() < 1.25


def test_ozone_profile_holds_the_requested_column():
    altitude_m = np.linspace(0.0, 100_000.0, 100_001)
    for column_du in (300.0, 450.0):
        density = ozone_number_density_per_m3(altitude_m, column_du)
        column = np.sum(0.5 * (density[1:] + density[:-1]) * np.diff(altitude_m)) / DOBSON_UNIT_PER_M2
        assert column == pytest.approx(column_du, rel=5e-3)
    density = ozone_number_density_per_m3(altitude_m)
    assert altitude_m[np.argmax(density)] == 25_000.0 and density.max() == pytest.approx(5.37e18, rel=2e-3)
    assert np.all(density[(altitude_m <= 10_000.0) | (altitude_m >= 40_000.0)] == 0.0)
    assert DOBSON_UNIT_PER_M2 == pytest.approx(2.6867e20, rel=1e-4)
    with pytest.raises(ValueError, match="above the ground"):
        ozone_number_density_per_m3(0.0, peak_altitude_m=5_000.0)
    with pytest.raises(ValueError, match="total_column_du"):
        ozone_number_density_per_m3(0.0, -1.0)


def test_ozone_chappuis_band_and_optical_depth():
    chappuis = (WAVELENGTHS_NM >= 500.0) & (WAVELENGTHS_NM <= 700.0)
    peak_nm = WAVELENGTHS_NM[chappuis][np.argmax(OZONE_CROSS_SECTION_M2[chappuis])]
    assert 590.0 <= peak_nm <= 610.0
    assert 4.0e-25 < OZONE_CROSS_SECTION_M2[chappuis].max() < 5.5e-25  # 5.1e-21 cm^2 near 603 nm
    assert OZONE_CROSS_SECTION_M2[at(600)] > 10 * OZONE_CROSS_SECTION_M2[at(450)]  # the blue is hardly absorbed
    tau = ozone_vertical_optical_depth(300.0)
    assert 0.035 < tau[at(600)] < 0.045
    # Hillaire 2020 / Bruneton 2017: 1.881e-6 1/m at 550 nm at the peak density of a 15 km-wide tent of 300 DU.
    assert tau[at(550)] == pytest.approx(1.881e-6 * 15_000.0, rel=0.1)
    absorption = ozone_absorption_per_m(np.array([25_000.0, 0.0]))
    assert absorption.shape == (2, WAVELENGTHS_NM.size) and np.all(absorption[1] == 0.0)
    np.testing.assert_allclose(absorption[0] * 15_000.0, tau, rtol=1e-12)  # tent area = peak * half width


def test_ozone_agrees_with_serdyuchenko_233k_over_the_chappuis_band():
    # Serdyuchenko et al. 2014 at 233 K, 10 nm bin means over [lambda, lambda + 10) nm for lambda = 550..650
    # (Bruneton 2017, demo.cc), m^2. Band integral 555-655 nm, half bins at both ends.
    serdyuchenko = np.array([3.5e-25, 4.266e-25, 4.672e-25, 4.398e-25, 4.701e-25, 5.019e-25, 4.305e-25,
                             3.74e-25, 3.215e-25, 2.662e-25, 2.238e-25])
    weights = np.r_[0.5, np.ones(9), 0.5]
    band_serdyuchenko = np.sum(weights * serdyuchenko) * 10.0
    band_here = OZONE_CROSS_SECTION_M2[at(560):at(650) + 1].sum() * 10.0  # centred bins 555-655 nm
    assert band_here == pytest.approx(band_serdyuchenko, rel=0.05)


def test_rayleigh_spectrum_is_the_bodhaine_coefficient_on_the_grid():
    beta = rayleigh_spectrum_per_m()
    assert np.all(np.diff(beta) < 0.0)
    assert beta[at(550)] == pytest.approx(rayleigh_coefficients([550.0])[0], rel=1e-12)
    assert rayleigh_spectrum_per_m(pressure_pa=50662.5)[at(550)] == pytest.approx(0.5 * beta[at(550)], rel=1e-12)


def test_angstrom_law():
    beta = angstrom_spectrum(2.0e-5, 1.3)
    assert beta[at(550)] == pytest.approx(2.0e-5, rel=1e-12)
    assert beta[at(440)] / beta[at(550)] == pytest.approx((440 / 550) ** -1.3, rel=1e-12)
    np.testing.assert_allclose(angstrom_spectrum(3.0e-5, 0.0), 3.0e-5)
    assert angstrom_spectrum([1.0e-5, 2.0e-5], 1.0).shape == (2, WAVELENGTHS_NM.size)
    with pytest.raises(ValueError, match="beta_550_per_m"):
        angstrom_spectrum(-1.0e-5, 1.0)


# --- Three channels standing for the spectrum ------------------------------------------------------------------


def test_channel_weights_turn_a_thin_layer_s_spectrum_into_its_rgb():
    """The optically thin limit, exactly: a layer scattering beta(lambda) under the sun renders, in linear Rec.709,
    the sun's RGB times each channel's weighted mean of beta; for Rayleigh that mean is standard air's coefficient at
    the channel wavelengths 648.1 / 547.4 / 443.1 nm (to the 0.1 nm they are rounded to)."""
    weights = channel_response_weights()
    np.testing.assert_allclose(weights.sum(axis=0), 1.0, rtol=1e-12)
    assert weights[:, 0].min() < 0.0  # the red channel's negative lobe in the blue-green
    sun_rgb = spectrum_to_linear_rec709(SOLAR_IRRADIANCE_TOP_W_M2_NM)
    for beta in (rayleigh_spectrum_per_m(), angstrom_spectrum(4.44e-5, 1.3)):
        np.testing.assert_allclose(spectrum_to_linear_rec709(SOLAR_IRRADIANCE_TOP_W_M2_NM * beta),
                                   sun_rgb * (beta @ weights), rtol=1e-12)
    np.testing.assert_array_equal(CHANNEL_WAVELENGTHS_NM, [648.1, 547.4, 443.1])
    np.testing.assert_allclose(rayleigh_coefficients(CHANNEL_WAVELENGTHS_NM), rayleigh_spectrum_per_m() @ weights,
                               rtol=1e-3)
    # The customary 680 / 550 / 440 nm: a thin Rayleigh sky 25 % too blue in B/R.
    seed = rayleigh_coefficients([680.0, 550.0, 440.0])
    band = rayleigh_spectrum_per_m() @ weights
    assert (seed[2] / seed[0]) / (band[2] / band[0]) == pytest.approx(1.25, abs=0.01)
    # An Angstrom aerosol read at the channel wavelengths: within 1.1 % of its band mean (alpha 1.3).
    np.testing.assert_allclose((CHANNEL_WAVELENGTHS_NM / 550.0) ** -1.3, (WAVELENGTHS_NM / 550.0) ** -1.3 @ weights,
                               rtol=0.012)


def test_the_sun_above_the_atmosphere_is_the_solar_spectrum_s_colour():
    np.testing.assert_allclose(SUN_TOP_RGB, [1.0973, 0.9769, 0.9423], atol=1e-4)
    assert float(LINEAR_REC709_TO_XYZ[1] @ SUN_TOP_RGB) == pytest.approx(1.0, rel=1e-12)  # luminance 1
    x, y = chromaticity_xy(LINEAR_REC709_TO_XYZ @ SUN_TOP_RGB)
    assert (x, y) == pytest.approx((0.3230, 0.3327), abs=5e-4)  # warmer than D65 (0.3127, 0.3290)


def test_channel_value_at_reads_a_power_law_between_channels():
    wavelengths = np.array([648.1, 547.4, 443.1])
    np.testing.assert_allclose(channel_value_at(550.0, wavelengths, 2.0 * (wavelengths / 550.0) ** -1.3), 2.0,
                               rtol=1e-12)
    assert channel_value_at(550.0, wavelengths, rayleigh_coefficients(wavelengths)) == pytest.approx(
        float(rayleigh_coefficients([550.0])[0]), rel=1e-4)
    assert channel_value_at(700.0, wavelengths, [1.0, 2.0, 3.0]) == 1.0  # the nearest channel outside
    assert channel_value_at(400.0, wavelengths, [1.0, 2.0, 3.0]) == 3.0
    assert channel_value_at(597.75, wavelengths, [1.0, 0.0, 3.0]) == pytest.approx(0.5)  # a zero: a straight line


def test_default_channels_render_the_spectral_single_scattering_sky():
    """The clear preset's sky by brute-force single scattering (ozone included), three channels against 48
    wavelengths turned into linear Rec.709: with the channel wavelengths and the solar spectrum's sun the zenith's
    chromaticity is within 0.0025 (CIE xy) of the spectrum's at a sun of 60, 20 and 5 deg, its B/R within 5 % down to
    6 deg below the horizon; the seed's 680 / 550 / 440 nm under a white sun are 0.012-0.017 off by day."""
    from atmos_addon import presets
    from atmos_addon.physics import atmosphere as atmosphere_module
    from validation.reference import single_scattering
    from validation.spectral_reference import RGB_WEIGHTS, TRIPLE_INDICES, triple_atmospheres

    clear = presets.load("clear").atmosphere
    seed = clear.replace(wavelengths_nm=[680.0, 550.0, 440.0], rayleigh_scattering=None, sun_irradiance_top=4.5,
                         mie_scattering=clear.mie_scattering * (np.array([680.0, 550.0, 440.0]) / clear.wavelengths_nm)
                         ** -1.3,
                         mie_absorption=clear.mie_absorption * (np.array([680.0, 550.0, 440.0]) / clear.wavelengths_nm)
                         ** -1.3)
    zenith = np.array([0.0, 0.0, 1.0])
    top = clear.atmosphere_height
    channel_cross_section = atmosphere_module.OZONE_CHANNEL_CROSS_SECTION_M2

    def xy(rgb):
        return chromaticity_xy(LINEAR_REC709_TO_XYZ @ rgb)

    try:
        for sun_deg in (60.0, 20.0, 5.0, -2.0, -6.0):
            e = np.radians(sun_deg)
            sun = np.array([np.cos(e), 0.0, np.sin(e)])
            spectrum = np.empty(WAVELENGTHS_NM.size)
            for indices, atm in zip(TRIPLE_INDICES, triple_atmospheres(clear), strict=True):
                # One triple's ozone: the spectrum's cross-sections at its three wavelengths.
                atmosphere_module.OZONE_CHANNEL_CROSS_SECTION_M2 = OZONE_CROSS_SECTION_M2[indices]
                spectrum[indices] = single_scattering(2.0, zenith, top, sun, atm.replace(ozone_column_du=300.0),
                                                      n_steps=401, n_sun_steps=65)[1]
            atmosphere_module.OZONE_CHANNEL_CROSS_SECTION_M2 = channel_cross_section
            truth = spectrum @ RGB_WEIGHTS
            ours = single_scattering(2.0, zenith, top, sun, clear, n_steps=401, n_sun_steps=65)[1]
            assert ours[2] / ours[0] == pytest.approx(truth[2] / truth[0], rel=0.05), sun_deg
            if sun_deg >= 5.0:
                assert np.linalg.norm(xy(ours) - xy(truth)) < 0.0025, sun_deg
            if sun_deg >= 20.0:
                assert np.linalg.norm(xy(single_scattering(2.0, zenith, top, sun, seed, n_steps=401,
                                                           n_sun_steps=65)[1]) - xy(truth)) > 0.012, sun_deg
    finally:
        atmosphere_module.OZONE_CHANNEL_CROSS_SECTION_M2 = channel_cross_section
