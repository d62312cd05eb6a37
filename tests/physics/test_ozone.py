# SPDX-License-Identifier: GPL-3.0-or-later
"""Ozone in the product's atmosphere: the layer, its slant column, and every path that reads it.

Ozone (``Atmosphere.ozone_column_du``) absorbs in a tent between 10 and 40 km (Bruneton 2017). The checks: the
column it holds is the one asked for; the slant column against a brute-force march; the sun's optical depth (the
sun lamp), the Precise sun-transmittance table, the Precise sky and the Monte Carlo reference all read the same
absorber; and what it does to the twilight zenith (the reason it is in the default).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from atmos_addon.physics import Atmosphere
from atmos_addon.physics.optical_depth import optical_depth_to_space, ozone_slant_column
from atmos_addon.physics.precise import SunTransmittanceTable, sky_radiance
from atmos_addon.physics.spectrum import (DOBSON_UNIT_PER_M2, OZONE_CHANNEL_CROSS_SECTION_M2, OZONE_CROSS_SECTION_M2,
                                         WAVELENGTHS_NM, channel_response_weights,
                                         ozone_number_density_per_m3)
from atmos_addon.physics.sun import sun_irradiance_ground
from atmos_addon.presets import load
from validation import multiple_scattering_reference as ms_reference
from validation.reference import optical_depth_numerical

OZONE = Atmosphere(ozone_column_du=300.0)


def _march(atm: Atmosphere, altitude_m: float, cos_zenith: float, n: int = 200_001) -> float:
    """The relative density integrated to the top by the trapezoid rule on ``n`` equal steps, m."""
    r0 = atm.planet_radius + altitude_m
    b = r0 * cos_zenith
    r_top = atm.planet_radius + atm.atmosphere_height
    s = np.linspace(0.0, -b + math.sqrt(b * b - r0 * r0 + r_top * r_top), n)
    density = Atmosphere.ozone_density(np.sqrt(r0 * r0 + 2.0 * b * s + s * s) - atm.planet_radius)
    return float(np.sum(0.5 * (density[1:] + density[:-1]) * np.diff(s)))


def test_the_seed_atmosphere_has_none_and_the_earth_presets_hold_300_du():
    assert Atmosphere().ozone_column_du == 0.0
    assert np.all(Atmosphere().ozone_absorption == 0.0)
    for name in ("clear", "overcast", "sunset"):
        assert load(name).atmosphere.ozone_column_du == 300.0, name
    assert load("mars").atmosphere.ozone_column_du == 0.0
    for bad in (-1.0, float("nan"), float("inf"), "lots"):
        with pytest.raises(ValueError, match="ozone_column_du"):
            Atmosphere(ozone_column_du=bad)
    assert Atmosphere.from_dict(OZONE.to_dict()) == OZONE and OZONE != Atmosphere()


def test_the_layer_holds_the_column_asked_for():
    """Straight up from the ground the optical depth is the channel's cross-section x the column (300 DU: R 0.032,
    G 0.024, B 0.0025), and the tent's density is the spectrum module's number density."""
    assert float(ozone_slant_column(0.0, 1.0, OZONE)) == pytest.approx(15_000.0, rel=1e-12)
    tau = OZONE.ozone_absorption * float(ozone_slant_column(0.0, 1.0, OZONE))
    np.testing.assert_allclose(tau, OZONE_CHANNEL_CROSS_SECTION_M2 * 300.0 * DOBSON_UNIT_PER_M2, rtol=1e-12)
    assert tau[2] < 0.15 * tau[1] and tau[1] < tau[0]      # Chappuis band: red and green, hardly blue
    peak = ozone_number_density_per_m3(25e3, 300.0)
    np.testing.assert_allclose(OZONE.ozone_absorption_at(np.array([0.0, 10e3, 25e3, 32.5e3, 40e3, 60e3])),
                               OZONE_CHANNEL_CROSS_SECTION_M2[None, :] * peak
                               * np.array([0.0, 0.0, 1.0, 0.5, 0.0, 0.0])[:, None], rtol=1e-12)


def test_the_channel_cross_section_carries_the_band_s_transmittance():
    """Three numbers stand for 48: the channel mean of the cross-section under sunlight keeps exp(-sigma N) within 5 %
    of the band's own transmittance (the spectrum through the layer, weighted as the channel sees it, negative lobes
    included) from one to 30 vertical columns (a twilight ray); blue's band hardly sees ozone (within 0.7 % of 1) and
    takes none; one wavelength per channel (680, 550, 440 nm) is 64 % off in red."""
    weights = channel_response_weights()
    np.testing.assert_allclose(weights.sum(axis=0), 1.0, rtol=1e-12)
    assert OZONE_CHANNEL_CROSS_SECTION_M2[2] == 0.0
    np.testing.assert_allclose(OZONE_CHANNEL_CROSS_SECTION_M2[:2], (OZONE_CROSS_SECTION_M2 @ weights)[:2], rtol=1e-12)
    point = np.interp([680.0, 550.0, 440.0], WAVELENGTHS_NM, OZONE_CROSS_SECTION_M2)
    point_error = 0.0
    for columns in (1.0, 5.0, 12.0, 25.0, 30.0):
        n_per_m2 = columns * 300.0 * DOBSON_UNIT_PER_M2
        band = np.exp(-OZONE_CROSS_SECTION_M2 * n_per_m2) @ weights
        np.testing.assert_allclose(np.exp(-OZONE_CHANNEL_CROSS_SECTION_M2 * n_per_m2), band, rtol=0.05)
        assert band[2] == pytest.approx(1.0, abs=0.007)
        point_error = max(point_error, float(np.max(np.abs(np.exp(-point * n_per_m2) / band - 1.0))))
    assert point_error > 0.5


@pytest.mark.parametrize("altitude_m, cos_zenith", [
    (0.0, 1.0), (0.0, 0.3), (0.0, 0.02), (0.0, 0.0), (5_000.0, -0.03), (15_000.0, -0.05), (25_000.0, 0.0),
    (30_000.0, -0.1), (30_000.0, 0.3), (45_000.0, -0.12), (45_000.0, 0.5), (80_000.0, -0.14)])
def test_the_slant_column_is_the_march(altitude_m, cos_zenith):
    """Exact to the march's own error, going up, grazing, and down through the layer and out again."""
    assert float(ozone_slant_column(altitude_m, cos_zenith, OZONE)) == pytest.approx(
        _march(OZONE, altitude_m, cos_zenith), rel=1e-6, abs=1e-3)


def test_the_sun_lamp_and_the_precise_sun_table_read_the_same_ozone():
    """The optical depth to space (the sun lamp's E_sun) against the brute-force reference march, and the Precise
    table's bilinear lookup against both, from the ground to above the layer, to the horizon and below it."""
    altitude = np.array([0.0, 0.0, 0.0, 0.0, 5_000.0, 20_000.0, 30_000.0, 30_000.0, 60_000.0])
    cos_zenith = np.array([1.0, 0.3, 0.1, 0.0, -0.02, -0.05, 0.02, -0.08, -0.1])
    zenith = np.arccos(cos_zenith)
    exact = np.array([optical_depth_numerical(h, z, OZONE) for h, z in zip(altitude, zenith)])
    np.testing.assert_allclose(optical_depth_to_space(altitude, zenith, OZONE), exact, rtol=1e-4)
    without = optical_depth_to_space(altitude, zenith, Atmosphere())
    assert np.all(exact[:, 1] - without[:, 1] > 0.02)       # every such ray crosses the layer
    table = SunTransmittanceTable(OZONE)(OZONE.planet_radius + altitude, cos_zenith)
    np.testing.assert_allclose(table, np.exp(-exact), rtol=2e-3)
    # a zenith sun's lamp loses exactly the vertical column's transmittance
    ratio = sun_irradiance_ground(math.pi / 2, OZONE) / sun_irradiance_ground(math.pi / 2, Atmosphere())
    np.testing.assert_allclose(ratio, np.exp(-OZONE.ozone_absorption * 15_000.0), rtol=1e-6)


def test_the_monte_carlo_reference_reads_the_atmosphere_s_ozone_as_its_absorber_callback():
    """The reference's native ozone and the same absorber passed as ``extra_absorption`` are one computation: the
    same paths (same seed) give the same radiance."""
    views = np.array([[0.0, 0.0, 1.0], [0.8, 0.0, 0.6], [-0.99, 0.0, 0.14]])
    sun = np.array([math.cos(math.radians(3.0)), 0.0, math.sin(math.radians(3.0))])
    native, _ = ms_reference.sky_radiance_mc(views, sun, OZONE, paths=64, seed=3)
    callback, _ = ms_reference.sky_radiance_mc(views, sun, Atmosphere(), paths=64, seed=3,
                                            extra_absorption=OZONE.ozone_absorption_at)
    np.testing.assert_allclose(native, callback, rtol=1e-12)
    plain, _ = ms_reference.sky_radiance_mc(views, sun, Atmosphere(), paths=64, seed=3)
    assert not np.allclose(native, plain, rtol=1e-3)


#: Zenith B/R of the spectral Monte Carlo reference (every order, 48 wavelengths, clear preset, 300 DU, ground albedo
#: 0.3) at a sun 2, 4 and 6 deg below the horizon: docs/reference_sky.md (validation/measure_reference_sky.py).
SPECTRAL_REFERENCE_TWILIGHT_ZENITH_B_OVER_R = {-2.0: 2.59, -4.0: 3.4, -6.0: 4.46}


def test_ozone_keeps_the_twilight_zenith_blue():
    """The reason ozone is in the default: with the sun below the horizon the zenith is lit by light that crossed
    the layer at a slant, and ozone takes its red and green. Precise with multiple scattering, the clear preset: the
    zenith's B/R more than doubles at a sun 4 deg down, lies within 10 % of the spectral reference's at -2, -4
    and -6 deg (measured -5.7, -9.0 and -6.5 % since the multiple-scattering table interpolates log-linearly in
    the sun's cosine, which brought the twilight sky's luminance within 2-7 % of the reference at the zenith and
    away from the sun at -4 and -6 deg, from +4 to +50 %; linearly it read 0-5 % low in B/R with that surplus of
    blue light; without ozone: half of it or less), and hardly moves at noon."""
    clear = load("clear").atmosphere
    without = clear.replace(ozone_column_du=0.0)
    zenith = np.array([0.0, 0.0, 1.0])

    def blue_over_red(atm, sun_deg):
        e = math.radians(sun_deg)
        radiance = sky_radiance(zenith, np.array([math.cos(e), 0.0, math.sin(e)]), atm)
        return radiance[2] / radiance[0]

    assert blue_over_red(clear, -4.0) > 2.0 * blue_over_red(without, -4.0)
    for sun_deg, reference in SPECTRAL_REFERENCE_TWILIGHT_ZENITH_B_OVER_R.items():
        assert blue_over_red(clear, sun_deg) == pytest.approx(reference, rel=0.10), sun_deg
        assert blue_over_red(without, sun_deg) < 0.6 * reference, sun_deg
    assert blue_over_red(clear, 60.0) == pytest.approx(blue_over_red(without, 60.0), rel=0.05)
