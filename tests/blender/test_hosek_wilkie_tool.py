# SPDX-License-Identifier: GPL-3.0-or-later
"""``validation/compare_hosek_wilkie.py``: its Blender half renders the Hosek-Wilkie Sky Texture where it says it does.

Two tiny Cycles renders (the tool's own :func:`~validation.compare_hosek_wilkie.render_hosek_wilkie`, sun 20 deg, the
clear preset's turbidity): the zenith and the sky 5 deg above the horizon toward the sun. What a wrong sun
direction, a wrong sky type or a broken read-back would change: toward a 20 deg sun the low sky is far brighter
than the zenith (the tool's run, ``docs/hosek_wilkie.md``: 11.4 times; the same view away from the sun: 8.1, so a sun
put on the wrong side fails) and redder (the zenith is the bluest part of a clear day sky: B/R 3.5 against 1.2,
x 0.241 against 0.303). And the tool's scale-free quantities: the zenith's relative luminance is exactly 1, and the
turbidity it derives for the clear preset lies inside Hosek-Wilkie's fitted range 1-10.
"""

from __future__ import annotations

import numpy as np

from atmos_addon import presets
from validation.compare_hosek_wilkie import (
    VIEWS,
    preetham_turbidity,
    relative_luminance,
    render_hosek_wilkie,
    turbidities,
    xy_of_rgb,
)

SUN_ELEVATION_DEG = 20.0


def test_clear_turbidity_is_inside_hosek_wilkies_range_and_agrees_with_its_definition():
    info = preetham_turbidity(presets.load("clear").atmosphere)
    assert 1.0 < info["turbidity"] < 10.0
    # Preetham's appendix (beta of T) and his definition 1 + tau_a / tau_R at 550 nm describe the same column.
    assert abs(info["turbidity"] / info["turbidity_definition"] - 1.0) < 0.05
    assert turbidities()[0] == round(info["turbidity"], 2)


def test_rendered_hosek_wilkie_zenith_is_bluer_and_darker_than_the_horizon_toward_a_20_deg_sun():
    views = {name: VIEWS[name] for name in ("zenith", "5 toward")}
    renders = render_hosek_wilkie(turbidities()[0], sun_elevations_deg=(SUN_ELEVATION_DEG,), views=views)
    rgb = renders[f"{SUN_ELEVATION_DEG:g}"]
    assert set(rgb) == set(views)
    for value in rgb.values():
        assert np.all(np.isfinite(value)) and np.all(np.asarray(value) > 0.0)

    relative = relative_luminance(rgb)
    assert relative["zenith"] == 1.0
    assert relative["5 toward"] > 10.0

    zenith, toward = np.asarray(rgb["zenith"]), np.asarray(rgb["5 toward"])
    assert zenith[2] / zenith[0] > 1.5 * toward[2] / toward[0]
    assert xy_of_rgb(zenith)[0] < xy_of_rgb(toward)[0] - 0.03
