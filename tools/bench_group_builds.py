# SPDX-License-Identifier: GPL-3.0-or-later
"""What building each Atmos node group costs, and why a large group costs more than its size.

    .venv/bpy-5.2.3/bin/python tools/bench_group_builds.py [--repeats 3]

Builds, in a fresh file, the Precise level's groups an enable may build: the Compositor mode's per-sample "Atmos
Aerial Perspective", the Per Pixel mode's compositor group (a colour one vector socket, as in the shader groups), the
world's "Atmos Sky" and its camera "Atmos Sky View"; prints each one's node count (its own, and with its parts' nodes
counted as if inlined: ``atmos_addon.node_groups.parts``) and the median wall time of ``--repeats`` builds, its parts built
anew each time.
Then the cost of one ``nodes.new`` and one ``links.new`` in a compositor tree already holding 100, 400 and 1600 nodes:
Blender re-runs the tree's update over the nodes already there at every edit, so a build grows with the square of
its node count. Python wall time in background mode; not a test.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import bpy  # noqa: E402

from atmos_addon.node_groups import aerial_perspective, parts, per_pixel, registry, sky, sky_view, stamps  # noqa: E402
from atmos_addon.node_groups.sky import SkyFeatures  # noqa: E402
from atmos_addon.node_groups.terms import AerialFeatures  # noqa: E402


def _builds() -> tuple[tuple[str, str, object], ...]:
    precise = AerialFeatures(level="precise")
    return (
        ("Atmos Aerial Perspective (Compositor mode, per sample)", "ShaderNodeTree",
         lambda tree: aerial_perspective.build_aerial_perspective(tree, precise)),
        ("Atmos Aerial Composite (Per Pixel mode)", "CompositorNodeTree",
         lambda tree: per_pixel.build_per_pixel_composite(tree, precise)),
        ("Atmos Sky", "ShaderNodeTree", lambda tree: sky.build_sky(tree, SkyFeatures(level="precise"))),
        ("Atmos Sky View", "ShaderNodeTree", lambda tree: sky_view.build_sky_view(tree, SkyFeatures(level="precise"))),
    )


def group_builds(repeats: int) -> list[str]:
    rows = []
    for label, tree_type, build in _builds():
        times, count = [], 0
        for _ in range(repeats):
            tree = bpy.data.node_groups.new("bench", tree_type)
            start = time.perf_counter()
            build(tree)
            times.append(time.perf_counter() - start)
            count = f"{len(tree.nodes)} ({parts.inline_count(tree)})"
            bpy.data.node_groups.remove(tree)
            registry.remove_unused(stamps.PART_KINDS)   # its parts: built again by the next repeat
        rows.append(f"| {label} | {count} | {statistics.median(times):.2f} s |")
    return rows


def edit_costs() -> list[str]:
    rows = []
    for size in (100, 400, 1600):
        tree = bpy.data.node_groups.new("bench", "CompositorNodeTree")
        start = time.perf_counter()
        nodes = [tree.nodes.new("ShaderNodeMath") for _ in range(size)]
        added = time.perf_counter() - start
        start = time.perf_counter()
        for source, target in zip(nodes, nodes[1:]):
            tree.links.new(source.outputs[0], target.inputs[0])
        linked = time.perf_counter() - start
        rows.append(f"| {size} | {1000.0 * added / size:.3f} ms | {1000.0 * linked / (size - 1):.3f} ms |")
        bpy.data.node_groups.remove(tree)
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    print(f"Blender {bpy.app.version_string}, median of {args.repeats} builds\n")
    print("| group (Precise) | nodes (with its parts inlined) | build |\n|---|---:|---:|")
    print("\n".join(group_builds(args.repeats)))
    print("\n| nodes built (one chain) | nodes.new, mean per node | links.new, mean per link |\n|---:|---:|---:|")
    print("\n".join(edit_costs()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
