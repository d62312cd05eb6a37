# SPDX-License-Identifier: GPL-3.0-or-later
"""Visibility: Koschmieder's law where its assumptions hold, what the real atmosphere and each level give."""

import numpy as np
import pytest

from atmos_addon.physics.visibility import koschmieder_contrast, visibility_m
from validation.visibility import LEVELS, level_contrast, reference_contrast, sun_direction, view_direction
from atmos_addon.presets import load


def test_visibility_is_koschmieders():
    atm = load("clear").atmosphere
    assert visibility_m(atm) == pytest.approx(70_000.0, rel=1e-4)   # the preset is built for 70 km
    assert koschmieder_contrast(visibility_m(atm), visibility_m(atm)) == pytest.approx(0.02, rel=1e-12)


def test_reference_obeys_koschmieder_in_a_flat_homogeneous_atmosphere():
    # Koschmieder's assumptions made true: a flat planet (radius 1e9 m: 2.5 m of rise over 70 km) and uniform
    # densities (scale heights 1e9 m) in a 20 km deep layer. Then the horizon sky is the same from every point of
    # the level view ray, and a black target's contrast is exactly exp(-beta_ex d), every scattering order on.
    atm = load("clear").atmosphere.replace(planet_radius=1e9, rayleigh_scale_height=1e9, mie_scale_height=1e9,
                                           atmosphere_height=20_000.0)
    distances = np.array([10_000.0, 35_000.0, 70_000.0])
    contrast, error = reference_contrast(atm, distances, view_direction(0.0, 90.0), sun_direction(30.0),
                                         camera_altitude_m=2.0, paths=6000, seed=1)
    expected = np.exp(-np.outer(distances, atm.extinction_coefficient))
    assert np.all(np.abs(contrast - expected) <= 4.0 * error + 1e-3 * expected), (contrast, expected, error)
    assert np.all(error < 0.06 * expected)  # teeth: 2x off (the real atmosphere at 70 km) is 20 errors away


def test_the_real_atmosphere_keeps_more_contrast_than_koschmieder_at_the_visibility():
    # Clear preset, sun 30 deg, views 0.2 deg up across the sun: the haze thins along the rising ray, so the
    # horizon sky behind a target is dimmer than an endless sea-level layer's and a black target 70 km away
    # keeps 4.6 % contrast (measured with 20000 paths, docs/visibility.md), not 2 %.
    atm = load("clear").atmosphere
    contrast, error = reference_contrast(atm, [70_000.0], view_direction(0.2, 90.0), sun_direction(30.0),
                                         paths=3000, seed=2)
    assert 0.035 < contrast[0, 1] < 0.06 and error[0, 1] < 0.003, (contrast, error)


def test_levels_contrast():
    atm = load("clear").atmosphere
    distances = np.array([10_000.0, 35_000.0, 70_000.0])
    view, sun = view_direction(0.2, 90.0), sun_direction(30.0)
    contrasts = {level: level_contrast(level, atm, distances, view, sun)[:, 1] for level in LEVELS}
    for level, contrast in contrasts.items():
        assert np.all(np.diff(contrast) < 0.0) and np.all((contrast > 0.0) & (contrast < 1.0)), level
    # Fast's dome sky at sea-level density is nearly Koschmieder's homogeneous layer: within 0.01 of his law.
    np.testing.assert_allclose(contrasts["fast"], koschmieder_contrast(distances, visibility_m(atm)), atol=0.01)
    # Precise's table integrates the thinning haze, as the reference does: more contrast far away.
    assert contrasts["precise"][2] > 2.0 * contrasts["fast"][2] * 0.9
    with pytest.raises(ValueError, match="unknown level"):
        level_contrast("exact", atm, distances, view, sun)
