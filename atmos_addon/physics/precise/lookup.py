# SPDX-License-Identifier: GPL-3.0-or-later
"""The shader's side of a tile, step by step in numpy: where a ray falls in the table (:func:`table_coordinates`),
the texture filter (:func:`sample`, :func:`linear_lookup`), and the aerial perspective and sky it forms
(:func:`evaluate`, :func:`sky_from_tile`), in float32 as the node graphs compute them (or float64).

A tile holds, per cell (a ray from the camera ending at the row's altitude), tau / d and

    A_R(d) = E_top [J_R(d) + J_ms(d) / Phi_R(nu)] / (1 - exp(-tau(d))),   A_M(d) = E_top J_M(d) / (1 - exp(-tau(d)))

(``integrals``), and the shader forms

    F_ex = exp(-tau),    L_in = [Phi_R(nu) A_R + Phi_HG(nu, g) A_M] (1 - exp(-tau))

with nu = v . l. Dividing by 1 - exp(-tau) when baking (float64, never in the shader: no coloured banding) leaves
quantities that are constant for a homogeneous medium and vary slowly otherwise, so linear interpolation between
distance samples is accurate; the shader's 1 - exp(-tau) = tau phi1(tau) is exact to float32 at every distance. The
multiple scattering of a cell's ray depends on its direction v, fixed per cell, so it is stored in the Rayleigh
column divided by that cell's Phi_R(nu) (as Bruneton 2017 stores his higher orders).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

from ..aerial_perspective import one_minus_exp_over_x
from ..atmosphere import Atmosphere
from ..phase import phase_hg, phase_rayleigh
from .interpolation import bilinear
from .layout import Tile, distance_to_top, sky_path_length, target_altitude


def azimuth_column(view_dir: np.ndarray, sun_dir: np.ndarray, columns: int, dt) -> np.ndarray:
    """The view's azimuth from the sun's (0..pi: the tables are mirror-symmetric about it) as a fractional column
    of a block of ``columns`` azimuths, in the shader's arithmetic: atan2(|v x l|_z, (v . l)_xy) (N - 1) / pi."""
    v, s = view_dir, sun_dir
    cross = v[..., 0] * s[..., 1] - v[..., 1] * s[..., 0]
    dot = v[..., 0] * s[..., 0] + v[..., 1] * s[..., 1]
    return np.arctan2(np.abs(cross), dot) * dt((columns - 1) / np.pi)


def sky_from_tile(tile: Tile, view_dir: ArrayLike, sun_dir: ArrayLike, atm: Atmosphere,
                  dtype: DTypeLike = np.float32) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The Precise sky from the frame's table: (F_ex, L_in, hits the ground) along unit ``view_dir`` (..., 3).

    The table holds every ray from the camera to any target; a sky ray is the one whose target is the top of the
    atmosphere, or the ground where the ray meets it: :func:`evaluate` at the :func:`sky_path_length`. So a far
    surface's in-scattering (the aerial perspective at the Precise level) tends to exactly the sky behind it as
    its distance reaches the path's: the same table cells, the same arithmetic. The row is the top's or the
    ground's (row 0) exactly, not the one the target altitude's float32 cube root gives. What the "Atmos Sky" world
    group evaluates at the Precise level (without the sun's disk and the lit ground, which it adds as the dome sky
    does). Against the brute-force :func:`sky_radiance` (the tests): about 1 % mean.
    """
    dt = np.dtype(dtype).type
    views = np.asarray(view_dir, dtype=dt)
    altitude = float(tile.camera_radius_m - atm.planet_radius)
    length, hits = sky_path_length(views[..., 2], altitude, atm, dt)
    row = np.where(hits, dt(0), dt(tile.shape.altitudes - 1))   # the ray ends on the ground or at the top
    f_ex, light = evaluate(tile, views, sun_dir, length, atm, dt, row=row)
    return f_ex, light, hits


def table_coordinates(tile: Tile, view_dir: ArrayLike, sun_dir: ArrayLike, distance_m: ArrayLike, atm: Atmosphere,
                      dtype: DTypeLike = np.float32, row: ArrayLike | None = None):
    """(row, azimuth index, distance column) in texels, as the shader computes them from the unit view direction,
    the unit direction to the sun and the distance (m); ``row``: a whole row the caller knows instead (the top's or
    the ground's: the sky).

        row = clamp(h_p / top, 0, 1)^(1/3) (N_h - 1),   u = row / (N_h - 1),   d_min = |top u^3 - h_c| v,
        p = v (1 - u) + 2,   col = min(((max(s - d_min, 0) / max(D - d_min, 1))^(1/p), 1) (N_d - 1)

    with v = :attr:`Tile.vertical_columns` (1 or 0) and p the row's :func:`column_power`: the row's altitude sets
    d_min, so the sky's whole rows and a surface beyond the top (whose row rounds to the top's) read the same
    texels."""
    dt = np.dtype(dtype).type
    shape = tile.shape
    v = np.asarray(view_dir, dtype=dt)
    s = np.asarray(sun_dir, dtype=dt)
    d = np.maximum(np.asarray(distance_m, dtype=dt), dt(0))
    if row is None:
        altitude = target_altitude(tile.camera_radius_m, v[..., 2], d, atm.planet_radius, dtype)
        fraction = np.clip(altitude / dt(atm.atmosphere_height), dt(0), dt(1))
        row = np.power(fraction, dt(1.0 / 3.0)) * dt(shape.altitudes - 1)
    else:
        row = np.broadcast_to(np.asarray(row, dtype=dt), d.shape)
    u = row / dt(shape.altitudes - 1)
    vertical = dt(tile.vertical_columns)
    h_row = u * u * u * dt(atm.atmosphere_height)                                     # the row's altitude
    d_min = np.abs(h_row - dt(tile.camera_radius_m - atm.planet_radius)) * vertical
    span = np.maximum(dt(tile.max_distance_m) - d_min, dt(1))
    power = vertical * (dt(1) - u) + dt(2)                                            # column_power
    column = np.minimum(np.power(np.maximum(d - d_min, dt(0)) / span, dt(1) / power), dt(1)) * dt(shape.distances - 1)
    return row.astype(dt), azimuth_column(v, s, shape.azimuths, dt).astype(dt), column.astype(dt)


def sample(quantity: np.ndarray, row: np.ndarray, azimuth: np.ndarray, column: np.ndarray,
           dtype: DTypeLike = np.float32) -> np.ndarray:
    """A quantity (altitudes, azimuths, distances, 3) at fractional texel coordinates: bilinear in (row, column)
    within the two nearest azimuth slices (the texture filter), then linear between the slices."""
    dt = np.dtype(dtype).type
    q = np.asarray(quantity, dtype=dt)
    a0 = np.clip(np.floor(azimuth), 0, q.shape[1] - 2).astype(int)
    fa = (azimuth - a0).astype(dt)[..., None]
    low = bilinear(q, row, column, a0)
    high = bilinear(q, row, column, a0 + 1)
    return low + fa * (high - low)


def evaluate(tile: Tile, view_dir: ArrayLike, sun_dir: ArrayLike, distance_m: ArrayLike, atm: Atmosphere,
             dtype: DTypeLike = np.float32, row: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(F_ex, L_in) per channel, (..., 3), sampled from ``tile`` the way the shader samples its image.

    ``view_dir`` (..., 3) and ``sun_dir`` (3,) unit vectors (z up, any azimuth), ``distance_m`` (...) in m; ``atm``
    gives the planet, the table's top and the Mie anisotropy g. A distance beyond the top of the atmosphere is
    taken at the top (:func:`distance_to_top`): a surface out in space is seen through the whole atmosphere, so it
    composites to exactly the Precise sky behind it (:func:`sky_from_tile`). ``row``: the table row where the
    caller knows it (the sky's whole rows) instead of the one of the target's altitude.
    """
    dt = np.dtype(dtype).type
    f_ex, rayleigh, mie, nu = phase_free_terms(tile, view_dir, sun_dir, distance_m, atm, dtype, row)
    light = phase_rayleigh(nu, dtype)[..., None] * rayleigh + phase_hg(nu, atm.mie_g, dtype) * mie
    return f_ex.astype(dt), light.astype(dt)


def phase_free_terms(tile: Tile, view_dir: ArrayLike, sun_dir: ArrayLike, distance_m: ArrayLike, atm: Atmosphere,
                     dtype: DTypeLike, row: ArrayLike | None = None) -> tuple[np.ndarray, ...]:
    """:func:`evaluate`'s pieces before the phase functions: (F_ex, A_R (1 - F_ex), A_M (1 - F_ex), nu)."""
    dt = np.dtype(dtype).type
    views = np.asarray(view_dir, dtype=dt)
    to_top = distance_to_top(views[..., 2], float(tile.camera_radius_m - atm.planet_radius), atm, dt)
    d = np.minimum(np.maximum(np.asarray(distance_m, dtype=dt), dt(0)), to_top)
    row, azimuth, column = table_coordinates(tile, views, sun_dir, d, atm, dtype, row)
    extinction_per_m = bilinear(np.asarray(tile.mean_extinction, dtype=dt), row, column)
    a_r = sample(tile.a_rayleigh, row, azimuth, column, dtype)
    a_m = sample(tile.a_mie, row, azimuth, column, dtype)
    nu = np.einsum("...i,i->...", views, np.asarray(sun_dir, dtype=dt))
    tau = extinction_per_m * d[..., None]
    f_ex = np.exp(-tau)
    one_minus_t = tau * one_minus_exp_over_x(tau, dtype)
    return f_ex, a_r * one_minus_t, a_m * one_minus_t, nu


def linear_lookup(block: np.ndarray, x: np.ndarray, y: np.ndarray, dtype) -> np.ndarray:
    """``block`` (rows, columns, 3) at fractional texel coordinates (x column, y row; texel centres at whole
    numbers), bilinear with extended edges: a linear-filtered texture lookup."""
    dt = np.dtype(dtype).type
    q = np.asarray(block, dtype=dt)
    x0 = np.clip(np.floor(x), 0, q.shape[1] - 1).astype(int)
    y0 = np.clip(np.floor(y), 0, q.shape[0] - 1).astype(int)
    x1, y1 = np.minimum(x0 + 1, q.shape[1] - 1), np.minimum(y0 + 1, q.shape[0] - 1)
    fx, fy = (x - np.floor(x)).astype(dt)[..., None], (y - np.floor(y)).astype(dt)[..., None]
    low = q[y0, x0] + fx * (q[y0, x1] - q[y0, x0])
    high = q[y1, x0] + fx * (q[y1, x1] - q[y1, x0])
    return low + fy * (high - low)
