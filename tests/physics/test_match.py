# SPDX-License-Identifier: GPL-3.0-or-later
"""Fitting the atmosphere to a plate (physics.match).

* Round trip: plates the model itself makes from 20 random looks within the Earth presets' ranges (sky and the same
  ground at 2 and 20 km, 1 % noise, an unknown exposure, the sRGB transfer and 8 bits) are fitted from the clear
  preset: visibility within 10 %, sun elevation within 1 deg, and every region's mean colour within 2 % of the plate.
* Robustness: Mars fitted from an Earth start says it does not reproduce the plate, and the best of the built-in
  starts is Mars's and does; a sun 2 deg up and an overcast sky are recovered from the clear start.
* Degeneracy: a sky alone under overcast cannot tell the visibility from the haze's scale height, and the fit says so
  instead of returning the wrong visibility as found.
* Bad input (no sky, an overexposed sky, a distance of 0, an empty mask, a mask of the wrong size, a sun below the
  horizon) raises MatchError with one message; the parts (Levenberg-Marquardt, sRGB, the horizon's pitch, the haze
  split) are checked on their own.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from atmos_addon import presets
from atmos_addon.physics import match
from atmos_addon.physics.spectrum import channel_value_at
from atmos_addon.physics.visibility import (extinction_550_per_m, haze_extinction_for_visibility,
                                            haze_for_extinction, visibility_m)
from validation import match_plates

CLEAR = presets.load("clear").atmosphere
#: Pixels per region in the round trip (the default is 300; fewer keep the 20 fits quick).
ROUND_TRIP_SAMPLES = 150
WIDTH, HEIGHT = 160, 90


def region_colour_errors(plate: match.Plate, fit: match.Fit) -> dict[str, float]:
    """Each region's largest channel error of its mean colour over every pixel of its mask, relative to the plate
    region's mean brightness."""
    rendered = match.render_plate(plate, fit.look, fit.surface_radiance)
    errors = {}
    for region in plate.regions:
        plate_mean = plate.pixels[region.mask].mean(axis=0)
        errors[region.name] = float(np.max(np.abs(rendered[region.mask].mean(axis=0) - plate_mean))
                                    / plate_mean.mean())
    return errors


def scene_plate(atm, sun_elevation_deg: float, sun_azimuth_deg: float, *, sky_only: bool = False, seed: int = 3):
    """A level camera looking north, the sky above the middle and grey-brown ground at 20 and 2 km below it, exposed
    so the brightest marked pixels sit at 0.6, 1 % noise, sRGB 8 bits."""
    camera = match.PlateCamera(WIDTH, HEIGHT, 60.0, pitch_deg=2.0)
    rows = np.arange(HEIGHT)[:, None] * np.ones((1, WIDTH))
    horizon = HEIGHT * 0.55
    masks = [("sky", rows < horizon - 6, None)]
    if not sky_only:
        masks += [("far", (rows >= horizon + 2) & (rows < horizon + 10), 20_000.0), ("near", rows >= horizon + 16,
                                                                                     2_000.0)]
    look = match.Look(atm, sun_elevation_deg, sun_azimuth_deg, 0.0)
    radiance = np.array([0.02, 0.018, 0.012])
    probe = match_plates.synthetic_plate(look, camera, masks, radiance)
    marked = np.any([mask for _, mask, _ in masks], axis=0)
    look = replace(look, exposure_ev=math.log2(0.6 / float(np.percentile(probe.pixels[marked], 99.5))))
    return match_plates.synthetic_plate(look, camera, masks, radiance, noise=0.01, srgb=True, seed=seed), look


# ---------------------------------------------------------------------------------------------- round trip

@pytest.mark.parametrize("seed", range(20))
def test_round_trip_recovers_visibility_sun_and_colours(seed):
    plate, truth, _ = match_plates.round_trip_case(seed, CLEAR, width=WIDTH, height=HEIGHT)
    fit = match.fit(plate, CLEAR, samples_per_region=ROUND_TRIP_SAMPLES)
    assert fit.look.visibility_m == pytest.approx(truth.visibility_m, rel=0.10)
    assert abs(fit.look.sun_elevation_deg - truth.sun_elevation_deg) < 1.0
    errors = region_colour_errors(plate, fit)
    assert max(errors.values()) < 0.02, errors
    assert {region.name for region in fit.regions} == {"sky", "far ground", "near ground"}
    assert fit.misfit is None


def test_round_trip_with_the_sun_known_keeps_it():
    plate, truth, _ = match_plates.round_trip_case(3, CLEAR, width=WIDTH, height=HEIGHT)
    knowns = match.Knowns(truth.sun_elevation_deg, truth.sun_azimuth_deg)
    fit = match.fit(plate, CLEAR, knowns, samples_per_region=ROUND_TRIP_SAMPLES)
    assert fit.look.sun_elevation_deg == pytest.approx(truth.sun_elevation_deg, abs=1e-9)
    assert fit.look.sun_azimuth_deg == pytest.approx(truth.sun_azimuth_deg % 360.0, abs=1e-9)
    assert "sun_elevation" not in fit.fitted and "exposure" in fit.fitted
    assert fit.look.visibility_m == pytest.approx(truth.visibility_m, rel=0.05)


# ---------------------------------------------------------------------------------------------- robustness

def test_mars_from_an_earth_start_says_it_does_not_fit_and_the_mars_start_does():
    mars = presets.load("mars").atmosphere
    plate, truth = scene_plate(mars, 30.0, 40.0)
    fits = match.fits_from_starts(plate, {"clear": CLEAR, "mars": mars})
    from_earth, best = fits["clear"], fits["mars"]
    assert from_earth.misfit is not None and "start preset" in from_earth.misfit
    assert from_earth.worst_colour_error > 0.02
    assert best.cost < from_earth.cost  # what fit_best_start keeps
    assert best.misfit is None and max(region_colour_errors(plate, best).values()) < 0.02
    assert best.look.air_density == pytest.approx(truth.air_density, rel=0.5)
    assert best.look.visibility_m == pytest.approx(truth.visibility_m, rel=0.10)


def test_a_low_sun_is_recovered():
    plate, truth = scene_plate(presets.load("sunset").atmosphere, 2.0, 20.0)
    fit = match.fit(plate, CLEAR)
    assert abs(fit.look.sun_elevation_deg - 2.0) < 1.0
    assert fit.look.visibility_m == pytest.approx(truth.visibility_m, rel=0.10)
    assert "ozone" in fit.fitted or "ozone" in fit.held  # the sun is low enough for ozone to be tried
    assert max(region_colour_errors(plate, fit).values()) < 0.02


def test_an_overcast_sky_is_recovered_from_the_clear_start():
    overcast = presets.load("overcast").atmosphere
    plate, truth = scene_plate(overcast, 35.0, 60.0)
    fit = match.fit(plate, CLEAR)
    assert fit.look.visibility_m == pytest.approx(truth.visibility_m, rel=0.10)
    assert fit.look.atmosphere.mie_scale_height == pytest.approx(overcast.mie_scale_height, rel=0.25)
    assert np.all(fit.look.haze_colour > 0.9)  # grey
    assert max(region_colour_errors(plate, fit).values()) < 0.02


def test_a_sky_alone_under_overcast_says_it_cannot_tell_the_visibility():
    plate, truth = scene_plate(presets.load("overcast").atmosphere, 35.0, 60.0, sky_only=True)
    fit = match.fit(plate, CLEAR)
    assert "visibility" in fit.held and "visibility" not in fit.fitted
    assert "cannot tell it from" in fit.held["visibility"]
    assert "held" in fit.reported()["visibility"]
    # the sky it renders still matches: what is held is what the plate leaves open
    assert max(region_colour_errors(plate, fit).values()) < 0.02


def test_a_well_posed_plate_holds_nothing_but_what_the_sun_hides():
    plate, _, _ = match_plates.round_trip_case(10, CLEAR, width=WIDTH, height=HEIGHT)
    fit = match.fit(plate, CLEAR)
    assert set(fit.held) <= {"ozone", "sun_elevation", "exposure", "air_density"}
    assert "visibility" in fit.fitted and fit.standard_errors["visibility"] < 0.10


# ---------------------------------------------------------------------------------------------- bad input

def _plate_with(regions, pixels=None, clip_level=None):
    camera = match.PlateCamera(WIDTH, HEIGHT, 60.0)
    image = np.full((HEIGHT, WIDTH, 3), 0.2) if pixels is None else pixels
    return match.Plate(image, camera, tuple(regions), clip_level)


def _band(top, bottom):
    mask = np.zeros((HEIGHT, WIDTH), dtype=bool)
    mask[top:bottom] = True
    return mask


def test_bad_input_is_refused_with_one_message():
    sky = match.Region("sky", _band(0, 40))
    ground = match.Region("ground", _band(60, 90), 2000.0)
    cases = [
        (_plate_with([ground]), "no sky marked"),
        (_plate_with([sky, match.Region("ground", _band(60, 90), 0.0)]), "distance 0 m"),
        (_plate_with([sky, match.Region("ground", _band(60, 90), -5.0)]), "greater than 0"),
        (_plate_with([sky, match.Region("ground", np.zeros((HEIGHT, WIDTH), bool), 100.0)]), "mask is empty"),
        (_plate_with([sky, match.Region("ground", np.ones((10, 10), bool), 100.0)]), "its mask is 10x10 px"),
        (_plate_with([sky, match.Region("ground", _band(60, 90), np.zeros((HEIGHT, WIDTH)))]), "depth pass has no"),
        (_plate_with([sky, ground], np.zeros((HEIGHT, WIDTH, 3))), "is black"),
    ]
    overexposed = np.full((HEIGHT, WIDTH, 3), 0.3)
    overexposed[:40] = 1.0
    cases.append((_plate_with([sky, ground], overexposed, clip_level=1.0), "the sky is overexposed"))
    for plate, fragment in cases:
        with pytest.raises(match.MatchError) as error:
            match.fit(plate, CLEAR)
        assert fragment in str(error.value)
        assert "\n" not in str(error.value)
    with pytest.raises(match.MatchError, match="at least 0.2 deg up"):
        match.fit(_plate_with([sky, ground]), CLEAR, match.Knowns(sun_elevation_deg=-3.0))
    with pytest.raises(match.MatchError, match="field of view"):
        match.PlateCamera(WIDTH, HEIGHT, 0.0)


def test_a_few_clipped_sky_pixels_are_left_out():
    plate, truth = scene_plate(CLEAR, 30.0, 40.0)
    pixels = plate.pixels.copy()
    pixels[:3, :40] = 1.0  # a small blown-out patch (the sun's glare)
    fit = match.fit(replace(plate, pixels=pixels), CLEAR)
    assert fit.look.visibility_m == pytest.approx(truth.visibility_m, rel=0.10)


# ---------------------------------------------------------------------------------------------- the parts

def test_levenberg_marquardt_solves_rosenbrock():
    def residual(x):
        return np.array([10.0 * (x[1] - x[0] ** 2), 1.0 - x[0]])

    x, cost, iterations = match.levenberg_marquardt(residual, [-1.2, 1.0], max_iterations=200)
    assert np.allclose(x, [1.0, 1.0], atol=1e-6) and cost < 1e-12 and iterations < 200


def test_srgb_transfer_round_trips_and_matches_the_standard():
    values = np.linspace(0.0, 1.0, 101)
    assert np.allclose(match.linear_to_srgb(match.srgb_to_linear(values)), values, atol=1e-12)
    assert match.srgb_to_linear(0.5) == pytest.approx(0.214041, abs=1e-6)  # IEC 61966-2-1
    assert match.srgb_to_linear(0.04045) == pytest.approx(0.04045 / 12.92)


def test_the_horizon_line_gives_the_pitch_that_puts_it_there():
    for fraction in (0.5, 0.3, 0.8):
        pitch = match.pitch_from_horizon(fraction, 400, 300, 60.0)
        camera = match.PlateCamera(400, 300, 60.0, pitch_deg=pitch)
        row = fraction * 300 - 0.5  # the pixel whose centre lies on the line
        direction = camera.directions(np.array([row]), np.array([199.5]))[0]
        assert abs(direction[2]) < 1e-9
    assert match.pitch_from_horizon(0.5, 400, 300, 60.0) == pytest.approx(0.0, abs=1e-12)
    assert match.pitch_from_horizon(0.8, 400, 300, 60.0) > 0.0  # horizon low in the frame: looking up


def test_the_haze_split_gives_the_visibility_asked_for():
    wavelengths = CLEAR.wavelengths_nm
    for visibility in (5_000.0, 40_000.0, 150_000.0):
        extinction = haze_extinction_for_visibility(visibility, wavelengths, CLEAR.rayleigh_scattering)
        scattering, absorption = haze_for_extinction(extinction, wavelengths, [0.6, 0.8, 1.0], [0.1, 0.1, 0.2])
        atm = CLEAR.replace(mie_scattering=scattering, mie_absorption=absorption)
        assert visibility_m(atm) == pytest.approx(visibility, rel=1e-12)
        assert scattering / scattering[2] == pytest.approx([0.6, 0.8, 1.0])
        assert absorption / scattering == pytest.approx([0.1, 0.1, 0.2])
    # a visibility longer than clean air allows: no haze
    assert haze_extinction_for_visibility(1e7, wavelengths, CLEAR.rayleigh_scattering) == 0.0
    assert extinction_550_per_m(CLEAR) == pytest.approx(
        channel_value_at(550.0, wavelengths, CLEAR.rayleigh_scattering)
        + channel_value_at(550.0, wavelengths, CLEAR.mie_scattering)
        + channel_value_at(550.0, wavelengths, CLEAR.mie_absorption))


def test_the_comparison_shows_plate_atmos_and_difference():
    plate, _ = scene_plate(CLEAR, 30.0, 40.0)
    fit = match.fit(plate, CLEAR)
    image = match.comparison_image(plate, match.render_plate(plate, fit.look, fit.surface_radiance))
    assert image.shape == (HEIGHT, 3 * WIDTH, 3)
    assert np.all((image >= 0.0) & (image <= 1.0))
    difference = image[:, 2 * WIDTH:]
    sky = plate.regions[0].mask
    assert difference[sky].mean() < 0.15 < image[:, :WIDTH][sky].mean()  # the difference is dark where it fits
