# SPDX-License-Identifier: GPL-3.0-or-later
"""The Monte Carlo multiple-scattering yardstick: single scattering, energy conservation, thin limits.

Every comparison allows for the estimator's own noise (k standard errors) plus a small fixed margin for the
quadrature of optical depths; seeds are fixed, so the tests are deterministic.
"""

import numpy as np
import pytest

from atmos_addon.physics import Atmosphere, phase_hg, phase_rayleigh
from validation.multiple_scattering_reference import (diffuse_flux_mc, inscattering_mc, sample_hg_cosine,
                                                      sample_rayleigh_cosine, sky_radiance_mc, trace_paths)
from validation.reference import distance_to_top, single_scattering


def _direction(elevation_deg, azimuth_deg=0.0):
    elevation, azimuth = np.radians(elevation_deg), np.radians(azimuth_deg)
    return np.array([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)])


def _sky_single_scattering(view, sun, atm, sun_irradiance_top=None):
    """reference.single_scattering along ``view`` from the ground to the top of the atmosphere."""
    distance = float(distance_to_top(np.asarray(atm.planet_radius), np.asarray(view[2]), atm))
    return single_scattering(0.0, view, distance, sun, atm, sun_irradiance_top, n_steps=2001, n_sun_steps=257)[1]


def _scaled(atm, factor):
    return atm.replace(rayleigh_scattering=atm.rayleigh_scattering * factor,
                       mie_scattering=atm.mie_scattering * factor, mie_absorption=atm.mie_absorption * factor)


SUN_20 = _direction(20.0)
VIEWS = [_direction(90.0), _direction(30.0, 90.0), _direction(5.0), _direction(5.0, 180.0)]


def test_first_order_is_reference_single_scattering():
    # Zenith, 30 deg up across the sun, 5 deg up toward (Mie lobe) and away from a 20 deg sun.
    atm = Atmosphere()
    radiance, error = sky_radiance_mc(VIEWS, SUN_20, atm, max_order=1, paths=8000, seed=1)
    for view, mc, se in zip(VIEWS, radiance, error, strict=True):
        expected = _sky_single_scattering(view, SUN_20, atm)
        assert np.all(np.abs(mc - expected) <= 3.0 * se + 0.01 * expected), (view, mc, expected, se)
        assert np.all(se < 0.01 * expected)  # the test has teeth: the noise is below the margin


def test_white_furnace_conserves_radiance():
    # Uniform radiance 1 entering at the top, a white Lambertian ground, no absorption anywhere, no sun: the
    # isotropic field L = 1 solves the transfer equation in any geometry, so every view sees exactly 1.
    # This checks the bookkeeping of weights (forced collisions, albedos, roulette) to all orders.
    conservative = _scaled(Atmosphere(mie_absorption=0.0), 2.0)
    views = [_direction(90.0), _direction(0.5), _direction(-20.0)]
    furnace = dict(sun_irradiance_top=0.0, space_radiance=1.0, ground_albedo=1.0, paths=2000, seed=2)
    radiance, error = sky_radiance_mc(views, SUN_20, conservative, **furnace)
    np.testing.assert_array_less(np.abs(radiance - 1.0), 4.0 * error + 1e-3)
    # Control: the default haze absorbs, so the same furnace is visibly darker.
    absorbing, error = sky_radiance_mc(views, SUN_20, _scaled(Atmosphere(), 2.0), **furnace)
    np.testing.assert_array_less(absorbing + 10.0 * error, 1.0)


def test_white_ground_reflects_all_sunlight_plane_parallel():
    # Conservative air over a white ground: what the sun brings in (mu_sun E per unit area) must leave
    # through the top. The balance is local only in a plane-parallel atmosphere; over Earth's radius the
    # downward views within 10 deg of the horizon miss the ground (3 % of the cosine-weighted hemisphere,
    # the local flux reads 0.965), so the planet is made 100 times larger (the leak drops to 3e-4).
    atm = Atmosphere(mie_absorption=0.0, planet_radius=6.36e8)
    sun = _direction(40.0)
    flux, error = diffuse_flux_mc(sun, atm, altitude_m=atm.atmosphere_height, upwelling=True, sun_irradiance_top=1.0,
                                  ground_albedo=1.0, paths=6000, seed=3)
    incident = np.sin(np.radians(40.0))
    np.testing.assert_array_less(np.abs(flux / incident - 1.0), 4.0 * error / incident + 2e-3)
    assert np.all(error / incident < 0.01)


def test_reflection_is_reciprocal():
    # Helmholtz reciprocity of a plane-parallel atmosphere: the planet's BRDF L / (mu_sun E) at the top is
    # unchanged when the sun and the view swap. Single scattering is reciprocal term by term; the higher
    # orders only if the directions sampled at each vertex follow the same phase function that next-event
    # estimation evaluates (sampling with -g instead breaks it by about 8 standard errors). A thick grey
    # forward-scattering haze over a grey ground (single scattering is 37 % of the light) on a planet 100
    # times Earth's size; the channels are independent samples of the same grey answer and are averaged.
    atm = Atmosphere(rayleigh_scattering=2e-6, mie_scattering=3e-4, mie_absorption=0.0, planet_radius=6.36e8)
    sun, view = _direction(70.0), _direction(-30.0)
    common = dict(camera_altitude_m=atm.atmosphere_height, sun_irradiance_top=1.0, ground_albedo=0.3, paths=8000)
    forward, forward_error = sky_radiance_mc(view, sun, atm, seed=8, **common)
    backward, backward_error = sky_radiance_mc(-sun, -view, atm, seed=9, **common)
    brdf = forward.mean() / sun[2], backward.mean() / -view[2]
    error = np.hypot(np.linalg.norm(forward_error) / 3.0 / sun[2], np.linalg.norm(backward_error) / 3.0 / -view[2])
    assert abs(brdf[0] - brdf[1]) < 4.0 * error, (brdf, error)
    assert error < 0.01 * brdf[0]


def test_optically_thin_limit_is_single_scattering():
    # Scale every coefficient by k: single scattering grows as k, the higher orders as k^2, so their share
    # of the sky falls as k. The same seed replays the first vertex exactly, so per path the difference of
    # the two runs is the higher orders alone.
    sun, view, n = SUN_20, _direction(90.0), 6000
    directions, channel = np.tile(view, (3 * n, 1)), np.repeat(np.arange(3), n)
    share = {}
    for k in (1e-2, 1e-3):
        atm = _scaled(Atmosphere(), k)
        first = trace_paths([0.0, 0.0, 0.0], directions, channel, sun, atm, max_order=1, seed=4).reshape(3, n)
        every = trace_paths([0.0, 0.0, 0.0], directions, channel, sun, atm, seed=4).reshape(3, n)
        single, first_error = first.mean(axis=1), first.std(axis=1, ddof=1) / np.sqrt(n)
        expected = _sky_single_scattering(view, sun, atm)
        assert np.all(np.abs(single - expected) <= 3.0 * first_error + 0.01 * expected)
        higher = every - first
        assert np.all(higher >= 0.0)
        share[k] = higher.mean(axis=1) / single
    assert np.all(share[1e-3] < 2e-3)  # measured 2e-4 (R) to 9e-4 (B)
    ratio = share[1e-2].sum() / share[1e-3].sum()
    assert 4.0 < ratio < 25.0, ratio  # about 10: linear in k


def test_multiple_scattering_adds_light():
    # Default clear sky, sun 20 deg up, black ground: measured zenith all-orders / single = 1.17, 1.27, 1.53
    # (R, G, B); more in blue, where Rayleigh optical depth is largest.
    atm, view = Atmosphere(), _direction(90.0)
    single, _ = sky_radiance_mc(view, SUN_20, atm, max_order=1, paths=8000, seed=5)
    total, error = sky_radiance_mc(view, SUN_20, atm, paths=8000, seed=5)
    ratio = total / single
    assert np.all(ratio > 1.02) and np.all(ratio < 3.0), ratio
    assert ratio[0] < ratio[1] < ratio[2], ratio
    assert np.all(error < 0.01 * total)


def test_first_order_in_front_of_a_target_is_reference_single_scattering():
    # L_in in front of a black target: level views 100 m to 50 km (one 5 deg up), toward and away from a 20 deg
    # sun, and down 45 deg from 2 km to the ground, first order only, against the brute-force integral.
    atm = Atmosphere()
    cases = [(0.0, _direction(0.0, 30.0), 100.0), (0.0, _direction(0.0, 180.0), 10_000.0),
             (0.0, _direction(5.0), 50_000.0), (2000.0, _direction(-45.0, 90.0), 2500.0)]
    for altitude, view, distance in cases:
        radiance, error = inscattering_mc(view, distance, SUN_20, atm, camera_altitude_m=altitude, max_order=1,
                                          paths=4000, seed=7)
        expected = single_scattering(altitude, view, distance, SUN_20, atm, n_steps=2001, n_sun_steps=257)[1]
        assert np.all(np.abs(radiance - expected) <= 3.0 * error + 0.01 * expected), (distance, radiance, expected)
        assert np.all(error < 0.01 * expected)


def test_a_target_beyond_the_atmosphere_is_the_sky_sample_for_sample():
    atm, views = Atmosphere(), [_direction(10.0), _direction(60.0, 90.0)]
    sky, _ = sky_radiance_mc(views, SUN_20, atm, ground_albedo=0.3, paths=500, seed=8)
    far, _ = inscattering_mc(views, 1e9, SUN_20, atm, ground_albedo=0.3, paths=500, seed=8)
    np.testing.assert_array_equal(far, sky)
    near, _ = inscattering_mc(views, 20_000.0, SUN_20, atm, ground_albedo=0.3, paths=500, seed=8)
    assert np.all(near < far)


def test_inscattering_grows_with_distance_and_every_order_adds_to_it():
    # A level view away from a 20 deg sun: L_in(1 km) < L_in(10 km) < L_in(50 km) < the horizon sky, and the
    # higher orders add light at every distance (the same seed replays the first vertex).
    atm, view = Atmosphere(), _direction(0.0, 180.0)
    distances = [1000.0, 10_000.0, 50_000.0]
    every, error = inscattering_mc([view] * 3, distances, SUN_20, atm, paths=3000, seed=9)
    single, _ = inscattering_mc([view] * 3, distances, SUN_20, atm, max_order=1, paths=3000, seed=9)
    sky, _ = sky_radiance_mc(view, SUN_20, atm, paths=3000, seed=9)
    assert np.all(np.diff(every, axis=0) > 0.0) and np.all(every[-1] < sky)
    assert np.all(every > single + 3.0 * error)


def test_a_target_on_the_ground_is_the_black_surface_not_the_ground():
    # Looking 45 deg down from 2 km with the target at the ground-hit distance (as the bench's drone rays): the
    # ground's own reflection must not count, whatever its albedo; first order, so only that could differ.
    atm, view = Atmosphere(), _direction(-45.0)
    r0 = atm.planet_radius + 2000.0
    c = view[2]
    to_ground = -r0 * c - np.sqrt(r0 * r0 * c * c - (r0 * r0 - atm.planet_radius ** 2))
    dark, _ = inscattering_mc(view, to_ground, SUN_20, atm, camera_altitude_m=2000.0, ground_albedo=0.0,
                              max_order=1, paths=500, seed=10)
    white, _ = inscattering_mc(view, to_ground, SUN_20, atm, camera_altitude_m=2000.0, ground_albedo=1.0,
                               max_order=1, paths=500, seed=10)
    np.testing.assert_array_equal(white, dark)


def test_target_distance_is_checked():
    with pytest.raises(ValueError, match="target_distance_m"):
        inscattering_mc(_direction(0.0), -1.0, SUN_20, Atmosphere(), paths=10)


@pytest.mark.parametrize("g", [None, 0.76, -0.5, 0.0])
def test_sampled_directions_follow_the_phase_function(g):
    # Histogram of sampled cosines against the bin integrals of 2 pi Phi: Rayleigh, forward and backward HG.
    xi = np.random.default_rng(6).random(200_000)
    mu = sample_rayleigh_cosine(xi) if g is None else sample_hg_cosine(xi, g)
    edges = np.linspace(-1.0, 1.0, 41)
    fine = np.linspace(-1.0, 1.0, 40 * 200 + 1).reshape(-1)
    density = 2.0 * np.pi * (phase_rayleigh(fine) if g is None else phase_hg(fine, g))
    cumulative = np.concatenate([[0.0], np.cumsum(0.5 * (density[1:] + density[:-1]) * np.diff(fine))])
    expected = np.diff(cumulative[::200]) * mu.size
    observed = np.histogram(mu, edges)[0]
    assert np.all(np.abs(observed - expected) < 5.0 * np.sqrt(expected) + 2e-3 * expected)
    if g is not None:
        assert np.mean(mu) == pytest.approx(g, abs=0.01)  # the mean cosine of HG is g


def test_extra_absorption_callback_is_extinction_without_scattering():
    # An absorber with the aerosol profile passed as a callback equals the same amount of Mie absorption.
    atm = Atmosphere()
    extra = np.array([2e-5, 1e-5, 2e-5])

    def callback(altitude):
        return extra * np.exp(-altitude / atm.mie_scale_height)[..., np.newaxis]

    view = _direction(30.0, 45.0)
    with_callback, _ = sky_radiance_mc(view, SUN_20, atm, paths=2000, seed=7, extra_absorption=callback)
    merged, _ = sky_radiance_mc(view, SUN_20, atm.replace(mie_absorption=atm.mie_absorption + extra),
                                paths=2000, seed=7)
    plain, error = sky_radiance_mc(view, SUN_20, atm, paths=2000, seed=7)
    np.testing.assert_allclose(with_callback, merged, rtol=1e-3)
    assert np.all(with_callback < plain - 3.0 * error)


def test_rejects_bad_input():
    atm = Atmosphere()
    with pytest.raises(ValueError, match="inside the atmosphere"):
        sky_radiance_mc([0.0, 0.0, 1.0], SUN_20, atm, camera_altitude_m=2.0 * atm.atmosphere_height, paths=10)
    with pytest.raises(ValueError, match="max_order"):
        sky_radiance_mc([0.0, 0.0, 1.0], SUN_20, atm, max_order=0, paths=10)
    with pytest.raises(ValueError, match="ground_albedo"):
        sky_radiance_mc([0.0, 0.0, 1.0], SUN_20, atm, ground_albedo=1.5, paths=10)
    with pytest.raises(ValueError, match="view_dir"):
        sky_radiance_mc([0.0, 0.0, 0.0], SUN_20, atm, paths=10)
