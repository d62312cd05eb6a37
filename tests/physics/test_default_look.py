# SPDX-License-Identifier: GPL-3.0-or-later
"""What a user sees by default (Precise with multiple scattering), the issue's checklist as physics: the sky's
colours from ``physics.precise.sky_radiance`` (``validation/measure_default_sky.py`` prints them all). Under the seed's
single-scattering model each of these failed: a brown zenith at a low sun, a black blue hour, a black overcast dawn.
"""

from __future__ import annotations

import pytest

from validation.measure_default_sky import sky_colours


def test_clear_noon_and_low_sun_zenith_is_blue_over_a_golden_horizon() -> None:
    noon, _ = sky_colours("clear", 60.0)
    assert noon[2] > noon[1] > noon[0] and noon[2] > 2.0 * noon[0]
    zenith, horizon = sky_colours("clear", 5.0)
    assert zenith[2] > zenith[1] > zenith[0] and zenith[2] > 2.0 * zenith[0]     # blue, not brown
    assert horizon[0] > horizon[1] > horizon[2] and horizon[0] > 3.0 * horizon[2]   # golden toward the sun


@pytest.mark.parametrize("sun_deg", [-2.0, -6.0])
def test_the_blue_hour_is_blue(sun_deg: float) -> None:
    zenith, _ = sky_colours("clear", sun_deg)
    assert zenith.min() > 0.0
    assert zenith[2] > zenith[1] > zenith[0]


def test_an_overcast_sky_is_still_lit_at_a_one_degree_sun() -> None:
    dawn, _ = sky_colours("overcast", 1.0)
    day, _ = sky_colours("overcast", 20.0)
    assert dawn.min() > 0.03 * day.max()   # the seed's model: 1e-6 of noon's


def test_mars_is_butterscotch_by_day_with_a_blue_sunset_glow() -> None:
    noon, _ = sky_colours("mars", 60.0)
    assert noon[0] > noon[1] > noon[2]
    _, glow = sky_colours("mars", 1.0)
    assert glow[2] > glow[0]
