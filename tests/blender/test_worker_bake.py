# SPDX-License-Identifier: GPL-3.0-or-later
"""In the UI a still scene's Precise table is re-baked on a worker thread (``precise_tables.bake_on_worker``, which
the debounced timer calls 0.3 s after the last sun, camera or atmosphere change): the interface does not wait for the
0.4-0.5 s tile (plus the atmosphere's tables), and the image written when the worker is done is the synchronous
bake's to the bit. The pip ``bpy`` module has no event loop, so these tests call the timers' functions themselves;
Atmos's depsgraph handler is held off while the scene changes, else background mode would bake at once.

Scenes built from scratch (an empty factory file: no world, a bare camera, a sun lamp)."""

from __future__ import annotations

import collections
import contextlib
import math
import threading

import bpy
import numpy as np
import pytest

import render_utils as ru
from atmos_addon.blender import facts, orchestrator, scene_reading
from atmos_addon.blender.apply import precise_tables, sun_lamp


@contextlib.contextmanager
def _handler_held():
    """Atmos's depsgraph handler off (background mode would re-bake in it), Blender's own update still on."""
    handlers = bpy.app.handlers.depsgraph_update_post
    ours = [h for h in handlers if getattr(h, "__name__", "") == "on_depsgraph_update"]
    assert ours
    for handler in ours:
        handlers.remove(handler)
    try:
        yield
    finally:
        handlers.extend(ours)


def _scene(scene):
    ru.make_camera(scene, location=(0.0, 0.0, 30.0), rotation_euler=(math.radians(85.0), 0.0, 0.0))
    orchestrator.enable_effect(scene)                     # adds its sun lamp
    sun_lamp.set_sun_angles(scene, math.radians(20.0), math.radians(120.0))
    bpy.context.view_layer.update()
    assert scene.atmos.enabled and facts.plan_of(scene).tables   # the default bakes the tables
    return scene


def _move_sun(scene, elevation_deg: float) -> None:
    with _handler_held():
        sun_lamp.set_sun_angles(scene, math.radians(elevation_deg), math.radians(120.0))
        bpy.context.view_layer.update()


def _image():
    return bpy.data.images[scene_reading.groups().precise.IMAGE_NAME]


def _pixels() -> np.ndarray:
    image = _image()
    pixels = np.empty(len(image.pixels), np.float32)
    image.pixels.foreach_get(pixels)
    return pixels


def test_the_worker_bakes_what_the_synchronous_bake_bakes(addon, monkeypatch):
    scene = _scene(addon)
    threads = []
    original = precise_tables._integrate
    monkeypatch.setattr(precise_tables, "_integrate", lambda request: threads.append(
        threading.current_thread().name) or original(request))
    before = _pixels()
    _move_sun(scene, 6.0)
    stale = precise_tables._request(scene)
    assert _image()[precise_tables._KEY] != stale.key
    precise_tables.bake_on_worker(scene)
    assert precise_tables.pending() == [scene.name]
    assert bpy.app.timers.is_registered(precise_tables.write_finished)
    assert _image()[precise_tables._KEY] != stale.key     # nothing written on the main thread yet
    precise_tables.bake_on_worker(scene)                  # the same request again: no second job
    precise_tables.wait_for_worker()
    assert [name for name in threads if name.startswith("atmos-bake")] == [threads[0]]   # integrated once, there
    assert not precise_tables.pending() and not bpy.app.timers.is_registered(precise_tables.write_finished)
    assert _image()[precise_tables._KEY] == stale.key
    written = _pixels()
    assert not np.array_equal(written, before)            # a 6 deg sun's table, not the 20 deg one's
    assert precise_tables.bake(scene, force=True) == 1
    assert np.array_equal(_pixels(), written)
    precise_tables.bake_on_worker(scene)                  # current: nothing to do
    assert not precise_tables.pending()


def test_an_atmosphere_edit_shows_the_preview_first_then_the_full_table(addon, monkeypatch, without_table_store):
    """After an atmosphere edit the worker bakes the tile from the preview tables first (a fifth of the tables'
    build), which is written at once, its key marked as a preview, and then the full tile over it: the synchronous
    bake's to the bit. A sun move afterwards (the tables built) has no preview. Here the full bake waits until the
    preview is written, so the test sees both."""
    from atmos_addon.physics import precise

    scene = _scene(addon)
    release = threading.Event()
    original = precise_tables._integrate
    monkeypatch.setattr(precise_tables, "_integrate", lambda request: release.wait(60.0) and original(request))
    with _handler_held(), orchestrator.held(scene):   # the edit as the interface makes it: nothing baked here
        scene.atmos.mie_scattering_per_km = tuple(v * 1.3 for v in scene.atmos.mie_scattering_per_km)
    request = precise_tables._request(scene)
    assert not precise.tables_ready(request.atmosphere, request.albedo)
    try:
        precise_tables.bake_on_worker(scene)
        assert set(precise_tables._previews) == {scene.name}
        precise_tables.wait_for_first_look()
        assert _image()[precise_tables._KEY] == request.key + precise_tables.PREVIEW_MARK
        assert precise_tables.pending() == [scene.name]       # the full bake still to come
        assert precise_tables._current_image(request, scene) is None
        preview = _pixels()
    finally:
        release.set()
    precise_tables.wait_for_worker()
    assert _image()[precise_tables._KEY] == request.key and not precise_tables._previews
    full = _pixels()
    assert not np.array_equal(full, preview)
    relative = np.abs(preview - full) / np.maximum(np.abs(full), 1e-3 * np.abs(full).max())
    assert np.median(relative) < 0.005 and np.percentile(relative, 99) < 0.1
    precise_tables.bake(scene, force=True)
    assert np.array_equal(_pixels(), full)
    _move_sun(scene, 12.0)
    precise_tables.bake_on_worker(scene)
    assert not precise_tables._previews and precise_tables.pending() == [scene.name]
    precise_tables.wait_for_worker()
    assert _image()[precise_tables._KEY] == precise_tables._request(scene).key


def test_a_save_while_the_preview_shows_stores_the_full_table(addon, tmp_path):
    scene = _scene(addon)
    with _handler_held(), orchestrator.held(scene):   # the edit as the interface makes it: nothing baked here
        scene.atmos.mie_scattering_per_km = tuple(v * 0.7 for v in scene.atmos.mie_scattering_per_km)
    expected = precise_tables._request(scene).key
    precise_tables.bake_on_worker(scene)
    precise_tables.wait_for_first_look()
    path = tmp_path / "preview.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    assert not precise_tables.pending() and _image()[precise_tables._KEY] == expected
    bpy.ops.wm.open_mainfile(filepath=str(path))
    assert _image()[precise_tables._KEY] == expected


def test_a_change_while_the_worker_runs_bakes_the_latest_scene(addon, monkeypatch):
    """The sun moves again before the worker's tile is written: the table written is the last position's, never the
    one in between (an atmosphere edit meanwhile likewise: its key differs)."""
    scene = _scene(addon)
    integrated = []
    original = precise_tables._integrate
    monkeypatch.setattr(precise_tables, "_integrate", lambda request: integrated.append(request.key)
                        or original(request))
    _move_sun(scene, 8.0)
    precise_tables.bake_on_worker(scene)
    _move_sun(scene, 3.0)
    with _handler_held(), orchestrator.held(scene):   # the edit as the interface makes it: nothing baked here
        scene.atmos.mie_scattering_per_km = tuple(v * 1.5 for v in scene.atmos.mie_scattering_per_km)
    latest = precise_tables._request(scene)
    precise_tables.wait_for_worker()                      # the 8 deg job finishes, is found stale and re-queued
    # the 8 deg tile, then the latest on the worker (and read back from the tiles' cache by the bake that writes it)
    assert integrated[0] != latest.key and len(integrated) >= 2 and set(integrated[1:]) == {latest.key}
    assert _image()[precise_tables._KEY] == latest.key
    written = _pixels()
    precise_tables.bake(scene, force=True)
    assert np.array_equal(_pixels(), written)


def test_a_scene_deleted_or_switched_to_animation_meanwhile_is_left_alone(addon):
    scene = _scene(addon)
    other = bpy.data.scenes.new("Shot 2")
    other.atmos.enabled = False
    _move_sun(scene, 7.0)
    key = _image()[precise_tables._KEY]
    precise_tables.bake_on_worker(scene)
    bpy.data.scenes.remove(scene)
    precise_tables.wait_for_worker()
    assert not precise_tables.pending()
    assert _image()[precise_tables._KEY] == key           # nothing written for a scene that is gone


def test_a_worker_error_is_raised_on_the_main_thread_and_the_other_bakes_go_on(addon, monkeypatch, capsys):
    scene = _scene(addon)
    _move_sun(scene, 9.0)
    original = precise_tables._integrate

    def broken(request):
        raise RuntimeError("table integration failed")

    monkeypatch.setattr(precise_tables, "_integrate", broken)
    precise_tables.bake_on_worker(scene)
    precise_tables.wait_for_worker()                      # no exception escapes the timer
    assert "table integration failed" in capsys.readouterr().err
    assert not precise_tables.pending()
    monkeypatch.setattr(precise_tables, "_integrate", original)
    precise_tables.bake_on_worker(scene)
    precise_tables.wait_for_worker()
    assert _image()[precise_tables._KEY] == precise_tables._request(scene).key


def test_unregister_cancels_the_worker_and_its_timer(addon):
    scene = _scene(addon)
    _move_sun(scene, 11.0)
    precise_tables.bake_on_worker(scene)
    precise_tables.cancel_pending()
    assert not precise_tables.pending() and not precise_tables._worker
    assert not bpy.app.timers.is_registered(precise_tables.write_finished)


def test_a_save_writes_the_table_the_ui_left_for_later(addon, tmp_path):
    """A farm renders the file's table: saving 0.3 s after a change (the debounced timer not fired yet) or while the
    worker bakes must not store the table of before. The save handler bakes what is queued and writes the worker's
    tile first; the file opened afresh holds the scene's table."""
    scene = _scene(addon)
    _move_sun(scene, 5.0)
    precise_tables._later.request(scene)                  # what the UI's follow does: the timer, 0.3 s later
    expected = precise_tables._request(scene).key
    path = tmp_path / "queued.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    assert not precise_tables.pending() and _image()[precise_tables._KEY] == expected
    _move_sun(scene, 4.0)
    precise_tables.bake_on_worker(scene)                  # the timer fired: the worker bakes
    expected = precise_tables._request(scene).key
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    assert not precise_tables.pending()
    written = _pixels()
    bpy.ops.wm.open_mainfile(filepath=str(path))
    assert _image()[precise_tables._KEY] == expected
    assert np.array_equal(_pixels(), written)


def _tile_pixels(tile) -> np.ndarray:
    """A one-tile image's pixels (RGBA, alpha 1) of ``tile``, as ``precise_tables.write_tiles`` lays them out."""
    pixels = np.ones(tile.pixels().shape[:2] + (4,), np.float32)
    pixels[..., :3] = tile.pixels()
    return pixels.ravel()


def test_a_sun_move_among_the_banked_keys_shows_their_blend_at_once_then_the_exact_tile(addon, monkeypatch):
    """The UI's sun drag: once a still scene's tile is written, the worker bakes the keys of the sun's grid around it
    (the bank); a move between two of them writes their blend at once, nothing integrated, its key marked as a
    preview, and the debounced bake then writes the exact tile (the synchronous bake's). A move past the bank queues
    the two keys around it; a camera altitude the bank has no key of, or an atmosphere whose tables are not built,
    queues none (their own bakes come first)."""
    from atmos_addon.physics import precise
    from atmos_addon.physics.precise import bake, bank

    monkeypatch.setattr(bank, "_BANK", collections.OrderedDict())
    scene = _scene(addon)                                 # sun at 20 deg: keys 20, 22, 18, 24, 16, 26
    _move_sun(scene, 19.0)
    precise_tables.bake_on_worker(scene)
    precise_tables.wait_for_worker()                      # the exact tile written, then the bank's fill submitted
    assert precise_tables._bank_jobs
    assert precise_tables.wait_for_bank()
    request = precise_tables._request(scene)
    altitude = request.path.keys[0][0]
    options = {"multiple_scattering": request.multiple, "ground_albedo": request.albedo}
    assert all(precise.banked(request.atmosphere, altitude, unit, **options)
               for unit in precise.bank_units_around(math.radians(19.0), precise_tables.BANK_SPAN))
    assert not precise_tables.show_banked(scene)          # the image is the scene's: nothing to show
    _move_sun(scene, 21.0)
    moved = precise_tables._request(scene)
    integrate = precise.integrate_tile
    monkeypatch.setattr(bake, "integrate_tile", lambda *args, **kwargs: pytest.fail("integrated"))
    assert precise_tables.show_banked(scene)
    monkeypatch.setattr(bake, "integrate_tile", integrate)
    assert _image()[precise_tables._KEY] == moved.key + precise_tables.PREVIEW_MARK
    expected = precise.tile_from_bank(moved.atmosphere, altitude, moved.path.keys[0][1], **options)
    first_look = _pixels()
    assert np.array_equal(first_look, _tile_pixels(expected))
    assert not precise_tables.show_banked(scene)          # written once per position
    precise_tables.bake_on_worker(scene)                  # the debounced bake: the exact tile over it
    precise_tables.wait_for_worker()
    assert _image()[precise_tables._KEY] == moved.key
    exact = _pixels()
    relative = np.abs(first_look - exact) / np.maximum(np.abs(exact), 1e-3 * np.abs(exact).max())
    assert 0.0 < np.percentile(relative, 99) < 0.01      # the animation's mid-step error by day
    precise_tables.bake(scene, force=True)
    assert np.array_equal(_pixels(), exact)
    assert precise_tables.wait_for_bank()

    _move_sun(scene, 31.0)                                # past the bank: the two keys around it are queued
    assert not precise_tables.show_banked(scene)
    k, _ = precise.sun_key_bracket(math.radians(31.0))
    assert {key[2] for key in precise_tables._bank_jobs} == {k, k + 1}
    assert precise_tables.wait_for_bank()
    assert precise_tables.show_banked(scene)              # the next move there shows at once
    precise_tables.fill_bank(scene)                       # keys under way when the scene's own bake is handed over:
    jobs = list(precise_tables._bank_jobs.values())       # dropped, a running one stopped at its next block of rows
    assert jobs
    precise_tables.bake_on_worker(scene)
    assert not precise_tables._bank_jobs and all(future.cancelled() or stop.is_set() for future, stop in jobs)
    precise_tables.wait_for_worker()
    assert _image()[precise_tables._KEY] == precise_tables._request(scene).key
    assert precise_tables.wait_for_bank()

    camera = scene.camera
    with _handler_held():
        camera.location.z += 200.0
        bpy.context.view_layer.update()
    assert not precise_tables.show_banked(scene) and not precise_tables._bank_jobs
    with _handler_held():
        camera.location.z -= 200.0
        scene.atmos.mie_scattering_per_km = tuple(v * 1.2 for v in scene.atmos.mie_scattering_per_km)
        bpy.context.view_layer.update()
    assert not precise_tables.show_banked(scene) and not precise_tables._bank_jobs
    precise_tables.cancel_pending()
    assert not precise_tables._bank_jobs


def test_the_interfaces_follow_shows_a_banked_sun_move_then_bakes_the_exact_tile(addon, monkeypatch):
    """What a sun drag does in the interface (``precise_tables.interactive``), through the handler's ``follow``: the
    bake of Enable fills the bank, a move among its keys is shown by ``follow`` itself, and the debounced bake (its
    timer fired here) writes the exact tile, which a save would also wait for."""
    from atmos_addon.physics import precise
    from atmos_addon.physics.precise import bank

    monkeypatch.setattr(bank, "_BANK", collections.OrderedDict())
    monkeypatch.setattr(precise_tables, "interactive", lambda: True)
    scene = _scene(addon)
    precise_tables.bake(scene, force=True)               # Enable's (or Refresh's) bake, in the interface
    assert precise_tables._bank_jobs and precise_tables.wait_for_bank()
    _move_sun(scene, 20.7)
    request = precise_tables._request(scene)
    precise_tables.follow(scene)
    assert _image()[precise_tables._KEY] == request.key + precise_tables.PREVIEW_MARK
    assert not precise_tables.pending()                   # the exact tile waits for the debounced timer
    precise_tables._later.flush()
    precise_tables.wait_for_worker()
    assert _image()[precise_tables._KEY] == request.key
    precise_tables.cancel_pending()
