# SPDX-License-Identifier: GPL-3.0-or-later
"""The world's lighting table (atmos_addon.physics.sky_table): the dome sky factored as A(v_z) times the phases."""

import numpy as np
import pytest

from atmos_addon import presets
from atmos_addon.physics import Atmosphere, sun_irradiance_ground
from atmos_addon.physics.sky import dome_distance_approx, sky_radiance
from atmos_addon.physics.sky_table import (SKY_TABLE_SIZE, sky_lighting_table, sky_radiance_from_table,
                                           table_coordinate)

ATMOSPHERES = {name: presets.load(name).atmosphere for name in ("clear", "overcast", "sunset", "mars")}
ALBEDO = (0.18, 0.2, 0.15)


def _directions(elevation_deg, azimuth_deg):
    e, a = np.radians(elevation_deg), np.radians(azimuth_deg)
    return np.stack(np.broadcast_arrays(np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)), axis=-1)


def _analytic(view, sun, atm, e_sun):
    return sky_radiance(view, sun, atm, e_sun, dome=dome_distance_approx, ground_albedo=ALBEDO)


@pytest.mark.parametrize("name", sorted(ATMOSPHERES))
def test_table_samples_reproduce_the_dome_sky(name):
    """At the table's own elevations the factored form is the dome sky itself (any sun, above and below)."""
    atm = ATMOSPHERES[name]
    table = sky_lighting_table(atm)
    u = table.coordinate[::8]
    elevation = np.degrees(np.arcsin(u * u))
    rng = np.random.default_rng(3)
    for sun_elevation in (60.0, 5.0, 0.5):
        sun = _directions(sun_elevation, 0.0)
        e_sun = sun_irradiance_ground(np.radians(sun_elevation), atm)
        for azimuth in rng.uniform(0.0, 360.0, 4):
            view = _directions(elevation, azimuth)
            expected = _analytic(view, sun, atm, e_sun)
            np.testing.assert_allclose(sky_radiance_from_table(view, sun, atm, e_sun, table, ALBEDO), expected,
                                       rtol=1e-9, atol=1e-12 * float(np.max(expected)))
        below = _directions(np.array([-0.5, -10.0, -80.0]), 40.0)  # the ground, through the horizon's haze
        np.testing.assert_allclose(sky_radiance_from_table(below, sun, atm, e_sun, table, ALBEDO),
                                   _analytic(below, sun, atm, e_sun), rtol=1e-9)


@pytest.mark.parametrize("name", sorted(ATMOSPHERES))
def test_interpolated_table_within_a_tenth_of_a_percent(name):
    """Between the samples (linear in u = sqrt(v_z)), over the sphere and suns from zenith to horizon."""
    atm = ATMOSPHERES[name]
    table = sky_lighting_table(atm)
    rng = np.random.default_rng(11)
    view = rng.normal(size=(20000, 3))
    view /= np.linalg.norm(view, axis=1, keepdims=True)
    view[:2000, 2] *= 0.01  # crowd the horizon
    view /= np.linalg.norm(view, axis=1, keepdims=True)
    worst = 0.0
    for sun_elevation in (80.0, 25.0, 3.0, 0.3):
        sun = _directions(sun_elevation, 70.0)
        e_sun = sun_irradiance_ground(np.radians(sun_elevation), atm)
        expected = _analytic(view, sun, atm, e_sun)
        error = np.abs(sky_radiance_from_table(view, sun, atm, e_sun, table, ALBEDO) - expected)
        worst = max(worst, float(np.max(error / np.maximum(expected, 1e-3 * np.max(expected)))))
    print(f"{name}: worst relative error of the interpolated table {worst:.2e}")
    assert worst < 1e-3


def test_table_values_and_edge_cases():
    atm = ATMOSPHERES["clear"]
    table = sky_lighting_table(atm)
    assert table.coordinate.shape == (SKY_TABLE_SIZE,) and table.transmittance.shape == (SKY_TABLE_SIZE, 3)
    for values in (table.scattering_rayleigh, table.scattering_mie, table.transmittance):
        assert np.all((values >= 0.0) & (values <= 1.0))
    # Toward the horizon the air is longer: more scattered, less transmitted (blue more than red).
    assert np.all(np.diff(table.transmittance, axis=0) >= 0.0)
    assert np.all(table.transmittance[0] < table.transmittance[-1])
    np.testing.assert_allclose(table_coordinate([-0.3, 0.0, 0.25, 1.0, 1.5]), [0.0, 0.0, 0.5, 1.0, 1.0])
    # No air: nothing scattered, everything transmitted (no 0/0 anywhere).
    empty = sky_lighting_table(Atmosphere(rayleigh_scattering=0.0, mie_scattering=0.0, mie_absorption=0.0))
    assert np.all(empty.scattering_rayleigh == 0.0) and np.all(empty.scattering_mie == 0.0)
    assert np.all(empty.transmittance == 1.0)
    # Molecules alone: the one-species sky Phi_R (1 - exp(-beta_R R_R)).
    molecules = Atmosphere(mie_scattering=0.0, mie_absorption=0.0)
    only = sky_lighting_table(molecules)
    r_rayleigh, _ = dome_distance_approx(np.arcsin(only.coordinate ** 2), molecules)
    np.testing.assert_allclose(only.scattering_rayleigh,
                               -np.expm1(-molecules.rayleigh_scattering * r_rayleigh[:, np.newaxis]), rtol=1e-12)
    assert np.all(only.scattering_mie == 0.0)
    with pytest.raises(ValueError):
        sky_lighting_table(atm, size=1)
