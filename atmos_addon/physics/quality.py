# SPDX-License-Identifier: GPL-3.0-or-later
"""Quality levels of the aerial perspective, what each is measured to cost and to miss, and the Auto choice.

Levels (cheapest first)
    * FAST: Hoffman & Preetham 2002, eq. 19: sea-level densities along the whole ray
      (:mod:`~atmos_addon.physics.aerial_perspective`).
    * BALANCED: exponential densities along the (curved) ray in closed form (``validation/balanced.py``). Measured
      only, not a level the add-on builds: off the Pareto front of error against the complete reference versus
      render time (its worst day error 62 % against Fast's 83 % and Precise + multiple scattering's 3 %, at
      Precise's cost; docs/quality.md).
    * PRECISE: single scattering integrated numerically over the spherical planet, baked per frame into a
      camera-centred table the shader samples (:mod:`~atmos_addon.physics.precise`), with an optional
      multiple-scattering term (every order; :class:`~atmos_addon.physics.precise.MultipleScatteringTable`).

The measured errors come from the accuracy bench (``validation/accuracy.py``: the bench situations, the
brute-force references and the error measure; ``tools/bench_accuracy.py`` prints the tables), which the add-on
does not ship.

Auto rule (:func:`choose_level`)
    1. The scene summary is mapped to the nearest bench situations: the planet (Mars for a radius below
       5000 km), the geometry (aircraft if the camera reaches 5 km, drone if it reaches 200 m, distant range
       if views reach beyond 30 km or the geometry spans more than 500 m of altitude, ground vista
       otherwise), plus the low-sun cases when the sun is below 5 deg or animated.
    2. The expected error of a level is the largest measured pixel error (max over rays and channels,
       :data:`MEASURED_PIXEL_ERROR`) over those situations.
    3. The cheapest of the product's levels (:data:`PRODUCT_LEVELS`) whose expected error is within the tolerance
       wins; if none is, the one with the smallest expected error.
    A scene without haze (``mie_zero``) or absorption uses the same measured errors: the haze, with its
    short scale height, is what the constant-density model gets most wrong, so they are upper bounds.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

from .atmosphere import Atmosphere


class Level(enum.Enum):
    """Aerial-perspective quality levels, cheapest first."""

    FAST = "fast"
    BALANCED = "balanced"
    PRECISE = "precise"


#: Worst-ray luminance error by day (ground vista, distant range, drone, aircraft) against every scattering order,
#: lowest and highest case, %: docs/quality.md "Against the complete reference" (``tools/bench_accuracy.py --paths
#: 4000``). Keyed by level and whether Precise adds its multiple-scattering term.
DAY_ERROR_PCT = {
    (Level.FAST, False): (9, 83),
    (Level.BALANCED, False): (5, 62),
    (Level.PRECISE, False): (5, 62),
    (Level.PRECISE, True): (0.1, 2),   # the drone 0.1 %: each table row's columns start at its vertical ray
}
#: Render time against Blender's own Sky Texture alone (its sky and no aerial perspective), the sample valley in
#: Cycles: docs/benchmarks.md (``./run bench``, Blender 5.2.3, with the camera sky view: medians of 3 interleaved
#: repeats); Balanced's from docs/quality.md "Cost" (``tools/bench_quality_cost.py --engines cycles --repeats 5
#: --decompose``; ``./run bench`` does not build it). In-Render mode is part of neither bench.
RENDER_COST_VS_SKY = {
    (Level.FAST, "COMPOSITOR"): 1.20,
    (Level.FAST, "PER_PIXEL"): 1.03,
    (Level.BALANCED, "COMPOSITOR"): 1.85,
    (Level.BALANCED, "PER_PIXEL"): 1.14,
    (Level.PRECISE, "COMPOSITOR"): 1.75,
    (Level.PRECISE, "PER_PIXEL"): 1.05,
}


def level_summary(level: Level, multiple_scattering: bool, mode: str) -> str:
    """The panel's one plain line for a level: its measured error by day and its measured cost, e.g.
    "1-3 % off by day, 2.5x sky cost" (the cost against Blender's own sky; left out where it was not measured)."""
    low, high = DAY_ERROR_PCT[(level, multiple_scattering and level is Level.PRECISE)]
    cost = RENDER_COST_VS_SKY.get((level, mode))
    line = f"{low:g}-{high:g} % off by day"
    return f"{line}, {cost:.1f}x sky cost" if cost is not None else line


#: The levels the add-on builds, cheapest first: :func:`choose_level` picks among these.
PRODUCT_LEVELS = (Level.FAST, Level.PRECISE)

#: Planet radius below which a scene counts as Mars-like for the Auto choice, m.
MARS_LIKE_RADIUS_M = 5.0e6
#: Camera altitude from which a scene counts as an aircraft view, m.
AIRCRAFT_ALTITUDE_M = 5000.0
#: Camera altitude from which a scene counts as a drone view, m.
DRONE_ALTITUDE_M = 200.0
#: View distance beyond which a ground scene counts as a distant range, m.
DISTANT_RANGE_M = 30_000.0
#: Altitude span of the geometry beyond which a ground scene counts as a distant range (mountains), m.
MOUNTAIN_SPAN_M = 500.0
#: Sun elevation below which the low-sun (sunset) cases apply, deg.
LOW_SUN_DEG = 5.0

#: Max pixel error (over rays and channels) per (level, case), from ``tools/bench_accuracy.py``; the
#: Auto choice reads this table (a test checks it against a fresh measurement).
MEASURED_PIXEL_ERROR: dict[tuple[Level, str], float] = {
    (Level.FAST, "ground_vista"): 0.1245,
    (Level.BALANCED, "ground_vista"): 0.0050,
    (Level.PRECISE, "ground_vista"): 0.0002,
    (Level.FAST, "distant_range"): 0.3055,
    (Level.BALANCED, "distant_range"): 0.0078,
    (Level.PRECISE, "distant_range"): 0.0009,
    (Level.FAST, "drone"): 0.0474,
    (Level.BALANCED, "drone"): 0.0020,
    (Level.PRECISE, "drone"): 0.0000,
    (Level.FAST, "aircraft"): 1.6780,
    (Level.BALANCED, "aircraft"): 0.0711,
    (Level.PRECISE, "aircraft"): 0.0011,
    (Level.FAST, "sunset_toward"): 0.4219,
    (Level.BALANCED, "sunset_toward"): 0.3083,
    (Level.PRECISE, "sunset_toward"): 0.0007,
    (Level.FAST, "sunset_away"): 0.3214,
    (Level.BALANCED, "sunset_away"): 0.3519,
    (Level.PRECISE, "sunset_away"): 0.0047,
    (Level.FAST, "mars_noon"): 0.1007,
    (Level.BALANCED, "mars_noon"): 0.0074,
    (Level.PRECISE, "mars_noon"): 0.0001,
    (Level.FAST, "mars_sunset"): 0.5682,
    (Level.BALANCED, "mars_sunset"): 0.4292,
    (Level.PRECISE, "mars_sunset"): 0.0014,
}

_EARTH_R = Atmosphere().planet_radius


@dataclass(frozen=True)
class SceneSummary:
    """What the Auto choice needs to know about a scene (lengths m, angles deg)."""

    camera_altitude_range_m: tuple[float, float] = (0.0, 2.0)
    geometry_altitude_span_m: float = 0.0
    max_view_distance_m: float = 10_000.0
    sun_elevation_deg: float = 45.0
    mie_zero: bool = False
    sun_animated: bool = False
    planet_radius_m: float = field(default=_EARTH_R)


def nearest_cases(summary: SceneSummary) -> tuple[str, ...]:
    """Names of the bench situations that stand for ``summary`` (rule 1 of the module docstring)."""
    low_sun = summary.sun_animated or summary.sun_elevation_deg < LOW_SUN_DEG
    if summary.planet_radius_m < MARS_LIKE_RADIUS_M:
        return ("mars_noon", "mars_sunset") if low_sun else ("mars_noon",)
    top = max(summary.camera_altitude_range_m)
    if top >= AIRCRAFT_ALTITUDE_M:
        geometry = "aircraft"
    elif top >= DRONE_ALTITUDE_M:
        geometry = "drone"
    elif summary.max_view_distance_m > DISTANT_RANGE_M or summary.geometry_altitude_span_m > MOUNTAIN_SPAN_M:
        geometry = "distant_range"
    else:
        geometry = "ground_vista"
    return (geometry, "sunset_toward", "sunset_away") if low_sun else (geometry,)


def expected_error(level: Level, summary: SceneSummary) -> float:
    """Largest measured pixel error of ``level`` over the situations standing for ``summary``."""
    return max(MEASURED_PIXEL_ERROR[(level, name)] for name in nearest_cases(summary))


def choose_level(summary: SceneSummary, tolerance: float = 0.02) -> tuple[Level, float]:
    """(level, expected relative pixel error): the cheapest of :data:`PRODUCT_LEVELS` within ``tolerance``.

    If none meets it, the one with the smallest expected error (rule 3).
    """
    if not tolerance > 0.0:
        raise ValueError(f"choose_level: tolerance must be a relative error > 0 (e.g. 0.02); got {tolerance!r}")
    expected = [(level, expected_error(level, summary)) for level in PRODUCT_LEVELS]
    for level, error in expected:
        if error <= tolerance:
            return level, error
    return min(expected, key=lambda item: item[1])
