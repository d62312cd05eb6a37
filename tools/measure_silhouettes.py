# SPDX-License-Identifier: GPL-3.0-or-later
"""Silhouette error of the Per Pixel and Compositor modes against the per-sample reference -> docs/silhouettes.md.

    .venv/bpy-5.2.3/bin/python tools/measure_silhouettes.py [--engines CYCLES,EEVEE] [--source DIR] [--no-write]

The scene and the reference are ``tests/blender/silhouette_scenes.py``'s (what ``test_silhouettes.py`` asserts):
a plane 20 km away whose top edge stands against the sky (the ridge) and a plane 200 m away over it (near/far),
emissive and textured, the clear preset, the sun 30 deg up. The reference is the same render with the atmosphere
applied to every sample inside the shader (I F_ex + L_in from the Aerial Perspective group), so the two differ
only by what compositing filtered passes cannot know. Each variant changes the scene the same way for both:

- default: the scene as built (Cycles Blackman-Harris 1.5 px, Eevee 1.5 px filter);
- film transparent: Film > Transparent (the sky's pixels transparent; the ridge's edge then meets nothing);
- holdout: the near plane in a collection marked Holdout (the far plane's edge meets a hole);
- depth of field: focus at 200 m, f/0.03 (the far plane blurred over about 2 px at 48 px across);
- motion blur: the near plane moving 3 px across the frame during the shutter.

Errors are |Atmos - reference| / reference, the largest over RGB, over the edge pixels of each kind: a surface
covering the pixel in part against the sky (or the hole), and the near plane covering it in part over the far
one ("inside" leaves out the frame's own border pixels, whose neighbourhood the frame cuts). ``--source DIR``
measures another checkout's ``atmos_addon`` (a before/after comparison) with this scene and reference.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
DOC = REPO_ROOT / "docs" / "silhouettes.md"
VARIANTS = ("default", "film transparent", "holdout", "depth of field", "motion blur")
MODES = ("PER_PIXEL", "COMPOSITOR")
MODE_NAMES = {"PER_PIXEL": "Per Pixel", "COMPOSITOR": "Compositor"}


def apply_variant(ss, scene, variant: str, width: int) -> None:
    """Change ``scene`` as ``variant`` says (module docstring); ``ss``: the scenes module."""
    import bpy

    if variant == "film transparent":
        scene.render.film_transparent = True
    elif variant == "holdout":
        ss.hold_out(scene, "Near")
    elif variant == "depth of field":
        dof = scene.camera.data.dof
        dof.use_dof, dof.focus_distance, dof.aperture_fstop = True, 200.0, 0.03
    elif variant == "motion blur":
        near = bpy.data.objects["Near"]
        pixel_m = 2.0 * math.tan(math.radians(10.0)) * 200.0 / width
        scene.frame_set(1)
        near.location.x = 0.0
        near.keyframe_insert("location", index=0, frame=1)
        near.location.x = 6.0 * pixel_m   # 3 px over the default half-frame shutter
        near.keyframe_insert("location", index=0, frame=2)
        scene.frame_set(1)
        scene.render.use_motion_blur = True
    elif variant != "default":
        raise ValueError(variant)


def measure(ss, engine: str, mode: str, variant: str, width: int, height: int, samples: int) -> dict:
    scene = ss.build(engine, mode, width, height, samples)
    apply_variant(ss, scene, variant, width)
    result = ss.images(scene)
    row = {}
    for edge in ss.EDGES:
        pixels = ss.edge_pixels(edge, result)
        errors, inside = ss.errors(result, pixels), ss.errors(result, ss.inside_frame(pixels))
        row[edge] = (int(pixels.sum()), float(errors.mean()) if errors.size else math.nan,
                     float(errors.max()) if errors.size else math.nan,
                     float(inside.max()) if inside.size else math.nan)
    interior = ss.errors(result, ss.interior_pixels(result))
    row["interior"] = float(interior.max()) if interior.size else math.nan
    return row


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--engines", default="CYCLES,EEVEE")
    parser.add_argument("--variants", default=",".join(VARIANTS))
    parser.add_argument("--width", type=int, default=48)
    parser.add_argument("--height", type=int, default=24)
    parser.add_argument("--samples", type=int, default=32, help="samples per pixel (Cycles)")
    parser.add_argument("--eevee-samples", type=int, default=16, help="samples per pixel (Eevee)")
    parser.add_argument("--source", type=Path, default=REPO_ROOT,
                        help="the checkout whose atmos_addon is measured (default: this one)")
    parser.add_argument("--no-write", action="store_true", help="print the table only")
    args = parser.parse_args(argv)
    sys.path[:0] = [str(args.source.resolve()), str(REPO_ROOT / "tests" / "blender")]
    import bpy
    import render_utils as ru
    import silhouette_scenes as ss

    start = time.perf_counter()
    lines = ["| engine | mode | variant | surface/sky px | mean | max | near/far px | mean | max | max inside "
             "| interior max |", "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for engine in args.engines.upper().split(","):
        engine_id = "CYCLES" if engine == "CYCLES" else ru.EEVEE_ENGINE
        samples = args.samples if engine_id == "CYCLES" else args.eevee_samples
        for variant in args.variants.split(","):
            for mode in MODES:
                row = measure(ss, engine_id, mode, variant, args.width, args.height, samples)
                ridge, near = row["ridge"], row["near/far"]
                line = (f"| {engine.capitalize()} | {MODE_NAMES[mode]} | {variant} | {ridge[0]} | {ridge[1]:.2%} | "
                        f"{ridge[2]:.2%} | {near[0]} | {near[1]:.2%} | {near[2]:.2%} | {near[3]:.2%} | "
                        f"{row['interior']:.2%} |").replace("nan%", "-")
                lines.append(line)
                print(line, flush=True)
    import atmos_addon

    atmos_addon.unregister()
    table = "\n".join(lines)
    print(f"({time.perf_counter() - start:.0f} s)")
    if not args.no_write:
        shown = [a for a in (argv if argv is not None else sys.argv[1:])]
        command = " ".join(["python tools/measure_silhouettes.py", *shown])
        commit = subprocess.run(["git", "-C", str(args.source), "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True).stdout.strip() or str(args.source)
        source = "" if args.source.resolve() == REPO_ROOT else f" (`atmos_addon` of {commit})"
        engines = ", ".join(engine.capitalize() for engine in args.engines.upper().split(","))
        section = (f"## Blender {bpy.app.version_string}, {engines}{source}\n\n    {command}\n\n{platform.system()}, "
                   f"{os.cpu_count()} cores; {args.width}x{args.height} px, {args.samples} (Cycles) / "
                   f"{args.eevee_samples} (Eevee) samples per pixel.\n\n{table}\n")
        write_doc(section)
    return 0


def _version_key(section: str) -> tuple:
    """Minus the Blender version of a section's heading ("## Blender 5.2.3 LTS, ..."), for newest first."""
    words = section.split("\n", 1)[0].split()
    numbers = words[2].split(".") if len(words) > 2 else []
    return tuple(-int(n) for n in numbers if n.isdigit())


def write_doc(section: str) -> None:
    """Replace (or add) this section (by its heading) of docs/silhouettes.md below the page's hand-written part."""
    text = DOC.read_text()
    marker = section.split("\n", 1)[0]
    parts = text.split("\n## ")
    head, sections = parts[0], ["## " + p for p in parts[1:]]
    kept = [s for s in sections if not s.startswith("## Blender") or not s.startswith(marker + "\n")]
    written = [s for s in kept if not s.startswith("## Blender")]
    # This checkout's sections first (newest Blender first, then by engines), another checkout's after them.
    measured = sorted([s for s in kept if s.startswith("## Blender")] + [section],
                      key=lambda s: ("(`atmos_addon` of" in s.split("\n", 1)[0], _version_key(s), s.split("\n", 1)[0]))
    DOC.write_text(head.rstrip("\n") + "\n\n" + "\n".join(s.rstrip("\n") + "\n" for s in written + measured))
    print(f"wrote {DOC.relative_to(REPO_ROOT)}")


if __name__ == "__main__":
    raise SystemExit(main())
