# SPDX-License-Identifier: GPL-3.0-or-later
"""Write the .blend a release of Atmos saves, and its renders, for the migration test (tests/blender/test_migration.py).

Run it from a checkout of the release to keep, with that checkout's code:

    git worktree add /tmp/release <commit>
    cd /tmp/release && /path/to/.venv/bpy-5.2.3/bin/python /path/to/tools/make_release_blend.py \\
        --output /path/to/tests/blender/data/atmos_<commit>.blend

Scenes of one file, built from an empty factory file: "Compositor" (Fast level, Compositor mode, the Atmos sky),
"Per Pixel" (Per Pixel mode, 800 m up; the Balanced level in the stored addba16 and 7df8acd files, Fast since it
was retired in December 2026) and, with ``--precise`` (releases that have it, from
7df8acd on), "Precise" (Precise level with multiple scattering, Compositor mode, its baked table), each with
emissive planes at 300 m, 3 km and 20 km
(grey 0.2, 0.5, 0.8) against the Atmos sky, and a sun lamp 40 degrees up. Each scene is rendered in Cycles
(32 x 16 px, 1 sample, box filter: emission and the sky only, so the pixels do not depend on Cycles' sampling) and
its pixels saved beside the file as <output stem>_<scene>.npy: what the release rendered. Save it with the oldest
supported Blender (newer ones read older files).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import bpy
import numpy as np

CHECKOUT = Path.cwd()
sys.path.insert(0, str(CHECKOUT))
sys.path.insert(0, str(CHECKOUT / "tests" / "blender"))

import atmos_addon  # noqa: E402
import atmos_addon.api  # noqa: E402
import render_utils as ru  # noqa: E402

WIDTH, HEIGHT = 32, 16


def build_scene(scene, mode: str, quality: str, altitude_m: float) -> None:
    ru.make_camera(scene, location=(0.0, 0.0, 2.0), rotation_euler=(math.pi / 2.0, 0.0, 0.0),
                   fov_rad=math.radians(50.0), clip_start=0.5, clip_end=50_000.0)
    sun = bpy.data.objects.new(f"Sun {scene.name}", bpy.data.lights.new(f"Sun {scene.name}", "SUN"))
    scene.collection.objects.link(sun)
    for distance, azimuth, grey in ((300.0, -15.0, 0.2), (3000.0, 0.0, 0.5), (20_000.0, 15.0, 0.8)):
        a = math.radians(azimuth)
        half = distance * math.tan(math.radians(4.0))
        centre = np.array([distance * math.sin(a), distance * math.cos(a), 2.0])
        right = np.array([math.cos(a), -math.sin(a), 0.0]) * half
        up = np.array([0.0, 0.0, half])
        material = bpy.data.materials.get(f"Grey {grey}") or ru.emission_material(f"Grey {grey}", (grey,) * 3)
        ru.make_plane(scene, f"Plane {distance:g} {scene.name}", [centre - right - up, centre + right - up,
                                                                   centre + right + up, centre - right + up], material)
    ru.set_engine(scene, "CYCLES", width=WIDTH, height=HEIGHT)
    scene.cycles.seed = 5
    atmos_addon.api.enable(scene, preset="clear", sun_elevation_deg=40.0, sun_azimuth_deg=160.0, render_mode=mode,
                           quality=quality, origin_altitude=altitude_m)
    scene.render.use_compositing = True


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", required=True, help="the .blend to write")
    parser.add_argument("--precise", action="store_true", help="add the Precise scene")
    args = parser.parse_args(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:])
    output = Path(args.output).resolve()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    atmos_addon.register()
    first = bpy.context.scene
    first.name = "Compositor"
    second = bpy.data.scenes.new("Per Pixel")
    build_scene(first, "COMPOSITOR", "FAST", 0.0)
    build_scene(second, "PER_PIXEL", "FAST", 800.0)
    scenes = [first, second]
    if args.precise:
        scenes.append(bpy.data.scenes.new("Precise"))
        build_scene(scenes[-1], "COMPOSITOR", "PRECISE", 0.0)
    renders = {}
    for scene in scenes:
        renders[scene.name] = ru.render_to_array(scene)[..., :3]
    bpy.ops.wm.save_as_mainfile(filepath=str(output), compress=True)
    for name, pixels in renders.items():
        np.save(output.with_name(f"{output.stem}_{name.lower().replace(' ', '_')}.npy"), pixels.astype(np.float32))
    print(json.dumps({"blend": str(output), "blender": bpy.app.version_string, "scenes": list(renders)}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
