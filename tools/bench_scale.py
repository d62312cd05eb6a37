# SPDX-License-Identifier: GPL-3.0-or-later
"""One Blender version's scale measurements for ``tools/bench.py``: prints one JSON line (seconds / ms).

    .venv/bpy-5.2.3/bin/python tools/bench_scale.py --materials 5000 --objects 20000 [--profile] [--animated-frames 250]
        [--unique 5000]
"""

from __future__ import annotations

import argparse
import cProfile
import json
import math
import pstats
import statistics
import sys
import time
import warnings
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO_ROOT))

import bpy  # noqa: E402

import atmos_addon  # noqa: E402
from atmos_addon import presets  # noqa: E402
from atmos_addon.blender import orchestrator  # noqa: E402


def triangle(index: int):
    """A one-triangle mesh with a node-based material of its own, both numbered ``index``."""
    material = bpy.data.materials.new(f"Material {index}")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        material.use_nodes = True
    mesh = bpy.data.meshes.new(f"Mesh {index}")
    mesh.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
    mesh.materials.append(material)
    return mesh


def build_scene(n_materials: int, n_objects: int):
    """An empty file with a camera, a sun and ``n_objects`` triangles sharing ``n_materials`` meshes."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(camera)
    scene.camera = camera
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.rotation_euler = (math.radians(40.0), 0.0, 0.5)
    scene.collection.objects.link(sun)
    meshes = [triangle(index) for index in range(n_materials)]
    objects = scene.collection.objects
    for index in range(n_objects):
        objects.link(bpy.data.objects.new(f"Object {index}", meshes[index % n_materials]))
    bpy.context.view_layer.update()
    return scene


def build_unique_scene(n_objects: int):
    """An empty file with a camera and ``n_objects`` triangles, each with its own mesh and its own material; no world
    and no sun lamp (Atmos adds both): a pipeline's scene, whose objects share nothing."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.rotation_euler = (math.radians(90.0), 0.0, 0.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    for index in range(n_objects):
        obj = bpy.data.objects.new(f"Object {index}", triangle(index))
        obj.location = (3.0 * (index % 100), 100.0 + 3.0 * (index // 100), 0.0)
        scene.collection.objects.link(obj)
    return scene


def measure_unique(n_objects: int, repeats: int) -> dict:
    """Through the Python API, on :func:`build_unique_scene`, in a process that has baked nothing yet (the atmosphere's
    tables are built in the enable): the enable and the Precise bakes in it, a sun move
    (median of ``repeats``, each to a new elevation: a tile baked each time), an atmosphere edit (the visibility), and
    a frame change with Atmos on and off (medians, interleaved: the handlers' cost when nothing changes)."""
    from atmos_addon import api
    from atmos_addon.blender.apply import precise_tables

    scene = build_unique_scene(n_objects)
    baked = []
    bake = precise_tables.bake

    def counted(*args, **kwargs):
        tiles = bake(*args, **kwargs)
        baked.append(tiles)
        return tiles

    precise_tables.bake = counted
    try:
        start = time.perf_counter()
        api.enable(scene, preset="clear")
        results = {"unique_enable_s": time.perf_counter() - start, "unique_enable_bakes": sum(1 for n in baked if n)}
    finally:
        precise_tables.bake = bake
    moves = []
    for index in range(repeats):
        start = time.perf_counter()
        api.set_sun(scene, 30.0 + 2.0 * index, 45.0)
        moves.append(time.perf_counter() - start)
    results["unique_set_sun_s"] = statistics.median(moves)
    start = time.perf_counter()
    scene.atmos.visibility_km = 40.0
    results["unique_edit_s"] = time.perf_counter() - start
    on, off = [], []
    scene.frame_end = 2 * repeats + 2
    for index in range(repeats):
        for enabled, times in ((True, on), (False, off)):
            if enabled != api.is_enabled(scene):
                api.enable(scene) if enabled else api.disable(scene)
            start = time.perf_counter()
            scene.frame_set(2 + 2 * index + (0 if enabled else 1))
            times.append(time.perf_counter() - start)
    results["unique_frame_on_ms"] = statistics.median(on) * 1000.0
    results["unique_frame_off_ms"] = statistics.median(off) * 1000.0
    api.disable(scene)
    return results


def key_the_sun(scene, frames: int) -> None:
    """Key the scene's sun lamp from 30 deg up on frame 1 to 2 deg on frame ``frames`` (a sunset)."""
    sun = next(o for o in scene.objects if o.type == "LIGHT")
    scene.frame_start, scene.frame_end = 1, frames
    for frame, elevation in ((1, 30.0), (frames, 2.0)):
        sun.rotation_euler = (math.radians(90.0 - elevation), 0.0, 0.5)
        sun.keyframe_insert("rotation_euler", frame=frame)
    scene.frame_set(1)


def time_syncs(scene, repeats: int) -> float:
    """Mean ms of one ``mie_scattering_per_km`` write (its update callback syncs the parameters)."""
    settings = scene.atmos
    base = tuple(settings.mie_scattering_per_km)
    start = time.perf_counter()
    for index in range(repeats):
        scale = 1.0 + 0.01 * (index % 2 + 1)
        settings.mie_scattering_per_km = tuple(v * scale for v in base)
    elapsed = time.perf_counter() - start
    settings.mie_scattering_per_km = base
    return elapsed / repeats * 1000.0


def time_sun_moves(scene, repeats: int, after_move=None, *, axis: int = 0) -> float:
    """Median seconds of a depsgraph update after the sun lamp turns by 0.5 deg about its Euler ``axis`` (0: in
    elevation, where in the background the Precise tile is re-baked at once, the interface baking 0.3 s after the
    last move; 2: in azimuth, which no table depends on); ``after_move(sun)`` runs between the move and the
    update."""
    sun = next(o for o in scene.objects if o.type == "LIGHT")
    times = []
    for _ in range(repeats):
        sun.rotation_euler[axis] += math.radians(0.5)
        if after_move is not None:
            after_move(sun)
        start = time.perf_counter()
        bpy.context.view_layer.update()
        times.append(time.perf_counter() - start)
    return sorted(times)[len(times) // 2]


def time_handler_on_sun_turns(scene, repeats: int) -> tuple[float, float]:
    """(median seconds of the depsgraph update after an azimuth turn of the sun, median seconds of Atmos's handler
    in it): the Python a sun drag costs, no table to re-bake."""
    handler = next(h for h in bpy.app.handlers.depsgraph_update_post if h.__name__ == "on_depsgraph_update")
    spent = []

    def timed(scene_, depsgraph) -> None:
        start = time.perf_counter()
        handler(scene_, depsgraph)
        spent.append(time.perf_counter() - start)

    handlers = bpy.app.handlers.depsgraph_update_post
    index = list(handlers).index(handler)
    handlers[index] = timed
    try:
        update = time_sun_moves(scene, repeats, axis=2)
    finally:
        handlers[list(handlers).index(timed)] = handler
    return update, sorted(spent)[len(spent) // 2]


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--materials", type=int, default=5000)
    parser.add_argument("--objects", type=int, default=20000)
    parser.add_argument("--small", type=int, default=10)
    parser.add_argument("--repeats", type=int, default=50)
    parser.add_argument("--profile", action="store_true")
    parser.add_argument("--animated-frames", type=int, default=250,
                        help="frames of the sun's keys for the animated enable (0: not measured)")
    parser.add_argument("--unique", type=int, default=5000,
                        help="objects of the scene whose objects share no mesh or material (0: not measured)")
    args = parser.parse_args()
    atmos_addon.register()
    results = {"blender": bpy.app.version_string}
    if args.unique:   # first, as a pipeline's script meets it: nothing baked or built in this process yet
        results.update(measure_unique(args.unique, 5))

    scene = build_scene(args.small, args.small * 4)
    orchestrator.enable_effect(scene)
    time_syncs(scene, 3)  # warm the caches
    results["sync_small_ms"] = time_syncs(scene, args.repeats)
    orchestrator.disable_effect(scene)

    start = time.perf_counter()
    scene = build_scene(args.materials, args.objects)
    results["build_s"] = time.perf_counter() - start
    profile = cProfile.Profile() if args.profile else None
    start, cpu_start = time.perf_counter(), time.process_time()
    if profile:
        profile.enable()
    orchestrator.enable_effect(scene)
    if profile:
        profile.disable()
    results["enable_s"] = time.perf_counter() - start
    results["enable_cpu_s"] = time.process_time() - cpu_start   # the process's own CPU: less moved by other load
    if profile:
        pstats.Stats(profile, stream=sys.stdout).sort_stats("tottime").print_stats(15)
    time_syncs(scene, 3)
    results["sync_big_ms"] = time_syncs(scene, args.repeats)
    bpy.context.view_layer.update()   # the first evaluation after an enable (every edited material) is not timed
    results["sun_move_s"] = time_sun_moves(scene, 3)
    results["sun_turn_s"], results["sun_turn_handler_s"] = time_handler_on_sun_turns(scene, 5)
    handlers = list(bpy.app.handlers.depsgraph_update_post)
    bpy.app.handlers.depsgraph_update_post.clear()
    try:
        results["sun_move_plain_s"] = time_sun_moves(scene, 3)
    finally:
        bpy.app.handlers.depsgraph_update_post.extend(handlers)
    preset_times = []
    for name in ("overcast", "clear", "mars", "sunset"):
        start = time.perf_counter()
        orchestrator.apply_atmosphere(scene, presets.load(name).atmosphere)
        preset_times.append(time.perf_counter() - start)
    results["preset_ms"] = sum(preset_times[1:]) / len(preset_times[1:]) * 1000.0  # the first loads the parser
    start = time.perf_counter()
    orchestrator.refresh_effect(scene)
    results["refresh_s"] = time.perf_counter() - start
    start = time.perf_counter()
    for mode in ("COMPOSITOR", "PER_PIXEL"):   # the setting's update callback: the outputs group rebuilt
        scene.atmos.render_mode = mode
    results["mode_switch_s"] = (time.perf_counter() - start) / 2.0
    start = time.perf_counter()
    orchestrator.disable_effect(scene)
    results["disable_s"] = time.perf_counter() - start
    if args.animated_frames > 1:   # the same scene, its sun keyed: every frame's inputs and the key tiles
        scene = build_scene(args.materials, args.objects)
        key_the_sun(scene, args.animated_frames)
        start = time.perf_counter()
        orchestrator.enable_effect(scene)
        results["enable_animated_s"] = time.perf_counter() - start
        results["animated_key_tiles"] = int(scene.get("atmos_precise_key_tiles", 1))
    atmos_addon.unregister()
    print(json.dumps(results), flush=True)


if __name__ == "__main__":
    main()
