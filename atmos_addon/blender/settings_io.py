# SPDX-License-Identifier: GPL-3.0-or-later
"""``scene.atmos`` <-> the physics :class:`Atmosphere`: the one place that maps fields and units.

The settings store scattering coefficients in 1/km (readable in the interface); the physics core
works in 1/m. Writing many settings at once (a preset, the API) is batched so the scene is synced
once, not once per property.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import numpy as np

from ..physics import Atmosphere

#: Names of scenes whose settings are being written as a batch (their update callbacks wait).
_batched: set[str] = set()

#: (settings property, Atmosphere field, factor from the Atmosphere's unit to the property's unit).
FIELD_MAP: tuple[tuple[str, str, float], ...] = (
    ("rayleigh_scattering_per_km", "rayleigh_scattering", 1000.0),
    ("mie_scattering_per_km", "mie_scattering", 1000.0),
    ("mie_absorption_per_km", "mie_absorption", 1000.0),
    ("mie_g", "mie_g", 1.0),
    ("rayleigh_scale_height", "rayleigh_scale_height", 1.0),
    ("mie_scale_height", "mie_scale_height", 1.0),
    ("planet_radius", "planet_radius", 1.0),
    ("atmosphere_height", "atmosphere_height", 1.0),
    ("sun_irradiance_top", "sun_irradiance_top", 1.0),
    ("wavelengths_nm", "wavelengths_nm", 1.0),
)


def is_batched(scene) -> bool:
    """True while :func:`batch` holds the scene's updates back."""
    return scene.name in _batched


@contextlib.contextmanager
def batch(scene) -> Iterator[None]:
    """Write several settings of ``scene`` with one sync at the end (when the effect is enabled)."""
    if scene.name in _batched:
        yield
        return
    _batched.add(scene.name)
    try:
        yield
    finally:
        _batched.discard(scene.name)
    if scene.atmos.enabled:
        from . import sync

        sync.sync_scene(scene)


def atmosphere_from_settings(settings) -> Atmosphere:
    """The physics :class:`Atmosphere` that ``scene.atmos`` describes (1/km -> 1/m)."""
    values = {}
    for prop, field, factor in FIELD_MAP:
        value = np.asarray(getattr(settings, prop), dtype=float) / factor
        values[field] = value if value.ndim else float(value)
    return Atmosphere(**values)


def apply_atmosphere(scene, atm: Atmosphere) -> None:
    """Write every field of ``atm`` into ``scene.atmos`` (one sync at the end)."""
    settings = scene.atmos
    with batch(scene):
        for prop, field, factor in FIELD_MAP:
            value = np.asarray(getattr(atm, field), dtype=float) * factor
            setattr(settings, prop, tuple(value.tolist()) if value.ndim else float(value))
