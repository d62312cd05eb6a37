# SPDX-License-Identifier: GPL-3.0-or-later
"""Eq. 19 closed form: limits, the stable phi1, broadcasting and float32/float64 stability sweeps."""

import numpy as np
import pytest

from atmos_addon.physics import (SMALL_OPTICAL_DEPTH, Atmosphere, aerial_perspective, extinction, inscattering,
                                 one_minus_exp_over_x, phase_hg, phase_rayleigh)

DTYPES = [np.float64, np.float32]
TOLERANCE = {np.float64: 1e-5, np.float32: 1e-3}


def _exact_phi1(x):
    x = np.asarray(x, dtype=np.float64)
    return np.where(x > 0, -np.expm1(-x) / np.where(x > 0, x, 1.0), 1.0)


@pytest.mark.parametrize("dtype", DTYPES)
def test_phi1_matches_expm1_form(dtype):
    x = np.concatenate([[0.0], np.geomspace(1e-12, 1e4, 2000)])
    got = one_minus_exp_over_x(x.astype(dtype), dtype)
    assert got.dtype == dtype
    rel = 1e-10 if dtype == np.float64 else 1e-4  # series truncation x^3/24 <= 4.2e-11 at the threshold
    np.testing.assert_allclose(got, _exact_phi1(x.astype(dtype)), rtol=rel)


@pytest.mark.parametrize("dtype", DTYPES)
def test_phi1_is_continuous_across_the_series_threshold(dtype):
    threshold = dtype(SMALL_OPTICAL_DEPTH)
    below = np.nextafter(threshold, dtype(0.0))
    jump = abs(float(one_minus_exp_over_x(threshold, dtype)) - float(one_minus_exp_over_x(below, dtype)))
    assert jump < (1e-10 if dtype == np.float64 else 1e-4)


def test_extinction_is_beer_lambert():
    atm = Atmosphere()
    s = np.array([0.0, 1e3, 1e5])
    np.testing.assert_allclose(extinction(s, atm), np.exp(-np.outer(s, atm.extinction_coefficient)))


def test_inscattering_equals_paper_form():
    atm = Atmosphere()
    s, mu, e_sun = 20e3, 0.4, np.array([3.0, 3.2, 3.5])
    beta_ex = atm.extinction_coefficient
    angular = atm.rayleigh_scattering * phase_rayleigh(mu) + atm.mie_scattering * phase_hg(mu, atm.mie_g)
    expected = angular / beta_ex * e_sun * (1.0 - np.exp(-beta_ex * s))
    np.testing.assert_allclose(inscattering(s, mu, atm, e_sun), expected, rtol=1e-12)
    l0 = np.array([0.2, 0.5, 0.1])
    np.testing.assert_allclose(aerial_perspective(l0, s, mu, atm, e_sun),
                               l0 * np.exp(-beta_ex * s) + expected, rtol=1e-12)


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("scale", [1.0, 100.0])
def test_optically_thin_limit(dtype, scale):
    atm = Atmosphere(rayleigh_scattering=scale * Atmosphere().rayleigh_scattering, mie_scattering=scale * 3.3e-5,
                     mie_absorption=scale * 3.3e-6)
    s = np.geomspace(1e-6, 1e-3, 13)
    mu = np.linspace(-1.0, 1.0, 13)
    e_sun = np.array([1.0, 2.0, 3.0])
    angular = (atm.rayleigh_scattering * phase_rayleigh(mu)[:, None]
               + atm.mie_scattering * phase_hg(mu, atm.mie_g))
    expected = angular * e_sun * s[:, None]
    got = inscattering(s, mu, atm, e_sun, dtype)
    assert got.dtype == dtype
    np.testing.assert_allclose(got, expected, rtol=TOLERANCE[dtype])


def test_saturates_to_scattering_over_extinction_times_phase():
    atm = Atmosphere()
    got = inscattering(1e7, 1.0, atm, 1.0)
    angular = atm.rayleigh_scattering * phase_rayleigh(1.0) + atm.mie_scattering * phase_hg(1.0, atm.mie_g)
    np.testing.assert_allclose(got, angular / atm.extinction_coefficient, rtol=1e-12)


def test_broadcasting_shapes():
    atm = Atmosphere()
    s = np.linspace(0.0, 1e4, 4).reshape(4, 1)
    mu = np.linspace(-1.0, 1.0, 5)
    assert inscattering(s, mu, atm, [1.0, 1.0, 1.0]).shape == (4, 5, 3)
    assert inscattering(s, mu, atm, np.ones((4, 5, 3))).shape == (4, 5, 3)
    assert extinction(s, atm).shape == (4, 1, 3)
    assert aerial_perspective(np.ones((4, 5, 3)), s, mu, atm, 1.0).shape == (4, 5, 3)


@pytest.mark.parametrize("dtype", DTYPES)
def test_float32_tracks_float64(dtype):
    atm = Atmosphere()
    s = np.geomspace(1.0, 1e6, 50)[:, None]
    mu = np.linspace(-1.0, 1.0, 21)
    ref = aerial_perspective([0.3, 0.4, 0.5], s, mu, atm, [4.0, 3.8, 3.3])
    got = aerial_perspective([0.3, 0.4, 0.5], s, mu, atm, [4.0, 3.8, 3.3], dtype)
    assert got.dtype == dtype
    np.testing.assert_allclose(got, ref, rtol=1e-4)


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("scale", [0.0, 1e-3, 1.0, 100.0])
def test_stability_sweep(dtype, scale):
    distances = np.concatenate([[0.0], np.geomspace(1e-3, 1e7, 61)])[:, None]
    mu = np.linspace(-1.0, 1.0, 41)
    for g in (-0.999, -0.5, 0.0, 0.76, 0.999):
        default = Atmosphere()
        atm = default.replace(rayleigh_scattering=scale * default.rayleigh_scattering,
                              mie_scattering=scale * default.mie_scattering,
                              mie_absorption=scale * default.mie_absorption, mie_g=g)
        f_ex = extinction(distances, atm, dtype)
        l_in = inscattering(distances, mu, atm, [4.5, 4.5, 4.5], dtype)
        total = aerial_perspective([1.0, 1.0, 1.0], distances, mu, atm, [4.5, 4.5, 4.5], dtype)
        for values in (f_ex, l_in, total):
            assert values.dtype == dtype
            assert np.all(np.isfinite(values)) and np.all(values >= 0.0)
        assert np.all(f_ex <= 1.0)
        np.testing.assert_array_equal(l_in[0], 0.0)  # zero distance adds nothing
        if scale == 0.0:
            np.testing.assert_array_equal(l_in, 0.0)
            np.testing.assert_array_equal(f_ex, 1.0)
        else:
            assert np.all(np.diff(l_in, axis=0) >= -1e-6 * l_in.max())  # grows with distance


def test_negative_distance_is_clamped_to_zero():
    atm = Atmosphere()
    np.testing.assert_array_equal(extinction(-5.0, atm), 1.0)
    np.testing.assert_array_equal(inscattering(-5.0, 0.5, atm, 1.0), 0.0)
