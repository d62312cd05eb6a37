# SPDX-License-Identifier: GPL-3.0-or-later
"""A far ridge against the overcast sky, cropped and enlarged 4x (nearest pixel): what docs/silhouettes.md shows
before and after the silhouette correction.

    .venv/bpy-5.2.3/bin/python tools/make_ridge_crop.py --output docs/silhouettes/ridge_after.png
    .venv/bpy-5.2.3/bin/python tools/make_ridge_crop.py --source OLD_CHECKOUT --output docs/silhouettes/ridge_before.png

The valley sample as ``render valley --preset overcast --sun-elevation 60 --engine cycles --samples 16 --resolution
960x540`` renders it (the default Per Pixel mode), only the crop's pixels rendered (Render Region, cropped), saved
as an 8-bit PNG in the scene's view transform. ``--source DIR`` renders with another checkout's ``atmos_addon``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
#: The crop, as fractions of the frame (left, bottom, right, top): where the farthest ridge meets the sky.
CROP = (0.45, 0.42, 0.62, 0.54)
ENLARGE = 4


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, required=True)
    parser.add_argument("--source", type=Path, default=REPO_ROOT,
                        help="the checkout whose atmos_addon renders (default: this one)")
    parser.add_argument("--resolution", default="960x540")
    parser.add_argument("--samples", type=int, default=16)
    parser.add_argument("--crop", default=",".join(str(v) for v in CROP),
                        help="left,bottom,right,top as fractions of the frame")
    args = parser.parse_args(argv)
    sys.path.insert(0, str(args.source.resolve()))
    import bpy
    import numpy as np

    import atmos_addon
    from atmos_addon import api
    from atmos_addon.sample_scenes import valley

    atmos_addon.register()
    width, height = (int(v) for v in args.resolution.split("x"))
    left, bottom, right, top = (float(v) for v in args.crop.split(","))
    scene = valley.build(resolution=(width, height))
    scene.render.engine = "CYCLES"
    scene.cycles.samples = args.samples
    api.enable(scene, preset="overcast", sun_elevation_deg=60.0)
    render = scene.render
    render.use_border, render.use_crop_to_border = True, True
    render.border_min_x, render.border_min_y, render.border_max_x, render.border_max_y = left, bottom, right, top
    settings = render.image_settings
    if hasattr(settings, "media_type"):
        settings.media_type = "IMAGE"
    settings.file_format, settings.color_mode, settings.color_depth = "PNG", "RGB", "8"
    with tempfile.TemporaryDirectory() as folder:
        render.filepath = str(Path(folder) / "crop.png")
        bpy.ops.render.render(write_still=True, scene=scene.name)
        image = bpy.data.images.load(render.filepath, check_existing=False)
        w, h = image.size
        pixels = np.empty(w * h * 4, dtype=np.float32)
        image.pixels.foreach_get(pixels)
        bpy.data.images.remove(image)
    big = np.repeat(np.repeat(pixels.reshape(h, w, 4), ENLARGE, axis=0), ENLARGE, axis=1)
    out = bpy.data.images.new("Ridge crop", w * ENLARGE, h * ENLARGE, alpha=False)
    out.pixels.foreach_set(np.ascontiguousarray(big).ravel())
    args.output.parent.mkdir(parents=True, exist_ok=True)
    out.filepath_raw = str(args.output.resolve())
    out.file_format = "PNG"
    out.save()
    print(f"wrote {args.output} ({w * ENLARGE}x{h * ENLARGE})")
    atmos_addon.unregister()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
