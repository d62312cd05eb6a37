# SPDX-License-Identifier: GPL-3.0-or-later
"""What one node edit costs in a material, as a function of how many materials the file holds.

    .venv/bpy-5.2.3/bin/python tools/bench_node_edits.py [--materials 1000,5000]

Enabling Atmos makes two RNA edits per material (``nodes.new`` of the group node and its ``node_tree``
write, :mod:`atmos_addon.blender.apply.materials`); everything else is read with ``foreach_get`` or batched.
Each edit runs Blender's node-tree updater. This prints, per file size, the mean microseconds of each of
the two edits over every material of the file (an empty group as the target, as the bulk pass uses). In the
supported versions (4.5 and later) an edit costs the same with 1000 or 5000 materials, so an enable is linear in
the number of materials (docs/benchmarks.md).
"""

from __future__ import annotations

import argparse
import json
import time
import warnings

import bpy


def file_with_materials(count: int) -> list:
    """An empty file with ``count`` node-based materials (Principled BSDF and Material Output)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    materials = []
    for index in range(count):
        material = bpy.data.materials.new(f"Material {index}")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            material.use_nodes = True
        materials.append(material)
    return materials


def edit_costs_us(count: int) -> dict:
    """Mean us of ``nodes.new("ShaderNodeGroup")`` and of the group node's ``node_tree`` write."""
    materials = file_with_materials(count)
    group = bpy.data.node_groups.new("Empty Group", "ShaderNodeTree")
    start = time.perf_counter()
    nodes = [material.node_tree.nodes.new("ShaderNodeGroup") for material in materials]
    created = time.perf_counter()
    for node in nodes:
        node.node_tree = group
    done = time.perf_counter()
    return {"materials": count, "nodes_new_us": round((created - start) / count * 1e6, 1),
            "node_tree_write_us": round((done - created) / count * 1e6, 1)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--materials", default="1000,5000", help="comma-separated material counts")
    args = parser.parse_args()
    for count in (int(value) for value in args.materials.split(",")):
        print(json.dumps({"blender": bpy.app.version_string, **edit_costs_us(count)}), flush=True)


if __name__ == "__main__":
    main()
