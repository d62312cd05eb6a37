# SPDX-License-Identifier: GPL-3.0-or-later
"""At which camera clip end / clip start ratio does Eevee's world go one flat colour? (the limit is atmos_addon.plan.EEVEE_CLIP_RATIO_LIMIT)

    .venv/bpy-5.2.3/bin/python tools/measure_eevee_clip_range.py [--ratios 1.2e7,1.6e7,2e7]

An empty file whose world is Blender's own Sky Texture and a camera pitched 80 degrees up from straight down
(looking just below the horizon band), Eevee at 32x16 px; for each clip start and ratio it prints whether the sky still varies (the
relative spread of its pixels) or is flat (spread 0, or no finite pixel). Not a test: Blender's limit, measured.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO_ROOT / "tests" / "blender"))

import bpy  # noqa: E402
import numpy as np  # noqa: E402

from render_utils import EEVEE_ENGINE, render_to_array, reset_scene, set_engine, set_use_nodes  # noqa: E402


def sky_scene():
    scene = reset_scene()
    world = bpy.data.worlds.new("Sky")
    scene.world = world
    set_use_nodes(world)
    tree = world.node_tree
    sky = tree.nodes.new("ShaderNodeTexSky")
    tree.links.new(sky.outputs[0], tree.nodes["Background"].inputs[0])
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.rotation_euler = (math.radians(80.0), 0.0, 0.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    set_engine(scene, EEVEE_ENGINE, width=32, height=16)
    return scene


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--starts", default="0.001,0.01,0.05,0.1,0.5,1,10", help="clip starts, scene units")
    parser.add_argument("--ratios", default="1e7,1.2e7,1.4e7,1.6e7,1.8e7,2e7,2.2e7,3e7")
    args = parser.parse_args(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:])
    starts = [float(v) for v in args.starts.split(",")]
    ratios = [float(v) for v in args.ratios.split(",")]
    scene = sky_scene()
    print(f"Blender {bpy.app.version_string}, Eevee, Sky Texture; 'flat' = the sky is one colour")
    print("| clip start | " + " | ".join(f"{r:.2g}" for r in ratios) + " |")
    print("|---:|" + "---|" * len(ratios))
    for start in starts:
        cells = []
        for ratio in ratios:
            scene.camera.data.clip_start, scene.camera.data.clip_end = start, start * ratio
            pixels = render_to_array(scene)[..., :3]
            spread = float(pixels.std(axis=(0, 1)).mean() / pixels.mean()) if np.isfinite(pixels).all() else 0.0
            cells.append("sky" if spread > 1e-3 else "flat")
        print(f"| {start:g} | " + " | ".join(cells) + " |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
