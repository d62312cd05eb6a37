# SPDX-License-Identifier: GPL-3.0-or-later
"""Sunlight at the ground: setting, reddening, smoothness and the colour/strength split."""

import numpy as np
import pytest

from atmos_addon import presets
from atmos_addon.physics import Atmosphere, sun_color_and_strength, sun_irradiance_ground
from validation.reference import optical_depth_numerical, sun_irradiance_numerical
from atmos_addon.physics.sun import SUN_ANGULAR_RADIUS_RAD, visible_disk_fraction

ATM = Atmosphere()
RHO = SUN_ANGULAR_RADIUS_RAD


def test_zero_once_the_disk_has_set_and_positive_just_above():
    below = np.array([-np.pi / 2, -0.1, -RHO - 1e-9, -RHO])
    np.testing.assert_array_equal(sun_irradiance_ground(below, ATM), 0.0)
    assert np.all(sun_irradiance_ground(-0.99 * RHO, ATM) > 0.0)


def test_dense_sweep_is_finite_non_negative_and_bounded():
    elevation = np.linspace(-np.pi / 2, np.pi / 2, 4001)
    for atm in (ATM, ATM.replace(rayleigh_scattering=0.0, mie_scattering=0.0, mie_absorption=0.0),
                ATM.replace(rayleigh_scattering=100 * ATM.rayleigh_scattering, mie_scattering=3.3e-3)):
        e_sun = sun_irradiance_ground(elevation, atm)
        assert e_sun.shape == (4001, 3)
        assert np.all(np.isfinite(e_sun)) and np.all(e_sun >= 0.0) and np.all(e_sun <= atm.sun_irradiance_top)


def test_smooth_monotone_rise_through_sunrise():
    elevation = np.linspace(-2 * RHO, np.radians(5.0), 3001)
    e_sun = sun_irradiance_ground(elevation, ATM)
    assert np.all(np.diff(e_sun, axis=0) >= 0.0)
    # No jumps: each step of 2e-5 rad changes E by a small fraction of its 5-degree value.
    assert np.max(np.abs(np.diff(e_sun, axis=0))) < 0.01 * e_sun[-1].min()


def test_noon_attenuation_order_and_red_sunset():
    noon = sun_irradiance_ground(np.radians(60.0), ATM) / ATM.sun_irradiance_top
    assert noon[0] > noon[1] > noon[2]
    sunset = sun_irradiance_ground(np.radians(2.0), ATM)
    assert sunset[0] > sunset[1] > sunset[2]


def test_ground_noon_is_a_blender_daylight_strength():
    _, strength = sun_color_and_strength(np.radians([90.0, 60.0]), ATM)
    assert np.all((3.0 < strength) & (strength < 5.0))


def test_colour_times_strength_is_the_irradiance():
    elevation = np.radians(np.linspace(-5.0, 90.0, 200))
    colour, strength = sun_color_and_strength(elevation, ATM)
    np.testing.assert_allclose(colour * strength[:, None], sun_irradiance_ground(elevation, ATM), rtol=1e-12,
                               atol=0.0)
    lit = strength > 0
    np.testing.assert_allclose(colour[lit] @ [0.2126, 0.7152, 0.0722], 1.0, rtol=1e-12)
    np.testing.assert_array_equal(colour[~lit], 1.0)


def test_horizon_dips_for_a_high_observer():
    # From 10 km the geometric horizon lies 3.2 deg below the astronomical one.
    assert np.all(sun_irradiance_ground(np.radians(-2.0), ATM, altitude_m=10e3) > 0.0)
    np.testing.assert_array_equal(sun_irradiance_ground(np.radians(-3.5), ATM, altitude_m=10e3), 0.0)


def test_visible_disk_fraction():
    assert visible_disk_fraction(0.0, RHO) == pytest.approx(0.5)
    assert visible_disk_fraction(RHO, RHO) == 1.0 and visible_disk_fraction(-RHO, RHO) == 0.0
    # Segment area at half the radius: (pi/3 - sqrt(3)/4) / pi of the disk lies beyond the chord.
    assert visible_disk_fraction(-0.5 * RHO, RHO) == pytest.approx((np.pi / 3 - np.sqrt(3) / 4) / np.pi)


# -- E_sun against a brute-force integral over the limb-darkened disk (issue: 1.5 % at 2 deg) -----------------


ATMOSPHERES = {"default": Atmosphere(), **{name: presets.load(name).atmosphere for name in presets.BUILTIN_NAMES}}


@pytest.mark.parametrize("name", sorted(ATMOSPHERES))
def test_sun_irradiance_matches_a_brute_force_disk_integral(name):
    """E_sun is the disk's flux through the atmosphere: every preset, 90 down to 0.5 deg, within 0.1 % per channel
    of Simpson optical depths along straight rays summed over the limb-darkened disk (and within 0.5 % while the
    disk crosses the horizon)."""
    atm = ATMOSPHERES[name]
    for elevation_deg, tolerance in ((90.0, 1e-3), (30.0, 1e-3), (10.0, 1e-3), (5.0, 1e-3), (3.0, 1e-3),
                                     (2.0, 1e-3), (1.0, 1e-3), (0.5, 1e-3), (0.1, 5e-3), (-0.1, 5e-3)):
        ours = sun_irradiance_ground(np.radians(elevation_deg), atm)
        reference = sun_irradiance_numerical(np.radians(elevation_deg), atm)
        np.testing.assert_allclose(ours, reference, rtol=tolerance, err_msg=f"{name}, {elevation_deg} deg")


def test_a_uniform_disk_and_a_high_observer_match_the_brute_force_too():
    for altitude_m, elevation_deg in ((0.0, 2.0), (3000.0, 1.0), (10_000.0, -2.0)):
        for limb_darkening in (0.0, 1.0):
            ours = sun_irradiance_ground(np.radians(elevation_deg), ATM, altitude_m, RHO, limb_darkening)
            reference = sun_irradiance_numerical(np.radians(elevation_deg), ATM, altitude_m, RHO, limb_darkening)
            np.testing.assert_allclose(ours, reference, rtol=1e-3, err_msg=f"{altitude_m} m, u={limb_darkening}")


def test_the_disk_average_is_why_a_point_sun_differs():
    """Toward the disk's centre alone the transmittance is lower: exp(-tau) is convex across the disk. At 2 deg the
    blue channel differs by 1.5 % (the Atmosphere() default): the size of the error a point-sun brute force reports,
    which is not an error of E_sun."""
    elevation = np.radians(2.0)
    point = ATM.sun_irradiance_top * np.exp(-optical_depth_numerical(0.0, 0.5 * np.pi - elevation, ATM))
    disk = sun_irradiance_ground(elevation, ATM)
    assert 0.01 < disk[2] / point[2] - 1.0 < 0.02
    np.testing.assert_allclose(disk, sun_irradiance_numerical(elevation, ATM), rtol=1e-4)


def test_limb_darkened_visible_fraction():
    for u in (0.0, 0.6, 1.0):
        assert visible_disk_fraction(RHO, RHO, u) == 1.0 and visible_disk_fraction(-RHO, RHO, u) == 0.0
        assert visible_disk_fraction(0.0, RHO, u) == pytest.approx(0.5)
        sweep = visible_disk_fraction(np.linspace(-RHO, RHO, 201), RHO, u)
        assert np.all(np.diff(sweep) >= 0.0)
    # With the centre half a radius below the horizon only the upper cap shows, next to the dark limb: a smaller
    # share of a darkened disk's flux than of its area.
    assert visible_disk_fraction(-0.5 * RHO, RHO, 0.6) < visible_disk_fraction(-0.5 * RHO, RHO, 0.0)


@pytest.mark.parametrize("preset", ["clear", "overcast", "sunset", "mars"])
def test_the_sun_table_interpolates_e_sun(preset):
    """The table Blender's drivers read as the lamp moves (linear in the sine of the elevation) follows E_sun
    within 0.2 % wherever the sun is lit enough to matter (over 1e-6 of noon), and within 2e-5 of noon's E_sun
    everywhere, the disk's setting included; 0 once the disk has set."""
    from atmos_addon.physics.sun import interpolate_sun_irradiance, sun_irradiance_table

    atm = presets.load(preset).atmosphere
    table = sun_irradiance_table(atm)
    sines, rows = table
    assert np.all(np.diff(sines) > 0.0) and rows[0].tolist() == [0.0, 0.0, 0.0]
    # its rows are the physics' (the cached unit optical depths combined with the coefficients), to rounding
    np.testing.assert_allclose(rows, sun_irradiance_ground(np.arcsin(sines), atm), rtol=1e-12, atol=1e-300)
    edited = atm.replace(mie_scattering=2.0 * atm.mie_scattering)   # the same geometry: the cache's columns
    np.testing.assert_allclose(sun_irradiance_table(edited)[1], sun_irradiance_ground(np.arcsin(sines), edited),
                               rtol=1e-12, atol=1e-300)
    elevation = np.linspace(-2.0 * RHO, np.pi / 2, 20001)
    exact = sun_irradiance_ground(elevation, atm)
    read = interpolate_sun_irradiance(table, np.sin(elevation))
    noon = exact[-1]
    assert np.max(np.abs(read - exact) / noon) < 2e-5
    lit = (exact.min(axis=-1) > 1e-6 * noon.max()) & (elevation > RHO)
    relative = np.max(np.abs(read - exact)[lit] / exact[lit])
    print(f"\n{preset}: E_sun from the table, worst relative error {relative:.2e} above the disk's setting")
    assert relative < 2e-3
    np.testing.assert_array_equal(interpolate_sun_irradiance(table, np.sin([-0.5, -2.0 * RHO])), 0.0)
