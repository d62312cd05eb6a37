# SPDX-License-Identifier: GPL-3.0-or-later
"""The Precise quality level: single scattering integrated numerically, plus multiple scattering, baked into a
camera-centred table that the shader samples.

Why a camera-centred table
    For one frame the camera (altitude h_c) and the sun (elevation e_s) are fixed. A camera ray is then fixed by its
    elevation e, its azimuth a from the sun's azimuth (0..pi, mirror-symmetric) and the distance d to the surface it
    hits, so every aerial-perspective quantity is a function of (e, a, d): a 3-D table per frame, with no
    subtraction of two long-ray lookups (Bruneton 2008's S(x) - T S(p), which cancels for near objects) and no
    per-pixel march. An animated camera or sun gets key tiles along its path, blended per frame, all in one image the
    .blend carries, so a farm renders it without Python.

What the table holds, per colour channel (rays start at the camera, t in m along the unit direction v, nu = v . l)
    tau / d (1/m), F_ex = exp(-tau), and A_R, A_M: the in-scattered light divided by 1 - exp(-tau), the multiple
    scattering folded into A_R, so that the shader forms L_in = [Phi_R(nu) A_R + Phi_HG(nu, g) A_M] (1 - exp(-tau)).

The parts, each module's docstring has its equations and sources:
    * ``layout``: the table's axes (target-altitude rows, azimuth slices, each row's distance columns), the ray
      geometry over a spherical planet, and :class:`Tile`, one frame's table as the image holds it;
    * ``transmittance``: the local extinction and the sun's transmittance table (Chapman's function);
    * ``directions``, ``sun_nodes``, ``rays``, ``solver``, ``scattering``: the multiple-scattering table, every
      order of the light scattered at least once (Hillaire 2020 extended: the first two orders by direction, the rest
      a P1 field with delta-Eddington, one GMRES solve), and what a view ray in-scatters of it;
    * ``tables``: the per-atmosphere tables, cached (and kept in a :class:`TableStore`);
    * ``integrals``: the integrals along straight rays that fill a tile's cells, and the brute-force sky;
    * ``bake``: one frame's tile (:func:`bake_tile`, :func:`integrate_tile`), on ``parallel``'s threads;
    * ``lookup``, ``sky_blocks``: the shader's sampling step by step (:func:`evaluate`, :func:`sky_from_tile`) and
      the tile's two sky views;
    * ``animation``: key tiles along an animated camera's or sun's path, and their blend;
    * ``bank``: key tiles on the sun's grid, so that a still scene's sun move shows at once.

Units: lengths m, angles rad, coefficients 1/m, E_top and radiances W/m^2 (per sr for radiances) in Blender's
sun-strength unit.
"""

from .animation import (ALTITUDE_MAX_STEP_M, ALTITUDE_SCALE_M, ALTITUDE_STEP, KeyTiles, blend_tiles, key_tiles,
                        mid_step_error, path_coordinates, shared_max_distance)
from .bake import TileCancelled, bake_tile, integrate_tile
from .bank import (SUN_KEY_UNITS, bank_key, bank_tile, bank_units_around, banked, sun_key_bracket, sun_key_elevation,
                   tile_from_bank)
from .directions import grid_cut_deg, grid_forward_fraction
from .integrals import ray_inscattering, ray_integrals, sky_radiance
from .layout import (DEFAULT_SHAPE, TableShape, Tile, camera_sky_elevations, camera_sky_rows, cell_distances,
                     column_power, distance_to_top, horizon_cosine, horizon_elevation, max_distance, row_altitudes,
                     sky_path_length, sky_view_cosines, sky_view_rows, target_altitude)
from .lookup import evaluate, sample, sky_from_tile, table_coordinates
from .scattering import DEFAULT_GROUND_ALBEDO, MultipleScatteringTable
from .sky_blocks import camera_sky_from_tile, camera_sky_view, lighting_from_tile, sky_view
from .sun_nodes import SunCosineNodes
from .tables import PREVIEW_RESOLUTION, TableStore, atmosphere_tables, current_store, tables_ready, use_store
from .transmittance import SunTransmittanceTable

__all__ = [
    "ALTITUDE_MAX_STEP_M", "ALTITUDE_SCALE_M", "ALTITUDE_STEP", "DEFAULT_GROUND_ALBEDO", "DEFAULT_SHAPE",
    "PREVIEW_RESOLUTION", "SUN_KEY_UNITS", "KeyTiles", "MultipleScatteringTable", "SunCosineNodes",
    "SunTransmittanceTable", "TableShape", "TableStore", "Tile", "TileCancelled", "atmosphere_tables", "bake_tile",
    "bank_key", "bank_tile", "bank_units_around", "banked", "blend_tiles", "camera_sky_elevations",
    "camera_sky_from_tile", "camera_sky_rows", "camera_sky_view", "cell_distances", "column_power", "current_store",
    "distance_to_top", "evaluate", "grid_cut_deg", "grid_forward_fraction", "horizon_cosine", "horizon_elevation",
    "integrate_tile", "key_tiles", "lighting_from_tile", "max_distance", "mid_step_error", "path_coordinates",
    "ray_inscattering", "ray_integrals", "row_altitudes", "sample", "shared_max_distance", "sky_from_tile",
    "sky_path_length", "sky_radiance", "sky_view", "sky_view_cosines", "sky_view_rows", "sun_key_bracket",
    "sun_key_elevation", "table_coordinates", "tables_ready", "target_altitude", "tile_from_bank", "use_store",
]
