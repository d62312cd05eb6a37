# SPDX-License-Identifier: GPL-3.0-or-later
"""What a depsgraph update costs in a large scene after each kind of edit Atmos's sync makes, and whether the
evaluated scene then holds a custom property just written (what the groups' Attribute nodes and drivers read); and
the first update after an enable (every edited material evaluated); and a sun move that reaches a world node by
drivers on the sun object against one that writes and tags the scene.

    .venv/bpy-5.2.3/bin/python tools/measure_scene_tags.py [--materials 5000] [--objects 20000] [--repeats 3]

The scene of ``tools/bench_scale.py`` with Atmos enabled (its default); each edit is made, then
``view_layer.update()`` is timed (median of ``--repeats``). Wall time in background mode; not a test.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import bpy  # noqa: E402

import atmos_addon  # noqa: E402
from atmos_addon.blender import orchestrator  # noqa: E402
from bench_scale import build_scene, time_sun_moves  # noqa: E402

PROBE = "atmos_probe"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--materials", type=int, default=5000)
    parser.add_argument("--objects", type=int, default=20000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    atmos_addon.register()
    scene = build_scene(args.materials, args.objects)
    orchestrator.enable_effect(scene)
    layer = bpy.context.view_layer
    start = time.perf_counter()
    layer.update()
    first = time.perf_counter() - start
    scene[PROBE] = 0.0
    layer.update()
    base = tuple(scene.atmos.mie_scattering_per_km)
    edits = (
        ("a scene custom property written, no tag", lambda k: None),
        ("an Atmos setting (Mie scattering) written: its sync", lambda k: setattr(
            scene.atmos, "mie_scattering_per_km", tuple(v * (1.0 + 0.01 * (k % 2 + 1)) for v in base))),
        ("scene.render.fps written (Blender's own setting)", lambda k: setattr(scene.render, "fps", scene.render.fps)),
        ("world.update_tag()", lambda k: scene.world.update_tag()),
        ("scene.update_tag()", lambda k: scene.update_tag()),
        ("scene.update_tag(refresh={'TIME'})", lambda k: scene.update_tag(refresh={"TIME"})),
    )
    depsgraph = bpy.context.evaluated_depsgraph_get()
    print(f"Blender {bpy.app.version_string}, {args.materials} materials, {args.objects} objects, Atmos enabled; "
          f"the first depsgraph update after the enable: {first:.2f} s")
    print("| edit (and a custom property written) | depsgraph update, median | evaluated scene has the property |")
    print("|---|---:|---|")
    for label, edit in edits:
        times, seen = [], True
        for k in range(args.repeats):
            value = scene[PROBE] + 1.0
            scene[PROBE] = value
            edit(k)
            start = time.perf_counter()
            layer.update()
            times.append(time.perf_counter() - start)
            seen = seen and depsgraph.scene_eval.get(PROBE) == value
        print(f"| {label} | {statistics.median(times) * 1000:.0f} ms | {'yes' if seen else 'no'} |")
    print()
    print(sun_moves(scene, args.repeats))
    atmos_addon.unregister()


def sun_moves(scene, repeats: int) -> str:
    """A sun move with Atmos's handler removed: the world's tree holding a Combine XYZ whose inputs are driven by the
    sun object's matrix (single-property drivers, no Python), then the same with the sun's direction also written as
    a scene custom property and the scene tagged (what a sync does). The depsgraph update, median."""
    sun = next(o for o in scene.objects if o.type == "LIGHT")
    combine = scene.world.node_tree.nodes.new("ShaderNodeCombineXYZ")
    for index, socket in enumerate(combine.inputs):
        driver = socket.driver_add("default_value").driver
        driver.type = "AVERAGE"
        variable = driver.variables.new()
        variable.type = "SINGLE_PROP"
        variable.targets[0].id_type = "OBJECT"
        variable.targets[0].id = sun
        variable.targets[0].data_path = f"matrix_world[2][{index}]"   # RNA indexes the stored columns: the +Z axis
    handlers = list(bpy.app.handlers.depsgraph_update_post)
    bpy.app.handlers.depsgraph_update_post.clear()
    bpy.context.view_layer.update()
    lines = ["| sun moved 0.5 deg, Atmos's handler removed | depsgraph update, median | driven = the sun's +Z axis |",
             "|---|---:|---|"]

    def tag(sun) -> None:
        scene[PROBE + "_sun"] = tuple(sun.matrix_world.col[2][:3])
        scene.update_tag()

    try:
        for label, after_move in (("a world node driven by the sun object", None),
                                  ("the same, and the direction written to the scene and the scene tagged", tag)):
            seconds = time_sun_moves(scene, repeats, after_move)
            follows = all(abs(combine.inputs[i].default_value - sun.matrix_world.col[2][i]) < 1e-6 for i in range(3))
            lines.append(f"| {label} | {seconds * 1000:.0f} ms | {'yes' if follows else 'no'} |")
    finally:
        bpy.app.handlers.depsgraph_update_post.extend(handlers)
    return "\n".join(lines)


if __name__ == "__main__":
    main()
