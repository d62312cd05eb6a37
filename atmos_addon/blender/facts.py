# SPDX-License-Identifier: GPL-3.0-or-later
"""A scene's :class:`~atmos_addon.plan.SceneFacts`, read off its settings, engine and camera, and its plan.

Everything Atmos builds for a scene follows from :func:`plan_of`; :mod:`atmos_addon.plan` holds the rules.
"""

from __future__ import annotations

from ..plan import Plan, SceneFacts, plan_for
from .scene_reading import animation_curves, groups, held_out

#: Scene property: the number of key tiles the scene's last Precise bake wrote (``apply.precise_tables``).
KEY_TILES = "atmos_precise_key_tiles"


def _own_facts(scene, other_modes: tuple[str, ...] = ()) -> SceneFacts:
    settings = scene.atmos
    camera = scene.camera
    clip_ratio = clip_end_m = None
    if camera is not None and camera.type == "CAMERA" and camera.data.clip_start > 0.0:
        clip_ratio = float(camera.data.clip_end) / float(camera.data.clip_start)
        clip_end_m = float(camera.data.clip_end) * float(scene.unit_settings.scale_length)
    return SceneFacts(
        render_mode=settings.render_mode, quality=settings.quality, auto_level=settings.auto_level,
        engine=scene.render.engine,
        osl=bool(getattr(getattr(scene, "cycles", None), "shading_system", False)),
        mie=any(v > 0.0 for v in settings.mie_scattering_per_km),
        absorption=any(v > 0.0 for v in settings.mie_absorption_per_km),
        sky=bool(settings.sky_enabled), sky_ground=settings.sky_ground, sun_lamp=bool(settings.drive_sun_lamp),
        multiple_scattering=bool(settings.multiple_scattering), other_modes=other_modes, clip_ratio=clip_ratio,
        clip_end_m=clip_end_m, key_tiles=max(int(scene.get(KEY_TILES, 1)), 1),
        animated_settings=animated_settings(scene), holdout=has_holdout_collection(scene), blurs=blurs(scene))


def blurs(scene) -> tuple[str, ...]:
    """What blurs ``scene``'s image over depths: the scene camera's depth of field, the render's motion blur."""
    camera = scene.camera
    found = []
    if camera is not None and camera.type == "CAMERA" and camera.data.dof.use_dof:
        found.append("depth of field")
    if scene.render.use_motion_blur:
        found.append("motion blur")
    return tuple(found)


def has_holdout_collection(scene) -> bool:
    """True when a collection with objects in it is held out in some rendered view layers of ``scene`` and not in
    others: those objects keep no holdout mark (:mod:`.apply.holdouts`)."""
    return bool(held_out(scene)[1])


def animated_settings(scene) -> tuple[str, ...]:
    """The interface names of ``scene``'s Atmos settings that keys (its action, its NLA strips) or drivers change
    over time, in the order found. Atmos's own keys and drivers are on other paths (the scene's custom properties)."""
    paths = [curve.data_path for curve in animation_curves(scene)]
    properties = scene.atmos.bl_rna.properties
    names: list[str] = []
    for path in paths:
        if path.startswith("atmos."):
            identifier = path[len("atmos."):].split("[")[0].split(".")[0]
            prop = properties.get(identifier)
            name = prop.name if prop is not None else identifier
            if name not in names:
                names.append(name)
    return tuple(names)


def other_modes(scene) -> tuple[str, ...]:
    """The modes the file's other scenes with Atmos on render with (the shared material group serves them all)."""
    import bpy

    return tuple(sorted({plan_for(_own_facts(other)).mode for other in bpy.data.scenes
                         if other != scene and getattr(other, "atmos", None) is not None and other.atmos.enabled}))


def facts_of(scene) -> SceneFacts:
    """The :class:`SceneFacts` of ``scene`` (its settings, engine, camera and the file's other enabled scenes)."""
    return _own_facts(scene, other_modes(scene))


def plan_of(scene) -> Plan:
    """What Atmos builds for ``scene`` (:func:`atmos_addon.plan.plan_for`)."""
    return plan_for(facts_of(scene))


def aerial_features(plan: Plan):
    """The aerial node groups' feature set for ``plan`` (:class:`atmos_addon.node_groups.terms.AerialFeatures`)."""
    return groups().terms.AerialFeatures(mie=plan.mie, absorption=plan.absorption, level=plan.level, blend=plan.blend)


def sky_features(plan: Plan):
    """The sky group's feature set for ``plan`` (:class:`atmos_addon.node_groups.sky.SkyFeatures`): the plan's terms,
    ground and sky level (the Precise table's sky at the Precise level, the virtual dome otherwise)."""
    return groups().sky.SkyFeatures(mie=plan.mie, absorption=plan.absorption, ground=plan.sky_ground,
                                    level=plan.sky_level, blend=plan.blend and plan.sky_level == "precise")
