# SPDX-License-Identifier: GPL-3.0-or-later
"""``scene.atmos`` <-> the physics :class:`Atmosphere`: the one place that maps fields and units.

The settings store scattering coefficients in 1/km (readable in the interface); the physics core works in 1/m.
Writing many settings at once is batched by :func:`.orchestrator.batch` (one update, not one per property).
"""

from __future__ import annotations

import numpy as np

from ..physics import Atmosphere

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
    ("ozone_column_du", "ozone_column_du", 1.0),
)


def atmosphere_from_settings(settings) -> Atmosphere:
    """The physics :class:`Atmosphere` that ``scene.atmos`` describes (1/km -> 1/m)."""
    values = {}
    for prop, field, factor in FIELD_MAP:
        value = np.asarray(getattr(settings, prop), dtype=float) / factor
        values[field] = value if value.ndim else float(value)
    return Atmosphere(**values)


def write_atmosphere(settings, atm: Atmosphere) -> None:
    """Write every field of ``atm`` into ``scene.atmos`` (each write runs its update callback: batch them with
    :func:`.orchestrator.batch`, or use :func:`.orchestrator.apply_atmosphere`)."""
    for prop, field, factor in FIELD_MAP:
        value = np.asarray(getattr(atm, field), dtype=float) * factor
        setattr(settings, prop, tuple(value.tolist()) if value.ndim else float(value))
