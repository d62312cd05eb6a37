# SPDX-License-Identifier: GPL-3.0-or-later
"""The quality level a scene renders with: the user's choice, or Auto's from a summary of the scene.

Auto (``physics.quality.choose_level``) needs what the bench cases are told apart by: the camera's altitude
range over the frame range, the altitude span of the geometry, the farthest geometry from the camera, the sun's
elevation and whether it moves, whether the haze and its absorption are zero, and the planet. :func:`summarize`
reads them from the scene (lengths in m: scene units times metres per unit, plus the origin altitude);
:func:`resolve` stores the choice in ``scene.atmos.auto_level`` and a status line, and returns the action's plan at the
chosen level. It runs on enable, Refresh and a change of the quality setting, not per slider drag (the summary walks
every object's bounding box).
"""

from __future__ import annotations

import math

import numpy as np
from mathutils import Vector

from ..physics.quality import Level, SceneSummary, choose_level, level_summary, nearest_cases
from ..plan import NOTE_IN_RENDER_FAST, Plan
from . import scene_reading

#: Object types with geometry the camera sees (their bounding boxes count for the summary).
GEOMETRY_TYPES = frozenset({"MESH", "CURVE", "SURFACE", "META", "FONT", "VOLUME", "POINTCLOUD", "CURVES"})
#: Frames sampled for an animated camera (start, end and evenly between).
CAMERA_SAMPLES = 5


def _camera_heights(scene, camera) -> list[float]:
    """World z of the camera (scene units) at the current frame, or over the frame range when it moves (the camera a
    marker switches to at each sampled frame: ``scene.camera`` then)."""
    if not scene_reading.camera_moves(scene):
        return [camera.matrix_world.translation.z]
    current, subframe = scene.frame_current, scene.frame_subframe
    start, end = scene.frame_start, scene.frame_end
    frames = sorted({round(start + (end - start) * i / (CAMERA_SAMPLES - 1)) for i in range(CAMERA_SAMPLES)})
    heights = []
    try:
        for frame in frames:
            scene.frame_set(frame)
            heights.append((scene.camera or camera).matrix_world.translation.z)
    finally:
        scene.frame_set(current, subframe=subframe)
    return heights


def _geometry_corners(scene) -> np.ndarray:
    """World-space bounding-box corners of every visible geometry object, (n, 3) in scene units."""
    corners = []
    for obj in scene.objects:
        if obj.type not in GEOMETRY_TYPES or obj.hide_render:
            continue
        matrix = obj.matrix_world
        corners.extend(tuple(matrix @ Vector(corner)) for corner in obj.bound_box)
    return np.array(corners, dtype=np.float64).reshape(-1, 3)


def summarize(scene) -> SceneSummary:
    """The :class:`~atmos_addon.physics.quality.SceneSummary` of ``scene`` (lengths m, angles deg)."""
    settings = scene.atmos
    if len(scene.view_layers):
        scene.view_layers[0].update()  # objects moved by a script since the last evaluation: current matrices
    metres = scene_reading.metres_per_unit(scene)
    origin = float(settings.origin_altitude)
    camera = scene.camera
    heights = [origin + z * metres for z in _camera_heights(scene, camera)] if camera is not None else [origin]
    corners = _geometry_corners(scene)
    if len(corners) and camera is not None:
        span = float(np.ptp(corners[:, 2])) * metres
        position = np.array(camera.matrix_world.translation)
        farthest = float(np.max(np.linalg.norm(corners - position, axis=1)))
        if camera.type == "CAMERA":
            farthest = min(farthest, float(camera.data.clip_end))
        distance = farthest * metres
    else:
        span, distance = 0.0, 0.0
    direction, _ = scene_reading.sun_direction(scene)
    elevation = math.degrees(math.asin(float(np.clip(direction[2], -1.0, 1.0))))
    atmosphere = scene_reading.atmosphere_of(scene)
    return SceneSummary(camera_altitude_range_m=(min(heights), max(heights)), geometry_altitude_span_m=span,
                        max_view_distance_m=distance, sun_elevation_deg=elevation,
                        mie_zero=not np.any(atmosphere.mie_scattering > 0.0),
                        sun_animated=scene_reading.is_sun_animated(scene), planet_radius_m=atmosphere.planet_radius)


def resolve(scene, plan: Plan) -> Plan:
    """Resolve Auto for ``scene`` (summary, choice, status line); ``plan``: the scene's plan before. Returns the plan
    at the level the settings now ask for (Auto's choice made).

    In-Render mode builds its ray-segment graph with Fast whatever the level (a reflected ray does not start
    at the camera, around which the Precise table is baked); the status line says so.
    """
    settings = scene.atmos
    _resolve(scene, settings, plan.mode)
    resolved = plan.with_facts(auto_level=settings.auto_level)
    if NOTE_IN_RENDER_FAST in resolved.notes:
        scene_reading.set_if_changed(settings, "status_quality", f"{settings.status_quality}. {NOTE_IN_RENDER_FAST}")
    return resolved


def _resolve(scene, settings, mode: str) -> None:
    if settings.quality != "AUTO":
        level = Level(settings.quality.lower())
        summary = level_summary(level, settings.multiple_scattering, mode)
        line = f"{settings.quality.capitalize()}: {summary}"
        scene_reading.set_if_changed(settings, "status_quality", line)
        return
    summary = summarize(scene)
    level, error = choose_level(summary, tolerance=settings.auto_tolerance / 100.0)
    situations = ", ".join(name.replace("_", " ") for name in nearest_cases(summary))
    over = "" if error <= settings.auto_tolerance / 100.0 else f", over {settings.auto_tolerance:g} %"
    line = f"Auto chose {level.value.capitalize()}: {100.0 * error:.1f} %{over} ({situations})"
    scene_reading.set_if_changed(settings, "auto_level", level.value)
    scene_reading.set_if_changed(settings, "status_quality", line)
