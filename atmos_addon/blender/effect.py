# SPDX-License-Identifier: GPL-3.0-or-later
"""Turn aerial perspective on, off, or refresh it for a scene: the code the operators, CLI and API share.

Enabling builds (or reuses) the aerial perspective shader group, injects its AOV outputs into
every material the scene's objects use (:mod:`.materials`), declares the AOVs and inserts the
combining node into the compositor (:mod:`.compositor`), and writes the shader parameters
(:mod:`.sync`); with ``sky_enabled`` it inserts the "Atmos Sky" into the scene's world (:mod:`.world`); with
``drive_sun_lamp`` it finds or creates the sun lamp and drives its colour and strength (:mod:`.sun_lamp`), and
bakes an animated sun to keyframes. Disabling removes exactly what enabling added. Both are idempotent.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import bpy

from . import compositor, facts, in_render, materials, precise_tables, quality_choice, sun_lamp, sync, world

_applying: set[str] = set()


@dataclass
class Report:
    """What an enable/refresh did: managed materials, skipped ones with the reason, and messages."""

    managed: list[str] = field(default_factory=list)
    skipped: list[tuple[str, str]] = field(default_factory=list)
    objects_without_material: list[str] = field(default_factory=list)
    messages: list[str] = field(default_factory=list)


def _set_enabled(scene, value: bool) -> None:
    """Set ``scene.atmos.enabled`` without re-entering its update callback."""
    if scene.atmos.enabled != value:
        _applying.add(scene.name)
        try:
            scene.atmos.enabled = value
        finally:
            _applying.discard(scene.name)


def apply_enabled_state(scene) -> None:
    """The ``enabled`` update callback: enable or disable to match the switch."""
    if scene.name in _applying:
        return
    if scene.atmos.enabled:
        enable_effect(scene)
    else:
        disable_effect(scene)


def _status(scene, report: Report) -> None:
    settings = scene.atmos
    settings.status_materials = f"{len(report.managed)} material(s) with aerial perspective"
    settings.status_objects = (
        f"{len(report.objects_without_material)} object(s) without material: not affected"
        if report.objects_without_material else ""
    )
    settings.skipped_materials.clear()
    for name, reason in report.skipped:
        item = settings.skipped_materials.add()
        item.name = name
        item.reason = reason


def _apply_materials(scene, *, only_new: bool) -> Report:
    plan = facts.plan_of(scene)
    if plan.mode == "IN_RENDER":
        result = in_render.inject_scene(scene, sync.ensure_group(scene), only_new=only_new)
    else:
        result = materials.inject_scene(scene, sync.ensure_group(scene), only_new=only_new,
                                        evaluations=plan.surface_modes)
    report = Report(
        managed=result.managed,
        skipped=result.skipped,
        objects_without_material=result.objects_without_material,
    )
    report.messages.append(f"{len(result.managed)} material(s) with aerial perspective")
    for name, reason in result.skipped:
        report.messages.append(f"Material '{name}' skipped: {reason}")
    if result.objects_without_material:
        report.messages.append(
            f"{len(result.objects_without_material)} object(s) without material are not affected "
            "(give them a material to include them)"
        )
    return report


def mode_mismatch(scene) -> bool:
    """True when the effect is on in one mode (Compositor or Per Pixel / In-Render) and the scene now asks for the
    other (Compositor and Per Pixel share the materials' nodes: :func:`.compositor.install` swaps those two)."""
    return scene.atmos.enabled and in_render.is_installed(scene) != (facts.plan_of(scene).mode == "IN_RENDER")


def enable_effect(scene) -> Report:
    """Apply aerial perspective to every object of ``scene`` (idempotent).

    The mode is the plan's (:func:`.facts.plan_of`): Compositor (AOVs in the materials, the combining node in
    the compositor) or In-Render (Cycles: dome volumes, emission in the materials, world compensation). When
    the effect is on in the other mode (the setting or the render engine changed), that mode is removed first.
    """
    if mode_mismatch(scene):
        disable_effect(scene)
    _set_enabled(scene, True)
    if precise_tables.uses_precise(scene):
        scene.view_layers[0].update()   # the tables read the camera's matrix: objects moved by a script since
    quality_choice.resolve(scene)
    plan = facts.plan_of(scene)
    report = _apply_materials(scene, only_new=True)
    if plan.compositor is not None:
        report.messages.extend(compositor.install(scene, evaluation=plan.compositor,
                                                  features=sync.features_from_settings(scene.atmos)))
    if scene.atmos.drive_sun_lamp:
        _, lamp_message = sun_lamp.ensure_sun_lamp(scene)
        report.messages.append(lamp_message)
    sync.sync_scene(scene)
    if scene.atmos.sky_enabled:
        sky_features = sync.sky_features_from_settings(scene.atmos)
        report.messages.append(world.install_sky(scene, sync.ensure_sky_group(scene), sky_features))
        world.sync_sky_lighting(scene, sync.atmosphere_of(scene), sky_features)
    report.messages.extend(note for note in plan.notes if note not in scene.atmos.status_quality)
    if plan.mode == "IN_RENDER":
        report.messages.extend(in_render.install(scene, sync.features_from_settings(scene.atmos),
                                                 sync.atmosphere_of(scene), sync.metres_per_unit(scene)))
    if not sun_lamp.is_bake_current(scene):   # usually baked by sync_scene already (sun_lamp.follow)
        sun_lamp.bake_sun_animation(scene)
    if scene.get(sun_lamp.BAKED_KEY) is not None:
        report.messages.append(f"Animated sun: baked to keyframes for frames {scene.frame_start}-{scene.frame_end}")
    if precise_tables.uses_precise(scene):
        precise_tables.bake(scene)   # a no-op when sync_scene just baked the same inputs
        report.messages.append(precise_tables.describe())
    report.messages.append(scene.atmos.status_sun)
    report.messages.append(scene.atmos.status_quality)
    _status(scene, report)
    sync._last_counts[scene.name] = (len(bpy.data.materials), len(scene.objects))
    return report


def refresh_effect(scene) -> Report:
    """Pick up materials and objects added since enabling, and re-sync (enables when off)."""
    return enable_effect(scene)


def apply_sky_state(scene) -> None:
    """The ``sky_enabled`` update callback (effect on): add or remove the sky in the scene's world."""
    if scene.atmos.sky_enabled:
        world.install_sky(scene, sync.ensure_sky_group(scene), sync.sky_features_from_settings(scene.atmos))
        sync.sync_scene(scene)
    else:
        world.uninstall_sky(scene)
    in_render.refresh_world(scene, sync.features_from_settings(scene.atmos))


def pick_up_new_materials(scene) -> None:
    """Inject materials that appeared since the last pass (the depsgraph handler's cheap path)."""
    report = _apply_materials(scene, only_new=True)
    _status(scene, report)


def _materials_used_by_other_enabled_scenes(scene) -> set[int]:
    keep: set[int] = set()
    for other in bpy.data.scenes:
        if other != scene and getattr(other, "atmos", None) is not None and other.atmos.enabled:
            keep.update(m.as_pointer() for m in materials.scene_materials(other)[0])
    return keep


def disable_effect(scene) -> list[str]:
    """Remove everything :func:`enable_effect` added to ``scene``; the names of the stripped materials."""
    _set_enabled(scene, False)
    keep = _materials_used_by_other_enabled_scenes(scene)
    candidates = [m for m in bpy.data.materials if m.as_pointer() not in keep]
    stripped = materials.remove_all(candidates)
    materials.remove_surface_group()
    compositor.uninstall(scene)
    in_render.uninstall(scene)
    in_render.remove_unused_groups()
    world.uninstall_sky(scene)
    sun_lamp.restore_lamp(scene)
    sync.node_groups().parameters.clear_shader_parameters(scene)
    precise_tables.remove(scene)
    settings = scene.atmos
    settings.status_materials = ""
    settings.status_objects = ""
    settings.status_sun = ""
    settings.status_quality = ""
    settings.skipped_materials.clear()
    sync.forget(scene.name)
    return stripped
