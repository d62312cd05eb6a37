# SPDX-License-Identifier: GPL-3.0-or-later
"""Settings saved by an older Atmos, read as they were written: a file renders as it did when it was saved.

Blender writes a property into a file only once it has been set; one never set reads as the *current* default. So
when a default changes, a scene saved earlier with the effect on would silently switch to the new default (and, for
the quality, rebuild its node groups and look different). Two rules keep every file as it was:

- :func:`pin_defaults`: enabling writes the settings whose defaults ever changed explicitly, so a file saved from
  now on carries the values it renders with, whatever later defaults become.
- :func:`restore_former_defaults`: after a file loads, a scene with the effect on whose such setting was never set
  was saved before the default changed, so it gets the default it was saved under (:data:`FORMER_DEFAULTS`).

A retired choice is upgraded in place (:func:`upgrade_retired_settings`): the Balanced quality level opens as
Fast, which shares Balanced's sky (the virtual dome), so the file's sky and its other scenes stay as they were and
only the haze's density profile changes (Precise would re-make the sky: the sky groups are shared by the scenes of
a file, and the Precise sky is another model).
"""

from __future__ import annotations

from ..node_groups import parameters
from ..physics import rayleigh_coefficients
from ..physics.atmosphere import SEED_SUN_IRRADIANCE_TOP, SEED_WAVELENGTHS_NM
from ..plan import RETIRED_BALANCED_NOTE

#: Settings whose default changed, with the default a file saved before the change was made with (CHANGELOG.md
#: has when): the level was Fast without multiple scattering or ozone (now Precise with both and 300 DU); the
#: channels stood for 680, 550, 440 nm with a white sun of 4.5 (now the solar spectrum's channels and colour); the
#: mode was Compositor (now Per Pixel); the haze was grey, 0.033/km scattering and 0.0033/km absorption, under no
#: preset name (now the Clear preset's haze, and its name).
FORMER_DEFAULTS = {"render_mode": "COMPOSITOR", "quality": "FAST", "multiple_scattering": False,
                   "ozone_column_du": 0.0, "wavelengths_nm": SEED_WAVELENGTHS_NM,
                   "rayleigh_scattering_per_km": tuple(float(v) for v in rayleigh_coefficients(SEED_WAVELENGTHS_NM)
                                                       * 1000.0),
                   "sun_irradiance_top": (SEED_SUN_IRRADIANCE_TOP,) * 3,
                   "mie_scattering_per_km": (0.033,) * 3, "mie_absorption_per_km": (0.0033,) * 3,
                   "preset_name": ""}


def pin_defaults(settings) -> None:
    """Write the current value of every setting in :data:`FORMER_DEFAULTS` that ``settings`` (a scene's ``atmos``)
    has not set. The values do not change; the caller holds the update callbacks back
    (``orchestrator.held``)."""
    for name in FORMER_DEFAULTS:
        if not settings.is_property_set(name):
            setattr(settings, name, getattr(settings, name))


def restore_former_defaults(settings) -> list[str]:
    """For a scene's ``atmos`` settings with the effect on, loaded from a file: the settings of
    :data:`FORMER_DEFAULTS` it never set get the default it was saved under. Returns their names (none for a file
    saved by this version, or with the effect off). The caller holds the update callbacks back
    (``orchestrator.held``) and updates the scene afterwards (the load handler re-syncs every scene)."""
    if not settings.enabled:
        return []
    restored = [name for name in FORMER_DEFAULTS if not settings.is_property_set(name)]
    for name in restored:
        setattr(settings, name, FORMER_DEFAULTS[name])
    return restored


#: The number a file stores for the retired Balanced quality level (the Quality enum's items are numbered).
RETIRED_BALANCED = 1
#: The Quality a scene saved at Balanced opens with: Fast, Balanced's sky and single scattering with a constant
#: density along the ray (against every scattering order both were 48-89 % dark by day: Precise with Multiple
#: Scattering is the complete atmosphere, the artist's choice to make).
BALANCED_UPGRADE = "FAST"


def upgrade_retired_settings(scene) -> list[str]:
    """Upgrade a loaded ``scene``'s retired choices in place (whether the effect is on or off): a Quality saved as
    Balanced becomes :data:`BALANCED_UPGRADE`, Auto's remembered "balanced" choice "fast" (Auto chooses again on
    the next Refresh), and the Balanced level's shader parameters go (``parameters.clear_retired_parameters``; the
    effect on only, which owns them). Returns one sentence per scene changed (none for a file saved by this
    version). The caller holds the update callbacks back and re-syncs afterwards."""
    settings = scene.atmos
    notes = []
    if settings.is_property_set("quality") and settings.get("quality") == RETIRED_BALANCED:
        settings.quality = BALANCED_UPGRADE
        notes.append(f"Atmos: scene '{scene.name}': {RETIRED_BALANCED_NOTE}; it opens at Fast, with the same sky "
                     "(Precise with Multiple Scattering is the complete atmosphere)")
    if settings.auto_level == "balanced":
        settings.auto_level = "fast"
    if settings.enabled:
        parameters.clear_retired_parameters(scene)
    return notes
