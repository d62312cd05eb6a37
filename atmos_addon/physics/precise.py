# SPDX-License-Identifier: GPL-3.0-or-later
"""The Precise quality level: single scattering integrated numerically, plus multiple scattering, baked into a
camera-centred table that the shader samples.

Why a camera-centred table
    For one frame the camera (altitude h_c) and the sun (elevation e_s) are fixed. A camera ray is then fixed
    by its elevation e, its azimuth a from the sun's azimuth (0..pi, mirror-symmetric) and the distance d to
    the surface it hits, so every aerial-perspective quantity is a function of (e, a, d): a 3-D table per
    frame, with no subtraction of two long-ray lookups (Bruneton 2008's S(x) - T S(p), which cancels for
    near objects) and no per-pixel march. An animated camera or sun gets one table ("tile") per frame, all
    in one image the .blend carries, and a keyed tile index, so a farm renders it without Python.

What the table holds, per colour channel (rays start at the camera, t in m along the unit direction v)
    tau(d)  = integral_0^d beta_ex(h(t)) dt, stored as tau / d (1/m)             optical depth; F_ex = exp(-tau)
    A_R(d)  = E_top [J_R(d) + J_ms(d) / Phi_R(nu)] / (1 - exp(-tau(d)))
    A_M(d)  = E_top J_M(d) / (1 - exp(-tau(d)))
    J_i(d)  = integral_0^d beta_i n_i(h(t)) T_sun(x(t)) exp(-tau(t)) dt          i = R, M (scattering, no phase)
    J_ms(d) = integral_0^d (beta_R n_R S_R + beta_M n_M S_M)(h(t), mu_s(t), v) exp(-tau(t)) dt

and the shader forms
    F_ex = exp(-tau),    L_in = [Phi_R(nu) A_R + Phi_HG(nu, g) A_M] (1 - exp(-tau))

with nu = v . l (constant along a straight ray, so the phase functions leave the integrals). Dividing by
1 - exp(-tau) when baking (float64, never in the shader: no coloured banding) leaves quantities that are
constant for a homogeneous medium and vary slowly otherwise, so linear interpolation between distance samples
is accurate; the shader's 1 - exp(-tau) = tau phi1(tau) is exact to float32 at every distance. The multiple
scattering S_R, S_M of a cell's ray depends on its direction v, fixed per cell, so it is stored in the Rayleigh
column divided by that cell's Phi_R(nu) (as Bruneton 2017 stores his higher orders).

Geometry (spherical planet, radius R): the camera at radius r_c = R + h_c; a point at distance t has radius
r(t) = sqrt(r_c^2 + 2 r_c t sin e + t^2) and sun zenith cosine mu_s(t) = (r_c sin e_s + t nu) / r(t).
Densities n_i = exp(-max(h, 0) / H_i) (the ground is transparent to the table: a ray continues smoothly
below it, so terrain below the scene's ground level, which a flat scene may hold, keeps its haze). T_sun is 0
where the ray to the sun meets the planet (its shadow).

Table axes (:class:`TableShape`)
    * target-altitude rows: the altitude h_p of the point the ray reaches, h_j = top (j / (N_h - 1))^3
      (:func:`row_altitudes`; dense near the ground, where the haze and most surfaces are); the ray's elevation
      follows from the triangle (r_c, r_p, d) (:func:`bake_tile`), so a row holds every ray ending at that altitude;
    * azimuth slices, a = pi j / (N_a - 1) from the sun's azimuth, interpolated linearly (the shader's manual blend);
    * distance columns, each row's own (:func:`cell_distances`): d_k = d_min + (D - d_min) (k / (N_d - 1))^p from
      the shortest ray that reaches the row, d_min = |h_p - h_c| (the vertical one), to D, the longest ray that
      stays above the ground inside the atmosphere (:func:`max_distance`), d beyond D clamped; the power p
      (:func:`column_power`) goes from 3 at the ground's row (columns crowded near the camera: 35 m, 280 m,
      940 m... at D = 1000 km) to 2 at the top's (the sky's long rays near the horizon). So every cell is a ray that
      ends at its row's altitude, and the cells next to a steep ray are steep rays too. With the same columns for
      every row, D (k / (N_d - 1))^2, a steep ray's neighbours are a vertical ray cut short and rays of far lower
      elevation, whose multiply scattered light differs (rays to points kilometres up on Mars 14-17 % of the horizon
      sky off at the 99th percentile, against 2.5-9.0 % with each row's own columns:
      ``tools/measure_sun_free_table.py``, docs/quality.md). The key tiles of a camera whose frames blend keys of
      different altitudes use those shared columns (:attr:`Tile.vertical_columns` False): two keys' texels then map
      rays of one length.
Within one azimuth slice the shader blends (row, column) bilinearly from four unfiltered texels.

The sky view (:func:`sky_view`, the tile's last columns): the Precise sky by view direction (zenith rows crowded at
the horizon on both sides of it x azimuths from the sun), for the rays that light the scene in Cycles, read with
one filtered lookup (:func:`lighting_from_tile`) where the camera's sky takes ten texel fetches.

Sun transmittance: optical depth to space tau_i = beta_i H_i exp(-h / H_i) Ch(r / H_i, chi)
(:mod:`.optical_depth`), with log Ch interpolated from a table in (altitude, position between the local
horizon and the zenith) (:class:`SunTransmittanceTable`, 0.02 % of tau against direct quadrature), plus the
ozone's beta_O3 times its slant column from the same grid. beta_ex everywhere is :func:`local_extinction`: the
two exponential layers and, where the atmosphere has ozone, its absorbing tent 10-40 km up.

Multiple scattering (:class:`MultipleScatteringTable`, per atmosphere): every order of the light scattered at
least once, as its mean radiance Psi_ms(h, mu_s) and first moment (the P1 field) at each altitude and sun, the
orders carried from point to point by one linear solve with the haze's forward peak split off (delta-Eddington),
and what a ray looking along v in-scatters of the radiance field by direction with the true phase functions,
S_R(h, mu_s, v) and S_M: the second order is exact up to the direction sampling. The ground reflects the sun and
the sky as a Lambertian surface of ``ground_albedo``.

Units: lengths m, angles rad, coefficients 1/m, E_top and radiances W/m^2 (per sr for radiances) in Blender's
sun-strength unit. :func:`evaluate` reproduces the shader's float32 sampling step by step.
"""

from __future__ import annotations

import collections
import concurrent.futures
import dataclasses
import functools
import math
import os
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

from .aerial_perspective import one_minus_exp_over_x
from .atmosphere import Atmosphere
from .optical_depth import chapman, ozone_slant_column
from .phase import phase_hg, phase_rayleigh

#: Ground albedo of the multiple-scattering table when none is given (a grey, green-ish land).
DEFAULT_GROUND_ALBEDO = (0.18, 0.2, 0.15)


@dataclass(frozen=True)
class TableShape:
    """Sample counts of the camera-centred table: target-altitude rows, azimuth slices, distance columns."""

    altitudes: int = 65
    azimuths: int = 8
    distances: int = 32
    #: Azimuth columns of the sky-view block (:func:`sky_view`); its rows are the tile's rows.
    sky_azimuths: int = 33
    def __post_init__(self) -> None:
        if min(self.altitudes, self.azimuths, self.distances, self.sky_azimuths) < 2 or self.altitudes < 6:
            raise ValueError(f"TableShape needs >= 2 samples on every axis (>= 6 rows); got {self}")

    @property
    def sky_ground_rows(self) -> int:
        """Rows of the sky-view block below the horizon (the ground's, 3/8 of the rows: 24 of 65); the others are
        the sky's."""
        return self.altitudes * 3 // 8

    @property
    def sky_view_offset(self) -> int:
        """First column of the sky-view block: after the extinction block (one slice) and the two in-scattering
        blocks, px."""
        return self.distances * (1 + 2 * self.azimuths)

    @property
    def camera_sky_offset(self) -> int:
        """First column of the camera's sky view (:func:`camera_sky_view`): after the sky view's radiance columns
        and its ground-transmittance column, px. Two blocks of ``sky_azimuths`` columns: the Rayleigh term (its
        phase function included), then the Mie term (without it)."""
        return self.sky_view_offset + self.sky_azimuths + 1

    @property
    def width(self) -> int:
        """Texels across one tile: the aerial blocks, the sky view's radiance columns and its ground
        transmittance column, then the camera's sky view, px."""
        return self.camera_sky_offset + 2 * self.sky_azimuths


#: The shape the add-on bakes (its node graph is built for it).
DEFAULT_SHAPE = TableShape()


def max_distance(camera_altitude_m: float, atm: Atmosphere) -> float:
    """D = sqrt(r_c^2 - R^2) + sqrt(r_top^2 - R^2): the longest ray from the camera that leaves the atmosphere
    without meeting the ground (camera to tangent point to the top), m."""
    r = atm.planet_radius
    r_c = r + max(float(camera_altitude_m), 0.0)
    r_top = r + atm.atmosphere_height
    return math.sqrt(r_c * r_c - r * r) + math.sqrt(r_top * r_top - r * r)


def row_altitudes(shape: TableShape, atm: Atmosphere) -> np.ndarray:
    """Target altitude of each table row, m: top (j / (N_h - 1))^3 (47 m apart at 100 m, 220 m at 1 km)."""
    return atm.atmosphere_height * np.linspace(0.0, 1.0, shape.altitudes) ** 3


def column_power(row: ArrayLike, shape: TableShape, vertical: ArrayLike = 1.0) -> np.ndarray:
    """The power p of the distance columns at (fractional) ``row``: 2 + vertical (1 - row / (N_h - 1)), so 3 at the
    ground's row (the columns crowd near the camera: 35 m, 280 m, 940 m... at D = 1000 km, for the aerial
    perspective of near surfaces) down to 2 at the top's (the sky's long rays near the horizon keep their columns);
    2 everywhere where the columns do not start at the vertical ray (:attr:`Tile.vertical_columns`)."""
    return 2.0 + np.asarray(vertical) * (1.0 - np.asarray(row) / (shape.altitudes - 1))


def cell_distances(shape: TableShape, d_max_m: float, rise_m: ArrayLike, vertical: bool = True) -> np.ndarray:
    """Distance of each cell of the rows (all the table's, in order) whose targets are ``rise_m`` above the camera
    (r_p - r_c, m, shape (N_h,)), m, shape (N_h, N_d): d_min + (D - d_min) (k / (N_d - 1))^p with d_min = |rise| and
    p the row's :func:`column_power` (module docstring); with ``vertical`` False (:attr:`Tile.vertical_columns`)
    D (k / (N_d - 1))^2 for every row."""
    rise = np.asarray(rise_m, dtype=np.float64)
    power = column_power(np.arange(shape.altitudes), shape, float(vertical))[:, None]
    d_min = np.abs(rise)[:, None] * float(vertical)
    return d_min + (d_max_m - d_min) * np.linspace(0.0, 1.0, shape.distances) ** power


def target_altitude(camera_radius_m, cos_zenith, distance_m, planet_radius_m, dtype: DTypeLike = np.float64):
    """Altitude of the point at ``distance_m`` along a ray leaving radius r_c with zenith cosine c, m:
    h_p = h_c + (2 r_c c d + d^2) / (r_p + r_c), r_p = sqrt(r_c^2 + 2 r_c c d + d^2) (no cancellation in float32)."""
    dt = np.dtype(dtype).type
    r_c = dt(camera_radius_m)
    d = np.asarray(distance_m, dtype=dt)
    rise = (dt(2) * r_c * np.asarray(cos_zenith, dtype=dt) + d) * d
    r_p = np.sqrt(np.maximum(r_c * r_c + rise, dt(0)))
    return (r_c - dt(planet_radius_m)) + rise / (r_p + r_c)


def local_extinction(atm: Atmosphere, n_rayleigh: np.ndarray, n_mie: np.ndarray, altitude_m: np.ndarray) -> np.ndarray:
    """beta_R n_R + (beta_M,sc + beta_M,abs) n_M + beta_O3 n_O3(h), 1/m, (..., 3), from the relative densities of the
    two exponential layers (..., 1) and the altitude (...) where the ozone's tent is read (none when there is none).
    """
    beta_ex = atm.rayleigh_scattering * n_rayleigh + atm.mie_extinction * n_mie
    return beta_ex + atm.ozone_absorption_at(altitude_m) if atm.ozone_column_du > 0.0 else beta_ex


#: The grids of the last :class:`SunTransmittanceTable` shapes, keyed by what they depend on (:func:`_sun_geometry`).
_SUN_GEOMETRY: dict[tuple, tuple[np.ndarray, np.ndarray | None]] = {}


def _sun_geometry(atm: Atmosphere, n_altitudes: int, n_cosines: int) -> tuple[np.ndarray, np.ndarray | None]:
    """The grids of :class:`SunTransmittanceTable` (its docstring), read-only: log Ch of each layer (n, m, 2) and,
    where the atmosphere has ozone, the ozone's slant column (n, m, 1), m. Geometry only (the planet's radius, the
    top, the scale heights): kept for the last four, so an edit of a coefficient, a colour or the ozone's amount
    reuses them (0.28 s of an atmosphere's bake)."""
    key = (float(atm.planet_radius), float(atm.atmosphere_height), float(atm.rayleigh_scale_height),
           float(atm.mie_scale_height), bool(atm.ozone_column_du > 0.0), int(n_altitudes), int(n_cosines))
    if key in _SUN_GEOMETRY:
        return _SUN_GEOMETRY[key]
    altitude = atm.atmosphere_height * np.linspace(0.0, 1.0, n_altitudes) ** 2
    w = np.linspace(0.0, 1.0, n_cosines) ** 2
    radius = atm.planet_radius + altitude[:, None]
    mu_h = -np.sqrt(np.maximum(1.0 - (atm.planet_radius / radius) ** 2, 0.0))
    mu = np.clip(mu_h + (1.0 - mu_h) * w[None, :], -1.0, 1.0)
    zenith = np.arccos(mu)
    log_ch = np.stack([np.log(chapman(radius / h, zenith))
                       for h in (atm.rayleigh_scale_height, atm.mie_scale_height)], axis=-1)
    column = ozone_slant_column(altitude[:, None], mu, atm)[..., None] if key[4] else None
    for array in (log_ch, column):
        if array is not None:
            array.setflags(write=False)
    while len(_SUN_GEOMETRY) >= 4:
        del _SUN_GEOMETRY[next(iter(_SUN_GEOMETRY))]
    _SUN_GEOMETRY[key] = (log_ch, column)
    return log_ch, column


class SunTransmittanceTable:
    """exp(-tau to space toward the sun) from any radius r and sun zenith cosine mu, per channel.

    log Ch of each layer is tabulated at altitudes h_j = top (j / (n - 1))^2 and at w_k = (k / (m - 1))^2 of
    the way from the local horizon mu_h(r) = -sqrt(1 - R^2 / r^2) to the zenith, and interpolated bilinearly;
    the factor beta H exp(-h / H) is exact. The ozone's slant column (:func:`ozone_slant_column`), where there is
    ozone, on the same grid, interpolated linearly. Below mu_h the ray meets the planet: 0. A radius below the
    ground is taken at the ground (the table's transparent ground, as its densities are).
    """

    def __init__(self, atm: Atmosphere, n_altitudes: int = 96, n_cosines: int = 256) -> None:
        self.atm = atm
        self.n_alt, self.n_mu = n_altitudes, n_cosines
        #: log Ch per layer (n, m, 2) and the ozone's slant column (n, m, 1) m, or None without ozone (read-only)
        self.log_ch, self.ozone_column = _sun_geometry(atm, n_altitudes, n_cosines)

    def __call__(self, radius_m: ArrayLike, cos_zenith: ArrayLike) -> np.ndarray:
        """exp(-tau) to space, (..., 3), at radii and sun zenith cosines that broadcast: what depends on the radius
        alone is computed at the radii's own shape (a ray's samples under several suns or azimuths share it)."""
        atm = self.atm
        radius = np.clip(np.asarray(radius_m, dtype=np.float64), atm.planet_radius,
                         atm.planet_radius + atm.atmosphere_height)
        mu = np.clip(np.asarray(cos_zenith, dtype=np.float64), -1.0, 1.0)
        mu_h = -np.sqrt(np.maximum(1.0 - (atm.planet_radius / radius) ** 2, 0.0))
        lit = mu >= mu_h
        w = np.clip((mu - mu_h) / (1.0 - mu_h), 0.0, 1.0)
        altitude = radius - atm.planet_radius
        i = np.sqrt(altitude / atm.atmosphere_height) * (self.n_alt - 1)
        k = np.sqrt(w) * (self.n_mu - 1)
        slant = np.exp(_bilinear(self.log_ch, i, k))                                # (..., 2): both layers
        tau = np.zeros(np.broadcast_shapes(radius.shape, mu.shape) + (3,))
        for layer, beta, height in ((0, atm.rayleigh_scattering, atm.rayleigh_scale_height),
                                    (1, atm.mie_extinction, atm.mie_scale_height)):
            tau += beta * (height * np.exp(-altitude / height) * slant[..., layer])[..., None]
        if self.ozone_column is not None:
            tau += atm.ozone_absorption * _bilinear(self.ozone_column, i, k)
        return np.where(lit[..., None], np.exp(-tau), 0.0)


def _cell(rows: int, columns: int, i: np.ndarray, k: np.ndarray) -> tuple[np.ndarray, ...]:
    """(i0, k0, fi, fk): the lower corner of the table cell that holds the fractional indices (i, k), edge samples
    clamped (an image texture's filter), and the fractions within it."""
    i = np.clip(i, 0, rows - 1)
    k = np.clip(k, 0, columns - 1)
    i0 = np.minimum(np.floor(i).astype(int), rows - 2)
    k0 = np.minimum(np.floor(k).astype(int), columns - 2)
    return i0, k0, i - i0, k - k0


def _log_linear(low: np.ndarray, high: np.ndarray, fraction: np.ndarray) -> np.ndarray:
    """low^(1 - f) high^f: the straight line between two values in log space (light that falls exponentially), or
    the straight line itself where either is not positive."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        result = high / low
        result **= fraction
        result *= low
    positive = (low > 0.0) & (high > 0.0)
    if not positive.all():      # (the same numbers as np.where over both, a third of the time: few cells are dark)
        linear = low + fraction * (high - low)
        result[~positive] = np.broadcast_to(linear, result.shape)[~positive]
    return result


def _linear_then_log_linear(table: np.ndarray, i: np.ndarray, k: np.ndarray) -> np.ndarray:
    """Interpolation of a table (rows, columns, channels) at fractional indices (i, k), edge samples clamped: linear
    along the rows in each of the two columns around k, then :func:`_log_linear` between the columns."""
    columns = table.shape[1]
    i0, k0, fi, fk = _cell(table.shape[0], columns, i, k)
    fi, fk = fi[..., None], fk[..., None]
    flat = table.reshape(-1, table.shape[2])
    first = i0 * columns + k0
    second = first + columns
    a, b, c, d = (np.take(flat, index, axis=0) for index in (first, second, first + 1, second + 1))
    low = a + fi * (b - a)
    high = c + fi * (d - c)
    return _log_linear(low, high, fk)


def _bilinear(table: np.ndarray, i: np.ndarray, k: np.ndarray, slice_index=None) -> np.ndarray:
    """Bilinear interpolation at fractional indices (i, k), edge samples clamped (an image texture's filter), of
    a table (rows, columns[, channels]) or, with per-point ``slice_index``, of its slices
    (rows, slices, columns, channels)."""
    columns = table.shape[1] if slice_index is None else table.shape[2]
    i0, k0, fi, fk = _cell(table.shape[0], columns, i, k)
    fi, fk = fi.astype(table.dtype), fk.astype(table.dtype)
    if table.ndim == 3 or slice_index is not None:
        fi, fk = fi[..., None], fk[..., None]

    if slice_index is None:     # one flat gather per corner (the same values as table[r, c], faster)
        flat = table.reshape((-1,) + table.shape[2:])

        def at(r, c):
            return np.take(flat, r * columns + c, axis=0)
    else:
        def at(r, c):
            return table[r, slice_index, c]

    return ((1 - fi) * ((1 - fk) * at(i0, k0) + fk * at(i0, k0 + 1))
            + fi * ((1 - fk) * at(i0 + 1, k0) + fk * at(i0 + 1, k0 + 1)))


def _direction_grid(n_zenith: int, n_azimuth: int) -> tuple[np.ndarray, np.ndarray]:
    """(unit vectors (D, 3), solid angles (D,) summing to 4 pi): Gauss-Legendre zenith cosines on each hemisphere
    separately (``n_zenith`` per hemisphere, so the step in radiance at the horizon, sky above and ground below,
    falls between nodes) times ``n_azimuth`` even azimuths at (k + 1/2) 2 pi / n, a set symmetric about the
    azimuth 0 (the sun's)."""
    x, w = np.polynomial.legendre.leggauss(n_zenith)
    z = np.concatenate([-(x + 1.0) * 0.5, (x + 1.0) * 0.5])                         # (2 n_zenith,)
    dz = np.concatenate([w, w]) * 0.5
    phi = 2.0 * np.pi * (np.arange(n_azimuth) + 0.5) / n_azimuth
    across = np.sqrt(1.0 - z * z)[:, None]
    dirs = np.stack(np.broadcast_arrays(across * np.cos(phi), across * np.sin(phi), z[:, None]), axis=-1)
    return dirs.reshape(-1, 3), np.repeat(dz * (2.0 * np.pi / n_azimuth), n_azimuth)


#: The forward peak of the haze's phase function within an angle of straight on is carried as not scattered when the
#: table scatters the first order once more (:func:`grid_forward_fraction`); the rest is scattered on the direction
#: grid. A narrower cut sends light the grid cannot place (its azimuth step is 22.5 deg) off the sun's line, a wider
#: one keeps too much of it on that line. The angle grows with the haze's g (:func:`grid_cut_deg`): this many degrees
#: at :data:`GRID_CUT_REFERENCE_G`, the Earth presets' clear haze (the bench's day, sunset and blue-hour cases).
GRID_FORWARD_CUT_DEG = 30.0
#: The haze g at which the cut is :data:`GRID_FORWARD_CUT_DEG`.
GRID_CUT_REFERENCE_G = 0.76
#: How the cut grows with g, deg per unit of g (6 deg per 0.1), and its bounds, deg (the range the bench swept).
GRID_CUT_DEG_PER_G = 60.0
GRID_CUT_RANGE_DEG = (20.0, 35.0)


def grid_cut_deg(g: ArrayLike) -> np.ndarray:
    """The forward cut per channel, deg: :data:`GRID_FORWARD_CUT_DEG` + :data:`GRID_CUT_DEG_PER_G` (g - 0.76), within
    :data:`GRID_CUT_RANGE_DEG`.

    Why it follows g: one angle for every channel (30 deg) leaves Mars's dust (g 0.63 / 0.68 / 0.78) with red and
    green 2-6 % too bright and blue 2-10 % too dark at a 2 deg sun (5.6 % in luminance against 192 000 reference
    paths); a narrower cut for all channels darkens red and green but blue too (25 deg: 3.3 %, xy 0.0124). Swept
    per channel, the less forward a channel's haze, the narrower the cut it wants (Mars 25 / 25 / 30 deg: 3.6 %, xy
    0.0073; the overcast's g 0.6 is best at 20 deg, 3.5 % against 3.8 %). This line through them gives Mars
    22.2 / 25.2 / 31.2 deg (3.65 %, xy 0.0058) and every case of g 0.76 the 30 deg cut (docs/quality.md)."""
    g = np.asarray(g, dtype=np.float64)
    return np.clip(GRID_FORWARD_CUT_DEG + GRID_CUT_DEG_PER_G * (g - GRID_CUT_REFERENCE_G), *GRID_CUT_RANGE_DEG)


def grid_forward_fraction(atm: Atmosphere) -> np.ndarray:
    """f_c (3,): the share of the haze's scattering above the Henyey-Greenstein value at the cut
    (:func:`grid_cut_deg`) inside that cone (the peak the direction grid cannot resolve), per channel
    (:func:`_cone_fraction`)."""
    return _cone_fraction(_mie_g(atm))


def _cut_cosine(g: np.ndarray) -> np.ndarray:
    """cos of :func:`grid_cut_deg` per channel (3,)."""
    return np.cos(np.radians(grid_cut_deg(g)))


def _hg_at_cut(g: np.ndarray) -> np.ndarray:
    """Henyey-Greenstein at each channel's own cut (3,): the diagonal of every cut against every channel's g."""
    return np.diagonal(phase_hg(_cut_cosine(g), g)).copy()


def _cone_fraction(g: np.ndarray) -> np.ndarray:
    """:func:`grid_forward_fraction` of Henyey-Greenstein g (3,); 0 where g <= 0 (no forward peak). Closed form, mu_c
    the channel's cut cosine: 2 pi integral_{mu_c}^1 (Phi(mu) - Phi(mu_c)) dmu, with
    2 pi integral_{mu_c}^1 Phi dmu = (1 - g^2) / (2 g) (1 / (1 - g) - 1 / sqrt(1 + g^2 - 2 g mu_c))."""
    g = np.asarray(g, dtype=np.float64)
    safe = np.where(g > 0.0, g, 0.5)
    mu_c = _cut_cosine(safe)
    cone = (1.0 - safe ** 2) / (2.0 * safe) * (1.0 / (1.0 - safe) - 1.0 / np.sqrt(1.0 + safe ** 2 - 2.0 * safe * mu_c))
    flat = 2.0 * np.pi * (1.0 - mu_c) * _hg_at_cut(safe)
    return np.where(g > 0.0, np.maximum(cone - flat, 0.0), 0.0)


def _cut_phase_hg(mu: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Henyey-Greenstein (..., 3) with its forward cone (within each channel's cut, :func:`grid_cut_deg`, where
    g > 0) flattened to the value at the cone's edge: the part of the phase function left once
    :func:`grid_forward_fraction` is taken out (not normalised)."""
    mu = np.asarray(mu)
    safe = np.where(g > 0.0, g, 0.5)
    return np.where((mu[..., None] > _cut_cosine(safe)) & (g > 0.0), _hg_at_cut(safe), phase_hg(mu, g))


def _cell_weights(views: np.ndarray, n_zenith: int, n_azimuth: int, phase: Callable, sub: int = 8) -> np.ndarray:
    """(V, D, ...): ``phase(v . w')`` averaged over each cell of :func:`_direction_grid` (``sub`` x ``sub``
    directions even in the zenith cosine and the azimuth within the cell), times the cell's solid angle: the integral
    of the phase function over each cell, the weight a field constant over the cell takes. Read at the cells' centres
    instead, a lobe narrower than a cell is weighed by where the centres fall (the haze's g 0.78 summed to 0.95-1.00
    over the grid before normalising, by view direction); with the cell averages alone the accuracy bench's
    Martian sunset is 16.7 % against 18.7 % with the centres (measured with the second order as a P1 field)."""
    _, w = np.polynomial.legendre.leggauss(n_zenith)
    edges = np.concatenate([[0.0], np.cumsum(w * 0.5)])               # the Gauss-Legendre cells of z in 0..1
    u = (np.arange(sub) + 0.5) / sub
    z_up = edges[:-1, None] + np.diff(edges)[:, None] * u             # (n_zenith, sub), the grid's order
    z = np.concatenate([-z_up, z_up])
    phi = 2.0 * np.pi * (np.arange(n_azimuth)[:, None] + u) / n_azimuth
    total = 0.0
    for a in range(sub):
        across = np.sqrt(np.maximum(1.0 - z[:, a] ** 2, 0.0))[:, None]
        for b in range(sub):
            cells = np.stack(np.broadcast_arrays(across * np.cos(phi[:, b]), across * np.sin(phi[:, b]),
                                                 z[:, a][:, None]), axis=-1).reshape(-1, 3)
            total = total + phase(views @ cells.T)
    _, solid_angle = _direction_grid(n_zenith, n_azimuth)
    return total / (sub * sub) * solid_angle.reshape((1, -1) + (1,) * (np.ndim(total) - 2))


@functools.lru_cache(maxsize=8)
def _view_weights(n_zenith: int, n_azimuth: int, n_view_cosines: int, n_view_azimuths: int,
                  mie_g: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The view grid (V, 3) and, per view direction, the weights that scatter the light of each grid direction into it
    (:func:`_cell_weights`, each row normalised to 1): Rayleigh (V, D), the haze (V, D, 3), and the haze less its
    forward cone (V, D, 3, normalised then times 1 - f_c: :func:`grid_forward_fraction`). Cached: they depend on the
    grid and the haze's g only (0.1 s)."""
    view_z = np.linspace(-1.0, 1.0, n_view_cosines)[:, None]
    view_a = np.linspace(0.0, np.pi, n_view_azimuths)[None, :]
    across = np.sqrt(1.0 - view_z ** 2)
    views = np.stack(np.broadcast_arrays(across * np.cos(view_a), across * np.sin(view_a), view_z),
                     axis=-1).reshape(-1, 3)
    g = np.asarray(mie_g)
    rayleigh = _cell_weights(views, n_zenith, n_azimuth, phase_rayleigh)
    mie = _cell_weights(views, n_zenith, n_azimuth, lambda mu: phase_hg(mu, g))
    cut = _cell_weights(views, n_zenith, n_azimuth, lambda mu: _cut_phase_hg(mu, g))
    kept = 1.0 - _cone_fraction(g)
    result = (views, rayleigh / rayleigh.sum(axis=1, keepdims=True), mie / mie.sum(axis=1, keepdims=True),
              cut / cut.sum(axis=1, keepdims=True) * kept)
    for array in result:
        array.flags.writeable = False
    return result


@dataclass(frozen=True)
class _Rays:
    """The rays a :class:`MultipleScatteringTable` marches from the nodes of one altitude, in each marched direction
    (D) for every sun cosine (M), with S steps each (arrays as marked)."""

    altitude_m: np.ndarray        #: (D, S) altitude of each step's midpoint
    sun_cosine: np.ndarray        #: (M, D, S) sun zenith cosine there
    step_scattering: np.ndarray   #: (D, S, 3) T' sigma_s' dt: the step's scattering seen from the node (delta split)
    step_rayleigh: np.ndarray     #: (D, S, 3) T' beta_R n_R dt
    step_mie: np.ndarray          #: (D, S, 3) T' beta_M n_M dt
    radius_m: np.ndarray          #: (D, S) radius of each step's midpoint
    to_ground: np.ndarray         #: (D, 3) T'_ground albedo where the ray meets the ground, else 0
    ground_radius_m: np.ndarray   #: (D,) radius where the ray ends
    ground_sun_cosine: np.ndarray  #: (M, D) sun zenith cosine at the ray's end
    view_up: np.ndarray            #: (D, S) w . up_p: the ray's direction against the local zenith at each step
    toward_sun: np.ndarray         #: (M, D, S) w . sun_p: against the horizontal toward the sun there (0 under it)
    first_rayleigh: np.ndarray     #: (D, S, 3) T_c beta_R n_R dt: T_c the transmittance less the forward cone only
    first_mie: np.ndarray          #: (D, S, 3) T_c beta_M n_M dt
    first_to_ground: np.ndarray    #: (D, 3) T_c,ground albedo where the ray meets the ground, else 0


def forward_fraction(atm: Atmosphere) -> np.ndarray:
    """f = max(g, 0)^2 (3,): the share of the haze's scattering that the multiple-scattering table treats as not
    scattered at all (delta-Eddington: Joseph, Wiscombe & Weinman 1976, "The Delta-Eddington Approximation for
    Radiative Flux Transfer"). Henyey-Greenstein's forward peak is cut off as a delta function, f of the scattering:
    that light goes on in its direction as if it had not scattered (the haze's extinction less f beta_M), and the
    rest scatters with mean cosine g' = (g - f) / (1 - f), a field the first moment describes far better than the
    peaked whole. A haze that scatters backward (g <= 0) has no forward peak to cut: f = 0 (g^2 there would give
    |g'| > 1: g -0.9 made the table negative and its higher orders darker than the first)."""
    return np.maximum(_mie_g(atm), 0.0) ** 2


def _mie_g(atm: Atmosphere) -> np.ndarray:
    """The haze's Henyey-Greenstein g per channel (3,)."""
    return np.broadcast_to(np.asarray(atm.mie_g, dtype=np.float64), (3,))


#: Threads that build the rows of a table's altitudes at once (numpy's array loops release the GIL): the machine's
#: cores, at most 4 (each holds about 40 MB of temporaries).
WORKERS = max(1, min(4, os.cpu_count() or 1))


def in_parallel(work: Callable[[int], None], count: int) -> None:
    """work(0), ..., work(count - 1) on :data:`WORKERS` threads; each call must write only its own slices. The
    results are the same to the bit as in one thread; a call's exception is raised here."""
    if WORKERS == 1 or count < 2:
        for index in range(count):
            work(index)
        return
    with concurrent.futures.ThreadPoolExecutor(WORKERS) as pool:
        list(pool.map(work, range(count)))


#: Unknowns per node of the multiple-scattering solve: the mean radiance J and its first moment H (up, sun).
_MOMENTS = 3


def solve_orders(transport: np.ndarray, source: np.ndarray, *, tolerance: float = 1e-10,
                 max_iterations: int = 60) -> np.ndarray:
    """x with x = source + transport x, the sum of every scattering order (source, transport source, ...), by GMRES
    (Saad & Schultz 1986) on (I - A): each step multiplies by A once, and the orders of an atmosphere converge
    geometrically, so the Krylov space of a few steps holds the answer. Measured on the presets' tables (3168
    unknowns per channel): the spectral radius of A is 0.12-0.33 (clear, sunset, Mars) and 0.55-0.61 (overcast),
    GMRES meets a residual of 1e-10 of the source's in 6-12 steps, 12-28 ms per channel, within 1.2e-9 of the direct
    LU solve (0.35 s per channel). An atmosphere that has not converged in ``max_iterations`` steps (a thick haze
    that hardly absorbs) is solved directly."""
    norm = float(np.linalg.norm(source))
    if norm == 0.0:
        return np.zeros_like(source)
    basis = np.zeros((max_iterations + 1, source.size))
    hessenberg = np.zeros((max_iterations + 1, max_iterations))
    basis[0] = source / norm
    target = np.zeros(max_iterations + 1)
    target[0] = norm
    for k in range(max_iterations):
        w = basis[k] - transport @ basis[k]
        for _ in range(2):                         # Gram-Schmidt twice: the basis stays orthogonal to rounding
            h = basis[:k + 1] @ w
            w -= h @ basis[:k + 1]
            hessenberg[:k + 1, k] += h
        hessenberg[k + 1, k] = np.linalg.norm(w)
        y = np.linalg.lstsq(hessenberg[:k + 2, :k + 1], target[:k + 2], rcond=None)[0]
        residual = float(np.linalg.norm(hessenberg[:k + 2, :k + 1] @ y - target[:k + 2]))
        if residual <= tolerance * norm or hessenberg[k + 1, k] <= tolerance * norm:
            return y @ basis[:k + 1]
        basis[k + 1] = w / hessenberg[k + 1, k]
    return np.linalg.solve(np.eye(source.size) - transport, source)


#: The sun cosines beyond which the multiple-scattering table's nodes leave the terminator's spacing, as a share of
#: n = (resolution - 1) / 2: with 33 (n = 16) K = 10 nodes a side up to 23 deg.
TERMINATOR_SHARE = 0.625
#: How fast the band's cells grow away from the horizon: the k-th node of K lies at
#: band (exp(a k / K) - 1) / (exp(a) - 1), each cell exp(a / K) times the one before (1.22x with K = 10).
TERMINATOR_GROWTH = 2.0


@dataclass(frozen=True)
class SunCosineNodes:
    """The sun zenith cosines of the multiple-scattering table's nodes, and where a cosine falls between them.

    Around the terminator, K = 0.625 n nodes a side (n = (``resolution`` - 1) / 2) whose elevations grow
    geometrically from the horizon to +-23 deg (mu_s = +-(K / n)^2): e_k = 23 deg (exp(a k / K) - 1) /
    (exp(a) - 1) with a = :data:`TERMINATOR_GROWTH`, 0.8, 1.8, 3.0, 4.4, 6.2, 8.3, 11.0, 14.2, 18.1, 23.0 deg with
    n = 16 (the light falls by orders of magnitude within a few degrees of sun below the horizon and changes fastest
    there). Above that band K cells even in the sun's elevation up to the zenith (6.7 deg with n = 16); below it one
    cell to the nadir, where no light is left (the clear sky's mean radiance with the sun 23 deg below is 1e-10 of its
    most at that altitude on the ground and 4e-7 at 100 km; Mars's 4e-6 on the ground, 3e-3 at 100 km, where its air
    is thinnest). With half the resolution (17: the first look's tables) the nodes are every other one of these.

    A band even in sqrt|mu_s|, mu_s = +-(k / n)^2 (0.2, 0.9, 2.0, 3.6, 5.6, 8.1 ... deg), crowds within a degree
    of the horizon and leaves 2 deg cells where the blue hour lies. Against the same table at resolution 129, over
    suns 9 deg below the horizon to the zenith (the luminance of what a camera 2 m up sees at 1 km, 30 km and of the
    sky, 5 view elevations x 3 azimuths; ``tools/measure_sun_nodes.py``), its interpolation is off by up to 9.5 /
    12.2 / 3.2 / 11.7 % (clear, overcast, Mars, sunset presets) with the sun 1-6 deg down, where these nodes give
    5.8 / 7.4 / 2.8 / 7.1 %; from 1 deg down to 3 deg up 1.6 / 1.6 / 0.6 / 2.0 % -> 1.2 / 1.0 / 0.4 / 1.3 %; 3-30
    deg 1.5 / 1.6 / 1.1 / 1.9 % -> 0.8 / 1.4 / 0.9 / 1.1 %; 6-9 deg down 17 / 39 / 7.4 / 20 % -> 13 / 27 / 6.0 /
    16 %; the day's cells are the same. Against the complete reference the blue hour is 5.3 % with that band, 3.8 %
    with these nodes.
    Even in sqrt|mu_s| over the whole range (mu_s = sign(u) u^2, u even in -1 .. 1), the last cell would run from a
    sun 61.5 deg up to the zenith, where the view's azimuth from the sun means nothing, so a sun 80 deg up would read
    a horizontal view 88 % from the zenith node, which holds no difference between toward and away from the sun:
    Mars at noon 1.05x too bright away from the sun and 0.96x toward it (4.8 % against the complete reference at
    64 000 paths; 0.3 % with even day cells).

    Between two nodes a cosine's fractional index is linear in the sun's elevation (read linearly in sqrt|mu_s|,
    the same nodes give the overcast 1 deg sun 3.8 % instead of 2.4 %, the Martian sunset 6.0 % instead of 5.5 %,
    the blue hour's chromaticity 0.0101 instead of 0.0099, its luminance 5.3 % instead of 5.5 %)."""

    resolution: int = 33

    def __post_init__(self) -> None:
        if self.resolution < 9 or self.resolution % 2 == 0:
            raise ValueError(f"the sun-cosine resolution must be odd and at least 9, not {self.resolution}")

    @functools.cached_property
    def _layout(self) -> tuple[int, int]:
        """(n, K): n = (resolution - 1) / 2, the terminator's cells a side."""
        n = (self.resolution - 1) // 2
        return n, max(2, round(TERMINATOR_SHARE * n))

    @functools.cached_property
    def cosines(self) -> np.ndarray:
        """mu_s of the nodes, ascending, from -1 to 1: 1 + K + 1 + K + K of them."""
        n, k = self._layout
        edge = math.asin((k / n) ** 2)    # 23.0 deg: the band's edge, mu_s = (K / n)^2
        side = edge * np.expm1(TERMINATOR_GROWTH * np.arange(1, k + 1) / k) / math.expm1(TERMINATOR_GROWTH)
        elevations = np.concatenate([[-0.5 * np.pi], -side[::-1], [0.0], side,
                                     np.linspace(edge, 0.5 * np.pi, k + 1)[1:]])
        result = np.sin(elevations)
        result.flags.writeable = False
        return result

    def __len__(self) -> int:
        return len(self.cosines)

    @functools.cached_property
    def elevations(self) -> np.ndarray:
        """The nodes' sun elevations, rad."""
        result = np.arcsin(self.cosines)
        result.flags.writeable = False
        return result

    def index(self, cos_zenith: ArrayLike) -> np.ndarray:
        """The fractional node index of sun zenith cosines (clamped to -1 .. 1), linear in the sun's elevation between
        two nodes."""
        elevation = np.arcsin(np.clip(np.asarray(cos_zenith, dtype=np.float64), -1.0, 1.0))
        return np.interp(elevation, self.elevations, np.arange(len(self.cosines), dtype=np.float64))


class MultipleScatteringTable:
    """The light that has scattered at least once, per unit sun irradiance above the atmosphere, at every altitude h
    and sun zenith cosine mu_s, and what a view ray in-scatters of it (Hillaire 2020, "A Scalable and Production
    Ready Sky and Atmosphere Rendering Technique", section 5.5, extended as below).

    Nodes: altitudes h_j = top (j / (n - 1))^2 and the sun zenith cosines of :class:`SunCosineNodes` (mu_s = 0 is a
    node and they crowd at the terminator: with 32 linear samples the blue hour's light, which falls by orders of
    magnitude within a few degrees of sun below the horizon, was interpolated across one cell, 1.5x too bright on
    average at a sun 4 deg down; above 23 deg they are even in the sun's elevation). From each node rays in 2
    ``n_zenith`` x ``n_azimuth`` directions w (:func:`_direction_grid`: Gauss-Legendre in each hemisphere, even
    azimuths symmetric about the sun's; solid angles dOmega) are marched in ``n_steps`` steps to the ground or the
    top, t = length u^2 with u at the steps' middles (crowded at the node, where the air is densest for the rays
    that climb), p the point at distance t, where the sun has zenith cosine mu_s(p), up_p and sun_p its local zenith
    and horizontal toward the sun.

    The haze's Henyey-Greenstein phase function is split the delta-Eddington way (:func:`forward_fraction`): f = g^2
    of its scattering (g > 0; none for a haze scattering backward) is a delta function forward (light that goes on as
    if not scattered) and the rest scatters with mean cosine g' = (g - f) / (1 - f). So along the rays T' is the
    transmittance with the haze's extinction less f beta_M n_M, sigma_s' = beta_R n_R + (1 - f) beta_M n_M the
    scattering that turns light. The first two orders are carried by direction, the rest as a P1 field:

    * The first order, by direction: the sun's beam (true transmittance T_sun) scattered with the true phase functions,
      carried to x with T_c, the transmittance less only the part of the haze's peak the direction grid cannot
      resolve, f_c (:func:`grid_forward_fraction`: the peak above its value at the channel's cut,
      :func:`grid_cut_deg`):

        L_1(x, w) = integral T_c (beta_R n_R Phi_R + beta_M n_M Phi_HG)(w . sun) T_sun dt
                    + T_c,g T_sun mu_s,g albedo / pi

    * The second, by direction: L_1 at the nodes in-scattered with the phase functions on the direction grid
      (S_1, the haze's with its cone of f_c taken out, (1 - f_c) Phi_c: :func:`_view_weights`), read at each step's
      point for the direction it looks along (linearly between the nodes), and carried with T':

        L_2(x, w) = integral T' (beta_R n_R S_1R + beta_M n_M S_1M)(p, w) dt + T'_g albedo E_1(ground point) / pi

      with E_1 the ground's irradiance from L_1. The second order is not left to the P1 field: a field as peaked as
      the haze's light around a low sun (its aureole) is far from J + 3 H . w, and the delta cut, which keeps all of
      the peak on the sun's line, leaves the light of a Martian sunset 1.13x too bright toward the sun and 0.97x
      away (0.9x in blue). With the whole peak resolved (f_c = 0) the grid spreads the aureole over its 22.5 deg
      cells: the Martian sunset within 3 % but an Earth sunset's red toward the sun 0.8-0.87x and the blue hour 9 %.
      The cut between the two was swept over 0-45 deg (docs/quality.md): 20-35 deg improve every low-sun case.
    * The third and higher orders: at every node the light of the second and higher orders is described by its mean
      radiance J and its first moment H = (1 / 4 pi) integral L w dOmega (two components, up and toward the sun: the
      light is symmetric about the sun's plane), the P1 field L(w) ~ J + 3 H . w, and a point that scatters it sends
      J sigma_s' + 3 (g - f) beta_M n_M H . w back along w (Rayleigh's mean cosine is 0). With Q(p, w) that emission,
      read off the nodes bilinearly, and the Lambertian ground of ``ground_albedo`` lit by the sky's irradiance E
      (from the same field over the upper hemisphere):

        (J, H)(x) = (1 / 4 pi) sum_w (1, w) [L_2(x, w) + integral T' Q(p, w) dt + T'_g albedo E(ground point) / pi]
                    dOmega

      is linear in the nodes' (J, H): one linear solve, (I - A) X = X_2, over 3 unknowns per node and channel
      (:attr:`psi` and :attr:`first_moment` add the first order's J and H).

    The radiance field by direction is then

        L(x, w) = L_1(x, w) + L_2(x, w) + integral T' Q(p, w) dt + T'_g albedo E(ground point) / pi,

    and a view ray looking along v in-scatters it with the true phase functions at its own point (the light arriving
    from w is scattered by the angle whose cosine is w . v):

        S_i(x, v) = sum_w Phi_i(w . v) L(x, w) dOmega,      in-scattering sigma_R S_R + sigma_M S_M,

    tabulated over v's zenith cosine and its azimuth from the sun (:meth:`scattered`; the phase weights of each v
    averaged over the grid's cells and normalised to sum to 1, :func:`_cell_weights`, so the sharp forward peak of
    the haze neither gains nor loses light between the directions). So the second order seen by the camera is exact
    up to the direction sampling, the third up to the sampling and the cone f_c; the fourth and higher are a P1 field
    at their last-but-one point.

    Measured against the complete reference (``tools/bench_accuracy.py``, Monte Carlo, every order; worst pixel
    luminance error, docs/quality.md): at 4000 paths by day 1.1-2.0 %; against more paths the blue hour 3.8 % (xy
    0.0093) and the Martian sunset 3.7 % (xy 0.0058) at 192 000 (two seeds), the overcast 1 deg sun 2.9 % at 96 000
    (its reference's noise 1.1-1.4 % a ray), Mars at noon 0.4 % at 64 000. The simpler schemes it improves on, at
    4000 paths:

    * Hillaire 2020's Psi_ms = L_2 / (1 - f_ms), in-scattered isotropically: his series assumes the higher orders
      at x are those of a medium lit everywhere like x (A J ~ f_ms J(x)), which misses the light that enters a thick
      haze from the lit sky above and diffuses down to where the sun no longer reaches. By day 1.2-6.9 %, the
      sunsets 19 % / 31 %, blue hour 68 %, overcast 1 deg sun 82 %, Mars sunset 81 %.
    * Every order carried between the nodes as an isotropic mean radiance (J alone, the true extinction): by day
      1.1-3.0 %, the sunsets 5.4 % / 6.6 %, Mars noon 9.7 %, blue hour 23 %, overcast 34 %, Mars sunset 39 %. An
      isotropic third order cannot hold that the light of a forward-scattering haze at a low sun keeps travelling
      away from the sun: the overcast 0.6-0.8x the reference, Mars at sunset 0.6x toward the sun and 1.2-1.9x away.
    * The first moment and the delta-Eddington split from the second order on (the second order a P1 field too): by
      day 1.1-2.1 %, the sunsets 1.7 % / 1.6 %, Mars noon 5.5 %, overcast 4.5 %, blue hour 8.7 %, Mars sunset 18 %.
      The first moment alone (the true phase function's g, no delta cut) swings Mars the other way (0.3-0.4x away
      from the sun in blue: a P1 field of a peaked phase function goes negative behind it) and leaves the overcast
      0.85-0.95x; the delta cut alone (f = g, an isotropic rest) 1.2-1.6x too bright.

    What the sun-cosine nodes and the forward cut per channel gain is measured in :class:`SunCosineNodes` and
    :func:`grid_cut_deg`.

    The directions, steps and view grid were chosen by the bench (more directions change no day case by over 0.5 %
    and the low suns by a few %); 24 altitudes and 16 steps (32 and 24 take twice the build for the same errors
    within 0.12 point, the overcast's aside: 5.7 % against 4.5 %, with the second order a P1 field;
    ``tools/measure_ms_resolution.py``). Cost, on this project's 2-core machine, with the sun table: 1.07-1.11 s
    (1.54-1.71 s on one thread; ``tools/bench_tables.py``; 0.88-0.96 s without the second order by direction). The
    light is symmetric about the sun's plane, so only the half of the directions with w_y > 0 is marched and the
    other half mirrored (the same numbers for half the work: 4 s -> 2.7 s with J alone); the orders are summed by
    GMRES (:func:`solve_orders`, 0.02-0.03 s a channel where LU took 0.35 s: 4.0 -> 2.4 s); the altitudes' rows are
    built on :data:`WORKERS` threads (at 32 altitudes and 24 steps 2.3-2.4 s on one thread, 1.4-1.6 s on 2 cores;
    the same numbers to the bit). Where the time goes (one thread, 1.54-1.71 s in that bench): the transport
    matrix's rows, 27 weighted bincounts per altitude (0.57 s under cProfile; ``np.add.at`` and a sorted
    ``reduceat`` take 2.6-2.8x as long, batched matrix products over each altitude cell's points 1.6x), the lookups
    0.4 s, the march 0.15 s.
    """

    def __init__(self, atm: Atmosphere, sun_table: SunTransmittanceTable, ground_albedo=DEFAULT_GROUND_ALBEDO,
                 n_altitudes: int = 24, n_cosines: int = 33, n_zenith: int = 6, n_azimuth: int = 16, n_steps: int = 16,
                 n_view_cosines: int = 17, n_view_azimuths: int = 9,
                 sun_nodes: SunCosineNodes | None = None) -> None:
        self.atm = atm
        # ``sun_nodes``: another layout of the sun cosines (``tools/measure_sun_nodes.py``); ``n_cosines`` unused then
        self._sun_nodes = SunCosineNodes(n_cosines) if sun_nodes is None else sun_nodes
        self.n_alt, self.n_mu = n_altitudes, len(self._sun_nodes)
        self.n_view_z, self.n_view_a = n_view_cosines, n_view_azimuths
        self._albedo = np.asarray(ground_albedo, dtype=np.float64)
        self._sun_table = sun_table
        self._mu_s = self._sun_nodes.cosines  # crowded at the terminator (mu_s = 0), where the light changes fastest
        n_cosines = self.n_mu                 # from here the nodes' count (32 for the resolution 33)
        if n_azimuth % 2:
            raise ValueError(f"n_azimuth must be even (the directions pair up about the sun's plane), not {n_azimuth}")
        self._dirs, solid_angle = _direction_grid(n_zenith, n_azimuth)              # (D, 3), (D,)
        # The light is symmetric about the plane of the zenith and the sun, and so is the direction grid: the rays
        # are marched in the half with w_y > 0 only (counted twice); each direction of the other half reads its
        # mirror image (``mirror``: index into the marched half). Half the work, the same numbers.
        marched = self._dirs[:, 1] > 0.0
        ring, azimuth = np.divmod(np.arange(len(self._dirs)), n_azimuth)
        mirror = ring * (n_azimuth // 2) + np.minimum(azimuth, n_azimuth - 1 - azimuth)
        self._marched = self._dirs[marched]                                         # (D, 3): D the marched half
        n_dirs = len(self._marched)
        share = (2.0 * solid_angle[marched] / (4.0 * np.pi))[:, None]               # (D, 1): dOmega / 4 pi, twice
        sun_dirs = np.stack([np.sqrt(1.0 - self._mu_s ** 2), np.zeros_like(self._mu_s), self._mu_s], axis=-1)
        self._along = sun_dirs @ self._marched.T                                    # (M, D): sun . w
        self._steps = (np.arange(n_steps) + 0.5) / n_steps
        altitudes = atm.atmosphere_height * np.linspace(0.0, 1.0, n_altitudes) ** 2
        phase_r = phase_rayleigh(self._along)[:, :, None, None]                     # (M, D, 1, 1)
        phase_m = phase_hg(self._along, atm.mie_g)[:, :, None, :]                   # (M, D, 1, 3)
        n_nodes = n_altitudes * n_cosines
        # What the three unknowns of a node (J, H_up, H_sun) take of the light arriving at it along w: 1, w_up, w_sun
        # (x's frame: z up, the sun in the x-z plane toward +x).
        project = np.stack([np.ones(n_dirs), self._marched[:, 2], self._marched[:, 0]])   # (3, D)
        once = np.zeros((n_altitudes, n_cosines, n_dirs, 3))                        # L_1(x, w)
        transport = np.zeros((3, _MOMENTS * n_nodes, _MOMENTS * n_nodes))          # A per channel
        upward = 2.0 * np.maximum(self._marched[:, 2], 0.0) * solid_angle[marched]  # (D,): cos w dOmega, sky only
        all_rays = [self._rays(float(altitude)) for altitude in altitudes]
        ground_rows = [None] * n_altitudes     # per altitude: the ground points' weights on the ground's sun cosines
        sky = {}

        def march(j: int) -> None:             # the rows of altitude j's nodes: each call writes its own slices
            rays = all_rays[j]
            t_sun = sun_table(rays.radius_m, rays.sun_cosine)                      # (M, D, S, 3)
            light = np.sum(t_sun * (rays.first_rayleigh[None] * phase_r + rays.first_mie[None] * phase_m), axis=2)
            lit_ground = np.maximum(rays.ground_sun_cosine, 0.0)[..., None] * sun_table(
                rays.ground_radius_m + 1e-3, rays.ground_sun_cosine)
            once[j] = light + (rays.first_to_ground / np.pi)[None] * lit_ground
            emitted = self._emission(rays)                                          # (3, M, D, S, 3)
            # (out a, in b): sum over w of project_a(w) dOmega / 4 pi times what the steps along w send of b
            weights = emitted[None] * (project * share[:, 0])[:, None, None, :, None, None]
            blocks = self._matrix_rows(rays.altitude_m, rays.sun_cosine, weights)   # (3, 3, 3, M, N)
            for a in range(_MOMENTS):
                transport[:, a * n_nodes + j * n_cosines:a * n_nodes + (j + 1) * n_cosines] = np.concatenate(
                    list(blocks[a]), axis=-1)
            ground = self._matrix_rows(np.zeros(()), rays.ground_sun_cosine,
                                       rays.to_ground[None, None] * (project * share[:, 0] / np.pi)[:, None, :, None])
            ground_rows[j] = ground[..., :n_cosines]                                # (3 out, 3 ch, M, M_g)
            if j == 0:   # the ground's irradiance from the sky: E_1 of the once-scattered light, and E_B of the rest
                sky["once"] = np.einsum("mdc,d->mc", light, upward)                 # (M_g, 3)
                sky["more"] = np.concatenate(list(self._matrix_rows(
                    rays.altitude_m, rays.sun_cosine, emitted * upward[None, None, :, None, None])),
                    axis=-1)                                                        # (3, M_g, 3N)

        in_parallel(march, n_altitudes)
        sky_once, sky_more = sky["once"], sky["more"]
        _, weights_r, weights_m, weights_cut = _view_weights(n_zenith, n_azimuth, n_view_cosines,
                                                             n_view_azimuths, tuple(_mie_g(atm)))
        view_shape = (n_altitudes, n_cosines, n_view_cosines, n_view_azimuths, 3)

        def view_table(field: np.ndarray, haze_weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            """(S_R and S_M as (nodes, 6) rows, float32; the same beside the next sun cosine's, as
            :attr:`_with_next_cosine`) of a field by marched direction (altitudes, sun cosines, D, 3)."""
            field = field[:, :, mirror]                                             # every direction of the grid
            rayleigh = np.stack([field[..., ch] @ weights_r.T for ch in range(3)], axis=-1)       # (J, M, V, 3)
            mie = np.stack([field[..., ch] @ haze_weights[..., ch].T for ch in range(3)], axis=-1)
            # Not below 0: a P1 field can dip below it behind a peaked phase function, by under 1e-5 of the table's
            # largest value (measured: a backward haze g -0.999, Mars' dust 30x at g 0.99).
            rows = np.maximum(np.stack([rayleigh.reshape(view_shape), mie.reshape(view_shape)],
                                       axis=-2).reshape(-1, 6), 0.0).astype(np.float32)
            # Each row beside the same node at the next sun cosine (zeros past the last, which no lookup reaches), so
            # :meth:`_lookup` reads both sun-cosine nodes of a corner in one gather.
            step = n_view_cosines * n_view_azimuths
            return rows, np.concatenate([rows, np.concatenate([rows[step:], np.zeros((step, 6), np.float32)])], axis=1)

        # The first order scattered once more, by direction: L_2(x, w) = integral T' (beta_R n_R S_1R + beta_M n_M
        # S_1M)(p, w) dt + T'_g albedo E_1 / pi, S_1 the in-scattering of L_1 with the haze's forward cone taken out.
        first_rows = view_table(once, weights_cut)[1]
        second = np.zeros_like(once)

        def ground_light(rays: _Rays, irradiance: np.ndarray) -> np.ndarray:
            """(M, D, 3): T'_g albedo E / pi, what the Lambertian ground sends back along each ray that meets it, E
            (the ground's sun cosines, 3) read at the ray's end."""
            _, k = self._indices(0.0, rays.ground_sun_cosine)
            lit = np.stack([np.interp(k, np.arange(n_cosines), irradiance[:, ch]) for ch in range(3)], axis=-1)
            return rays.to_ground[None] / np.pi * lit

        def scatter_once(j: int) -> None:
            rays = all_rays[j]
            mu = rays.sun_cosine
            up = np.broadcast_to(rays.view_up[None], mu.shape)
            # linear between the sun-cosine nodes (log-linearly, against 192 000 reference paths, the blue hour is
            # 3.8 % and xy 0.0102 against 3.8 % and 0.0093, the Martian sunset 5.4 % against 5.6 % with a 30 deg cut
            # for every channel; the overcast 3.1 % against 2.6 % at 96 000)
            s_r, s_m = self._lookup(first_rows, np.broadcast_to(rays.altitude_m, mu.shape), mu, up, rays.toward_sun,
                                    log_linear=False)
            second[j] = np.sum(rays.step_rayleigh[None] * s_r + rays.step_mie[None] * s_m, axis=2)
            second[j] += ground_light(rays, sky_once)

        in_parallel(scatter_once, n_altitudes)
        # The ground reflects the sky's light as a Lambertian surface: radiance albedo / pi E, E from the upper
        # hemisphere (not J at the ground, whose mean over every direction would count the ground's own light).
        sky_second = np.einsum("mdc,d->mc", second[0], upward)                     # E_2 at the ground, (M_g, 3)
        once_moments = np.einsum("jmdc,ad->ajmc", once, project * share[:, 0])     # J_1, H_1 (3, J, M, 3)
        second_moments = np.einsum("jmdc,ad->ajmc", second, project * share[:, 0])
        reflected = [np.concatenate([np.einsum("cmg,gc->mc", rows[a], sky_second) for rows in ground_rows])
                     for a in range(_MOMENTS)]                                      # the ground's E_2, reflected
        source = np.concatenate([second_moments[a].reshape(n_nodes, 3) + reflected[a]
                                 for a in range(_MOMENTS)])                          # (3N, 3): J_2, H_2
        for a in range(_MOMENTS):                  # (3 ch, N, M_g) @ (3 ch, M_g, 3N): one batched product
            transport[:, a * n_nodes:(a + 1) * n_nodes] += np.concatenate(
                [rows[a] for rows in ground_rows], axis=1) @ sky_more
        solved = np.stack([solve_orders(transport[ch], source[:, ch]) for ch in range(3)], axis=-1)
        transport = None                           # its 240 MB freed before the field is gathered
        higher = solved.reshape(_MOMENTS, n_altitudes, n_cosines, 3)               # J, H of every order from the 2nd
        moments = once_moments + higher
        #: Psi_ms (altitudes, sun cosines, 3): the mean radiance of light scattered at least once, 1/sr per unit E_top.
        self.psi = np.maximum(moments[0], 0.0)
        #: H (altitudes, sun cosines, 2, 3): its first moment (1 / 4 pi) integral L w dOmega, along the local zenith and
        #: the horizontal toward the sun, 1/sr per unit E_top.
        self.first_moment = np.moveaxis(moments[1:], 0, 2).copy()
        #: J_1 (altitudes, sun cosines, 3): the mean radiance of light scattered exactly once.
        self.single = once_moments[0]
        sky_irradiance = sky_second + np.einsum("cgn,nc->gc", sky_more, solved)    # E_2 + E_B at the ground
        # Between sun-cosine nodes the higher orders' J is read log-linearly (it falls by orders of magnitude across
        # the terminator) and H as J times the interpolated H / J, which changes slowly; |H| <= J for any radiance
        # field that is nowhere negative, which bounds the ratio where J is the solve's rounding.
        higher_mean = np.maximum(higher[0], 0.0)
        mean = np.broadcast_to(higher[0][:, :, None], (n_altitudes, n_cosines, 2, 3))
        anisotropy = np.clip(np.divide(np.moveaxis(higher[1:], 0, 2), mean, out=np.zeros_like(mean),
                                       where=mean > 0.0), -1.0, 1.0).reshape(n_altitudes, n_cosines, 6)
        field = once + second

        def gather(j: int) -> None:            # + the third and higher orders by direction, at altitude j's nodes
            rays = all_rays[j]
            emitted = self._emission(rays)
            altitude_m = np.broadcast_to(rays.altitude_m, rays.sun_cosine.shape)
            i, k = self._indices(altitude_m, rays.sun_cosine)
            shape = _bilinear(anisotropy, i, k).reshape(i.shape + (2, 3))          # H / J, linear
            field[j] += np.sum(_linear_then_log_linear(higher_mean, i, k)           # J, log-linear in the sun
                               * (emitted[0] + emitted[1] * shape[..., 0, :] + emitted[2] * shape[..., 1, :]), axis=2)
            field[j] += ground_light(rays, sky_irradiance)

        in_parallel(gather, n_altitudes)
        #: S_R and S_M (altitudes, sun cosines, view cosines, view azimuths, 2, 3), flattened to (nodes, 6) rows;
        #: float32, half the memory read. The view ray scatters with the true phase functions (:func:`_view_weights`).
        self.in_scattering, self._with_next_cosine = view_table(field, weights_m)

    def _rays(self, altitude_m: float) -> _Rays:
        """March the rays from the nodes at ``altitude_m`` (module docstring of the class)."""
        atm, c = self.atm, self._marched[:, 2]
        r_ground, top = atm.planet_radius, atm.atmosphere_height
        r0 = r_ground + altitude_m
        t_top = -r0 * c + np.sqrt(np.maximum(r0 * r0 * (c * c - 1.0) + (r_ground + top) ** 2, 0.0))
        disc_ground = r0 * r0 * (c * c - 1.0) + r_ground ** 2
        hits = (c < 0.0) & (disc_ground >= 0.0)
        length = np.where(hits, -r0 * c - np.sqrt(np.maximum(disc_ground, 0.0)), t_top)   # (D,)
        u = self._steps                                # steps crowd at the node: t = length u^2, dt = 2 u du length
        t = length[:, None] * u * u                                                 # (D, S)
        dt = (length[:, None] * (2.0 * u / u.size))[..., None]
        radius = np.sqrt(np.maximum(r0 * r0 + 2.0 * r0 * c[:, None] * t + t * t, 0.0))
        h = np.maximum(radius - r_ground, 0.0)
        n_r, n_m = np.exp(-h / atm.rayleigh_scale_height)[..., None], np.exp(-h / atm.mie_scale_height)[..., None]
        extinction = local_extinction(atm, n_r, n_m, h)

        def carried(kept: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            """(T dt to each step's midpoint (D, S, 3), T to the ray's end (D, 3)), where ``kept`` of the haze's
            scattering goes on as if not scattered."""
            step = (extinction - kept * atm.mie_scattering * n_m) * dt
            through = np.cumsum(step, axis=1)
            return np.exp(-(through - 0.5 * step)) * dt, np.exp(-through[:, -1])

        forward = forward_fraction(atm)                # delta-Eddington: the haze's forward peak does not attenuate
        seen, to_end = carried(forward)                                             # T'
        seen_first, to_end_first = carried(grid_forward_fraction(atm))             # T_c: all but the forward cone
        turning = atm.rayleigh_scattering * n_r + (1.0 - forward) * atm.mie_scattering * n_m   # sigma_s'
        r_end = np.sqrt(np.maximum(r0 * r0 + 2.0 * r0 * c * length + length * length, 0.0))
        # sun zenith cosine along the rays, for every sun position: (x . sun) / |x|, x = (0, 0, r0) + t w
        mu_s = self._mu_s
        sun_cosine = (r0 * mu_s[:, None, None] + t[None] * self._along[..., None]) / radius
        view_up = (t + r0 * c[:, None]) / np.maximum(radius, 1.0)
        across = np.sqrt(np.maximum(1.0 - sun_cosine * sun_cosine, 0.0))
        toward_sun = np.where(across > 1e-6, (self._along[..., None] - sun_cosine * view_up[None])
                              / np.maximum(across, 1e-6), 0.0)
        return _Rays(altitude_m=h, sun_cosine=sun_cosine,
                     step_scattering=seen * turning,
                     step_rayleigh=seen * atm.rayleigh_scattering * n_r, step_mie=seen * atm.mie_scattering * n_m,
                     radius_m=radius,
                     to_ground=np.where(hits[:, None], to_end * self._albedo, 0.0),
                     ground_radius_m=r_end, ground_sun_cosine=(r0 * mu_s[:, None] + length * self._along) / r_end,
                     view_up=view_up, toward_sun=toward_sun,
                     first_rayleigh=seen_first * atm.rayleigh_scattering * n_r,
                     first_mie=seen_first * atm.mie_scattering * n_m,
                     first_to_ground=np.where(hits[:, None], to_end_first * self._albedo, 0.0))

    def _indices(self, altitude_m: ArrayLike, cos_zenith: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Fractional node indices (altitude row, sun-cosine column) of points, as :meth:`__call__` reads them."""
        altitude = np.clip(np.asarray(altitude_m, dtype=np.float64), 0.0, self.atm.atmosphere_height)
        i = np.sqrt(altitude / self.atm.atmosphere_height) * (self.n_alt - 1)
        return i, self._sun_nodes.index(cos_zenith)

    def _emission(self, rays: _Rays) -> np.ndarray:
        """(3, M, D, S, 3): what each step of the rays sends back to their node per unit J, H_up and H_sun at the
        step: T' dt times sigma_s' (the delta-Eddington scattering, :func:`forward_fraction`), and times
        3 (g - f) beta_M n_M (w . up_p) and 3 (g - f) beta_M n_M (w . sun_p), where up_p and sun_p are the local
        zenith and the horizontal toward the sun at the step. A medium that scatters with mean cosine g' turns a
        field J + 3 H . w into J + 3 g' H . w; sigma_s' g' = (1 - f) beta_M g' = (g - f) beta_M for the haze, and
        Rayleigh's mean cosine is 0."""
        up = rays.view_up[None]                                                     # (1, D, S)
        moment = 3.0 * (_mie_g(self.atm) - forward_fraction(self.atm)) * rays.step_mie   # (D, S, 3)
        shape = rays.sun_cosine.shape + (3,)
        return np.stack([np.broadcast_to(rays.step_scattering[None], shape),
                         np.broadcast_to(moment[None] * up[..., None], shape),
                         moment[None] * rays.toward_sun[..., None]])

    def _matrix_rows(self, altitude_m: np.ndarray, cos_zenith: np.ndarray, weights: np.ndarray) -> np.ndarray:
        """Rows of A for one altitude's M nodes, (..., 3 channels, M, nodes), from points of shape (M, ...) (the
        altitude broadcast to it) with weights (..., M, ..., 3): each point adds its weight times the bilinear weight
        of each of the four nodes around it (the matrix form of J(point) read off the nodes), one bincount per
        leading index and channel."""
        i, k = self._indices(np.broadcast_to(altitude_m, np.shape(cos_zenith)), cos_zenith)
        i0, k0, fi, fk = _cell(self.n_alt, self.n_mu, i, k)
        n_rows, n_nodes = i.shape[0], self.n_alt * self.n_mu
        row = np.arange(n_rows).reshape((-1,) + (1,) * (i.ndim - 1)) * n_nodes
        flat = np.concatenate([(row + (i0 + di) * self.n_mu + (k0 + dk)).ravel() for di in (0, 1) for dk in (0, 1)])
        corner = np.concatenate([(wi * wk).ravel() for wi in (1.0 - fi, fi) for wk in (1.0 - fk, fk)])
        lead = weights.shape[:-1 - i.ndim]
        columns = np.moveaxis(np.broadcast_to(weights, lead + i.shape + (3,)), -1, len(lead))
        columns = columns.reshape(-1, i.size)                                       # (lead x 3, points)
        corners = corner.reshape(4, -1)                                             # (4 corners, points)
        result = np.stack([np.bincount(flat, weights=(corners * column).ravel(), minlength=n_rows * n_nodes)
                           for column in columns])
        return result.reshape(lead + (3, n_rows, n_nodes))

    def __call__(self, altitude_m: ArrayLike, cos_zenith: ArrayLike) -> np.ndarray:
        """Psi_ms at altitude ``altitude_m`` (m, clamped to the atmosphere) and sun zenith cosine, (..., 3):
        linear in altitude, log-linear in the sun cosine as :meth:`scattered` (so that the mean of S_i over every
        view is Psi_ms between the nodes too)."""
        i, k = self._indices(altitude_m, cos_zenith)
        return _linear_then_log_linear(self.psi, i, k)

    def scattered(self, altitude_m: ArrayLike, cos_zenith: ArrayLike, view_cos_zenith: ArrayLike,
                  view_toward_sun: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """(S_R, S_M), each (..., 3): what a view ray in-scatters of the multiply scattered light per unit Rayleigh and
        Mie scattering coefficient, 1/sr per unit E_top, at altitude ``altitude_m`` (m) with the sun at zenith cosine
        ``cos_zenith``, for a view direction v with local zenith cosine ``view_cos_zenith`` and component
        ``view_toward_sun`` along the horizontal direction to the sun (v . x_sun; arrays that broadcast).

        Interpolated linearly in altitude and the two view coordinates at the two sun-cosine nodes around the point,
        then log-linearly (geometrically) between them: across the terminator the light falls by orders of
        magnitude within a few degrees of sun, roughly exponentially, so a straight line between two nodes lies far
        above it. Measured on the clear preset's sky seen from the ground (5 deg up, away from the sun;
        ``MultipleScatteringTable`` built with 257 sun cosines as the converged value): linear interpolation on the
        33 nodes was 1.30x too bright at a sun 4 deg below the horizon and 1.42x at 6 deg (the spectral reference's
        +27 % and +50 %, docs/reference_sky.md), log-linear 0.96x and 0.99x (the zenith 0.99x and 1.00x, from 1.05x
        and 1.11x); by day the two differ by under 0.3 %. Where either node is 0 (no light at all) the
        interpolation is linear."""
        return self._lookup(self._with_next_cosine, altitude_m, cos_zenith, view_cos_zenith, view_toward_sun)

    def _lookup(self, table: np.ndarray, altitude_m: ArrayLike, cos_zenith: ArrayLike, view_cos_zenith: ArrayLike,
                view_toward_sun: ArrayLike, *, log_linear: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`scattered` of a ``table`` laid out as :attr:`_with_next_cosine`; between the sun-cosine nodes
        log-linear, or linear (``log_linear=False``)."""
        i, k = self._indices(altitude_m, cos_zenith)
        vz = np.clip(np.asarray(view_cos_zenith, dtype=np.float64), -1.0, 1.0)
        across = np.sqrt(np.maximum(1.0 - vz * vz, 1e-12))
        azimuth = np.arccos(np.clip(np.asarray(view_toward_sun, dtype=np.float64) / across, -1.0, 1.0))
        coords = np.broadcast_arrays(i, k, (vz + 1.0) * 0.5 * (self.n_view_z - 1),
                                     azimuth * ((self.n_view_a - 1) / np.pi))
        sizes = (self.n_alt, self.n_mu, self.n_view_z, self.n_view_a)
        strides = (sizes[1] * sizes[2] * sizes[3], sizes[2] * sizes[3], sizes[3], 1)
        base, pairs = 0, []
        for x, n, stride in zip(coords, sizes, strides):
            low = np.clip(np.floor(x).astype(np.int64), 0, n - 2)
            fraction = np.clip(x - low, 0.0, 1.0).astype(np.float32)
            base = base + low * stride
            pairs.append((1.0 - fraction, fraction))
        # linear in altitude and the view at the two sun-cosine nodes around the point (8 corners, each row holding
        # both nodes), then (log-)linear between the two; in float32, the table's own precision (float64 changed the
        # tiles by under 5e-7 relative and took twice the time)
        second = [[a * b for b in pairs[3]] for a in pairs[2]]
        both = np.zeros(coords[0].shape + (12,), np.float32)
        for corner in range(8):
            bits = [(corner >> axis) & 1 for axis in range(3)]
            row = base + bits[0] * strides[0] + bits[1] * strides[2] + bits[2] * strides[3]
            rows = np.take(table, row, axis=0)      # np.take: half the time of [row] here
            rows *= (pairs[0][bits[0]] * second[bits[1]][bits[2]])[..., None]
            both += rows
        fraction = pairs[1][1][..., None]
        if log_linear:
            result = _log_linear(both[..., :6], both[..., 6:], fraction).astype(np.float64)
        else:
            result = (both[..., :6] + fraction * (both[..., 6:] - both[..., :6])).astype(np.float64)
        return result[..., :3], result[..., 3:]


#: The multiple-scattering table of the first look after an atmosphere edit in the interface
#: (``blender/apply/precise_tables.py``, :func:`atmosphere_tables` with ``preview=True``): half the altitudes and
#: sun cosines, about a fifth of the build (0.29 s against 1.52 s on 2 cores); the full table follows on the same
#: worker; its sun-cosine nodes are every other one of the full table's. Against the complete reference
#: (``tools/bench_accuracy.py``'s references; Mars and the overcast with a 30 deg forward cut for every channel) by
#: day 1.1-2.1 % (the full table 1.1-2.0 %), Earth sunsets 1.9 % / 2.5 %, Mars 0.2 % / 6.4 %, the overcast 1 deg sun
#: 8.2 %, the blue hour 6.5 % (the full table 3.8 %).
PREVIEW_RESOLUTION = {"n_altitudes": 12, "n_cosines": 17}
class TableStore(Protocol):
    """Somewhere beyond this process that keeps what :func:`stored` builds: ``load`` returns the object saved under
    ``key`` (None when there is none), ``save`` keeps one. The tests' store (``tests/conftest.py``) shares the tables
    and tiles that many tests bake alike between their processes."""

    def load(self, key: str) -> object | None: ...

    def save(self, key: str, value: object) -> None: ...


_STORE: list[TableStore] = []


def use_store(store: TableStore | None) -> None:
    """Keep the per-atmosphere tables and the tiles in ``store`` as well as in memory (None: in memory only)."""
    _STORE[:] = [] if store is None else [store]


def current_store() -> TableStore | None:
    """The store :func:`use_store` set, or None."""
    return _STORE[0] if _STORE else None


def stored(inputs: tuple, build: Callable[[], object]) -> object:
    """``build()``, or what the store (:func:`use_store`) kept for ``inputs``, a tuple of plain values whose
    ``repr`` names them (frozen dataclasses included)."""
    if not _STORE:
        return build()
    key = repr(inputs)
    value = _STORE[0].load(key)
    if value is None:
        value = build()
        _STORE[0].save(key, value)
    return value


#: How many atmospheres' tables :func:`atmosphere_tables` keeps, and apart from them how many previews.
TABLES_KEPT = 8
PREVIEWS_KEPT = 2
_TABLES: collections.OrderedDict = collections.OrderedDict()
_TABLES_LOCK = threading.Lock()


def atmosphere_tables(atm: Atmosphere, ground_albedo: tuple[float, float, float] = DEFAULT_GROUND_ALBEDO, *,
                      preview: bool = False) -> tuple[SunTransmittanceTable, MultipleScatteringTable]:
    """The per-atmosphere tables (sun transmittance, multiple scattering), cached (the last :data:`TABLES_KEPT`):
    they change with the atmosphere's parameters only, never with the sun or the camera. ``preview``: the
    multiple-scattering table at :data:`PREVIEW_RESOLUTION`, for the interface's first look (kept apart: the
    last :data:`PREVIEWS_KEPT`)."""
    key = (atm, tuple(float(a) for a in ground_albedo), bool(preview))
    with _TABLES_LOCK:
        if key in _TABLES:
            _TABLES.move_to_end(key)
            return _TABLES[key]

    def build() -> tuple[SunTransmittanceTable, MultipleScatteringTable]:
        sun_table = SunTransmittanceTable(atm)
        return sun_table, MultipleScatteringTable(atm, sun_table, key[1], **(PREVIEW_RESOLUTION if preview else {}))

    tables = stored(("atmosphere_tables", key), build)
    with _TABLES_LOCK:
        _TABLES[key] = tables
        for kept, limit in ((False, TABLES_KEPT), (True, PREVIEWS_KEPT)):
            keys = [k for k in _TABLES if k[2] == kept]
            for old in keys[:max(len(keys) - limit, 0)]:
                del _TABLES[old]
    return tables


def tables_ready(atm: Atmosphere, ground_albedo: tuple[float, float, float] = DEFAULT_GROUND_ALBEDO) -> bool:
    """True when :func:`atmosphere_tables` holds this atmosphere's full tables (a tile then costs only itself)."""
    return (atm, tuple(float(a) for a in ground_albedo), False) in _TABLES


@dataclass(frozen=True, eq=False)
class Tile:
    """One frame's table: ``mean_extinction`` tau / d (1/m), (altitudes, distances, 3), and ``a_rayleigh``,
    ``a_mie`` (W/m^2), (altitudes, azimuths, distances, 3); with the frame's camera radius r_c and largest
    distance D (m) that the shader maps with."""

    shape: TableShape
    camera_radius_m: float
    max_distance_m: float
    mean_extinction: np.ndarray
    a_rayleigh: np.ndarray
    a_mie: np.ndarray
    #: The sky view (:func:`sky_view`): radiance W/(m^2 sr), (altitudes rows, sky azimuths, 3), and the ground's
    #: transmittance (altitudes rows, 3); None until :func:`integrate_tile` adds them.
    sky_radiance: np.ndarray | None = None
    sky_ground_transmittance: np.ndarray | None = None
    #: The camera's sky view (:func:`camera_sky_view`): the Rayleigh in-scattering (its phase function included) and
    #: the Mie in-scattering without its phase function, per view direction above the horizon, W/(m^2 sr), each
    #: (altitudes rows, sky azimuths, 3); None until :func:`integrate_tile` adds them.
    camera_sky_rayleigh: np.ndarray | None = None
    camera_sky_mie: np.ndarray | None = None
    #: Each row's distance columns start at its vertical ray (:func:`cell_distances`); False for the key tiles of a
    #: camera whose frames blend keys of different altitudes (:attr:`KeyTiles.vertical_columns`), whose columns all
    #: start at the camera (d_min = 0): two keys' texels then map rays of one length, which is what blending them
    #: needs. The shader reads it from ``atmos_precise_atlas``'s z.
    vertical_columns: bool = True

    def pixels(self) -> np.ndarray:
        """The tile as image pixels (altitudes, width, 3): row = altitude, columns = the extinction block
        (distance), then A_R and A_M, each azimuth slice * distances + distance, then the sky view (row = view
        zenith, its azimuth columns and the ground-transmittance column; the add-on's atlas layout)."""
        rows = self.shape.altitudes
        return np.concatenate([self.mean_extinction, self.a_rayleigh.reshape(rows, -1, 3),
                               self.a_mie.reshape(rows, -1, 3), self.sky_radiance,
                               self.sky_ground_transmittance[:, None, :], self.camera_sky_rayleigh,
                               self.camera_sky_mie], axis=1)


def _simpson_weights(n: int) -> np.ndarray:
    """Composite Simpson weights for n (odd) equally spaced samples on [0, 1]."""
    weights = np.ones(n)
    weights[1:-1:2], weights[2:-1:2] = 4.0, 2.0
    return weights / (3.0 * (n - 1))


#: Samples along each table ray (odd: Simpson's rule in w = sqrt(t / d)).
RAY_SAMPLES = 65
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
    largest, :func:`blend_tiles`). The last :data:`TILE_CACHE_SIZE` tiles are kept: the same inputs return the same
    :class:`Tile`, its arrays read-only (:func:`integrate_tile` integrates afresh). ``preview``: from the preview
    tables (:data:`PREVIEW_RESOLUTION`); ``vertical_columns``: :attr:`Tile.vertical_columns`."""
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
    return _frozen(stored(("tile", inputs), lambda: integrate_tile(
        atm, camera_altitude_m, sun_elevation_rad, multiple_scattering=multiple_scattering,
        ground_albedo=ground_albedo, shape=shape, max_distance_m=max_distance_m, preview=preview,
        vertical_columns=vertical_columns)))


def _frozen(tile: Tile) -> Tile:
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
                   preview: bool = False, tables: tuple | None = None, stop: threading.Event | None = None,
                   vertical_columns: bool = True) -> Tile:
    """Integrate one frame's table (module docstring), uncached (:func:`bake_tile` keeps the last ones); ``preview``
    reads the preview tables (:func:`atmosphere_tables`); ``tables``: the (sun transmittance, multiple-scattering)
    tables to read instead (the tools that measure variants of them); ``stop``: once set, the integration ends at
    its next block of rows (20-40 ms) with :class:`TileCancelled` (a tile no longer wanted frees its thread).

    Each cell (target altitude h_p, azimuth a, distance d) is its own ray: the elevation follows from the
    triangle (r_c, r_p, d), sin e = (r_p^2 - r_c^2 - d^2) / (2 r_c d), clamped to a vertical ray where the
    altitude cannot be reached at that distance. The ray is integrated by Simpson's rule in w = sqrt(t / d) on
    :data:`RAY_SAMPLES` samples (dense near the camera), the optical depth to each sample by the trapezoid rule
    on the same samples. The rows are integrated in blocks of :data:`TILE_BLOCK_ROWS` on :data:`WORKERS` threads,
    each block's arrays small enough to stay in the processor's cache (``tools/bench_tables.py`` against whole-tile
    arrays in a worktree, interleaved: 0.50-0.57 s a tile on one thread where they take 0.87-1.23 s, 0.33-0.40 s on
    2 cores where one block per thread takes 0.54-0.71 s; the same numbers to the bit).
    """
    h_c = max(float(camera_altitude_m), 0.0)
    sun_table, ms_table = (atmosphere_tables(atm, tuple(float(a) for a in ground_albedo), preview=preview)
                           if tables is None else tables)
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

    blocks = np.array_split(np.arange(shape.altitudes), max(WORKERS, shape.altitudes // TILE_BLOCK_ROWS))
    in_parallel(integrate, len(blocks))
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


def ray_integrals(atm: Atmosphere, tables: tuple, radius_m: ArrayLike, view_cos_zenith: ArrayLike,
                  sun_cos_zenith: ArrayLike, nu: ArrayLike, length_m: ArrayLike, *,
                  multiple_scattering: bool = True) -> tuple[np.ndarray, ...]:
    """The integrals of the module docstring along straight rays, per unit E_top: each ray starts at radius
    ``radius_m`` with view and sun zenith cosines ``view_cos_zenith`` and ``sun_cos_zenith`` there, nu = v . l, and
    is ``length_m`` long (arrays that broadcast, shape (...)); ``tables``: (sun transmittance, multiple scattering),
    :func:`atmosphere_tables`. Returns (tau, J_R, J_M, the Rayleigh and Mie scattering and the extinction at the
    start), each (..., 3); J_R holds J_ms / Phi_R(nu) with ``multiple_scattering``. Simpson's rule in
    w = sqrt(t / d) on :data:`RAY_SAMPLES` samples (dense near the start), the optical depth to each sample by the
    trapezoid rule on the same samples, rescaled to the Simpson total. :func:`integrate_tile` integrates its cells
    with it, ``tools/measure_sun_free_table.py`` rays from anywhere; pass each input in its smallest shape (the tile's
    geometry is (H, 1, D), its angles (H, A, D): the geometry's arrays stay small)."""
    sun_table, ms_table = tables
    r_c, sin_e, sin_s, nu, d = (np.asarray(x, dtype=np.float64)[..., None]
                                for x in (radius_m, view_cos_zenith, sun_cos_zenith, nu, length_m))
    w = np.linspace(0.0, 1.0, RAY_SAMPLES)
    t = d * w * w                                                                     # (..., S)
    radius = np.sqrt(np.maximum(r_c * r_c + 2.0 * r_c * t * sin_e + t * t, 0.0))
    h = np.maximum(radius - atm.planet_radius, 0.0)
    n_r, n_m = np.exp(-h / atm.rayleigh_scale_height)[..., None], np.exp(-h / atm.mie_scale_height)[..., None]
    beta_ex = local_extinction(atm, n_r, n_m, h)                                      # (..., S, 3)
    dt_dw = (2.0 * d * w)[..., None]                                                  # (..., S, 1)
    dw = w[1] - w[0]
    f = beta_ex * dt_dw
    tau_to = np.concatenate([np.zeros_like(f[..., :1, :]),
                             np.cumsum(0.5 * (f[..., 1:, :] + f[..., :-1, :]) * dw, axis=-2)], axis=-2)
    view_t = np.exp(-tau_to)
    tau = np.sum(f * _simpson_weights(RAY_SAMPLES)[:, None], axis=-2)                 # (..., 3)
    view_t = np.where(tau_to > 0.0, np.exp(-tau_to * (tau[..., None, :] / np.maximum(tau_to[..., -1:, :], 1e-300))),
                      view_t)                                                         # rescaled to the Simpson total
    mu_s = (r_c * sin_s + t * nu) / np.maximum(radius, 1.0)
    sun_t = sun_table(radius, mu_s)                                                   # 0 in the planet's shadow
    weights = (_simpson_weights(RAY_SAMPLES)[:, None] * dt_dw)
    j_r = np.sum(weights * view_t * atm.rayleigh_scattering * n_r * sun_t, axis=-2)
    j_m = np.sum(weights * view_t * atm.mie_scattering * n_m * sun_t, axis=-2)
    start_r = atm.rayleigh_scattering * n_r[..., 0, :] * sun_t[..., 0, :]
    if multiple_scattering:
        view_z = (r_c * sin_e + t) / np.maximum(radius, 1.0)                           # local zenith cosine of the ray
        view_x = (nu - mu_s * view_z) / np.sqrt(np.maximum(1.0 - mu_s * mu_s, 1e-12))   # ... toward the sun
        s_r, s_m = ms_table.scattered(np.broadcast_to(h, mu_s.shape), mu_s, view_z, view_x)
        source = atm.rayleigh_scattering * n_r * s_r + atm.mie_scattering * n_m * s_m
        phase = phase_rayleigh(nu)
        j_r = j_r + np.sum(weights * view_t * source, axis=-2) / phase
        start_r = start_r + source[..., 0, :] / phase
    start_m = atm.mie_scattering * n_m[..., 0, :] * sun_t[..., 0, :]
    return tau, j_r, j_m, start_r, start_m, beta_ex[..., 0, :]


def ray_inscattering(atm: Atmosphere, tables: tuple, radius_m: ArrayLike, view_cos_zenith: ArrayLike,
                     sun_cos_zenith: ArrayLike, nu: ArrayLike, length_m: ArrayLike, *,
                     multiple_scattering: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """(tau, L_in), each (..., 3), along the rays of :func:`ray_integrals` (same arguments), the phase functions
    applied as the shader applies them to the table: L_in = E_top [Phi_R(nu) J_R + Phi_HG(nu, g) J_M] (W/(m^2 sr)).
    What the tile's cells hold before the division by 1 - exp(-tau), for any ray: the yardstick of the table
    (``tools/measure_sun_free_table.py``, the tests)."""
    tau, j_r, j_m, *_ = ray_integrals(atm, tables, radius_m, view_cos_zenith, sun_cos_zenith, nu, length_m,
                                      multiple_scattering=multiple_scattering)
    nu = np.asarray(nu, dtype=np.float64)
    light = phase_rayleigh(nu)[..., None] * j_r + phase_hg(nu, atm.mie_g) * j_m
    return tau, np.asarray(atm.sun_irradiance_top) * light


def horizon_cosine(camera_altitude_m: float, atm: Atmosphere) -> float:
    """Zenith cosine of the horizon seen from altitude h_c (clamped at 0): -sqrt(h_c (2 R + h_c)) / (R + h_c)."""
    h_c = max(float(camera_altitude_m), 0.0)
    return -math.sqrt(h_c * (2.0 * atm.planet_radius + h_c)) / (atm.planet_radius + h_c)


#: How far beyond the horizon the sky view's two horizon rows are evaluated (zenith cosine): each row holds its own
#: side's ray (the ground's tangent ray, the sky's grazing one), never the other's.
HORIZON_NUDGE = 1e-9


def _azimuth_column(view_dir: np.ndarray, sun_dir: np.ndarray, columns: int, dt) -> np.ndarray:
    """The view's azimuth from the sun's (0..pi: the tables are mirror-symmetric about it) as a fractional column
    of a block of ``columns`` azimuths, in the shader's arithmetic: atan2(|v x l|_z, (v . l)_xy) (N - 1) / pi."""
    v, s = view_dir, sun_dir
    cross = v[..., 0] * s[..., 1] - v[..., 1] * s[..., 0]
    dot = v[..., 0] * s[..., 0] + v[..., 1] * s[..., 1]
    return np.arctan2(np.abs(cross), dot) * dt((columns - 1) / np.pi)


def _view_grid(across: np.ndarray, z: np.ndarray, azimuths: int,
               sun_elevation_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """(views, sun): unit view directions at horizontal components ``across`` and zenith cosines ``z`` (rows, 1),
    crossed with ``azimuths`` azimuths from the sun's, 0..pi; and the sun's direction at azimuth 0."""
    azimuth = np.linspace(0.0, np.pi, azimuths)[None, :]
    views = np.stack(np.broadcast_arrays(across * np.cos(azimuth), across * np.sin(azimuth), z), axis=-1)
    return views, np.array([math.cos(sun_elevation_rad), 0.0, math.sin(sun_elevation_rad)])


def sky_view_cosines(shape: TableShape, horizon: float) -> np.ndarray:
    """View zenith cosines of the sky view's rows for a horizon at zenith cosine ``horizon``: the first
    ``sky_ground_rows`` K rows the ground's, from the nadir to the horizon,
    z = z_h - (1 + z_h) ((K - 1 - j) / (K - 1))^2, the others the sky's, from the horizon to the zenith,
    z = z_h + (1 - z_h) ((j - K) / (N - 1 - K))^2 (crowded at the horizon, where the sky changes fastest: 2e-4
    apart there for 41 sky rows). The horizon is a row on both sides, so a lookup never blends the ground with the
    sky (:func:`lighting_from_tile`)."""
    k, n = shape.sky_ground_rows, shape.altitudes
    ground = horizon - (1.0 + horizon) * (np.arange(k - 1, -1, -1) / (k - 1)) ** 2
    sky = horizon + (1.0 - horizon) * (np.arange(n - k) / (n - 1 - k)) ** 2
    return np.concatenate([ground, sky])


def sky_view_rows(shape: TableShape, view_cos_zenith: ArrayLike, horizon, dtype: DTypeLike = np.float32):
    """Fractional sky-view rows of view zenith cosines (the inverse of :func:`sky_view_cosines`, as the shader
    computes it): below the horizon (K - 1) (1 - sqrt((z_h - z) / (1 + z_h))), else
    K + (N - 1 - K) sqrt((z - z_h) / (1 - z_h))."""
    dt = np.dtype(dtype).type
    k, n = shape.sky_ground_rows, shape.altitudes
    z = np.asarray(view_cos_zenith, dtype=dt)
    z_h = dt(horizon)
    sky = dt(k) + np.sqrt(np.maximum(z - z_h, dt(0)) / (dt(1) - z_h)) * dt(n - 1 - k)
    ground = dt(k - 1) - np.sqrt(np.maximum(z_h - z, dt(0)) / (dt(1) + z_h)) * dt(k - 1)
    return np.where(z < z_h, ground, sky).astype(dt)


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


def _linear_lookup(block: np.ndarray, x: np.ndarray, y: np.ndarray, dtype) -> np.ndarray:
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


def lighting_from_tile(tile: Tile, view_dir: ArrayLike, sun_dir: ArrayLike, atm: Atmosphere, albedo: ArrayLike,
                       e_sun: ArrayLike, dtype: DTypeLike = np.float32) -> np.ndarray:
    """The sky the scene is lit by at the Precise level, radiance (..., 3) along unit ``view_dir`` (..., 3): the
    sky view (:func:`sky_view`) sampled bilinearly at the row :func:`sky_view_rows` and the azimuth column
    a (N - 1) / pi, plus the lit ground albedo E_sun max(l_z, 0) / pi times its transmittance; what Cycles' Linear
    image lookup gives the lighting group (``atmos_addon.nodes.sky_lighting``). ``atm``: the tile's."""
    dt = np.dtype(dtype).type
    shape = tile.shape
    v = np.asarray(view_dir, dtype=dt)
    s = np.asarray(sun_dir, dtype=dt)
    horizon = horizon_cosine(tile.camera_radius_m - atm.planet_radius, atm)
    row = sky_view_rows(shape, np.clip(v[..., 2], dt(-1), dt(1)), horizon, dt)
    azimuth = _azimuth_column(v, s, shape.sky_azimuths, dt)
    light = _linear_lookup(tile.sky_radiance, azimuth, row, dt)
    ground = _linear_lookup(tile.sky_ground_transmittance[:, None, :], np.zeros_like(row), row, dt)
    lit = np.asarray(albedo, dtype=dt) * np.asarray(e_sun, dtype=dt) * (max(float(s[2]), 0.0) / np.pi)
    return (light + ground * lit).astype(dt)


# -- The camera's sky view ---------------------------------------------------------------------------------------
#
# Cycles evaluates the world for every camera sample that misses the scene: the Precise sky of :func:`sky_from_tile`
# (ten texel fetches and some 240 nodes) there cost about as much as Blender's whole Sky Texture (the camera's sky
# 0.85 s of a 3.6 s Per Pixel render, Blender's sky 0.88 s; tools/bench_quality_cost.py --decompose). Above the
# horizon the same sky tabulated by view direction reads it with two filtered lookups; the Mie phase function stays
# in the shader, so the sun's aureole keeps its exact shape however coarse the azimuths. Rows go by elevation,
# crowded at the horizon (the sky's fastest change) without starving the zenith (a zenith cosine's rows are 18 deg
# apart there). At and below the horizon the camera keeps the table's own sky: a 2 m camera sees the ground's path
# shrink from 5 km to 1 km within 0.05 deg below it, which no row spacing follows, and a far surface's haze meets
# the sky behind it there (the seamless horizon; ``atmos_addon.nodes.sky_view``).

def camera_sky_elevations(shape: TableShape, horizon_elevation_rad: float) -> np.ndarray:
    """Elevations (rad) of the camera sky view's rows: e_j = e_h + (pi/2 - e_h) (j / (N - 1))^2 from the horizon's
    e_h to the zenith, the first nudged above the horizon (:data:`HORIZON_NUDGE`: the sky's grazing ray)."""
    t = np.arange(shape.altitudes) / (shape.altitudes - 1)
    elevations = horizon_elevation_rad + (0.5 * np.pi - horizon_elevation_rad) * t * t
    elevations[0] += HORIZON_NUDGE
    return elevations


def camera_sky_rows(shape: TableShape, view_cos_zenith: ArrayLike, horizon_elevation_rad,
                    dtype: DTypeLike = np.float32) -> np.ndarray:
    """Fractional rows of :func:`camera_sky_elevations` for view zenith cosines, as the shader computes them:
    (N - 1) sqrt(max(asin(z) - e_h, 0) / (pi/2 - e_h)) (row 0 at and below the horizon)."""
    dt = np.dtype(dtype).type
    e_h = dt(horizon_elevation_rad)
    elevation = np.arcsin(np.clip(np.asarray(view_cos_zenith, dtype=dt), dt(-1), dt(1)))
    return (np.sqrt(np.maximum(elevation - e_h, dt(0)) / (dt(0.5 * np.pi) - e_h))
            * dt(shape.altitudes - 1)).astype(dt)


def horizon_elevation(camera_altitude_m: float, atm: Atmosphere) -> float:
    """Elevation of the horizon seen from altitude h_c, rad (<= 0): asin(:func:`horizon_cosine`)."""
    return math.asin(horizon_cosine(camera_altitude_m, atm))


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
    _, rayleigh, mie, nu = _phase_free_terms(tile, views, sun, length, atm, np.float64,
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
    azimuth = _azimuth_column(v, s, shape.sky_azimuths, dt)
    rayleigh = _linear_lookup(tile.camera_sky_rayleigh, azimuth, row, dt)
    mie = _linear_lookup(tile.camera_sky_mie, azimuth, row, dt)
    nu = np.einsum("...i,i->...", v, s)
    return (rayleigh + phase_hg(nu, atm.mie_g, dtype) * mie).astype(dt)


def sky_radiance(view_dir: ArrayLike, sun_dir: ArrayLike, atm: Atmosphere, *, camera_altitude_m: float = 0.0,
                 multiple_scattering: bool = True, ground_albedo=DEFAULT_GROUND_ALBEDO,
                 n_samples: int = 513) -> np.ndarray:
    """Sky radiance in W/(m^2 sr) per channel, (..., 3), along unit view directions ``view_dir`` (..., 3), z up.

    The Precise level's integrand along whole rays from a camera at ``camera_altitude_m`` (m, clamped at 0) to
    the atmosphere's top, or to the ground below the horizon (no ground reflection, no sun disk):

        L = E_top integral T_view(t) [(beta_R n_R Phi_R(nu) + beta_M n_M Phi_HG(nu, g)) T_sun
                                      + beta_R n_R S_R + beta_M n_M S_M] dt

    with nu = view . sun, T_sun from :class:`SunTransmittanceTable` (the planet's shadow included) and, with
    ``multiple_scattering``, the multiple scattering S_R, S_M of :class:`MultipleScatteringTable`
    (``ground_albedo``). Simpson's rule in w = sqrt(t / length) on ``n_samples`` (odd) samples, as the table
    cells of :func:`bake_tile`. What the comparison with Blender's own sky models uses
    (``tools/compare_sky_texture.py``): with ``multiple_scattering=False`` it is the brute-force single scattering
    of :mod:`.reference` with the sun's optical depth from a table instead of a march.
    """
    if n_samples < 3 or n_samples % 2 == 0:
        raise ValueError(f"n_samples must be odd and >= 3; got {n_samples}")
    given = np.asarray(view_dir, dtype=np.float64)
    views = given.reshape(-1, 3) / np.linalg.norm(given.reshape(-1, 3), axis=-1, keepdims=True)
    sun = np.asarray(sun_dir, dtype=np.float64)
    sun = sun / np.linalg.norm(sun)
    sun_table, ms_table = atmosphere_tables(atm, tuple(float(a) for a in ground_albedo))
    r_ground = atm.planet_radius
    r_c = r_ground + max(float(camera_altitude_m), 0.0)
    c = views[..., 2]
    length = sky_path_length(c, camera_altitude_m, atm)[0][..., None]                  # (..., 1)
    w = np.linspace(0.0, 1.0, n_samples)
    t = length * w * w                                                                  # (..., S)
    radius = np.sqrt(np.maximum(r_c * r_c + 2.0 * r_c * t * c[..., None] + t * t, 0.0))
    h = np.maximum(radius - r_ground, 0.0)
    n_r, n_m = np.exp(-h / atm.rayleigh_scale_height)[..., None], np.exp(-h / atm.mie_scale_height)[..., None]
    dt_dw = (2.0 * length * w)[..., None]                                               # (..., S, 1)
    f = local_extinction(atm, n_r, n_m, h) * dt_dw
    dw = w[1] - w[0]
    tau_to = np.concatenate([np.zeros_like(f[..., :1, :]),
                             np.cumsum(0.5 * (f[..., 1:, :] + f[..., :-1, :]) * dw, axis=-2)], axis=-2)
    nu = np.clip(views @ sun, -1.0, 1.0)[..., None]                                     # (..., 1)
    mu_s = (r_c * sun[2] + t * nu) / np.maximum(radius, 1.0)                            # sun zenith cosine
    sun_t = sun_table(radius, mu_s)                                                     # (..., S, 3)
    phase_r, phase_m = phase_rayleigh(nu)[..., None], phase_hg(nu, atm.mie_g)      # (N, 1, 1), (N, 1, 3)
    source = (atm.rayleigh_scattering * n_r * phase_r + atm.mie_scattering * n_m * phase_m) * sun_t
    if multiple_scattering:
        view_z = (r_c * c[..., None] + t) / np.maximum(radius, 1.0)
        view_x = (nu - mu_s * view_z) / np.sqrt(np.maximum(1.0 - mu_s * mu_s, 1e-12))
        s_r, s_m = ms_table.scattered(h, mu_s, view_z, view_x)
        source = source + atm.rayleigh_scattering * n_r * s_r + atm.mie_scattering * n_m * s_m
    weights = _simpson_weights(n_samples)[:, None] * dt_dw
    radiance = atm.sun_irradiance_top * np.sum(weights * np.exp(-tau_to) * source, axis=-2)
    return radiance.reshape(given.shape[:-1] + (3,))


def distance_to_top(cos_zenith: ArrayLike, camera_altitude_m: float, atm: Atmosphere,
                    dtype: DTypeLike = np.float64) -> np.ndarray:
    """Distance from the camera (altitude h_c, clamped at 0) along a ray with zenith cosine c = v_z to the top of
    the atmosphere, m, without cancellation in float32 (the shaders' arithmetic, node for node):

        K = (top - h_c)(2 R + top + h_c) = r_top^2 - r_c^2,   root = sqrt(K + (r_c c)^2)
        K / (r_c c + root)  for c >= 0,   root - r_c c  for c < 0       floored at 0

    (a camera above the top looking away from the atmosphere sees none of it); the denominator is floored at 1 m,
    which keeps the branch not taken finite and changes no real path.
    """
    dt = np.dtype(dtype).type
    c = np.asarray(cos_zenith, dtype=dt)
    radius, top = dt(atm.planet_radius), dt(atm.atmosphere_height)
    h_c = dt(max(float(camera_altitude_m), 0.0))
    r_c_c = (radius + h_c) * c
    top_term = (top - h_c) * (dt(2) * radius + top + h_c)
    root = np.sqrt(np.maximum(top_term + r_c_c * r_c_c, dt(0)))
    up = top_term / np.maximum(root + r_c_c, dt(1))
    return np.maximum(np.where(c < 0, root - r_c_c, up), dt(0)).astype(dt)


def sky_path_length(cos_zenith: ArrayLike, camera_altitude_m: float, atm: Atmosphere,
                    dtype: DTypeLike = np.float64) -> tuple[np.ndarray, np.ndarray]:
    """(length m, hits the ground) of the ray from the camera (altitude h_c, clamped at 0) with zenith cosine
    c = v_z: to the spherical ground where it meets it, else to the top (:func:`distance_to_top`). The ground
    without cancellation in float32 (the sky shader's arithmetic, node for node):

        G = h_c (2 R + h_c) = r_c^2 - R^2,   meets it where c < 0 and (r_c c)^2 >= G,
        at G / (sqrt(max((r_c c)^2 - G, 0)) - r_c c)

    (the denominator floored at 1 m like the top's: a ray that meets the ground has one of at least sqrt(G),
    5 km for a camera 2 m up).
    """
    dt = np.dtype(dtype).type
    c = np.asarray(cos_zenith, dtype=dt)
    radius = dt(atm.planet_radius)
    h_c = dt(max(float(camera_altitude_m), 0.0))
    r_c_c = (radius + h_c) * c
    ground_term = h_c * (dt(2) * radius + h_c)
    ground_disc = r_c_c * r_c_c - ground_term
    hits = (c < 0) & (ground_disc >= 0)
    to_ground = ground_term / np.maximum(np.sqrt(np.maximum(ground_disc, dt(0))) - r_c_c, dt(1))
    to_top = distance_to_top(c, camera_altitude_m, atm, dt)
    return np.maximum(np.where(hits, to_ground, to_top), dt(0)).astype(dt), hits


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
    return row.astype(dt), _azimuth_column(v, s, shape.azimuths, dt).astype(dt), column.astype(dt)


def sample(quantity: np.ndarray, row: np.ndarray, azimuth: np.ndarray, column: np.ndarray,
           dtype: DTypeLike = np.float32) -> np.ndarray:
    """A quantity (altitudes, azimuths, distances, 3) at fractional texel coordinates: bilinear in (row, column)
    within the two nearest azimuth slices (the texture filter), then linear between the slices."""
    dt = np.dtype(dtype).type
    q = np.asarray(quantity, dtype=dt)
    a0 = np.clip(np.floor(azimuth), 0, q.shape[1] - 2).astype(int)
    fa = (azimuth - a0).astype(dt)[..., None]
    low = _bilinear(q, row, column, a0)
    high = _bilinear(q, row, column, a0 + 1)
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
    f_ex, rayleigh, mie, nu = _phase_free_terms(tile, view_dir, sun_dir, distance_m, atm, dtype, row)
    light = phase_rayleigh(nu, dtype)[..., None] * rayleigh + phase_hg(nu, atm.mie_g, dtype) * mie
    return f_ex.astype(dt), light.astype(dt)


def _phase_free_terms(tile: Tile, view_dir: ArrayLike, sun_dir: ArrayLike, distance_m: ArrayLike, atm: Atmosphere,
                      dtype: DTypeLike, row: ArrayLike | None = None) -> tuple[np.ndarray, ...]:
    """:func:`evaluate`'s pieces before the phase functions: (F_ex, A_R (1 - F_ex), A_M (1 - F_ex), nu)."""
    dt = np.dtype(dtype).type
    views = np.asarray(view_dir, dtype=dt)
    to_top = distance_to_top(views[..., 2], float(tile.camera_radius_m - atm.planet_radius), atm, dt)
    d = np.minimum(np.maximum(np.asarray(distance_m, dtype=dt), dt(0)), to_top)
    row, azimuth, column = table_coordinates(tile, views, sun_dir, d, atm, dtype, row)
    extinction_per_m = _bilinear(np.asarray(tile.mean_extinction, dtype=dt), row, column)
    a_r = sample(tile.a_rayleigh, row, azimuth, column, dtype)
    a_m = sample(tile.a_mie, row, azimuth, column, dtype)
    nu = np.einsum("...i,i->...", views, np.asarray(sun_dir, dtype=dt))
    tau = extinction_per_m * d[..., None]
    f_ex = np.exp(-tau)
    one_minus_t = tau * one_minus_exp_over_x(tau, dtype)
    return f_ex, a_r * one_minus_t, a_m * one_minus_t, nu


# -- An animated camera or sun: key tiles along its path, blended ----------------------------------------------
#
# A tile is a function of the camera's altitude h_c and the sun's elevation e_s alone (the azimuths are the shader's),
# so a scene whose camera or sun moves traces a path in (h_c, e_s) over its frames. Instead of a tile per frame
# (1.5-2.5 s of baking and about 0.6 MB of .blend each, tools/bench_animation.py) the add-on bakes "key tiles" where
# the path has moved one step since the last key, and each frame blends the two keys around it, texel by texel: the
# shader's lookups are linear in the texels, so blending the texels is sampling :func:`blend_tiles`. The steps keep
# the blend's error at mid-step small (tools/measure_key_tiles.py -> docs/quality.md "Animation"): the sun's elevation
# moves 2 deg per key above 10 deg, 1 deg down to 3 deg, 0.5 deg below (twilight's light changes fastest); the
# camera's altitude a step of ln(1 + h / 300 m) of 0.35 (0 -> 125 m, 300 -> 570 m) until that step reaches 500 m (at
# 1.13 km), then 500 m (a step of 1.3 km at 3 km put steep rays to points about 1 km up out of the lower key's reach:
# 12.7 % at the 99th percentile on Mars, 2.8 % with 500 m). All key tiles of a path share the largest distance D, so
# the two keys' texels map the same rays.

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


# -- A still scene's sun moved: key tiles of its camera's altitude on the sun's key grid ----------------------------
#
# A still scene has one tile, baked for its sun's elevation, so a sun move needs a new one (0.3-0.4 s on 2 cores). In
# the interface the tile is baked on a worker thread after the last move (blender/apply/precise_tables.py), so during
# a drag the sky would stay where it was. The bank keeps key tiles of the camera's altitude at the sun elevations of
# the key grid (SUN_STEPS_DEG: whole units of path_coordinates' sun axis), baked around the sun on the worker once
# the exact tile is written: a move between two banked keys is shown at once as their blend (blend_tiles: the
# animation's mid-step error, docs/quality.md, at most), and the exact tile follows.

#: The grid's last key: the sun at the zenith.
SUN_KEY_UNITS = int(round(float(path_coordinates(0.0, math.pi / 2.0)[0])))
#: Key tiles the bank keeps (about 0.85 MB each): the keys around a sun, for a few atmospheres and cameras.
BANK_TILES = 24
_BANK: collections.OrderedDict = collections.OrderedDict()
_BANK_LOCK = threading.Lock()


def sun_key_elevation(unit: int) -> float:
    """The sun elevation of key ``unit`` of the grid, rad: the inverse of :func:`path_coordinates`' sun axis at a
    whole unit (0 at -90 deg, :data:`SUN_KEY_UNITS` at the zenith)."""
    remaining = float(min(max(int(unit), 0), SUN_KEY_UNITS))
    ceiling = 90.0
    bands = []
    for floor, step in SUN_STEPS_DEG:              # highest first, as path_coordinates reads them
        bands.append((floor, ceiling, step))
        ceiling = floor
    for floor, ceiling, step in reversed(bands):   # from the nadir up
        width = (ceiling - floor) / step
        if remaining <= width or ceiling >= 90.0:
            return math.radians(min(floor + remaining * step, 90.0))
        remaining -= width
    raise AssertionError("unreachable: the top band ends at the zenith")


def sun_key_bracket(sun_elevation_rad: float) -> tuple[int, float]:
    """(k, w): the sun lies between keys k and k + 1 of the grid, at weight w in [0, 1] (linear in the grid's unit,
    as :func:`key_tiles` weighs a frame between its keys)."""
    x = float(path_coordinates(0.0, float(sun_elevation_rad))[0])
    k = min(max(int(math.floor(x)), 0), SUN_KEY_UNITS - 1)
    return k, float(np.clip(x - k, 0.0, 1.0))


def bank_units_around(sun_elevation_rad: float, count: int) -> list[int]:
    """The ``count`` keys of the grid nearest the sun (at least the two around it): those two first, then outward,
    the lower side first at each distance."""
    k, _ = sun_key_bracket(sun_elevation_rad)
    units = [k, k + 1]
    below, above = k - 1, k + 2
    while len(units) < count and (below >= 0 or above <= SUN_KEY_UNITS):
        for unit in (below, above):
            if 0 <= unit <= SUN_KEY_UNITS and len(units) < count:
                units.append(unit)
        below, above = below - 1, above + 1
    return units


def bank_key(atm: Atmosphere, camera_altitude_m: float, unit: int, *, multiple_scattering: bool = True,
             ground_albedo=DEFAULT_GROUND_ALBEDO, shape: TableShape = DEFAULT_SHAPE) -> tuple:
    """What names key ``unit`` in the bank (the worker's jobs are named by it too): (atmosphere, camera altitude,
    unit, multiple scattering, ground albedo, shape)."""
    return (atm, float(camera_altitude_m), int(unit), bool(multiple_scattering),
            tuple(float(a) for a in ground_albedo), shape)


def bank_tile(atm: Atmosphere, camera_altitude_m: float, unit: int, *, multiple_scattering: bool = True,
              ground_albedo=DEFAULT_GROUND_ALBEDO, shape: TableShape = DEFAULT_SHAPE,
              stop: threading.Event | None = None) -> Tile | None:
    """Key ``unit`` of the sun's grid for a camera at ``camera_altitude_m`` (its own largest distance, as a still
    scene's tile): the bank's, or integrated (:func:`integrate_tile`) and kept (the last :data:`BANK_TILES`); None
    when ``stop`` was set meanwhile (nothing kept). Thread-safe: the worker thread fills the bank while the main
    thread reads it."""
    key = bank_key(atm, camera_altitude_m, unit, multiple_scattering=multiple_scattering,
                   ground_albedo=ground_albedo, shape=shape)
    with _BANK_LOCK:
        if key in _BANK:
            _BANK.move_to_end(key)
            return _BANK[key]
    try:
        tile = integrate_tile(atm, camera_altitude_m, sun_key_elevation(unit),
                              multiple_scattering=multiple_scattering, ground_albedo=ground_albedo, shape=shape,
                              stop=stop)
    except TileCancelled:
        return None
    with _BANK_LOCK:
        _BANK[key] = _frozen(tile)
        while len(_BANK) > BANK_TILES:
            _BANK.popitem(last=False)
    return tile


def banked(atm: Atmosphere, camera_altitude_m: float, unit: int | None = None, *, multiple_scattering: bool = True,
           ground_albedo=DEFAULT_GROUND_ALBEDO, shape: TableShape = DEFAULT_SHAPE) -> bool:
    """True when the bank holds key ``unit`` for this camera altitude and atmosphere (``unit`` None: any key)."""
    options = {"multiple_scattering": multiple_scattering, "ground_albedo": ground_albedo, "shape": shape}
    if unit is not None:
        with _BANK_LOCK:
            return bank_key(atm, camera_altitude_m, unit, **options) in _BANK
    base = bank_key(atm, camera_altitude_m, 0, **options)
    with _BANK_LOCK:
        return any(key[:2] + key[3:] == base[:2] + base[3:] for key in _BANK)   # any unit


def tile_from_bank(atm: Atmosphere, camera_altitude_m: float, sun_elevation_rad: float, *,
                   multiple_scattering: bool = True, ground_albedo=DEFAULT_GROUND_ALBEDO,
                   shape: TableShape = DEFAULT_SHAPE) -> Tile | None:
    """The blend (:func:`blend_tiles`) of the bank's two keys around the sun, or None when either is not banked
    (nothing is integrated here)."""
    k, weight = sun_key_bracket(sun_elevation_rad)
    keys = [bank_key(atm, camera_altitude_m, unit, multiple_scattering=multiple_scattering,
                     ground_albedo=ground_albedo, shape=shape) for unit in (k, k + 1)]
    with _BANK_LOCK:
        if not all(key in _BANK for key in keys):
            return None
        first, second = (_BANK[key] for key in keys)
    return blend_tiles(first, second, weight, camera_altitude_m, atm)


#: Rec. 709 luminance weights (Blender's default scene-linear space), for the blend's error.
_LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def mid_step_error(atm: Atmosphere, first: tuple[float, float], second: tuple[float, float], *, rays: int = 4000,
                   multiple_scattering: bool = True) -> dict[str, tuple[float, float]]:
    """How far the blend of two key tiles is from the tile baked where it is used, at the worst place, half way:
    keys at ``first`` and ``second`` (camera altitude m, sun elevation rad), sharing D, blended with w = 1/2
    (:func:`blend_tiles`) against :func:`bake_tile` at the mid inputs. Relative luminance errors (median, 99th
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
