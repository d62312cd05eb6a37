# SPDX-License-Identifier: GPL-3.0-or-later
"""The built-in presets' looks hold on rendered pixels (Cycles, the real add-on path: api.enable + the sky).

Mars: the daytime sky reads butterscotch (R > G > B) and the glow around a setting sun is bluish (B/R near
the sun higher than away from it). Sunset: the horizon toward the sun is red-dominant and the sun lamp
orange. Each view is a 4 x 4 px render through a 2 degree field of view aimed at one direction.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import render_utils as ru
from atmos_addon import api


@pytest.fixture()
def scene(addon):
    return addon


def _look(scene, elevation_deg: float, azimuth_deg: float) -> np.ndarray:
    """Mean linear RGB of the sky in the direction (elevation, azimuth clockwise from +Y), degrees."""
    camera = scene.camera
    camera.rotation_euler = (math.radians(90.0 + elevation_deg), 0.0, -math.radians(azimuth_deg))
    return ru.render_to_array(scene)[..., :3].reshape(-1, 3).mean(axis=0)


def _setup(scene, preset: str, sun_elevation_deg: float) -> None:
    ru.make_camera(scene, fov_rad=math.radians(2.0), clip_end=100.0)
    ru.set_engine(scene, "CYCLES", width=4, height=4)
    api.enable(scene, preset=preset, sun_elevation_deg=sun_elevation_deg, sun_azimuth_deg=0.0)
    scene.world.cycles.sampling_method = "NONE"  # only camera rays see the sky here


def test_mars_day_sky_is_butterscotch(scene) -> None:
    _setup(scene, "mars", 40.0)
    sky = _look(scene, 30.0, 180.0)
    assert sky[0] > sky[1] > sky[2] > 0.0, sky


def test_mars_sunset_glow_is_blue(scene) -> None:
    _setup(scene, "mars", 2.0)
    near = _look(scene, 2.0, 4.0)  # 4 degrees from the sun: outside the disk, inside the forward glow
    far = _look(scene, 2.0, 90.0)
    assert near[2] / near[0] > 1.5 * far[2] / far[0], (near, far)
    assert near[2] > near[0], near  # bluish around the sun


def test_sunset_horizon_is_red_and_the_sun_orange(scene) -> None:
    _setup(scene, "sunset", 2.0)
    horizon = _look(scene, 1.0, 15.0)
    assert horizon[0] > horizon[1] > horizon[2], horizon
    lamp = next(obj for obj in scene.objects if obj.type == "LIGHT").data
    assert lamp.color[0] > lamp.color[1] > lamp.color[2], tuple(lamp.color)
    assert np.isfinite(horizon).all()


def test_the_blue_hour_is_blue_and_ozone_makes_it_so(scene) -> None:
    """The default (Precise with multiple scattering) with the clear preset, the sun 4 deg below the horizon: the
    zenith renders B > G > R; the same sky without its ozone (the preset's 300 DU set to 0) is far less blue, as the
    physics says (tests/physics/test_ozone.py: zenith B/R 3.1 against 1.4)."""
    _setup(scene, "clear", -4.0)
    assert scene.atmos.quality == "PRECISE" and scene.atmos.multiple_scattering
    assert scene.atmos.ozone_column_du == 300.0
    zenith = _look(scene, 90.0, 0.0)
    assert zenith[2] > zenith[1] > zenith[0] > 0.0, zenith
    scene.atmos.ozone_column_du = 0.0
    without = _look(scene, 90.0, 0.0)
    assert zenith[2] / zenith[0] > 1.8 * without[2] / without[0], (zenith, without)
