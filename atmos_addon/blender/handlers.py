# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender's handlers and message-bus subscriptions: how Atmos follows what the user does outside its panel.

- :func:`on_depsgraph_update`: the sun lamp moved, the camera moved, keys were edited, materials or objects were
  added, a material was edited, the render engine changed: each the cheap check first, then the orchestrator.
- :func:`on_load_post`, :func:`on_undo_redo`: the file's data changed under the caches: everything is updated again
  (after a load, settings saved before a default changed first get their former default: :mod:`.migration`).
- :func:`on_save_pre`: what the interface left for later (debounced re-bakes, the worker thread's tile) is done
  before the file is written.
- :func:`follow_render_settings` (message bus): the engine or Cycles' Open Shading Language changed.
"""

from __future__ import annotations

import bpy
from bpy.app.handlers import persistent

from . import facts, group_integrity, migration, orchestrator, sun_bake, sync
from .apply import compositor, holdouts, materials, precise_tables


#: True while :func:`_evaluate_enabled_scenes` runs: the depsgraph handler waits for the re-sync that follows.
_evaluating = False


@persistent
def on_depsgraph_update(scene, depsgraph) -> None:
    """Follow the sun lamp and pick up new materials in scenes with the effect on (cheap checks first)."""
    if _evaluating:
        return
    group_integrity.on_depsgraph_update(scene, depsgraph)  # drops the panel's cached edit check (one flag query)
    settings = getattr(scene, "atmos", None)
    if settings is None or not settings.enabled:
        return
    plan = facts.plan_of(scene)
    if orchestrator.mode_mismatch(scene, plan):  # the engine or the mode changed: switch Compositor <-> In-Render
        orchestrator.enable_effect(scene)
        return
    edited = materials.edited_materials(depsgraph)   # first: what follows may free the updates' evaluated copies
    key_tiles = scene.get(facts.KEY_TILES)
    if sync.sun_moved(scene):
        orchestrator.update(scene, plan)
        _redraw_properties()   # the sun's values it shows are written without a tag, which would redraw it
    elif sync.note_camera(scene):   # the Precise tables follow the camera
        if plan.tables:
            precise_tables.follow(scene)
    elif any(depsgraph.id_type_updated(kind) for kind in ("ACTION", "OBJECT", "SCENE")):
        # keys edited at other frames, a parent or a target moved, the frame range changed
        sun_bake.follow(scene, plan)
    plan = orchestrator.follow_key_tiles(scene, key_tiles, plan)   # an animation that started or stopped: blend or not
    if edited:
        materials.follow_edits(edited)   # a surface Cycles folds away stays opaque
    if depsgraph.id_type_updated("SCENE"):
        compositor.follow_shown_view_layer(scene)   # a view layer switched on or off: the shown one composited
    if depsgraph.id_type_updated("SCENE") or depsgraph.id_type_updated("COLLECTION"):
        holdouts.follow(scene)   # a collection's Holdout switched, objects linked into one or out of it
    if orchestrator.note_counts(scene):
        orchestrator.pick_up_new_materials(scene, plan)


def _redraw_properties() -> None:
    """Redraw the Properties editors (the interface's; nothing to do in the background)."""
    window_manager = bpy.context.window_manager
    for window in getattr(window_manager, "windows", ()) if window_manager is not None else ():
        for area in window.screen.areas:
            if area.type == "PROPERTIES":
                area.tag_redraw()


@persistent
def on_load_post(*_args) -> None:
    """After a file loads: settings saved before a default changed keep the value they were saved with, retired
    choices are upgraded (:mod:`.migration`); rebuild stale node groups and re-sync every scene with the effect on;
    subscribe to the render settings again (loading a file clears the message bus).

    A file does not hold the objects' world matrices (Blender keeps them in runtime data): until the depsgraph
    evaluates, every ``matrix_world`` reads the identity, which made the re-sync write a sun at the zenith into
    the shader parameters of every file opened (a farm with the add-on rendered the wrong sky). Each scene's
    view layers are evaluated first."""
    for scene in bpy.data.scenes:
        if getattr(scene, "atmos", None) is not None:
            with orchestrator.held(scene):
                migration.restore_former_defaults(scene.atmos)
                for note in migration.upgrade_retired_settings(scene):
                    print(note)
    _evaluate_enabled_scenes()
    orchestrator.resync_all()
    _subscribe()


def _evaluate_enabled_scenes() -> None:
    """Evaluate the view layers of every scene with the effect on, so that its objects' ``matrix_world`` is
    current (after a load or a memfile undo it is not until the depsgraph runs), the depsgraph handler held back
    (the caller re-syncs)."""
    global _evaluating
    _evaluating = True
    try:
        for scene in bpy.data.scenes:
            if getattr(scene, "atmos", None) is not None and scene.atmos.enabled:
                for view_layer in scene.view_layers:
                    view_layer.update()
    finally:
        _evaluating = False


@persistent
def on_undo_redo(*_args) -> None:
    """After an undo or redo step, which restores the file's data from memory (memfile undo).

    - Our caches describe the state undone from: they are dropped and every enabled scene re-synced. A step can
      hold parameters older than its lamp (in the UI a transform pushes its step before the depsgraph handler
      writes the sun's parameters), which the sun-matrix cache would otherwise take as current.
    - Blender keeps image buffers across undo, so the Precise table would keep the pixels of the state undone from
      while its packed data and bake key are restored: its buffer is freed (read again from the packed data)
      before the re-sync compares bake keys.
    """
    precise_tables.free_buffers()
    _evaluate_enabled_scenes()
    orchestrator.resync_all()


#: The owner of Atmos' message-bus subscriptions (cleared on unregister, made again after a file loads).
_MSGBUS_OWNER = object()


def follow_render_settings(*_args) -> None:
    """Switch every enabled scene whose render settings now call for another mode (the engine changed, Cycles'
    Open Shading Language toggled: :func:`atmos_addon.plan.mode_for`). The message bus calls this when the user
    changes those settings in the interface; Cycles' settings do not tag the depsgraph, so the depsgraph handler
    would see the change only at the next edit."""
    for scene in bpy.data.scenes:
        settings = getattr(scene, "atmos", None)
        if settings is not None and settings.enabled and orchestrator.mode_mismatch(scene, facts.plan_of(scene)):
            orchestrator.enable_effect(scene)


def _subscribe() -> None:
    bpy.msgbus.clear_by_owner(_MSGBUS_OWNER)
    keys = [(bpy.types.RenderSettings, "engine")]
    cycles = getattr(bpy.types, "CyclesRenderSettings", None)
    if cycles is not None:
        keys.append((cycles, "shading_system"))
    for key in keys:
        bpy.msgbus.subscribe_rna(key=key, owner=_MSGBUS_OWNER, args=(), notify=follow_render_settings)


@persistent
def on_save_pre(*_args) -> None:
    """Before a save: the re-bakes and records the UI left for later (a timer 0.3 s after the last change, a tile on
    the worker thread) are done now, so the file holds the tables of the scene it saves (a farm renders those)."""
    sun_bake.finish_pending()
    precise_tables.finish_pending()


HANDLERS = (
    (bpy.app.handlers.depsgraph_update_post, on_depsgraph_update),
    (bpy.app.handlers.save_pre, on_save_pre),
    (bpy.app.handlers.load_post, on_load_post),
    (bpy.app.handlers.undo_post, on_undo_redo),
    (bpy.app.handlers.redo_post, on_undo_redo),
)


def add_handlers() -> None:
    for handler_list, function in HANDLERS:
        if function not in handler_list:
            handler_list.append(function)
    _subscribe()


def remove_handlers() -> None:
    """Remove our handlers, also copies left by an earlier import of this module (add-on reload)."""
    for handler_list, function in HANDLERS:
        for registered in list(handler_list):
            if registered is function or (
                getattr(registered, "__module__", None) == function.__module__
                and getattr(registered, "__qualname__", None) == function.__qualname__
            ):
                handler_list.remove(registered)
    bpy.msgbus.clear_by_owner(_MSGBUS_OWNER)
    orchestrator.forget()
