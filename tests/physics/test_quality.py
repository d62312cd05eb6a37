# SPDX-License-Identifier: GPL-3.0-or-later
"""Quality levels: the catalogue, the accuracy targets against the brute-force reference, the Auto choice."""

import numpy as np
import pytest

from atmos_addon.physics.precise import evaluate as evaluate_precise
from atmos_addon.physics.quality import MEASURED_PIXEL_ERROR, PRODUCT_LEVELS, Level, SceneSummary, choose_level
from validation.accuracy import (BENCH_CASES, COMPLETE_ONLY_CASES, IMPLEMENTED_LEVELS, MEASURED_PIXEL_ERROR_PER_PIXEL,
                                 bench_case, complete_reference, errors, errors_of, evaluate, precise_tile, reference,
                                 relative_error)


def test_catalogue():
    assert [lv.value for lv in Level] == ["fast", "balanced", "precise"]
    assert IMPLEMENTED_LEVELS == (Level.FAST, Level.BALANCED, Level.PRECISE)
    assert PRODUCT_LEVELS == (Level.FAST, Level.PRECISE)   # Balanced is measured, no longer built (retired)
    with pytest.raises(ValueError, match="unknown quality level"):
        evaluate("exact", BENCH_CASES[0])
    assert {name for _, name in MEASURED_PIXEL_ERROR} == {case.name for case in BENCH_CASES}


def test_complete_only_cases_are_bench_cases_by_name_but_not_in_the_auto_table():
    for case in COMPLETE_ONLY_CASES:
        assert bench_case(case.name) is case
        assert all(name != case.name for _, name in MEASURED_PIXEL_ERROR)


def test_luminance_and_chromaticity_errors():
    case = bench_case("ground_vista")
    ref = reference(case)
    same = errors_of(case, ref, ref)
    assert same["luminance_max"] == 0.0 and same["xy_max"] == 0.0
    # Every pixel 10 % brighter in every channel: luminance off by 10 %, chromaticity unchanged.
    l0 = case.surface_radiance
    brighter = errors_of(case, (ref[0], ref[1] + 0.1 * (l0 * ref[0] + ref[1])), ref)
    assert brighter["luminance_max"] == pytest.approx(0.1, rel=1e-9)
    assert brighter["xy_max"] < 1e-12
    # Blue added: the chromaticity moves.
    bluer = errors_of(case, (ref[0], ref[1] + np.array([0.0, 0.0, 0.05]) * ref[1].max()), ref)
    assert bluer["xy_max"] > 1e-3


def test_complete_reference_is_single_scattering_plus_the_higher_orders():
    # The single-scattering levels miss a large part of the light (the orders above the first); Precise's
    # multiple-scattering term recovers most of it. Ground vista, 600 paths (noise about 4 % of L_in).
    case = bench_case("ground_vista")
    f_ex, l_in, error = complete_reference(case, 600, 3)
    f_single, l_single = reference(case)
    np.testing.assert_array_equal(f_ex, f_single)
    assert np.all(l_in > l_single - 3.0 * error)
    assert np.mean(l_in / l_single) > 1.3  # measured 2.3 in each channel on average
    single_scattering = errors_of(case, evaluate(Level.PRECISE, case), (f_ex, l_in))["luminance_max"]
    multiple = evaluate_precise(precise_tile(case, True), case.view_dirs, case.sun_dir, case.distances_m,
                                case.atmosphere, np.float64)
    with_term = errors_of(case, multiple, (f_ex, l_in))["luminance_max"]
    assert single_scattering > 0.3 and with_term < 0.5 * single_scattering, (single_scattering, with_term)


def test_relative_error_floor():
    np.testing.assert_allclose(relative_error(np.array([0.002, 1.1]), np.array([0.001, 1.0]), 0.01), [0.1, 0.1])


def test_fast_within_5_percent_on_level_ground_views():
    # Level views to 30 km (the 1 deg up, 30 km ray of the bench ends 590 m up: 12.9 %, reported in docs).
    case = bench_case("ground_vista")
    level = [i for i, ray in enumerate(case.rays) if ray[0] == 0.0]
    sub = type(case)(case.name, case.description, case.preset, case.camera_altitude_m, case.sun_elevation_deg,
                     tuple(case.rays[i] for i in level))
    assert errors(Level.FAST, sub)["pixel_max"].max() < 0.05


@pytest.mark.parametrize("name", ["ground_vista", "drone", "mars_noon"])
def test_balanced_within_2_percent(name):
    assert errors(Level.BALANCED, bench_case(name))["pixel_max"].max() < 0.02


@pytest.mark.parametrize("case", [c for c in BENCH_CASES if "sunset" not in c.name], ids=lambda case: case.name)
def test_balanced_per_pixel_within_2_percent_except_sunsets(case):
    """The issue's Balanced target (every case but grazing sunset paths) for the Per Pixel variant: 8 pieces, the
    sun at their middles. (Per sample, 4 pieces at their lower ends leave the aircraft at 7.3 %.)"""
    measured = errors(Level.BALANCED, case, per_pixel=True)["pixel_max"].max()
    assert measured < 0.02
    assert measured == pytest.approx(MEASURED_PIXEL_ERROR_PER_PIXEL[case.name], abs=2e-4)


@pytest.mark.parametrize("case", BENCH_CASES, ids=lambda case: case.name)
def test_precise_within_1_percent_in_every_case(case):
    """The issue's Precise target: every case, sunsets included, within 1 % (pixel) of the reference."""
    assert errors(Level.PRECISE, case)["pixel_max"].max() < 0.01


def test_measured_table_is_current():
    for name in (case.name for case in BENCH_CASES):
        for level in IMPLEMENTED_LEVELS:
            measured = errors(level, bench_case(name))["pixel_max"].max()
            assert measured == pytest.approx(MEASURED_PIXEL_ERROR[(level, name)], abs=2e-4)


def test_auto_choice():
    """Auto picks among the levels the add-on builds, Fast and Precise (never the retired Balanced, though the
    bench still measures it)."""
    ground = SceneSummary(camera_altitude_range_m=(1.7, 1.7), max_view_distance_m=8000.0, sun_elevation_deg=40.0)
    assert choose_level(ground, tolerance=0.2)[0] is Level.FAST
    assert choose_level(ground) == (Level.PRECISE, MEASURED_PIXEL_ERROR[(Level.PRECISE, "ground_vista")])
    drone = SceneSummary(camera_altitude_range_m=(1500.0, 2500.0), max_view_distance_m=5000.0)
    assert choose_level(drone, tolerance=0.05) == (Level.FAST, MEASURED_PIXEL_ERROR[(Level.FAST, "drone")])
    assert choose_level(drone)[0] is Level.PRECISE
    aircraft = SceneSummary(camera_altitude_range_m=(10_000.0, 10_000.0), max_view_distance_m=3.6e5)
    assert choose_level(aircraft) == (Level.PRECISE, MEASURED_PIXEL_ERROR[(Level.PRECISE, "aircraft")])
    assert choose_level(aircraft, tolerance=0.1)[0] is Level.PRECISE   # Balanced's 7 % would have met it
    sunset = SceneSummary(sun_elevation_deg=1.0)
    assert choose_level(sunset)[0] is Level.PRECISE                    # Fast misses sunsets by 32-42 %
    assert choose_level(sunset, tolerance=0.001) == (Level.PRECISE, MEASURED_PIXEL_ERROR[(Level.PRECISE,
                                                                                          "sunset_away")])
    animated = SceneSummary(sun_animated=True)
    assert choose_level(animated) == choose_level(sunset)             # an animated sun may set
    mars = SceneSummary(planet_radius_m=3_389_500.0, sun_elevation_deg=70.0)
    assert choose_level(mars) == (Level.PRECISE, MEASURED_PIXEL_ERROR[(Level.PRECISE, "mars_noon")])
    assert choose_level(mars, tolerance=0.11)[0] is Level.FAST
    assert all(choose_level(summary, tolerance)[0] in PRODUCT_LEVELS for summary in (ground, drone, aircraft, sunset,
                                                                                   mars)
               for tolerance in (0.001, 0.01, 0.02, 0.05, 0.1, 0.5, 2.0))
    with pytest.raises(ValueError, match="tolerance"):
        choose_level(ground, tolerance=0.0)
