# SPDX-License-Identifier: GPL-3.0-or-later
"""Virtual sky dome, sky radiance, seamless horizon and the sun's disk (atmos_addon.physics.sky)."""

import numpy as np
import pytest

from atmos_addon import presets
from atmos_addon.physics import (Atmosphere, extinction, inscattering, phase_hg, phase_rayleigh,
                                 sun_irradiance_ground)
from atmos_addon.physics.sky import (aerial_distance_clamped, atmosphere_at_altitude, chapman_approx,
                                     dome_distance, dome_distance_approx, extinction_layered, extinction_two_species,
                                     inscattering_layered, inscattering_two_species, limb_darkening_factor,
                                     sky_radiance, sun_disk_radiance, sun_disk_solid_angle)
from atmos_addon.physics.sun import LUMINANCE_WEIGHTS, SUN_ANGULAR_RADIUS_RAD
from validation import reference

ATM = Atmosphere()
MARS = Atmosphere(planet_radius=3_389_500.0, rayleigh_scale_height=11_100.0, mie_scale_height=11_000.0)
DTYPES = [np.float64, np.float32]


def _direction(elevation_deg, azimuth_deg=0.0):
    """Unit vector(s) (..., 3), z up, azimuth from +x toward +y."""
    e, a = np.radians(elevation_deg), np.radians(azimuth_deg)
    return np.stack(np.broadcast_arrays(np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)), axis=-1)


def _sky(view_elevation_deg, sun_elevation_deg, view_azimuth_deg=0.0, atm=ATM, **kwargs):
    e_sun = sun_irradiance_ground(np.radians(sun_elevation_deg), atm)
    return sky_radiance(_direction(view_elevation_deg, view_azimuth_deg), _direction(sun_elevation_deg), atm, e_sun,
                        **kwargs)


def _column_numerical(atm, species, altitude_m, elevation_deg):
    """Brute-force integrated relative density of one species along the ray, divided by n(h): the dome, m."""
    if species == "rayleigh":
        unit = atm.replace(rayleigh_scattering=1.0, mie_scattering=0.0, mie_absorption=0.0)
        scale_height = atm.rayleigh_scale_height
    else:
        unit = atm.replace(rayleigh_scattering=0.0, mie_scattering=1.0, mie_absorption=0.0)
        scale_height = atm.mie_scale_height
    tau = reference.optical_depth_numerical(altitude_m, np.radians(90.0 - elevation_deg), unit, n_steps=40001)
    return tau[0] / np.exp(-altitude_m / scale_height)


# --- the dome -------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("atm", [ATM, MARS], ids=["earth", "mars"])
def test_dome_at_zenith_is_the_truncated_scale_height(atm):
    r_r, r_m = dome_distance(0.5 * np.pi, atm)
    for r, h in ((r_r, atm.rayleigh_scale_height), (r_m, atm.mie_scale_height)):
        np.testing.assert_allclose(r, h * (1.0 - np.exp(-atm.atmosphere_height / h)), rtol=1e-6)


@pytest.mark.parametrize("atm", [ATM, MARS], ids=["earth", "mars"])
@pytest.mark.parametrize("species", ["rayleigh", "mie"])
@pytest.mark.parametrize("altitude_m, elevation_deg", [(0.0, 0.0), (0.0, 3.0), (0.0, 30.0), (3000.0, 0.0),
                                                       (3000.0, -1.0)])
def test_dome_matches_brute_force_integrated_density(atm, species, altitude_m, elevation_deg):
    r_r, r_m = dome_distance(np.radians(elevation_deg), atm, altitude_m)
    expected = _column_numerical(atm, species, altitude_m, elevation_deg)
    np.testing.assert_allclose(r_r if species == "rayleigh" else r_m, expected, rtol=5e-3)


def test_dome_below_the_horizon_is_the_grazing_rays():
    low = dome_distance(np.radians([-0.001, -5.0, -90.0]), ATM)
    horizon = dome_distance(0.0, ATM)
    for r, r0 in zip(low, horizon):
        np.testing.assert_array_equal(r, r0)
    # Elevated camera: continuous and rising down to the geometric horizon, constant beyond it.
    elevation = np.radians(np.linspace(2.0, -10.0, 1201))
    r_r, _ = dome_distance(elevation, ATM, 5000.0)
    assert np.all(np.isfinite(r_r)) and np.all(np.diff(r_r) >= 0.0)


@pytest.mark.parametrize("atm", [ATM, MARS], ids=["earth", "mars"])
def test_dome_approximation_error(atm):
    elevation = np.radians(np.linspace(0.0, 90.0, 9001))
    exact = dome_distance(elevation, atm)
    approx = dome_distance_approx(elevation, atm)
    errors = [np.max(np.abs(a / e - 1.0)) for a, e in zip(approx, exact)]
    print(f"dome_distance_approx max relative error (Rayleigh, Mie): {errors[0]:.4%}, {errors[1]:.4%}")
    assert max(errors) < 0.005


def test_chapman_approx_ends_and_float32():
    for x in (300.0, 754.0, 5300.0):
        # Zenith: 1 - 1 / (2 (1 - p) c^2), 0.3 % low at x = 300; horizon: Chapman's asymptote c.
        assert chapman_approx(x, 1.0) == pytest.approx(1.0, rel=4e-3)
        assert chapman_approx(x, 0.0) == pytest.approx(np.sqrt(np.pi * x / 2.0), rel=1e-12)
    mu = np.linspace(0.0, 1.0, 101)
    np.testing.assert_allclose(chapman_approx(754.0, mu, np.float32), chapman_approx(754.0, mu), rtol=1e-6)


# --- two-species aerial perspective ---------------------------------------------------------------------------

@pytest.mark.parametrize("dtype", DTYPES)
def test_two_species_reduce_to_the_core_for_equal_lengths(dtype):
    s = np.concatenate([[0.0, 1e-3], np.geomspace(1.0, 1e6, 40)])
    mu = np.linspace(-1.0, 1.0, s.size)
    e_sun = np.array([3.0, 2.5, 1.5])
    rtol = 1e-12 if dtype == np.float64 else 2e-6
    np.testing.assert_allclose(inscattering_two_species(s, s, mu, ATM, e_sun, dtype),
                               inscattering(s, mu, ATM, e_sun, dtype), rtol=rtol, atol=1e-30)
    # tau is summed per species here and from beta_ex in the core: rounding of tau (~ tau eps) shows in exp(-tau).
    rtol = 1e-12 if dtype == np.float64 else 2e-6 * (1.0 + float(ATM.extinction_coefficient.max() * s.max()))
    np.testing.assert_allclose(extinction_two_species(s, s, ATM, dtype), extinction(s, ATM, dtype), rtol=rtol,
                               atol=1e-30)


def test_two_species_closed_form():
    s_r, s_m, mu, e_sun = 90e3, 20e3, 0.3, np.array([3.0, 2.5, 1.5])
    tau = ATM.rayleigh_scattering * s_r + ATM.mie_extinction * s_m
    scattered = ATM.rayleigh_scattering * phase_rayleigh(mu) * s_r + ATM.mie_scattering * phase_hg(mu, ATM.mie_g) * s_m
    np.testing.assert_allclose(inscattering_two_species(s_r, s_m, mu, ATM, e_sun),
                               scattered / tau * e_sun * (1.0 - np.exp(-tau)), rtol=1e-12)


# --- the layered dome --------------------------------------------------------------------------------------------

#: Atmospheres for the layered-dome checks: clear and sunset Earth, Mars (dust almost as high as the gas), and one
#: with the haze above the molecules (H_M > H_R: the Rayleigh dome is the shorter one).
LAYERED_ATMOSPHERES = {"clear": presets.load("clear").atmosphere, "sunset": presets.load("sunset").atmosphere,
                       "mars": presets.load("mars").atmosphere,
                       "high-haze": Atmosphere(rayleigh_scale_height=3_000.0, mie_scale_height=9_000.0)}


@pytest.mark.parametrize("dtype", DTYPES)
def test_layered_dome_is_the_core_model_nearer_than_both_domes(dtype):
    s = np.concatenate([[0.0, 1e-3], np.geomspace(1.0, 1e6, 40)])
    mu = np.linspace(-1.0, 1.0, s.size)
    e_sun = np.array([3.0, 2.5, 1.5])
    rtol = 1e-12 if dtype == np.float64 else 2e-6
    np.testing.assert_allclose(inscattering_layered(s, s, mu, ATM, e_sun, dtype),
                               inscattering(s, mu, ATM, e_sun, dtype), rtol=rtol, atol=1e-30)
    rtol = 1e-12 if dtype == np.float64 else 2e-6 * (1.0 + float(ATM.extinction_coefficient.max() * s.max()))
    np.testing.assert_allclose(extinction_layered(s, s, ATM, dtype), extinction(s, ATM, dtype), rtol=rtol,
                               atol=1e-30)


def test_layered_dome_closed_form():
    """Both species over [0, a], the longer one alone over [a, b], seen through the first segment."""
    e_sun = np.array([3.0, 2.5, 1.5])
    for s_r, s_m in ((90e3, 20e3), (15e3, 40e3)):
        mu, a = 0.3, min(s_r, s_m)
        sigma_r = ATM.rayleigh_scattering * phase_rayleigh(mu)
        sigma_m = ATM.mie_scattering * phase_hg(mu, ATM.mie_g)
        tau_a = (ATM.rayleigh_scattering + ATM.mie_extinction) * a
        near = (sigma_r + sigma_m) * a * e_sun * (1.0 - np.exp(-tau_a)) / tau_a
        sigma, beta, tail = (sigma_r, ATM.rayleigh_scattering, s_r - a) if s_r > s_m else (
            sigma_m, ATM.mie_extinction, s_m - a)
        far = sigma * e_sun * (1.0 - np.exp(-beta * tail)) / beta
        np.testing.assert_allclose(inscattering_layered(s_r, s_m, mu, ATM, e_sun), near + np.exp(-tau_a) * far,
                                   rtol=1e-12)
        np.testing.assert_allclose(extinction_layered(s_r, s_m, ATM), extinction_two_species(s_r, s_m, ATM),
                                   rtol=1e-12)


@pytest.mark.parametrize("name", LAYERED_ATMOSPHERES)
@pytest.mark.parametrize("dome", [dome_distance, dome_distance_approx])
def test_black_wall_never_outshines_the_sky(name, dome):
    """L_in of a black wall is non-decreasing in its distance, toward and away from the sun, and ends at the sky.

    Also below the shorter dome it is the core's eq. 19, and beyond the longer one exactly the sky.
    """
    atm = LAYERED_ATMOSPHERES[name]
    sun_elevation = 25.0
    e_sun = sun_irradiance_ground(np.radians(sun_elevation), atm)
    elevation = np.array([0.0, 2.0, 10.0, 20.0, 30.0, 60.0])
    for azimuth in (0.0, 5.0, 90.0, 180.0):  # 0: toward the sun (10-30 deg from it at these elevations)
        views, sun = _direction(elevation, azimuth), _direction(sun_elevation)
        mu = views @ sun
        sky = sky_radiance(views, sun, atm, e_sun, dome=dome)
        r_r, r_m = dome(np.radians(elevation), atm, 0.0)
        s = np.geomspace(1.0, 2e6, 600)[:, np.newaxis]
        s_r, s_m = aerial_distance_clamped(s, np.radians(elevation), atm, dome=dome)
        light = inscattering_layered(s_r, s_m, mu, atm, e_sun)
        assert np.all(np.diff(light, axis=0) >= -1e-15 * np.abs(light[1:])), f"{name} az {azimuth}: not monotonic"
        assert np.all(light <= sky * (1.0 + 1e-12)), f"{name} az {azimuth}: a wall outshines the sky"
        np.testing.assert_allclose(light[-1], sky, rtol=1e-12)  # 2000 km: beyond both domes
        near = s <= np.minimum(r_r, r_m)
        core = inscattering(np.broadcast_to(s, near.shape), mu, atm, e_sun)
        np.testing.assert_allclose(light[near], core[near], rtol=1e-12)
        assert np.any(near) and np.any(~near)


def test_even_mixture_overshoot_is_gone():
    """The black wall 18 / 99 km away near the sun that the even mixture made 16 / 24 % brighter than its sky."""
    sun = _direction(25.0, 20.0)
    e_sun = sun_irradiance_ground(np.radians(25.0), ATM)
    elevation = np.radians(np.linspace(-3.0, 12.0, 16))
    views = _direction(np.degrees(elevation), 17.5)
    r_r, r_m = dome_distance_approx(elevation, ATM)
    old_sky = inscattering_two_species(r_r, r_m, views @ sun, ATM, e_sun)
    sky = sky_radiance(views, sun, ATM, e_sun, dome=dome_distance_approx)
    for distance, overshoot in ((18e3, 1.15), (99e3, 1.2)):
        s_r, s_m = aerial_distance_clamped(distance, elevation, ATM, dome=dome_distance_approx)
        old = inscattering_two_species(s_r, s_m, views @ sun, ATM, e_sun)
        assert np.max(old / old_sky) > overshoot
        assert np.all(inscattering_layered(s_r, s_m, views @ sun, ATM, e_sun) <= sky * (1.0 + 1e-12))


# --- sky colour -------------------------------------------------------------------------------------------------

def test_clear_noon_zenith_is_blue():
    r, g, b = _sky(90.0, 60.0)
    assert b > g > r > 0.0


def test_sunset_horizon_toward_the_sun_is_red():
    r, g, b = _sky(0.0, 2.0)
    assert r > g > b > 0.0


def test_night_sky_is_dark():
    noon = _sky(np.linspace(0.0, 90.0, 10), 60.0) @ LUMINANCE_WEIGHTS
    night = _sky(np.linspace(0.0, 90.0, 10), -12.0) @ LUMINANCE_WEIGHTS
    # E_sun at the ground is exactly 0 once the sun has set, and so is single scattering with it.
    assert np.all(night == 0.0) and np.all(night < 0.01 * noon)


@pytest.mark.parametrize("sun_elevation_deg", [5.0, 20.0, 40.0])
def test_mie_halo_points_at_the_sun(sun_elevation_deg):
    azimuth = np.linspace(-180.0, 180.0, 721)
    ring = _sky(5.0, sun_elevation_deg, azimuth) @ LUMINANCE_WEIGHTS
    assert abs(azimuth[np.argmax(ring)]) < 0.5
    assert ring.max() > 2.0 * ring.min()


def test_sky_is_continuous_across_the_horizon_and_ground_is_lit():
    above, below = _sky(np.array([1e-7, -1e-7]), 30.0)
    np.testing.assert_allclose(above, below, rtol=1e-6)
    ground = _sky(-30.0, 30.0, ground_albedo=0.3)
    haze = _sky(-30.0, 30.0)
    assert np.all(ground > haze)


# --- seamless horizon -------------------------------------------------------------------------------------------

@pytest.mark.parametrize("altitude_m", [0.0, 1500.0])
@pytest.mark.parametrize("dome", [dome_distance, dome_distance_approx])
def test_black_surface_beyond_the_dome_shows_the_sky(altitude_m, dome):
    elevation = np.array([0.0, 0.5, 3.0, 10.0, 45.0, 89.0, -0.2])
    azimuth = np.linspace(0.0, 300.0, elevation.size)
    views, sun = _direction(elevation, azimuth), _direction(15.0, 40.0)
    e_sun = sun_irradiance_ground(np.radians(15.0), ATM)
    sky = sky_radiance(views, sun, ATM, e_sun, altitude_m=altitude_m, dome=dome)
    far = 5e7  # m, beyond every dome
    s_r, s_m = aerial_distance_clamped(far, np.radians(elevation), ATM, altitude_m, dome=dome)
    local = atmosphere_at_altitude(ATM, altitude_m)
    surface = np.zeros(3) * extinction_layered(s_r, s_m, local) + inscattering_layered(
        s_r, s_m, views @ sun, local, e_sun)
    np.testing.assert_allclose(surface, sky, rtol=1e-6)
    # A nearer surface is clamped per species only beyond that species' dome.
    s_r, s_m = aerial_distance_clamped(5e3, np.radians(elevation), ATM, altitude_m, dome=dome)
    np.testing.assert_array_equal(s_r, 5e3)


# --- robustness -------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("altitude_m", [0.0, 8000.0, 100_000.0])
def test_no_nan_anywhere(dtype, altitude_m):
    elevation, azimuth = np.meshgrid(np.linspace(-90.0, 90.0, 73), np.linspace(-180.0, 180.0, 25))
    views = _direction(elevation, azimuth)
    for sun_elevation in (-90.0, -12.0, -0.1, 0.0, 0.1, 2.0, 60.0, 90.0):
        e_sun = sun_irradiance_ground(np.radians(sun_elevation), ATM)
        for dome in (dome_distance, dome_distance_approx):
            radiance = sky_radiance(views, _direction(sun_elevation, 30.0), ATM, e_sun, altitude_m=altitude_m,
                                    dome=dome, ground_albedo=0.2, dtype=dtype)
            assert radiance.dtype == dtype and radiance.shape == views.shape
            assert np.all(np.isfinite(radiance)) and np.all(radiance >= 0.0)


# --- the sun's disk -------------------------------------------------------------------------------------------

@pytest.mark.parametrize("elevation_deg", [90.0, 30.0, 2.0, 0.0])
def test_sun_disk_radiance_times_solid_angle_is_irradiance(elevation_deg):
    e_sun = sun_irradiance_ground(np.radians(elevation_deg), ATM)
    radiance = sun_disk_radiance(ATM, np.radians(elevation_deg))
    np.testing.assert_allclose(radiance * sun_disk_solid_angle(), e_sun, rtol=1e-12)
    assert sun_disk_solid_angle() == pytest.approx(2.0 * np.pi * (1.0 - np.cos(SUN_ANGULAR_RADIUS_RAD)), rel=1e-12)


@pytest.mark.parametrize("limb_darkening", [0.0, 0.6, 1.0])
def test_limb_darkened_disk_keeps_its_irradiance(limb_darkening):
    r = SUN_ANGULAR_RADIUS_RAD
    t = np.linspace(0.0, r, 200001)
    radiance = sun_disk_radiance(ATM, np.radians(45.0), offset_rad=t, limb_darkening=limb_darkening)
    integrand = radiance * (2.0 * np.pi * np.sin(t))[:, np.newaxis]
    integral = np.sum(0.5 * (integrand[1:] + integrand[:-1]) * np.diff(t)[:, np.newaxis], axis=0)
    np.testing.assert_allclose(integral, sun_irradiance_ground(np.radians(45.0), ATM), rtol=1e-4)
    assert limb_darkening_factor(1.01 * r) == 0.0
    if limb_darkening > 0.0:
        assert radiance[0, 1] > radiance[-1, 1]
