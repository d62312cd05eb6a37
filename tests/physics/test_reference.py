# SPDX-License-Identifier: GPL-3.0-or-later
"""The brute-force integrator against closed forms: vertical columns and the constant-density limit."""

import numpy as np
import pytest

from atmos_addon.physics import Atmosphere, inscattering
from validation.reference import optical_depth_numerical, single_scattering


@pytest.mark.parametrize("species", ["rayleigh", "mie"])
def test_vertical_optical_depth_is_the_exponential_column(species):
    default = Atmosphere()
    if species == "rayleigh":
        atm = default.replace(mie_scattering=0.0, mie_absorption=0.0)
        beta, height = atm.rayleigh_scattering, atm.rayleigh_scale_height
    else:
        atm = default.replace(rayleigh_scattering=0.0)
        beta, height = atm.mie_extinction, atm.mie_scale_height
    expected = beta * height * (1.0 - np.exp(-atm.atmosphere_height / height))
    np.testing.assert_allclose(optical_depth_numerical(0.0, 0.0, atm), expected, rtol=1e-8)


def test_uniform_horizontal_chord():
    # Constant density: the optical depth is beta_ex times the chord length to the top sphere.
    atm = Atmosphere(rayleigh_scale_height=1e12, mie_scale_height=1e12, atmosphere_height=5000.0)
    radius, top = atm.planet_radius, atm.planet_radius + atm.atmosphere_height
    chord = np.sqrt(top ** 2 - radius ** 2)
    np.testing.assert_allclose(optical_depth_numerical(0.0, np.pi / 2, atm), atm.extinction_coefficient * chord,
                               rtol=1e-7)


@pytest.mark.parametrize("sun_elevation_deg", [30.0, 60.0, 90.0])
def test_constant_density_limit_is_the_paper_model(sun_elevation_deg):
    # Huge scale heights: constant density. A 2 km thin atmosphere and horizontal view rays keep the
    # sun's transmittance the same along the ray (the ray rises 8 m in 10 km), as eq. 19 assumes.
    atm = Atmosphere(rayleigh_scale_height=1e9, mie_scale_height=1e9, atmosphere_height=2000.0,
                     mie_scattering=9e-5, mie_absorption=1e-5)
    camera_altitude = 10.0
    elevation = np.radians(sun_elevation_deg)
    sun_dir = np.array([np.cos(elevation), 0.0, np.sin(elevation)])
    e_sun = atm.sun_irradiance_top * np.exp(-atm.extinction_coefficient
                                            * (atm.atmosphere_height - camera_altitude) / np.sin(elevation))
    for azimuth in np.radians([0.0, 70.0, 130.0, 180.0]):
        view_dir = np.array([np.cos(azimuth), np.sin(azimuth), 0.0])
        for distance in (1000.0, 10000.0):
            f_ex, l_in = single_scattering(camera_altitude, view_dir, distance, sun_dir, atm, n_steps=401,
                                           n_sun_steps=65)
            mu = float(view_dir @ sun_dir)
            np.testing.assert_allclose(l_in, inscattering(distance, mu, atm, e_sun), rtol=5e-3)
            np.testing.assert_allclose(f_ex, np.exp(-atm.extinction_coefficient * distance), rtol=1e-6)


def test_planet_shadow_and_convergence():
    atm = Atmosphere()
    _, dark = single_scattering(100.0, [1.0, 0.0, 0.0], 20e3, [0.0, 0.0, -1.0], atm, n_steps=201, n_sun_steps=65)
    np.testing.assert_array_equal(dark, 0.0)
    args = (100.0, [1.0, 0.0, 0.05], 30e3, [0.3, 0.2, 0.5], atm)
    coarse = single_scattering(*args, n_steps=401, n_sun_steps=129)[1]
    fine = single_scattering(*args, n_steps=1601, n_sun_steps=513)[1]
    np.testing.assert_allclose(coarse, fine, rtol=1e-4)
    assert np.all(fine > 0.0)
