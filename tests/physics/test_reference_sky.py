# SPDX-License-Identifier: GPL-3.0-or-later
"""The spectral reference sky: wavelength bookkeeping, linearity, ozone's sign, and first order against quadrature.

Path counts are tiny (the full runs are validation/measure_reference_sky.py); every Monte Carlo comparison allows for
the estimator's own standard error, and the seeds are fixed.
"""

import numpy as np
import pytest

from atmos_addon import presets
from atmos_addon.physics import Atmosphere
from validation.reference import distance_to_top, single_scattering
from validation.spectral_reference import (N_TRIPLES, RGB_WEIGHTS, TRIPLE_INDICES, XYZ_WEIGHTS, OzoneTriple,
                                           aerosol_angstrom_fit, linear_stderr, ratio_and_stderr, spectral_coefficients,
                                           spectral_radiance, spectral_sky, triple_atmospheres)
from atmos_addon.physics.spectrum import (CIE_1931_XYZ_BAR, SOLAR_IRRADIANCE_TOP_W_M2_NM, WAVELENGTHS_NM,
                                          channel_value_at, chromaticity_xy, ozone_absorption_per_m,
                                          rayleigh_spectrum_per_m, spectrum_to_linear_rec709, spectrum_to_xyz,
                                          xyz_to_linear_rec709)

ZENITH = np.array([0.0, 0.0, 1.0])


def _sun(elevation_deg):
    elevation = np.radians(elevation_deg)
    return np.array([0.0, np.cos(elevation), np.sin(elevation)])


def at(wavelength_nm):
    return int(np.flatnonzero(WAVELENGTHS_NM == wavelength_nm)[0])


@pytest.fixture(scope="module")
def clear():
    return presets.load("clear").atmosphere


def test_triples_cover_the_grid_once_in_order():
    assert N_TRIPLES == 16 and TRIPLE_INDICES.shape == (16, 3)
    np.testing.assert_array_equal(np.sort(TRIPLE_INDICES.ravel()), np.arange(WAVELENGTHS_NM.size))
    atmospheres = triple_atmospheres(Atmosphere())
    for indices, atm in zip(TRIPLE_INDICES, atmospheres, strict=True):
        np.testing.assert_array_equal(atm.wavelengths_nm, WAVELENGTHS_NM[indices])
        np.testing.assert_array_equal(atm.sun_irradiance_top, SOLAR_IRRADIANCE_TOP_W_M2_NM[indices])


def test_spectral_atmosphere_passes_through_the_clear_preset(clear):
    # The preset's comments: 550 nm aerosol extinction 4.440e-5 1/m, alpha 1.3, albedo 0.93, g 0.76.
    fit = aerosol_angstrom_fit(clear)
    assert fit["extinction_550_per_m"] == pytest.approx(4.440e-5, rel=1e-3)
    assert fit["alpha"] == pytest.approx(1.3, abs=2e-3)
    assert fit["single_scattering_albedo"] == pytest.approx(0.93, abs=1e-4)
    assert fit["g"] == pytest.approx(0.76)
    spectra = spectral_coefficients(clear)
    np.testing.assert_allclose(spectra["rayleigh_scattering"], rayleigh_spectrum_per_m(), rtol=1e-12)  # standard air
    for channel, wavelength in enumerate(clear.wavelengths_nm):  # the preset's own channels are reproduced
        assert channel_value_at(wavelength, WAVELENGTHS_NM, spectra["mie_scattering"]) == pytest.approx(
            clear.mie_scattering[channel], rel=2e-3)
        assert channel_value_at(wavelength, WAVELENGTHS_NM, spectra["mie_absorption"]) == pytest.approx(
            clear.mie_absorption[channel], rel=2e-3)


def test_ozone_callback_is_the_spectral_ozone_at_the_triples_wavelengths():
    altitude = np.linspace(0.0, 50_000.0, 201)
    for indices in TRIPLE_INDICES[[0, 8, 15]]:
        np.testing.assert_allclose(OzoneTriple(indices, 300.0)(altitude),
                                   ozone_absorption_per_m(altitude, 300.0)[..., indices], rtol=1e-13, atol=0.0)


def test_assembly_is_linear_in_the_sun_spectrum():
    # Same seeds, so the paths do not depend on the sun: doubling the sun doubles every number, and two sun
    # spectra add. A grey world (no air, grey aerosol) with ozone 0.
    grey = Atmosphere(rayleigh_scattering=0.0, mie_scattering=2e-5, mie_absorption=2e-6, mie_g=0.7)
    sun = SOLAR_IRRADIANCE_TOP_W_M2_NM
    blue = np.where(WAVELENGTHS_NM < 550.0, sun, 0.0)
    run = dict(atmosphere=grey, ozone_du=0.0, paths=60, seed=3, triples=[1, 6, 12])
    views = [ZENITH, [0.0, 0.9, 0.1]]
    once, error = spectral_radiance(views, _sun(30.0), **run)
    twice, error_twice = spectral_radiance(views, _sun(30.0), sun_spectrum=2.0 * sun, **run)
    split = spectral_radiance(views, _sun(30.0), sun_spectrum=blue, **run)[0] + \
        spectral_radiance(views, _sun(30.0), sun_spectrum=sun - blue, **run)[0]
    computed = ~np.isnan(once)
    assert computed.sum() == 2 * 9 and np.all(once[computed] > 0.0)
    np.testing.assert_allclose(twice[computed], 2.0 * once[computed], rtol=1e-12)
    np.testing.assert_allclose(error_twice[computed], 2.0 * error[computed], rtol=1e-12)
    np.testing.assert_allclose(split[computed], once[computed], rtol=1e-12)


def test_each_wavelength_lands_in_its_own_slot():
    # Sunlight at 550 nm only: only that wavelength is lit, and the colour is the spectral locus at 550 nm.
    delta = np.where(WAVELENGTHS_NM == 550.0, 1.5, 0.0)
    spectrum, _ = spectral_radiance(ZENITH, _sun(40.0), atmosphere=Atmosphere(), ozone_du=300.0, paths=40, seed=4,
                                    sun_spectrum=delta, triples=[at(550) // 3])
    lit = np.flatnonzero(np.nan_to_num(spectrum) > 0.0)
    np.testing.assert_array_equal(lit, [at(550)])
    xyz = np.nan_to_num(spectrum) @ XYZ_WEIGHTS
    np.testing.assert_allclose(chromaticity_xy(xyz), chromaticity_xy(CIE_1931_XYZ_BAR[at(550)]), rtol=1e-12)
    # The weights are those of the spectrum module's conversions.
    test_spectrum = np.linspace(0.5, 2.0, WAVELENGTHS_NM.size)
    np.testing.assert_allclose(test_spectrum @ XYZ_WEIGHTS, spectrum_to_xyz(test_spectrum), rtol=1e-13)
    np.testing.assert_allclose(test_spectrum @ RGB_WEIGHTS, spectrum_to_linear_rec709(test_spectrum), rtol=1e-12)


def test_ozone_makes_the_low_sun_zenith_bluer(clear):
    # Ozone's Chappuis band (500-700 nm) takes the green and red out of sunlight that crosses the ozone layer
    # obliquely: at sun 1 deg the zenith B/R rises by half (measured 2.3 vs 1.4 with more paths) and Y drops.
    options = dict(atmosphere=clear, ground_albedo=0.3, paths=150, seed=5)
    ratios, luminance = [], []
    for ozone in (300.0, 0.0):
        spectrum, error = spectral_radiance(ZENITH, _sun(1.0), ozone_du=ozone, **options)
        ratios.append(ratio_and_stderr(spectrum, error, RGB_WEIGHTS[:, 2], RGB_WEIGHTS[:, 0]))
        luminance.append((spectrum @ XYZ_WEIGHTS[:, 1], linear_stderr(error, XYZ_WEIGHTS[:, 1])))
    (on, on_error), (off, off_error) = ratios
    assert on > 1.3 * off and on - off > 4.0 * np.hypot(on_error, off_error), ratios
    (y_on, y_on_error), (y_off, y_off_error) = luminance
    assert y_on < 0.85 * y_off and y_off - y_on > 3.0 * np.hypot(y_on_error, y_off_error), luminance


def test_first_order_is_the_quadrature_single_scattering(clear):
    # max_order=1 at sun 60 deg, zenith, two triples (blue-green and red), against reference.single_scattering
    # on the same three-wavelength atmospheres (no ozone: the quadrature has no extra absorber).
    triples = [4, 10]
    spectrum, error = spectral_radiance(ZENITH, _sun(60.0), atmosphere=clear, ozone_du=0.0, ground_albedo=0.3,
                                        max_order=1, paths=1500, seed=6, triples=triples)
    atmospheres = triple_atmospheres(clear)
    distance = float(distance_to_top(np.asarray(clear.planet_radius), np.asarray(1.0), clear))
    for t in triples:
        expected = single_scattering(0.0, ZENITH, distance, _sun(60.0), atmospheres[t], n_steps=1001,
                                     n_sun_steps=129)[1]
        mc, se = spectrum[TRIPLE_INDICES[t]], error[TRIPLE_INDICES[t]]
        assert np.all(se < 0.01 * expected), (t, se / expected)  # the test has teeth
        assert np.all(np.abs(mc - expected) <= 3.0 * se + 0.005 * expected), (t, mc, expected, se)


def test_ratio_stderr_is_the_first_order_propagation():
    rng = np.random.default_rng(7)
    spectrum = rng.uniform(1.0, 2.0, WAVELENGTHS_NM.size)
    stderr = np.zeros_like(spectrum)
    stderr[20] = 1e-3
    a, b = RGB_WEIGHTS[:, 2], RGB_WEIGHTS[:, 0]
    ratio, error = ratio_and_stderr(spectrum, stderr, a, b)
    bumped = spectrum.copy()
    bumped[20] += 1e-6
    derivative = ((bumped @ a) / (bumped @ b) - ratio) / 1e-6
    assert ratio == pytest.approx((spectrum @ a) / (spectrum @ b), rel=1e-14)
    assert error == pytest.approx(abs(derivative) * 1e-3, rel=1e-4)
    assert ratio_and_stderr(spectrum, stderr + 1e-3, a, a)[1] == pytest.approx(0.0, abs=1e-15)


def test_spectral_sky_returns_rgb_xyz_and_rgb_error():
    rgb, xyz, error = spectral_sky(ZENITH, _sun(45.0), atmosphere=Atmosphere(), ozone_du=0.0, paths=10, seed=8,
                                   max_order=1)
    assert rgb.shape == xyz.shape == error.shape == (3,)
    np.testing.assert_allclose(rgb, xyz_to_linear_rec709(xyz), rtol=1e-12)
    assert np.all(xyz > 0.0) and np.all(error > 0.0) and rgb[2] > rgb[0]
    with pytest.raises(ValueError):
        spectral_radiance(ZENITH, _sun(45.0), ozone_du=-1.0, paths=10)
