# SPDX-License-Identifier: GPL-3.0-or-later
"""A black target's contrast against the horizon sky: by the complete reference and as each quality level renders it.

For a black target, L_target is exactly the in-scattering L_in(d) in front of it, so its apparent contrast is
C(d) = 1 - L_in(d) / L_sky (Koschmieder's law, :mod:`~atmos_addon.physics.visibility`, is the homogeneous case).
:func:`reference_contrast` evaluates it by Monte Carlo over every scattering order; :func:`level_contrast`
evaluates it as each quality level renders it (the aerial group and the world sky of that level, from the
functions the node groups are tested against). ``tools/measure_visibility.py`` writes docs/visibility.md from them.
Lengths m, angles rad unless named _deg. Numpy only.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from atmos_addon.physics.atmosphere import Atmosphere
from atmos_addon.physics.precise import bake_tile, sky_from_tile
from atmos_addon.physics.precise import evaluate as evaluate_precise
from atmos_addon.physics.sky import (aerial_distance_clamped, atmosphere_at_altitude, dome_distance_approx,
                                     inscattering_layered)
from atmos_addon.physics.sky import sky_radiance as dome_sky_radiance
from atmos_addon.physics.sun import sun_irradiance_ground
from validation.balanced import inscattering_balanced, sun_optical_depths_ground
from validation.multiple_scattering_reference import trace_paths
from validation.reference import single_scattering

#: The levels :func:`level_contrast` knows ("precise+ms": Precise with its multiple-scattering term).
LEVELS = ("fast", "balanced", "precise", "precise+ms")


def view_direction(elevation_deg: float, azimuth_from_sun_deg: float) -> np.ndarray:
    """Unit view direction, z up, the sun's azimuth along +x."""
    e, a = math.radians(elevation_deg), math.radians(azimuth_from_sun_deg)
    return np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])


def sun_direction(elevation_deg: float) -> np.ndarray:
    """Unit vector toward the sun at ``elevation_deg``, azimuth +x."""
    e = math.radians(elevation_deg)
    return np.array([math.cos(e), 0.0, math.sin(e)])


def reference_contrast(atm: Atmosphere, distances_m: ArrayLike, view_dir: ArrayLike, sun_dir: ArrayLike, *,
                       camera_altitude_m: float = 2.0, ground_albedo: ArrayLike = 0.0,
                       max_order: int | None = None, paths: int = 20_000, seed: int = 0
                       ) -> tuple[np.ndarray, np.ndarray]:
    """A black target's contrast per channel at each distance, (k, 3), and its standard error (k, 3), every
    scattering order up to ``max_order``; the camera at ``camera_altitude_m`` looks along ``view_dir``.

    Along the view ray the transfer equation splits the horizon sky at the target's place x_d:
    L_sky(0) = L_in(d) + F_ex(d) L_sky(x_d), so C = 1 - L_in(d) / L_sky(0) = F_ex(d) L_sky(x_d) / L_sky(0): the
    transmittance (deterministic, :func:`~validation.reference.single_scattering`) times the ratio of the sky seen
    along the same direction from the target's place and from the camera (two Monte Carlo estimates, ``paths`` per
    channel each). Koschmieder's law is the case L_sky(x_d) = L_sky(0). Estimating C as a product keeps its relative
    noise that of the two skies (about 1 %), where 1 - L_in / L_sky would carry L_sky's noise into a small C.
    """
    distances = np.atleast_1d(np.asarray(distances_m, dtype=np.float64))
    view = np.asarray(view_dir, dtype=np.float64)
    view = view / np.linalg.norm(view)
    camera = np.array([0.0, 0.0, float(camera_altitude_m)])
    n = int(paths)
    channel = np.repeat(np.arange(3), n)
    common = dict(ground_albedo=ground_albedo, max_order=max_order)

    def sky_from(origin: np.ndarray, stream: int) -> tuple[np.ndarray, np.ndarray]:
        samples = trace_paths(origin, np.tile(view, (3 * n, 1)), channel, sun_dir, atm, seed=seed + stream,
                              **common).reshape(3, n)
        return samples.mean(axis=1), samples.std(axis=1, ddof=1) / math.sqrt(n)

    near, near_error = sky_from(camera, 0)
    contrast, error = np.empty((distances.size, 3)), np.empty((distances.size, 3))
    for k, distance in enumerate(distances):
        f_ex = single_scattering(camera_altitude_m, view, float(distance), sun_dir, atm, n_steps=2001,
                                 n_sun_steps=3)[0]
        far, far_error = sky_from(camera + distance * view, k + 1)
        contrast[k] = f_ex * far / near
        error[k] = contrast[k] * np.sqrt((far_error / far) ** 2 + (near_error / near) ** 2)
    return contrast, error


def level_contrast(level: str, atm: Atmosphere, distances_m: ArrayLike, view_dir: ArrayLike, sun_dir: ArrayLike, *,
                   camera_altitude_m: float = 2.0) -> np.ndarray:
    """A black target's contrast 1 - L_in(d) / L_sky per channel, (k, 3), as ``level`` (:data:`LEVELS`) renders it:

    * fast: the layered dome (the aerial group's lengths min(d, R_i) and the world's dome sky, float32 domes as
      the nodes compute them); balanced: the curved-ray aerial group (the sun raised to each piece's altitude)
      under the same dome sky; precise, precise+ms: the frame's table for both (``physics.precise``).
    """
    distances = np.atleast_1d(np.asarray(distances_m, dtype=np.float64))
    view = np.asarray(view_dir, dtype=np.float64)
    sun = np.asarray(sun_dir, dtype=np.float64)
    views = np.tile(view, (distances.size, 1))
    sun_elevation = math.asin(max(min(float(sun[2]), 1.0), -1.0))
    e_sun = sun_irradiance_ground(max(sun_elevation, 0.0), atm)
    mu = views @ sun
    if level in ("precise", "precise+ms"):
        tile = bake_tile(atm, camera_altitude_m, sun_elevation, multiple_scattering=level == "precise+ms")
        _, l_in = evaluate_precise(tile, views, sun, distances, atm, np.float64)
        _, sky, _ = sky_from_tile(tile, view[None], sun, atm, np.float64)
        return 1.0 - l_in / sky[0]
    if level not in ("fast", "balanced"):
        raise ValueError(f"unknown level {level!r}; expected one of {LEVELS}")

    def dome(elevation, atmosphere, altitude):
        return dome_distance_approx(elevation, atmosphere, altitude, np.float32)

    sky = dome_sky_radiance(view, sun, atm, e_sun, altitude_m=camera_altitude_m, dome=dome)
    if level == "fast":
        s_r, s_m = aerial_distance_clamped(distances, math.asin(float(view[2])), atm, camera_altitude_m, dome=dome)
        l_in = inscattering_layered(s_r, s_m, mu, atmosphere_at_altitude(atm, camera_altitude_m), e_sun)
    else:
        taus = sun_optical_depths_ground(sun_elevation, atm, e_sun)
        l_in = inscattering_balanced(camera_altitude_m, views, distances, mu, atm, e_sun, sun_optical_depths=taus)
    return 1.0 - l_in / sky
