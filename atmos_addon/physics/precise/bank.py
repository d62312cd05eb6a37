# SPDX-License-Identifier: GPL-3.0-or-later
"""A still scene's sun moved: key tiles of its camera's altitude on the sun's key grid (the bank).

A still scene has one tile, baked for its sun's elevation, so a sun move needs a new one (0.3-0.4 s on 2 cores). In
the interface the tile is baked on a worker thread after the last move (blender/apply/precise_tables.py), so during
a drag the sky would stay where it was. The bank keeps key tiles of the camera's altitude at the sun elevations of
the key grid (``animation.SUN_STEPS_DEG``: whole units of ``animation.path_coordinates``' sun axis), baked around the
sun on the worker once the exact tile is written: a move between two banked keys is shown at once as their blend
(``animation.blend_tiles``: the animation's mid-step error, docs/quality.md, at most), and the exact tile follows.
"""

from __future__ import annotations

import collections
import math
import threading

import numpy as np

from ..atmosphere import Atmosphere
from . import bake
from .animation import SUN_STEPS_DEG, blend_tiles, path_coordinates
from .layout import DEFAULT_SHAPE, TableShape, Tile
from .scattering import DEFAULT_GROUND_ALBEDO


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
    scene's tile): the bank's, or integrated (``bake.integrate_tile``) and kept (the last :data:`BANK_TILES`); None
    when ``stop`` was set meanwhile (nothing kept). Thread-safe: the worker thread fills the bank while the main
    thread reads it."""
    key = bank_key(atm, camera_altitude_m, unit, multiple_scattering=multiple_scattering,
                   ground_albedo=ground_albedo, shape=shape)
    with _BANK_LOCK:
        if key in _BANK:
            _BANK.move_to_end(key)
            return _BANK[key]
    try:
        tile = bake.integrate_tile(atm, camera_altitude_m, sun_key_elevation(unit),
                                   multiple_scattering=multiple_scattering, ground_albedo=ground_albedo, shape=shape,
                                   stop=stop)
    except bake.TileCancelled:
        return None
    with _BANK_LOCK:
        _BANK[key] = bake.frozen_tile(tile)
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
