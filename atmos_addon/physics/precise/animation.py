# SPDX-License-Identifier: GPL-3.0-or-later
"""An animated camera or sun: key tiles along its path, blended.

A tile is a function of the camera's altitude h_c and the sun's elevation e_s alone (the azimuths are the shader's),
so a scene whose camera or sun moves traces a path in (h_c, e_s) over its frames. Instead of a tile per frame
(1.5-2.5 s of baking and about 0.6 MB of .blend each, tools/bench_animation.py) the add-on bakes "key tiles" where
the path has moved one step since the last key (:func:`key_tiles`), and each frame blends the two keys around it,
texel by texel: the shader's lookups are linear in the texels, so blending the texels is sampling
:func:`blend_tiles`. The steps keep the blend's error at mid-step small (:func:`mid_step_error`, docs/quality.md
"Animation"): the sun's elevation moves 2 deg per key above 10 deg, 1 deg down to 3 deg, 0.5 deg below (twilight's
light changes fastest); the camera's altitude a step of ln(1 + h / 300 m) of 0.35 (0 -> 125 m, 300 -> 570 m) until
that step reaches 500 m (at 1.13 km), then 500 m (a step of 1.3 km at 3 km puts steep rays to points about 1 km up
out of the lower key's reach: 12.7 % at the 99th percentile on Mars, 2.8 % with 500 m). All key tiles of a path
share the largest distance D (:func:`shared_max_distance`), so the two keys' texels map the same rays.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..atmosphere import Atmosphere
from .bake import bake_tile
from .layout import Tile, max_distance
from .lookup import evaluate, sky_from_tile


#: Sun-elevation steps between key tiles: (from this elevation up, deg; step, deg), highest first.
SUN_STEPS_DEG = ((10.0, 2.0), (3.0, 1.0), (-90.0, 0.5))
#: The camera altitude's key coordinate is ln(1 + h / ALTITUDE_SCALE_M) / ALTITUDE_STEP (one unit per step) up to
#: the altitude where that step is ALTITUDE_MAX_STEP_M, then one unit per ALTITUDE_MAX_STEP_M.
ALTITUDE_SCALE_M = 300.0
ALTITUDE_STEP = 0.35
ALTITUDE_MAX_STEP_M = 500.0
#: Where the logarithmic step reaches ALTITUDE_MAX_STEP_M: d/dh of the coordinate, 1 / (STEP (SCALE + h)), is 1 / MAX.
_ALTITUDE_LINEAR_FROM_M = ALTITUDE_MAX_STEP_M / ALTITUDE_STEP - ALTITUDE_SCALE_M


def path_coordinates(camera_altitude_m: ArrayLike, sun_elevation_rad: ArrayLike) -> np.ndarray:
    """(..., 2) coordinates of the inputs in which one key step is one unit on each axis: the sun's elevation
    through the piecewise-linear warp of :data:`SUN_STEPS_DEG`, the camera's altitude through :data:`ALTITUDE_STEP`
    and :data:`ALTITUDE_MAX_STEP_M` (logarithmic, then linear; the slope is continuous)."""
    e = np.degrees(np.asarray(sun_elevation_rad, dtype=np.float64))
    warped = np.zeros_like(e)
    ceiling = np.inf
    for floor, step in SUN_STEPS_DEG:                 # the elevation's share in each band, over its step
        warped += (np.clip(e, floor, ceiling) - floor) / step
        ceiling = floor
    h = np.maximum(np.asarray(camera_altitude_m, dtype=np.float64), 0.0)
    low = np.minimum(h, _ALTITUDE_LINEAR_FROM_M)
    altitude = np.log1p(low / ALTITUDE_SCALE_M) / ALTITUDE_STEP + (h - low) / ALTITUDE_MAX_STEP_M
    return np.stack([warped, altitude], axis=-1)


@dataclass(frozen=True)
class KeyTiles:
    """The key tiles of a path and how each of its inputs blends two of them.

    ``keys``: the key tiles' inputs (camera altitude m, sun elevation rad), in path order; ``segments[i]``: the k
    whose keys k and k + 1 input i blends; ``weights[i]``: w in [0, 1], input i's tile being
    key_k + w (key_{k+1} - key_k). One key: segments 0, weights 0 (nothing to blend)."""

    keys: tuple[tuple[float, float], ...]
    segments: tuple[int, ...]
    weights: tuple[float, ...]
    #: The step used, in key steps (1, or larger where ``max_keys`` forced coarser keys).
    step: float = 1.0

    @property
    def vertical_columns(self) -> bool:
        """Whether the key tiles may have each row's columns start at its vertical ray (:attr:`Tile.vertical_columns`):
        no input blends two keys of different camera altitudes (a still camera, a sun alone, a cut between cameras
        whose frames each sit on a key); where one does, both keys' texels must map rays of one length."""
        return not any(0.0 < weight < 1.0 and self.keys[segment][0] != self.keys[segment + 1][0]
                       for segment, weight in zip(self.segments, self.weights))


def key_tiles(camera_altitudes_m: ArrayLike, sun_elevations_rad: ArrayLike, *, max_keys: int | None = None,
              step: float = 1.0) -> KeyTiles:
    """The key tiles of a path of inputs (one per frame, in order; linear between frames): the first input, then
    each point where the path leaves the box of half-width ``step`` around the previous key
    (:func:`path_coordinates`: one unit per key step on each axis), each input where the path turns back, then the
    last input; where one frame moves a step or more, its two frames are keys instead (nothing between frames is
    rendered). Every input lies within a step of its segment's first key; its weight is its projection on the
    segment. Inputs that all equal the first give one key (a camera that pans at one altitude under a still sun).
    With more than ``max_keys`` keys the step grows by half until they fit."""
    raw = np.stack([np.asarray(camera_altitudes_m, dtype=np.float64).ravel(),
                    np.asarray(sun_elevations_rad, dtype=np.float64).ravel()], axis=-1)
    if len(raw) == 0:
        raise ValueError("key_tiles needs at least one input")
    x = path_coordinates(raw[:, 0], raw[:, 1])
    keys_x, keys_raw, segments = [x[0]], [raw[0]], [0]
    for i in range(1, len(x)):
        start_x, start_raw = x[i - 1], raw[i - 1]
        if float(np.max(np.abs(x[i] - start_x))) >= step:   # a frame's move spans a step: keys at the frames
            for point, point_raw in ((start_x, start_raw), (x[i], raw[i])):
                if np.any(point != keys_x[-1]):
                    keys_x.append(point)
                    keys_raw.append(point_raw)
            segments.append(len(keys_x) - 1)
            continue
        while True:
            direction = x[i] - start_x
            exits = [((keys_x[-1][j] + math.copysign(step, direction[j]) - start_x[j]) / direction[j])
                     for j in range(2) if direction[j] != 0.0]
            t = min(exits, default=math.inf)
            if t >= 1.0:
                break
            t = max(t, 0.0)
            start_raw = start_raw + t * (raw[i] - start_raw)   # the key's inputs; its coordinates from them (the
            start_x = path_coordinates(start_raw[0], start_raw[1])   # warp bends within a frame across 10 and 3 deg)
            keys_x.append(start_x)
            keys_raw.append(start_raw)
        turns = i + 1 < len(x) and float(np.dot(x[i] - x[i - 1], x[i + 1] - x[i])) < 0.0
        if turns and np.any(x[i] != keys_x[-1]):   # the path turns back: a key where it turns
            keys_x.append(x[i])
            keys_raw.append(raw[i])
        segments.append(len(keys_x) - 1)
    if np.any(x[-1] != keys_x[-1]):
        keys_x.append(x[-1])
        keys_raw.append(raw[-1])
    if max_keys is not None and len(keys_x) > max(int(max_keys), 1):
        return key_tiles(camera_altitudes_m, sun_elevations_rad, max_keys=max_keys, step=step * 1.5)
    keys = tuple((float(h), float(e)) for h, e in keys_raw)
    if len(keys) == 1:
        return KeyTiles(keys, (0,) * len(x), (0.0,) * len(x), step)
    weights = []
    for i, k in enumerate(segments):
        k = min(k, len(keys) - 2)
        segments[i] = k
        a, b = keys_x[k], keys_x[k + 1]
        span = float(np.dot(b - a, b - a))
        weights.append(float(np.clip(np.dot(x[i] - a, b - a) / span, 0.0, 1.0)) if span > 0.0 else 0.0)
    return KeyTiles(keys, tuple(segments), tuple(weights), step)


def shared_max_distance(camera_altitudes_m: ArrayLike, atm: Atmosphere) -> float:
    """The largest distance D the key tiles of a path share: :func:`max_distance` of its highest camera, m."""
    return max_distance(float(np.max(np.asarray(camera_altitudes_m, dtype=np.float64))), atm)


def blend_tiles(first: Tile, second: Tile, weight: float, camera_altitude_m: float, atm: Atmosphere) -> Tile:
    """The tile a frame samples between two key tiles: every texel first + w (second - first) (what the shader's
    blended lookups give: they are linear in the texels), mapped from the frame's own camera altitude. The two
    must share their shape and distance D (:func:`shared_max_distance`)."""
    if (first.shape != second.shape or first.max_distance_m != second.max_distance_m
            or first.vertical_columns != second.vertical_columns):
        raise ValueError("blend_tiles needs two tiles of one shape, one largest distance D and one column layout")
    w = float(weight)

    def lerp(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return a + w * (b - a)

    return Tile(first.shape, atm.planet_radius + max(float(camera_altitude_m), 0.0), first.max_distance_m,
                lerp(first.mean_extinction, second.mean_extinction), lerp(first.a_rayleigh, second.a_rayleigh),
                lerp(first.a_mie, second.a_mie), lerp(first.sky_radiance, second.sky_radiance),
                lerp(first.sky_ground_transmittance, second.sky_ground_transmittance),
                lerp(first.camera_sky_rayleigh, second.camera_sky_rayleigh),
                lerp(first.camera_sky_mie, second.camera_sky_mie), first.vertical_columns)


#: Rec. 709 luminance weights (Blender's default scene-linear space), for the blend's error.
_LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def mid_step_error(atm: Atmosphere, first: tuple[float, float], second: tuple[float, float], *, rays: int = 4000,
                   multiple_scattering: bool = True) -> dict[str, tuple[float, float]]:
    """How far the blend of two key tiles is from the tile baked where it is used, at the worst place, half way:
    keys at ``first`` and ``second`` (camera altitude m, sun elevation rad), sharing D, blended with w = 1/2
    (:func:`blend_tiles`) against ``bake.bake_tile`` at the mid inputs. Relative luminance errors (median, 99th
    percentile) of the sky (:func:`sky_from_tile`, views from 3 deg below the horizon up) and of the aerial
    perspective's L_in (:func:`evaluate`, distances 100 m to 200 km), over ``rays`` seeded random rays; a value
    under a thousandth of the 99th percentile counts at that floor (deep in the planet's shadow)."""
    rng = np.random.default_rng(1)
    elevation = np.arcsin(rng.uniform(-0.05, 1.0, rays))
    azimuth = rng.uniform(0.0, 2.0 * np.pi, rays)
    views = np.stack([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)],
                     axis=-1)
    distances = 10.0 ** rng.uniform(2.0, 5.3, rays)
    d_max = shared_max_distance([first[0], second[0]], atm)
    middle = (0.5 * (first[0] + second[0]), 0.5 * (first[1] + second[1]))

    def tile(inputs: tuple[float, float]) -> Tile:
        return bake_tile(atm, inputs[0], inputs[1], multiple_scattering=multiple_scattering, max_distance_m=d_max,
                         vertical_columns=first[0] == second[0])

    exact = tile(middle)
    blended = blend_tiles(tile(first), tile(second), 0.5, middle[0], atm)
    sun = np.array([math.cos(middle[1]), 0.0, math.sin(middle[1])])
    result = {}
    for name, light in (("sky", lambda t: sky_from_tile(t, views, sun, atm, np.float64)[1]),
                        ("aerial", lambda t: evaluate(t, views, sun, distances, atm, np.float64)[1])):
        want, got = light(exact) @ _LUMINANCE, light(blended) @ _LUMINANCE
        floor = 1e-3 * max(float(np.percentile(want, 99)), 1e-30)
        error = np.abs(got - want) / np.maximum(want, floor)
        result[name] = (float(np.median(error)), float(np.percentile(error, 99)))
    return result
