# SPDX-License-Identifier: GPL-3.0-or-later
"""The one place that applies a scene's plan: enable, refresh, update after an edit, switch mode or level, disable.

The operators, the panel's switches, the API, the CLI and the handlers all come here. Each action makes the scene's
plan once, first (:func:`.facts.plan_of`), and hands it down: every applier builds its part with
``install(scene, plan)``: the sun lamp (:mod:`.sun_lamp`), the Precise tables (:mod:`.precise_tables`), the nodes
in every material (:mod:`.materials`, or :mod:`.in_render` in In-Render mode), the compositor (:mod:`.compositor`),
the sky in the world (:mod:`.world`), the haze domes (:mod:`.in_render`); then :mod:`.sync` writes the values the
built nodes read and drives the sun's from the lamp (:mod:`.sun_drivers`), and :mod:`.sun_bake` records an animated
sun for the key tiles. Where the action itself changes what the plan was made from (Auto's choice of level,
:func:`.quality_choice.resolve`; the key tiles a bake writes, :func:`bake_tables`) the next plan is made from the
first one's facts (:meth:`~atmos_addon.plan.Plan.with_facts`), the scene not read again. :func:`update` runs after
every settings edit: it rebuilds what the plan no longer matches (cheap when everything does) and writes the
values. Disabling has every applier remove exactly what it added (``remove(scene)``). All of it is idempotent.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from dataclasses import dataclass, field

import bpy

from . import facts, group_integrity, migration, quality_choice, scene_reading, settings_io, sun_bake, sync
from ..node_groups import registry, stamps
from ..plan import Plan
from .apply import compositor, holdouts, in_render, materials, precise_tables, sun_drivers, sun_lamp, world

#: Names of scenes whose ``enabled`` switch this module is setting (its update callback waits).
_applying: set[str] = set()
#: Names of scenes whose settings are being written as a batch (their update callbacks wait; one update at the end).
_batched: set[str] = set()
#: Per scene: (material count, object count) at the last pass (the depsgraph handler's cheap check for new ones).
_last_counts: dict[str, tuple[int, int]] = {}
#: Group name -> (its stamps and node count, its inline node count): :func:`_inline_count`'s cache.
_inline_counts: dict[str, tuple[tuple, int]] = {}


@dataclass
class Report:
    """What an enable/refresh did: managed materials, skipped ones with the reason, and messages."""

    managed: list[str] = field(default_factory=list)
    skipped: list[tuple[str, str]] = field(default_factory=list)
    objects_without_material: list[str] = field(default_factory=list)
    messages: list[str] = field(default_factory=list)


# -- settings written as a batch -----------------------------------------------------------------------


def is_batched(scene) -> bool:
    """True while :func:`batch` holds the scene's updates back."""
    return scene.name in _batched


@contextlib.contextmanager
def held(scene) -> Iterator[None]:
    """Hold back the update callbacks of ``scene``'s settings while the caller writes them (it updates, if needed)."""
    if scene.name in _batched:
        yield
        return
    _batched.add(scene.name)
    try:
        yield
    finally:
        _batched.discard(scene.name)


@contextlib.contextmanager
def batch(scene) -> Iterator[None]:
    """Write several settings of ``scene`` with one :func:`update` at the end (when the effect is enabled)."""
    if scene.name in _batched:
        yield
        return
    with held(scene):
        yield
    if scene.atmos.enabled:
        update(scene)


def apply_atmosphere(scene, atmosphere) -> None:
    """Write every field of the physics ``atmosphere`` into ``scene.atmos`` (one update at the end)."""
    with batch(scene):
        settings_io.write_atmosphere(scene.atmos, atmosphere)


# -- the switch ----------------------------------------------------------------------------------------


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


# -- building what the plan lists ----------------------------------------------------------------------


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


def _built_groups(scene, plan: Plan) -> None:
    """Build (or rebuild in place when stale) the compositor group of the plan's mode (:func:`.compositor.ensure_group`)
    and write the "built" status line: what the aerial groups hold, with the Per Pixel group's node count."""
    features = facts.aerial_features(plan)
    built = scene_reading.groups().aerial_perspective.describe_features(features)
    tree = compositor.ensure_group(plan)
    if plan.mode == "PER_PIXEL":
        built = f"{built.split(':')[0]}, per pixel: {_inline_count(tree)} compositor nodes"
    scene_reading.set_if_changed(scene.atmos, "status_built", built)


def _inline_count(tree) -> int:
    """:func:`.parts.inline_count` of ``tree`` for the status line, counted again only when the tree was rebuilt (its
    stamps or its node count changed): every sync writes the status, and the count walks the tree and its parts."""
    key = (tree.as_pointer(), tree.get(stamps.VERSION_KEY), tree.get(stamps.FEATURES_KEY), len(tree.nodes))
    if _inline_counts.get(tree.name, (None,))[0] != key:
        _inline_counts[tree.name] = (key, scene_reading.groups().parts.inline_count(tree))
    return _inline_counts[tree.name][1]


def _apply_materials(scene, plan: Plan, *, only_new: bool) -> Report:
    """Give the scene's materials the nodes of the plan's mode (:func:`.in_render.install_materials` in In-Render
    mode, else :func:`.materials.install`); the report of the pass."""
    _built_groups(scene, plan)
    if plan.mode == "IN_RENDER":
        result = in_render.install_materials(scene, plan, only_new=only_new)
    else:
        result = materials.install(scene, plan, only_new=only_new)
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


def mode_mismatch(scene, plan: Plan) -> bool:
    """True when the effect is on in one mode (Compositor or Per Pixel / In-Render) and ``plan`` (the scene's) asks
    for the other (Compositor and Per Pixel share the materials' nodes: :func:`.compositor.install` swaps those
    two)."""
    return scene.atmos.enabled and in_render.is_installed(scene) != (plan.mode == "IN_RENDER")


def _ensure_groups(scene, plan: Plan) -> None:
    """Rebuild in place every group ``plan`` lists that is stale for it (cheap when current), and stamp them."""
    if plan.mode == "IN_RENDER":
        in_render.surface_group(plan)
    else:
        materials.update_groups(plan)
    _built_groups(scene, plan)
    if plan.compositor is not None and compositor.installed_evaluation(scene) == plan.compositor:
        compositor.upgrade_passes(scene, plan.compositor)
    if plan.sky:
        world.update(scene, plan)
    in_render.update_groups(scene, plan)
    group_integrity.stamp_new()


def _drop_tables(scene) -> None:
    """Remove the Precise tables, their parameters and pending bakes of a scene whose plan is not at the Precise
    level."""
    parameters = scene_reading.groups().parameters
    if parameters.PRECISE_TILE in scene:
        precise_tables.remove(scene)
        for name in parameters.PRECISE_PARAMETER_NAMES:
            del scene[name]
    else:
        precise_tables.drop_pending(scene)


def _follow_tables_and_keys(scene, plan: Plan) -> None:
    """The Precise tables and an animated sun's record follow the values just written: baked again when their inputs
    changed (at once in the background, else shortly after the last change); tables of a level left are removed."""
    key_tiles = scene.get(facts.KEY_TILES)
    if plan.tables:
        precise_tables.follow(scene)
    else:
        _drop_tables(scene)
    sun_bake.follow(scene, plan)
    follow_key_tiles(scene, key_tiles, plan)


def bake_tables(scene, plan: Plan, *, force: bool = False, sampled=None) -> Plan:
    """Bake the Precise tables ``plan`` lists (:func:`.precise_tables.install`; ``sampled``: the frames an enable
    sampled for its first bake, :class:`.precise_tables.Sampled`) and rebuild the groups when the blend of key tiles
    came or went with them (a camera or sun that started or stopped moving); the plan with the key tiles baked."""
    key_tiles = scene.get(facts.KEY_TILES)
    precise_tables.install(scene, plan, force=force, sampled=sampled)
    return follow_key_tiles(scene, key_tiles, plan)


def follow_key_tiles(scene, key_tiles_before, plan: Plan) -> Plan:
    """Rebuild the groups whose blend of key tiles changed with a bake (``key_tiles_before``: the scene's
    :data:`.facts.KEY_TILES` before it). A group built without the blend over several key tiles would render each
    frame from its first key alone; one built with it over a single tile renders that tile exactly (weight 0).
    Returns ``plan`` for the key tiles the scene now holds (what the bake wrote)."""
    key_tiles = max(int(scene.get(facts.KEY_TILES, 1)), 1)
    plan = plan.with_facts(key_tiles=key_tiles)
    if scene.atmos.enabled and (key_tiles > 1) != ((key_tiles_before or 1) > 1):
        _ensure_groups(scene, plan)
    return plan


def update(scene, plan: Plan | None = None) -> None:
    """After an edit of ``scene``'s settings or its sun: rebuild what the plan no longer matches, write the values,
    and let the tables and the sun's record follow. A scene with the effect off only gets its displayed values.
    ``plan``: the scene's, where the caller has just made it (:func:`.facts.plan_of`; made here otherwise)."""
    if not scene.atmos.enabled:
        sync.sync_scene(scene)
        return
    plan = facts.plan_of(scene) if plan is None else plan
    if mode_mismatch(scene, plan):   # the mode or the engine changed: Compositor <-> In-Render
        enable_effect(scene)
        return
    _ensure_groups(scene, plan)
    sync.sync_scene(scene)
    _follow_tables_and_keys(scene, plan)


def enable_effect(scene) -> Report:
    """Apply aerial perspective to every object of ``scene`` (idempotent), as its plan says: Compositor or Per
    Pixel mode (AOVs in the materials, a group in the compositor) or In-Render mode (Cycles: dome volumes, emission
    in the materials, world compensation). When the effect is on in the other mode (the setting or the render
    engine changed), that mode is removed first."""
    plan = facts.plan_of(scene)
    if mode_mismatch(scene, plan):
        disable_effect(scene)
    if len(scene.view_layers) and scene_reading.needs_evaluation(scene):
        # The tables read the sun's and the camera's world matrices, composed from their transforms where nothing
        # else moves them (scene_reading.world_matrix); a constraint or driver needs the depsgraph. Before this
        # function writes the scene's properties: a written scene re-evaluates every object (3 s of a 20000-object
        # enable, measured), an untouched one only what the script moved. After the mode switch: the depsgraph
        # handler would otherwise see the mismatch and enable again from in here.
        scene.view_layers[0].update()
    with held(scene):
        migration.pin_defaults(scene.atmos)   # a file saved from now on keeps these whatever later defaults are
    _set_enabled(scene, True)
    plan = quality_choice.resolve(scene, plan)
    # Before the tables, which follow the lamp: a lamp created after them would bake them again.
    lamp_message = sun_lamp.install(scene, plan)
    sampled = None
    if plan.tables:
        # Before the materials: the groups link the table image as they are built. Pointing a group that 5000
        # materials already use at a new image re-evaluates every one of them (3.4 s of a 5000-material enable).
        sampled = precise_tables.sample(scene)
        plan = bake_tables(scene, plan, sampled=sampled)   # the bake decides the blend of key tiles
    report = _apply_materials(scene, plan, only_new=True)
    holdouts.install(scene, plan)
    if plan.compositor is not None:
        report.messages.extend(compositor.install(scene, plan))
    if lamp_message is not None:
        report.messages.append(lamp_message)
    if plan.sky:
        report.messages.append(world.install(scene, plan))
    _ensure_groups(scene, plan)
    sync.sync_scene(scene)
    report.messages.extend(note for note in plan.notes if note not in scene.atmos.status_quality)
    if plan.mode == "IN_RENDER":
        report.messages.extend(in_render.install(scene, plan))
    if not sun_bake.is_bake_current(scene):
        sun_bake.bake_sun_animation(scene)
    if scene.get(sun_bake.BAKED_KEY) is not None:
        report.messages.append(f"Animated sun: its light follows the lamp on every frame, "
                               f"{scene.frame_start}-{scene.frame_end} (drivers; no add-on needed to render)")
    if plan.tables:
        # A no-op when its inputs are those of the last bake; the frames not sampled again while the sun lamp and
        # the camera are the ones they were, where they were.
        bake_tables(scene, plan, sampled=sampled)
        report.messages.append(precise_tables.describe())
    else:
        _drop_tables(scene)
    report.messages.append(scene.atmos.status_sun)
    report.messages.append(scene.atmos.status_quality)
    _status(scene, report)
    note_counts(scene)
    return report


def refresh_effect(scene) -> Report:
    """Pick up materials and objects added since enabling, and re-sync (enables when off)."""
    return enable_effect(scene)


def change_quality(scene) -> None:
    """The quality settings' update callback (effect on): resolve Auto, rebuild and re-sync, and bake the Precise
    tables for every frame of an animated camera or sun."""
    plan = quality_choice.resolve(scene, facts.plan_of(scene))
    update(scene, plan)
    if plan.tables:
        bake_tables(scene, plan)


def apply_sky_state(scene) -> None:
    """The ``sky_enabled`` update callback (effect on): add or remove the sky in the scene's world."""
    plan = facts.plan_of(scene)
    if plan.sky:
        world.install(scene, plan)
        update(scene, plan)
    else:
        world.remove(scene)
    in_render.refresh_world(scene, plan)


def note_counts(scene) -> bool:
    """Record the file's material count, the scene's object count and its view layers' Material Overrides; True when
    they changed since the last call."""
    counts = (len(bpy.data.materials), len(scene.objects),
              tuple(layer.material_override.as_pointer() if layer.material_override else 0
                    for layer in scene.view_layers))
    changed = _last_counts.get(scene.name) != counts
    _last_counts[scene.name] = counts
    return changed


def pick_up_new_materials(scene, plan: Plan) -> None:
    """Inject materials that appeared since the last pass (the depsgraph handler's cheap path; ``plan``: the
    scene's)."""
    report = _apply_materials(scene, plan, only_new=True)
    _status(scene, report)
    group_integrity.stamp_new()


def resync_all() -> None:
    """Drop every cache and update every scene with the effect on (stale node groups are rebuilt): after a file
    loads, and after an undo or redo step."""
    forget()
    holdouts.forget()
    group_integrity.invalidate()
    for scene in bpy.data.scenes:
        settings = getattr(scene, "atmos", None)
        if settings is not None and settings.enabled:
            update(scene)
            holdouts.install(scene, None)   # the marks as the loaded or restored view layers hold out
            note_counts(scene)


def forget(scene_name: str | None = None) -> None:
    """Drop the cached state of a scene (every scene when ``scene_name`` is None)."""
    sync.forget(scene_name)
    if scene_name is None:
        _last_counts.clear()
    else:
        _last_counts.pop(scene_name, None)


def disable_effect(scene) -> list[str]:
    """Remove everything :func:`enable_effect` added to ``scene``; the names of the stripped materials."""
    _set_enabled(scene, False)
    stripped = materials.remove(scene)
    holdouts.remove(scene)
    compositor.remove(scene)
    in_render.remove(scene)
    world.remove(scene)
    registry.remove_unused()   # no Atmos orphans left in the file
    sun_bake.clear_baked_keys(scene)
    sun_drivers.remove(scene)   # before the lamp's own values are put back: a driver would override them
    sun_lamp.remove(scene)
    scene_reading.groups().parameters.clear_shader_parameters(scene)
    precise_tables.remove(scene)
    settings = scene.atmos
    settings.status_materials = ""
    settings.status_objects = ""
    settings.status_sun = ""
    settings.status_quality = ""
    settings.skipped_materials.clear()
    forget(scene.name)
    return stripped
