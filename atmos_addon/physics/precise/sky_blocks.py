# SPDX-License-Identifier: GPL-3.0-or-later
"""The tile's two sky blocks, the Precise sky tabulated by view direction so that the shader reads it with one or two
filtered lookups where the table's own sky (``lookup.sky_from_tile``) takes ten texel fetches and some 240 nodes.

The sky view (:func:`sky_view`, read by :func:`lighting_from_tile`): for the rays that light the scene in Cycles
(non-camera rays), the sky's radiance and the ground's transmittance by view zenith cosine, rows crowded at the
horizon on both sides of it (``layout.sky_view_cosines``), and azimuth from the sun.

The camera's sky view (:func:`camera_sky_view`, read by :func:`camera_sky_from_tile`): Cycles evaluates the world for
every camera sample that misses the scene, where the table's own sky would cost about as much as Blender's whole Sky
Texture (the camera's sky 0.85 s of a 3.6 s Per Pixel render, Blender's sky 0.88 s; tools/bench_quality_cost.py
--decompose). Above the horizon the same sky tabulated by view direction reads it with two filtered lookups; the Mie
phase function stays in the shader, so the sun's aureole keeps its exact shape however coarse the azimuths. Rows go
by elevation, crowded at the horizon (the sky's fastest change) without starving the zenith (a zenith cosine's rows
are 18 deg apart there). At and below the horizon the camera keeps the table's own sky: a 2 m camera sees the
ground's path shrink from 5 km to 1 km within 0.05 deg below it, which no row spacing follows, and a far surface's
haze meets the sky behind it there (the seamless horizon; ``atmos_addon.node_groups.sky_view``).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

from ..atmosphere import Atmosphere
from ..phase import phase_hg, phase_rayleigh
from .layout import (HORIZON_NUDGE, Tile, camera_sky_elevations, camera_sky_rows, horizon_cosine, horizon_elevation,
                     sky_path_length, sky_view_cosines, sky_view_rows)
from .lookup import azimuth_column, linear_lookup, phase_free_terms, sky_from_tile


def _view_grid(across: np.ndarray, z: np.ndarray, azimuths: int,
               sun_elevation_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """(views, sun): unit view directions at horizontal components ``across`` and zenith cosines ``z`` (rows, 1),
    crossed with ``azimuths`` azimuths from the sun's, 0..pi; and the sun's direction at azimuth 0."""
    azimuth = np.linspace(0.0, np.pi, azimuths)[None, :]
    views = np.stack(np.broadcast_arrays(across * np.cos(azimuth), across * np.sin(azimuth), z), axis=-1)
    return views, np.array([math.cos(sun_elevation_rad), 0.0, math.sin(sun_elevation_rad)])


def sky_view(tile: Tile, sun_elevation_rad: float, atm: Atmosphere) -> tuple[np.ndarray, np.ndarray]:
    """The tile's Precise sky tabulated by view direction, for the rays that light the scene (Cycles' non-camera
    rays, which :func:`sky_from_tile`'s ten texel fetches and some two hundred nodes made most of the Precise
    level's render cost): (radiance, ground transmittance).

    radiance (rows, sky azimuths, 3) W/(m^2 sr): :func:`sky_from_tile`'s L_in (phase functions included, float64)
    at the view zenith cosines :func:`sky_view_cosines` and azimuths from the sun pi k / (N - 1); ground
    transmittance (rows, 3): F_ex where the ray meets the ground, else 0 (the lit ground's radiance is added by the
    shader from the albedo and E_sun, so those stay parameters). Sampled bilinearly (:func:`lighting_from_tile`),
    no sun disk (the sun lamp carries it)."""
    shape = tile.shape
    horizon = horizon_cosine(tile.camera_radius_m - atm.planet_radius, atm)
    z = sky_view_cosines(shape, horizon)
    z[shape.sky_ground_rows - 1] -= HORIZON_NUDGE
    z[shape.sky_ground_rows] += HORIZON_NUDGE
    z = z[:, None]
    views, sun = _view_grid(np.sqrt(np.maximum(1.0 - z * z, 0.0)), z, shape.sky_azimuths, sun_elevation_rad)
    f_ex, light, hits = sky_from_tile(tile, views, sun, atm, dtype=np.float64)
    ground_transmittance = np.where(hits[:, :1], f_ex[:, 0], 0.0)
    return np.ascontiguousarray(light), np.ascontiguousarray(ground_transmittance)


def lighting_from_tile(tile: Tile, view_dir: ArrayLike, sun_dir: ArrayLike, atm: Atmosphere, albedo: ArrayLike,
                       e_sun: ArrayLike, dtype: DTypeLike = np.float32) -> np.ndarray:
    """The sky the scene is lit by at the Precise level, radiance (..., 3) along unit ``view_dir`` (..., 3): the
    sky view (:func:`sky_view`) sampled bilinearly at the row :func:`sky_view_rows` and the azimuth column
    a (N - 1) / pi, plus the lit ground albedo E_sun max(l_z, 0) / pi times its transmittance; what Cycles' Linear
    image lookup gives the lighting group (``atmos_addon.node_groups.sky_lighting``). ``atm``: the tile's."""
    dt = np.dtype(dtype).type
    shape = tile.shape
    v = np.asarray(view_dir, dtype=dt)
    s = np.asarray(sun_dir, dtype=dt)
    horizon = horizon_cosine(tile.camera_radius_m - atm.planet_radius, atm)
    row = sky_view_rows(shape, np.clip(v[..., 2], dt(-1), dt(1)), horizon, dt)
    azimuth = azimuth_column(v, s, shape.sky_azimuths, dt)
    light = linear_lookup(tile.sky_radiance, azimuth, row, dt)
    ground = linear_lookup(tile.sky_ground_transmittance[:, None, :], np.zeros_like(row), row, dt)
    lit = np.asarray(albedo, dtype=dt) * np.asarray(e_sun, dtype=dt) * (max(float(s[2]), 0.0) / np.pi)
    return (light + ground * lit).astype(dt)


def camera_sky_view(tile: Tile, sun_elevation_rad: float, atm: Atmosphere) -> tuple[np.ndarray, np.ndarray]:
    """The tile's Precise sky above the horizon by view direction, for Cycles' camera rays: (Rayleigh, Mie), each
    (rows, sky azimuths, 3) W/(m^2 sr): :func:`sky_from_tile`'s Phi_R(nu) A_R (1 - F_ex) and A_M (1 - F_ex) (float64,
    the same cells) at the elevations :func:`camera_sky_elevations` and azimuths from the sun pi k / (N - 1). The
    shader forms L = Rayleigh + Phi_HG(nu, g) Mie (:func:`camera_sky_from_tile`)."""
    shape = tile.shape
    altitude = float(tile.camera_radius_m - atm.planet_radius)
    elevation = camera_sky_elevations(shape, horizon_elevation(altitude, atm))[:, None]
    views, sun = _view_grid(np.cos(elevation), np.sin(elevation), shape.sky_azimuths, sun_elevation_rad)
    length, _ = sky_path_length(views[..., 2], altitude, atm, np.float64)
    _, rayleigh, mie, nu = phase_free_terms(tile, views, sun, length, atm, np.float64,
                                            row=np.full(length.shape, shape.altitudes - 1.0))
    return np.ascontiguousarray(phase_rayleigh(nu)[..., None] * rayleigh), np.ascontiguousarray(mie)


def camera_sky_from_tile(tile: Tile, view_dir: ArrayLike, sun_dir: ArrayLike, atm: Atmosphere,
                         dtype: DTypeLike = np.float32) -> np.ndarray:
    """The camera's Precise sky above the horizon, radiance (..., 3) along unit ``view_dir`` (..., 3) (no sun disk):
    the camera sky view (:func:`camera_sky_view`) sampled bilinearly at the row :func:`camera_sky_rows` and the
    azimuth column a (N - 1) / pi, Rayleigh + Phi_HG(nu, g) Mie: what the "Atmos Sky View" group's two Linear
    lookups give. Below the horizon it reads the horizon's row (the world shows :func:`sky_from_tile` there)."""
    dt = np.dtype(dtype).type
    shape = tile.shape
    v = np.asarray(view_dir, dtype=dt)
    s = np.asarray(sun_dir, dtype=dt)
    row = camera_sky_rows(shape, v[..., 2], horizon_elevation(tile.camera_radius_m - atm.planet_radius, atm), dt)
    azimuth = azimuth_column(v, s, shape.sky_azimuths, dt)
    rayleigh = linear_lookup(tile.camera_sky_rayleigh, azimuth, row, dt)
    mie = linear_lookup(tile.camera_sky_mie, azimuth, row, dt)
    nu = np.einsum("...i,i->...", v, s)
    return (rayleigh + phase_hg(nu, atm.mie_g, dtype) * mie).astype(dt)
