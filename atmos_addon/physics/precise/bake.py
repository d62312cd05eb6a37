# SPDX-License-Identifier: GPL-3.0-or-later
"""One frame's table, baked: for a camera at altitude h_c and the sun at elevation e_s, every cell (target altitude
h_p, azimuth a, distance d; ``layout``) is its own ray, integrated (``integrals.ray_integrals``) and divided by
1 - exp(-tau) (``lookup``'s module docstring), then the tile's two sky blocks are tabulated from it
(``sky_blocks``). :func:`bake_tile` keeps the last tiles; :func:`integrate_tile` integrates afresh, on
``parallel.WORKERS`` threads, and can be cancelled between blocks of rows.

A tile depends on h_c and e_s alone for a given atmosphere (the azimuths are the shader's), so an animated camera or
sun gets key tiles along its path (``animation``) and a still scene's sun move is shown from the sun's key grid
(``bank``).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import threading

import numpy as np

from ..atmosphere import Atmosphere
from . import parallel
from .integrals import ray_integrals
from .layout import DEFAULT_SHAPE, TableShape, Tile, cell_distances, max_distance, row_altitudes
from .scattering import DEFAULT_GROUND_ALBEDO
from .sky_blocks import camera_sky_view, sky_view
from .tables import atmosphere_tables, stored


#: Target-altitude rows :func:`integrate_tile` integrates in one block (one task on the threads).
TILE_BLOCK_ROWS = 4


#: Tiles :func:`bake_tile` keeps (about 0.85 MB each): a scene switched off and on, an undo step, a preset tried and
#: left, or a sun moved back reuses its bake (0.4-0.5 s on 2 cores, plus the atmosphere's tables when they changed)
#: instead of integrating again.
TILE_CACHE_SIZE = 16


def bake_tile(atm: Atmosphere, camera_altitude_m: float, sun_elevation_rad: float, *,
              multiple_scattering: bool = True, ground_albedo=DEFAULT_GROUND_ALBEDO,
              shape: TableShape = DEFAULT_SHAPE, max_distance_m: float | None = None, preview: bool = False,
              vertical_columns: bool = True) -> Tile:
    """One frame's table (module docstring) for a camera at ``camera_altitude_m`` (m above sea level, clamped at 0)
    and the sun at ``sun_elevation_rad``; ``multiple_scattering=False`` leaves J_ms out; ``max_distance_m``: the
    last column's distance D (default :func:`max_distance` of the camera; the key tiles of an animation share the
    largest, ``animation.blend_tiles``). The last :data:`TILE_CACHE_SIZE` tiles are kept: the same inputs return the
    same :class:`Tile`, its arrays read-only (:func:`integrate_tile` integrates afresh). ``preview``: from the
    preview tables (``tables.PREVIEW_RESOLUTION``); ``vertical_columns``: :attr:`Tile.vertical_columns`."""
    return _cached_tile(atm, float(camera_altitude_m), float(sun_elevation_rad), bool(multiple_scattering),
                        tuple(float(a) for a in ground_albedo), shape,
                        None if max_distance_m is None else float(max_distance_m), bool(preview),
                        bool(vertical_columns))


@functools.lru_cache(maxsize=TILE_CACHE_SIZE)
def _cached_tile(atm: Atmosphere, camera_altitude_m: float, sun_elevation_rad: float, multiple_scattering: bool,
                 ground_albedo: tuple[float, float, float], shape: TableShape, max_distance_m: float | None,
                 preview: bool, vertical_columns: bool) -> Tile:
    inputs = (atm, camera_altitude_m, sun_elevation_rad, multiple_scattering, ground_albedo, shape, max_distance_m,
              preview, vertical_columns)
    return frozen_tile(stored(("tile", inputs), lambda: integrate_tile(
        atm, camera_altitude_m, sun_elevation_rad, multiple_scattering=multiple_scattering,
        ground_albedo=ground_albedo, shape=shape, max_distance_m=max_distance_m, preview=preview,
        vertical_columns=vertical_columns)))


def frozen_tile(tile: Tile) -> Tile:
    """``tile`` with its arrays read-only (a kept tile is shared by whoever asks for it)."""
    for array in (tile.mean_extinction, tile.a_rayleigh, tile.a_mie, tile.sky_radiance,
                  tile.sky_ground_transmittance, tile.camera_sky_rayleigh, tile.camera_sky_mie):
        array.setflags(write=False)
    return tile


class TileCancelled(Exception):
    """Raised by :func:`integrate_tile` when its ``stop`` event is set."""


def integrate_tile(atm: Atmosphere, camera_altitude_m: float, sun_elevation_rad: float, *,
                   multiple_scattering: bool = True, ground_albedo=DEFAULT_GROUND_ALBEDO,
                   shape: TableShape = DEFAULT_SHAPE, max_distance_m: float | None = None,
                   preview: bool = False, stop: threading.Event | None = None,
                   vertical_columns: bool = True) -> Tile:
    """Integrate one frame's table (module docstring), uncached (:func:`bake_tile` keeps the last ones); ``preview``
    reads the preview tables (``tables.atmosphere_tables``); ``stop``: once set, the integration ends at its next
    block of rows (20-40 ms) with :class:`TileCancelled` (a tile no longer wanted frees its thread).

    Each cell (target altitude h_p, azimuth a, distance d) is its own ray: the elevation follows from the
    triangle (r_c, r_p, d), sin e = (r_p^2 - r_c^2 - d^2) / (2 r_c d), clamped to a vertical ray where the
    altitude cannot be reached at that distance. The ray is integrated by Simpson's rule in w = sqrt(t / d) on
    ``integrals.RAY_SAMPLES`` samples (dense near the camera), the optical depth to each sample by the trapezoid
    rule on the same samples. The rows are integrated in blocks of :data:`TILE_BLOCK_ROWS` on ``parallel.WORKERS``
    threads, each block's arrays small enough to stay in the processor's cache (``tools/bench_tables.py``, against
    whole-tile arrays: 0.50-0.57 s a tile on one thread where they take 0.87-1.23 s, 0.33-0.40 s on 2 cores where one
    block per thread takes 0.54-0.71 s; the same numbers to the bit).
    """
    h_c = max(float(camera_altitude_m), 0.0)
    sun_table, ms_table = atmosphere_tables(atm, tuple(float(a) for a in ground_albedo), preview=preview)
    d_max = max_distance(h_c, atm) if max_distance_m is None else float(max_distance_m)
    if not d_max > 0.0:
        raise ValueError(f"max_distance_m must be > 0; got {max_distance_m!r}")
    r_c = atm.planet_radius + h_c
    all_rows = (atm.planet_radius + row_altitudes(shape, atm))[:, None, None, None]   # (H, 1, 1, 1)
    distances = cell_distances(shape, d_max, all_rows[:, 0, 0, 0] - r_c, vertical_columns)   # (H, D)
    mean_extinction = np.zeros((shape.altitudes, shape.distances, 3))
    a_r = np.zeros((shape.altitudes, shape.azimuths, shape.distances, 3))
    a_m = np.zeros_like(a_r)

    def integrate(block: int) -> None:       # the rays ending at one block of target altitudes (rows)
        if stop is not None and stop.is_set():
            raise TileCancelled
        rows = blocks[block]
        r_p = all_rows[rows]
        d = distances[rows][:, None, :, None]                                         # (H, 1, D, 1)
        with np.errstate(divide="ignore", invalid="ignore"):
            sin_e = np.where(d > 0.0, (r_p * r_p - r_c * r_c - d * d) / (2.0 * r_c * d), 0.0)
        sin_e = np.clip(sin_e, -1.0, 1.0)
        cos_e = np.sqrt(1.0 - sin_e * sin_e)
        azimuth = np.linspace(0.0, np.pi, shape.azimuths)[None, :, None, None]       # (1, A, 1, 1)
        sin_s, cos_s = math.sin(sun_elevation_rad), math.cos(sun_elevation_rad)
        nu = cos_e * np.cos(azimuth) * cos_s + sin_e * sin_s                          # (H, A, D, 1)
        tau, j_r, j_m, start_r, start_m, local_ex = ray_integrals(
            atm, (sun_table, ms_table), r_c, sin_e[..., 0], sin_s, nu[..., 0], d[..., 0],
            multiple_scattering=multiple_scattering)
        one_minus_t = -np.expm1(-tau)
        small = one_minus_t < 1e-9      # d -> 0: J / (1 - T) -> the local scattering over the local extinction
        with np.errstate(divide="ignore", invalid="ignore"):
            a_r[rows] = np.where(small, np.where(local_ex > 0.0, start_r / local_ex, 0.0), j_r / one_minus_t)
            a_m[rows] = np.where(small, np.where(local_ex > 0.0, start_m / local_ex, 0.0), j_m / one_minus_t)
            mean_extinction[rows] = np.where(d > 0.0, tau / d, local_ex)[:, 0]         # (H, D, 3)

    blocks = np.array_split(np.arange(shape.altitudes), max(parallel.WORKERS, shape.altitudes // TILE_BLOCK_ROWS))
    parallel.in_parallel(integrate, len(blocks))
    if stop is not None and stop.is_set():
        raise TileCancelled
    e_top = atm.sun_irradiance_top
    full = (shape.altitudes, shape.azimuths, shape.distances, 3)
    tile = Tile(shape, r_c, d_max, np.ascontiguousarray(np.broadcast_to(mean_extinction, full[:1] + full[2:])),
                np.ascontiguousarray(np.broadcast_to(a_r * e_top, full)),
                np.ascontiguousarray(np.broadcast_to(a_m * e_top, full)), vertical_columns=bool(vertical_columns))
    radiance, ground_transmittance = sky_view(tile, sun_elevation_rad, atm)
    rayleigh, mie = camera_sky_view(tile, sun_elevation_rad, atm)
    return dataclasses.replace(tile, sky_radiance=radiance, sky_ground_transmittance=ground_transmittance,
                               camera_sky_rayleigh=rayleigh, camera_sky_mie=mie)
