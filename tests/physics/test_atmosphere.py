# SPDX-License-Identifier: GPL-3.0-or-later
"""The Atmosphere dataclass: defaults, conversion, validation and round trips."""

import json

import numpy as np
import pytest

from atmos_addon.physics import Atmosphere
from atmos_addon.physics.spectrum import LINEAR_REC709_TO_XYZ, SUN_TOP_RGB
from atmos_addon.physics.visibility import visibility_m


def test_defaults_are_a_clear_earth_sky():
    atm = Atmosphere()
    assert atm.planet_radius == 6_360_000.0 and atm.atmosphere_height == 100_000.0
    assert atm.mie_scale_height == 1200.0
    np.testing.assert_array_equal(atm.mie_g, [0.76, 0.76, 0.76])
    np.testing.assert_array_equal(atm.wavelengths_nm, [648.1, 547.4, 443.1])  # Rec.709's channels under sunlight
    # The sun above the atmosphere: the solar spectrum's colour (slightly warm) at luminance 4.5.
    np.testing.assert_allclose(atm.sun_irradiance_top, 4.5 * SUN_TOP_RGB, rtol=1e-12)
    assert float(LINEAR_REC709_TO_XYZ[1] @ atm.sun_irradiance_top) == pytest.approx(4.5, rel=1e-9)
    assert atm.sun_irradiance_top[0] > atm.sun_irradiance_top[1] > atm.sun_irradiance_top[2]
    # Rayleigh grows toward blue; Koschmieder visibility 3.912 / beta_ex at 550 nm of 50-100 km.
    assert atm.rayleigh_scattering[0] < atm.rayleigh_scattering[1] < atm.rayleigh_scattering[2]
    assert 50e3 < visibility_m(atm) < 100e3
    np.testing.assert_allclose(atm.extinction_coefficient,
                               atm.rayleigh_scattering + atm.mie_scattering + atm.mie_absorption)
    np.testing.assert_allclose(atm.scattering_coefficient, atm.rayleigh_scattering + atm.mie_scattering)


def test_scalars_broadcast_and_arrays_are_read_only_copies():
    source = np.array([0.1, 0.2, 0.3])
    atm = Atmosphere(mie_scattering=2e-5, mie_g=source)
    np.testing.assert_array_equal(atm.mie_scattering, [2e-5] * 3)
    assert atm.mie_g.dtype == np.float64 and not atm.mie_g.flags.writeable
    source[0] = 0.9
    assert atm.mie_g[0] == 0.1
    with pytest.raises(ValueError):
        atm.mie_scattering[0] = 1.0


@pytest.mark.parametrize("field, value", [
    ("rayleigh_scattering", [-1e-6, 1e-5, 2e-5]),
    ("mie_scattering", -1e-5),
    ("mie_absorption", -1e-7),
    ("mie_g", 1.0),
    ("mie_g", [0.2, -1.5, 0.1]),
    ("mie_scattering", [1e-5, np.nan, 1e-5]),
    ("sun_irradiance_top", np.inf),
    ("mie_scattering", [1e-5, 2e-5]),
    ("rayleigh_scale_height", 0.0),
    ("mie_scale_height", -5.0),
    ("planet_radius", np.nan),
    ("atmosphere_height", "high"),
    ("sun_irradiance_top", -1.0),
    ("wavelengths_nm", [680.0, 0.0, 440.0]),
])
def test_invalid_values_name_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        Atmosphere(**{field: value})


def test_dict_round_trip_through_json():
    atm = Atmosphere(mie_g=[0.7, 0.75, 0.8], mie_scale_height=1500.0)
    data = json.loads(json.dumps(atm.to_dict()))
    assert all(isinstance(v, (list, float)) for v in data.values())
    again = Atmosphere.from_dict(data)
    assert again == atm and hash(again) == hash(atm)
    with pytest.raises(ValueError, match="unknown field"):
        Atmosphere.from_dict({**data, "ozone": 1.0})


def test_replace_validates_and_leaves_the_original():
    atm = Atmosphere()
    hazier = atm.replace(mie_scattering=1e-4)
    np.testing.assert_array_equal(hazier.mie_scattering, [1e-4] * 3)
    np.testing.assert_array_equal(atm.mie_scattering, [3.3e-5] * 3)
    assert hazier != atm
    with pytest.raises(ValueError, match="mie_g"):
        atm.replace(mie_g=-1.0)
    shifted = atm.replace(wavelengths_nm=[700.0, 550.0, 450.0], rayleigh_scattering=None)
    assert shifted.rayleigh_scattering[0] < atm.rayleigh_scattering[0]
