# SPDX-License-Identifier: GPL-3.0-or-later
"""Reflections that start far from the camera, In-Render mode: where the dome filters are exact, and where not.

    .venv/bpy-5.2.3/bin/python tools/measure_in_render_far_reflections.py [--samples 32]

Part 1, mirrors 50 km away in the top row of the In-Render test camera (32 x 16 px, 20 deg, 4.7 deg up there:
beyond the aerosols' dome, whose distance R_M(4.7 deg) is 14 km), reflecting a plain world (no Atmos sky) at
several elevations. A reflected ray that enters the aerosols' dome and leaves it again is exact (the filters
exp(-sigma L) entering and exp(sigma L - tau) leaving); one that never enters it has nothing to cancel the
world's compensation exp(tau_M(d)) and shows the sky that much too bright. Printed: In-Render / expected, the
expected value F_1 W + L_1 of the physics core with the dome clamp (W the world colour), per channel, 1 sample
per pixel at the pixel centre (the test suite's set-up; tests/blender/test_in_render.py).

Part 2, the sample valley (320 x 180, ``--samples``, "clear" preset, Atmos sky, Cycles CPU): bright outliers,
pixels whose luminance passes 2x and 3x the median of their 5 x 5 neighbourhood, in Compositor and In-Render
mode, and the brightest pixel of the band of the far ridges (rows 80-119 from the bottom). Fireflies from the
sky compensation show as extra outliers in In-Render mode.
"""

from __future__ import annotations

import argparse
import math
import platform
import sys
import tempfile
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO_ROOT))
sys.path.insert(0, str(REPO_ROOT / "tests" / "blender"))

import bpy  # noqa: E402
import numpy as np  # noqa: E402
from mathutils import Vector  # noqa: E402
from numpy.lib.stride_tricks import sliding_window_view  # noqa: E402

import atmos_addon  # noqa: E402
from atmos_addon import api  # noqa: E402
from atmos_addon.blender.apply import in_render
from atmos_addon.blender import orchestrator  # noqa: E402
from atmos_addon.sample_scenes import valley  # noqa: E402

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
#: (pixel column, elevation of the reflected ray in deg, its x direction)
FAR_MIRRORS = ((4, 10.0, 1.0), (12, -3.0, -1.0), (20, -1.0, 1.0), (28, -6.0, 1.0))


def far_mirrors(tmp: Path) -> None:
    import test_in_render as t  # the In-Render test scene and its expected values

    bpy.ops.wm.read_factory_settings(use_empty=True)
    atmos_addon.register()
    scene, _sun = t._scene()
    scene.cycles.max_bounces = scene.cycles.glossy_bounces = 4
    scene.atmos.sky_enabled = False
    scene.atmos.render_mode = "IN_RENDER"
    cases = []
    for column, elevation, x in FAR_MIRRORS:
        view = t._pixel_direction(column, 15)
        out = Vector((x, 0.3, math.tan(math.radians(elevation)))).normalized()
        t._mirror_towards(f"Mirror {column}", view, 50_000.0, out, 300.0)
        cases.append((column, elevation, view))
    orchestrator.enable_effect(scene)
    assert in_render.is_installed(scene)
    pixels = t._render(scene, tmp, "far_mirrors")
    print("| reflected ray elevation | within 0.1 % | In-Render / expected (R, G, B) |")
    print("|---:|---|---|")
    for column, elevation, view in cases:
        f1, l1 = t._dome_segment(scene, view, 50_000.0)
        ratio = pixels[15, column] / (f1 * np.asarray(t.WORLD_COLOUR) + l1)
        exact = "yes" if np.all(np.abs(ratio - 1.0) < 1e-3) else "no"
        print(f"| {elevation:+.0f} deg | {exact} | {', '.join(f'{r:.4f}' for r in ratio)} |")
    atmos_addon.unregister()


def outliers(image: np.ndarray) -> tuple[int, int]:
    luminance = image @ LUMINANCE
    median = np.median(sliding_window_view(np.pad(luminance, 2, mode="edge"), (5, 5)), axis=(-1, -2))
    ratio = luminance / np.maximum(median, 1e-9)
    return int((ratio > 2.0).sum()), int((ratio > 3.0).sum())


def valley_outliers(tmp: Path, samples: int) -> None:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    atmos_addon.register()
    scene = valley.build((320, 180))
    scene.render.engine = "CYCLES"
    cycles = scene.cycles
    cycles.samples, cycles.use_adaptive_sampling, cycles.use_denoising, cycles.device, cycles.seed = \
        samples, False, False, "CPU", 0
    scene.view_settings.view_transform = "Standard"
    settings = scene.render.image_settings
    settings.file_format, settings.color_depth = "OPEN_EXR", "32"
    images = {}
    for mode in ("COMPOSITOR", "IN_RENDER"):
        if mode == "COMPOSITOR":
            api.enable(scene, "clear", render_mode=mode)
        else:
            scene.atmos.render_mode = mode
        scene.render.filepath = str(tmp / f"valley_{mode}.exr")
        bpy.ops.render.render(write_still=True)
        image = bpy.data.images.load(scene.render.filepath, check_existing=False)
        width, height = image.size
        images[mode] = np.array(image.pixels[:], dtype=float).reshape(height, width, 4)[..., :3]
        bpy.data.images.remove(image)
    print(f"\n| valley, {samples} samples | pixels > 2x local median | > 3x | brightest pixel of the far ridges' "
          "band (luminance) | mean luminance |")
    print("|---|---:|---:|---:|---:|")
    for mode, image in images.items():
        two, three = outliers(image)
        band = image[80:120] @ LUMINANCE
        print(f"| {mode.replace('_', '-').title()} | {two} | {three} | {band.max():.3f} | "
              f"{(image @ LUMINANCE).mean():.4f} |")
    atmos_addon.unregister()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=32)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp_dir:
        tmp = Path(tmp_dir)
        far_mirrors(tmp)
        valley_outliers(tmp, args.samples)
    print(f"\nBlender {bpy.app.version_string}, {platform.system()}, Python {platform.python_version()}")


if __name__ == "__main__":
    main()
