# SPDX-License-Identifier: GPL-3.0-or-later
"""Chapman optical depths against Kasten & Young air masses and brute-force integration."""

import numpy as np
import pytest

from atmos_addon.physics import Atmosphere, chapman, optical_depth_to_space, relative_air_mass
from validation.reference import optical_depth_numerical

EARTH = Atmosphere(atmosphere_height=400e3)  # tall top: the Chapman layers extend to infinity
MARS = Atmosphere(planet_radius=3_389_500.0, rayleigh_scale_height=11_000.0, mie_scale_height=11_000.0,
                  rayleigh_scattering=[1e-6, 2e-6, 4e-6], mie_scattering=[1e-5, 1e-5, 1e-5],
                  mie_absorption=[2e-6, 3e-6, 5e-6], atmosphere_height=500e3)


def kasten_young_air_mass(zenith_deg):
    """Kasten & Young 1989 relative optical air mass (with refraction), zenith in degrees."""
    return 1.0 / (np.cos(np.radians(zenith_deg)) + 0.50572 * (96.07995 - zenith_deg) ** -1.6364)


def test_air_mass_matches_kasten_young():
    zenith = np.linspace(0.0, 80.0, 81)
    np.testing.assert_allclose(relative_air_mass(np.radians(zenith), Atmosphere()), kasten_young_air_mass(zenith),
                               rtol=0.02)
    horizon = relative_air_mass(np.pi / 2, Atmosphere())
    assert horizon == pytest.approx(kasten_young_air_mass(90.0), rel=0.10)  # K&Y includes refraction
    assert relative_air_mass(np.radians(90.5), Atmosphere()) == np.inf


def test_chapman_limits():
    x = np.array([100.0, 754.0, 5300.0])
    np.testing.assert_allclose(chapman(x, 0.0), 1.0, rtol=1e-12)
    # Ch(x, 90 deg) = x e^x K_1(x) = sqrt(pi x / 2) (1 + 3 / (8 x) - 15 / (128 x^2) + ...) (Huestis 2001).
    asymptotic = np.sqrt(np.pi * x / 2) * (1 + 3 / (8 * x) - 15 / (128 * x ** 2))
    np.testing.assert_allclose(chapman(x, np.pi / 2), asymptotic, rtol=1e-6)
    # Small angles: close to the flat-earth secant.
    assert chapman(754.0, np.radians(30.0)) == pytest.approx(1 / np.cos(np.radians(30.0)), rel=1e-3)


def _zenith_angles_missing_the_ground(altitude_m, atm):
    """0..90 deg, then (above the ground) descending angles up to just short of the grazing ray."""
    upward = np.radians(np.concatenate([np.arange(0.0, 85.0, 5.0), np.arange(85.0, 90.01, 0.5)]))
    if altitude_m == 0.0:
        return upward
    grazing = np.pi - np.arcsin(atm.planet_radius / (atm.planet_radius + altitude_m))
    return np.concatenate([upward, np.linspace(np.pi / 2, grazing, 8)[1:] - 1e-7])


@pytest.mark.parametrize("atm", [EARTH, MARS], ids=["earth", "mars"])
@pytest.mark.parametrize("altitude_m", [0.0, 3000.0, 20000.0])
def test_chapman_path_matches_numerical_integration(atm, altitude_m):
    for zenith in _zenith_angles_missing_the_ground(altitude_m, atm):
        numerical = optical_depth_numerical(altitude_m, zenith, atm, n_steps=8001)
        np.testing.assert_allclose(optical_depth_to_space(altitude_m, zenith, atm), numerical, rtol=5e-3,
                                   err_msg=f"altitude {altitude_m} m, zenith {np.degrees(zenith):.4f} deg")


def test_rays_into_the_ground_have_infinite_optical_depth():
    atm = Atmosphere()
    tau = optical_depth_to_space([0.0, 1000.0, 1000.0], np.radians([90.5, 95.0, 91.0]), atm)
    assert tau.shape == (3, 3)
    assert np.all(np.isinf(tau[:2])) and np.all(np.isfinite(tau[2]))  # 1 km sees 1.01 deg below horizontal
    vacuum = atm.replace(rayleigh_scattering=0.0, mie_scattering=0.0, mie_absorption=0.0)
    assert np.all(np.isinf(optical_depth_to_space(0.0, np.pi, vacuum)))
    np.testing.assert_array_equal(optical_depth_to_space(0.0, np.radians([0.0, 90.0]), vacuum), 0.0)


def test_broadcasting_and_vertical_column():
    atm = Atmosphere()
    tau = optical_depth_to_space(np.array([0.0, 1000.0])[:, None], np.radians([0.0, 45.0, 89.0]), atm)
    assert tau.shape == (2, 3, 3)
    vertical = (atm.rayleigh_scattering * atm.rayleigh_scale_height
                + atm.mie_extinction * atm.mie_scale_height)
    np.testing.assert_allclose(tau[0, 0], vertical, rtol=1e-10)
