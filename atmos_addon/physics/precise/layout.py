# SPDX-License-Identifier: GPL-3.0-or-later
"""The camera-centred table's layout: its axes, the geometry that maps a ray to them, and the :class:`Tile` that
holds one frame's table (the add-on's image layout, :meth:`Tile.pixels`).

Geometry (spherical planet, radius R): the camera at radius r_c = R + h_c; a point at distance t along a ray of
elevation e has radius r(t) = sqrt(r_c^2 + 2 r_c t sin e + t^2). The horizon from altitude h_c has zenith cosine
-sqrt(h_c (2 R + h_c)) / (R + h_c) (:func:`horizon_cosine`); a ray's length to the top or the ground is found
without cancellation in float32 (:func:`distance_to_top`, :func:`sky_path_length`, node for node the shaders').

Table axes (:class:`TableShape`)
    * target-altitude rows: the altitude h_p of the point the ray reaches, h_j = top (j / (N_h - 1))^3
      (:func:`row_altitudes`; dense near the ground, where the haze and most surfaces are); the ray's elevation
      follows from the triangle (r_c, r_p, d) (``bake.integrate_tile``), so a row holds every ray ending at that
      altitude;
    * azimuth slices, a = pi j / (N_a - 1) from the sun's azimuth, interpolated linearly (the shader's manual blend);
    * distance columns, each row's own (:func:`cell_distances`): d_k = d_min + (D - d_min) (k / (N_d - 1))^p from
      the shortest ray that reaches the row, d_min = |h_p - h_c| (the vertical one), to D, the longest ray that
      stays above the ground inside the atmosphere (:func:`max_distance`), d beyond D clamped; the power p
      (:func:`column_power`) goes from 3 at the ground's row (columns crowded near the camera: 35 m, 280 m,
      940 m... at D = 1000 km) to 2 at the top's (the sky's long rays near the horizon). So every cell is a ray that
      ends at its row's altitude, and the cells next to a steep ray are steep rays too. With the same columns for
      every row, D (k / (N_d - 1))^2, a steep ray's neighbours are a vertical ray cut short and rays of far lower
      elevation, whose multiply scattered light differs (rays to points kilometres up on Mars 14-17 % of the horizon
      sky off at the 99th percentile, against 2.5-9.0 % with each row's own columns, measured against the integrals
      along each ray: docs/quality.md). The key tiles of a camera whose frames blend keys of different altitudes use
      those shared columns (:attr:`Tile.vertical_columns` False): two keys' texels then map rays of one length.
Within one azimuth slice the shader blends (row, column) bilinearly from four unfiltered texels.

After the aerial blocks a tile holds two sky views (``sky_blocks``), each with the tile's row count: the sky by view
zenith cosine, rows crowded at the horizon on both sides of it (:func:`sky_view_cosines`), and the camera's sky above
the horizon by elevation (:func:`camera_sky_elevations`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

from ..atmosphere import Atmosphere


@dataclass(frozen=True)
class TableShape:
    """Sample counts of the camera-centred table: target-altitude rows, azimuth slices, distance columns."""

    altitudes: int = 65
    azimuths: int = 8
    distances: int = 32
    #: Azimuth columns of the sky-view block (``sky_blocks.sky_view``); its rows are the tile's rows.
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
        """First column of the camera's sky view (``sky_blocks.camera_sky_view``): after the sky view's radiance columns
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
    #: The sky view (``sky_blocks.sky_view``): radiance W/(m^2 sr), (altitudes rows, sky azimuths, 3), and the ground's
    #: transmittance (altitudes rows, 3); None until :func:`integrate_tile` adds them.
    sky_radiance: np.ndarray | None = None
    sky_ground_transmittance: np.ndarray | None = None
    #: The camera's sky view (``sky_blocks.camera_sky_view``): the Rayleigh in-scattering (its phase function
    #: included) and the Mie in-scattering without its phase function, per view direction above the horizon,
    #: W/(m^2 sr), each (altitudes rows, sky azimuths, 3); None until :func:`integrate_tile` adds them.
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


def horizon_cosine(camera_altitude_m: float, atm: Atmosphere) -> float:
    """Zenith cosine of the horizon seen from altitude h_c (clamped at 0): -sqrt(h_c (2 R + h_c)) / (R + h_c)."""
    h_c = max(float(camera_altitude_m), 0.0)
    return -math.sqrt(h_c * (2.0 * atm.planet_radius + h_c)) / (atm.planet_radius + h_c)


#: How far beyond the horizon the sky view's two horizon rows are evaluated (zenith cosine): each row holds its own
#: side's ray (the ground's tangent ray, the sky's grazing one), never the other's.
HORIZON_NUDGE = 1e-9


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
