# SPDX-License-Identifier: GPL-3.0-or-later
"""Limits of Blender itself that make an Atmos render look broken, measured, with the line that tells the user.

Eevee's world: with the camera's clip end / clip start above about 2^24 (1.7e7), Eevee renders the whole world
one flat colour, Blender's own Sky Texture as well as the Atmos sky (float32 precision of the projection:
1 + 2 clip_start / clip_end rounds to 1). Measured with ``tools/measure_eevee_clip_range.py`` (Eevee, bpy 4.5.15,
5.2.3 and 5.3.0): every clip start from 1 mm to 10 m renders the sky up to a ratio of 1.6e7; from 1.8e7 (clip
start 0.5 m and 1 m) and 2.2e7 (0.1 m) the sky is one colour. Atmos warns above :data:`EEVEE_CLIP_RATIO_LIMIT`
and never sets a larger ratio itself.
"""

from __future__ import annotations

#: The largest clip end / clip start ratio at which Eevee's world rendered correctly for every clip start measured.
EEVEE_CLIP_RATIO_LIMIT = 1.6e7
EEVEE_ENGINES = frozenset({"BLENDER_EEVEE", "BLENDER_EEVEE_NEXT"})


def clip_ratio(camera) -> float | None:
    """clip end / clip start of a perspective or orthographic camera object, None for anything else."""
    if camera is None or camera.type != "CAMERA" or camera.data.clip_start <= 0.0:
        return None
    return float(camera.data.clip_end) / float(camera.data.clip_start)


def largest_clip_end(camera) -> float:
    """The largest clip end (scene units) that keeps ``camera`` within :data:`EEVEE_CLIP_RATIO_LIMIT` (less one part
    in 10^6, so the float32 it is stored as stays within)."""
    return float(camera.data.clip_start) * EEVEE_CLIP_RATIO_LIMIT * (1.0 - 1e-6)


def clip_range_warning(scene) -> str | None:
    """One line when ``scene`` renders with Eevee and its camera's clip range flattens Eevee's world; else None."""
    ratio = clip_ratio(scene.camera)
    if scene.render.engine not in EEVEE_ENGINES or ratio is None or ratio <= EEVEE_CLIP_RATIO_LIMIT:
        return None
    needed_m = largest_clip_start_needed(scene.camera) * float(scene.unit_settings.scale_length)
    return (f"Camera '{scene.camera.name}': Clip End / Clip Start is {ratio:.2g}, over Eevee's limit of "
            f"{EEVEE_CLIP_RATIO_LIMIT:.2g}, so Eevee renders the sky one flat colour: raise Clip Start to at least "
            f"{needed_m:.3g} m (or lower Clip End)")


def largest_clip_start_needed(camera) -> float:
    """The smallest clip start (scene units) that brings ``camera``'s clip end within the limit."""
    return float(camera.data.clip_end) / EEVEE_CLIP_RATIO_LIMIT
