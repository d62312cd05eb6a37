# SPDX-License-Identifier: GPL-3.0-or-later
"""The per-atmosphere tables (sun transmittance, multiple scattering), built once and kept: they change with the
atmosphere's parameters and the ground's albedo only, never with the sun or the camera. A preview build at half the
resolution (:data:`PREVIEW_RESOLUTION`) serves the interface's first look after an edit, and a :class:`TableStore`
beyond the process (the tests' folder) can keep what is built.
"""

from __future__ import annotations

import collections
import threading
from collections.abc import Callable
from typing import Protocol

from ..atmosphere import Atmosphere
from .scattering import DEFAULT_GROUND_ALBEDO, MultipleScatteringTable
from .transmittance import SunTransmittanceTable


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
