# SPDX-License-Identifier: GPL-3.0-or-later
"""Render cost of each quality level on the sample valley: effect off, Fast, Precise; Cycles and Eevee.

    .venv/bpy-5.2.3/bin/python tools/bench_quality_cost.py [--engines cycles,eevee] [--resolution 320x180]
        [--samples 64] [--repeats 3] [--decompose] [--only off,fast-per-pixel-aerial-only,...]

Method. The valley (``sample_scenes/valley.py``) is built once and rendered in Compositor mode (or
Per Pixel: "-per-pixel") with ``api.enable(scene, preset, quality=...)``: "off" is the effect disabled (the
valley's plain world), "fast" and "precise" the two levels (Balanced, measured here until December 2026, was
retired). Cycles renders on the CPU with ``samples`` samples, adaptive sampling off, a fixed seed and denoising
off; Eevee with ``samples`` TAA samples. Each repeat renders the configurations once, the order rotated from one
repeat to the next (slow drift of the machine falls on all alike). Before the repeats each configuration renders once
untimed: Cycles loads its kernels, Eevee compiles the configuration's shaders (reported apart: the first
render of each configuration). Switching the level changes the tree and Eevee compiles again (its cache did
not always serve: 47 s instead of 14 s was seen), so in Eevee every timed render follows an untimed one of the
same configuration.
With ``--decompose`` two more configurations split Fast's cost: "fast-sky-only" (Fast enabled, then the
compositing and the view layer's AOVs switched off, so Cycles drops the aerial nodes and only the Atmos sky
remains) and "fast-aerial-only" (Fast enabled, then the world's output relinked to the world's own
Background, so only the aerial group and its compositing remain). "fast-per-pixel" and "precise-per-pixel" are
those levels in Per Pixel mode (the materials write distance and view direction; the compositor evaluates the
level once per pixel; the node count is the compositor group's), and with ``--decompose`` the "-aerial-only"
variants of the levels and of their Per Pixel configurations are those configurations without the Atmos sky,
like "fast-aerial-only". "precise-sky-lit" and "precise-per-pixel-sky-lit" are those configurations with Cycles'
non-camera rays relinked to the camera's Precise sky (what they saw before the Precise sky view of December 2026):
the A/B of the lighting group. "precise-per-pixel-camera-sky-flat" and "precise-per-pixel-lighting-flat" give
the camera's rays, or all the others, a flat colour instead of the Atmos sky: what each of the world's groups
costs; "precise-per-pixel-table-sky" and "precise-table-sky" give the camera's rays the table's own Precise sky
everywhere, as before the camera sky view (the A/B of the "Atmos Sky View" group). Before the sky view
(December 2026, Blender 5.2.3, ``--engines cycles --repeats 3 --only off,off-sky-texture,precise-per-pixel,
precise-per-pixel-camera-sky-flat,precise-per-pixel-lighting-flat``): Per Pixel Precise 3.63 s, camera sky flat
2.78 s, lighting flat 3.27 s, off 1.93 s, Blender's Sky Texture 2.81 s: the camera's sky 0.85 s, the sky's light
0.36 s, where Blender's whole sky costs 0.88 s. With it (``--repeats 2 --only off,off-sky-texture,
precise-per-pixel,precise-per-pixel-table-sky,precise-per-pixel-camera-sky-flat``): Per Pixel Precise 3.12 s
(1.10x Blender's sky), with the table's sky for the camera 3.67 s, camera sky flat 2.78 s: the camera's sky 0.34 s.
"off-sky-texture" is the effect off with Blender's own Sky Texture (multiple scattering in 5.0, Nishita in 4.x,
at the valley's sun) feeding the valley world's Background: what an artist would render without Atmos, whose sky
replaces the world; the table gives the ratio to it as well as to the plain world's "off".
The time is the wall time of ``bpy.ops.render.render`` (no file written). The table gives medians, the
ratio to "off" (and in brackets the median of each repeat's ratio to that repeat's "off", which the drift
disturbs less), every single time, and the node count of the aerial-perspective group. Not a test: nothing fails.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import statistics
import sys
import time
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO_ROOT))

import bpy  # noqa: E402

from tools.bench import cpu_model  # noqa: E402  (one definition for the bench tools)

import atmos_addon  # noqa: E402
from atmos_addon import api  # noqa: E402
from atmos_addon.blender.apply.materials import TAG  # noqa: E402  (the tag on nodes the add-on made)
from atmos_addon.sample_scenes import valley  # noqa: E402

CONFIGS = ("off", "fast", "fast-per-pixel", "precise", "precise-per-pixel")


def eevee_engine_id() -> str:
    engines = {item.identifier for item in bpy.types.RenderSettings.bl_rna.properties["engine"].enum_items}
    return "BLENDER_EEVEE_NEXT" if "BLENDER_EEVEE_NEXT" in engines else "BLENDER_EEVEE"


def build(args: argparse.Namespace, engine: str):
    scene = valley.build(args.resolution)
    render = scene.render
    render.resolution_percentage = 100
    render.threads_mode = "FIXED"
    render.threads = args.threads
    if engine == "cycles":
        render.engine = "CYCLES"
        cycles = scene.cycles
        cycles.device = "CPU"
        cycles.samples = args.samples
        cycles.use_adaptive_sampling = False
        cycles.use_denoising = False
        cycles.seed = 0
        cycles.use_animated_seed = False
    else:
        render.engine = eevee_engine_id()
        scene.eevee.taa_render_samples = args.samples
    return scene


#: The configurations ``--decompose`` adds (see the module docstring).
DECOMPOSED = ("fast-sky-only", "fast-aerial-only", "fast-per-pixel-aerial-only", "precise-aerial-only",
              "precise-per-pixel-aerial-only",
              "precise-sky-lit", "precise-per-pixel-sky-lit",
              "precise-per-pixel-camera-sky-flat", "precise-per-pixel-lighting-flat", "precise-per-pixel-table-sky",
              "precise-table-sky")
#: The suffixes of the configurations whose camera rays (``-camera-sky-flat``) or other rays (``-lighting-flat``) see
#: a flat colour instead of the Atmos sky: what each of the world's two groups costs.
FLAT_SUFFIXES = {"-camera-sky-flat": "sky background", "-lighting-flat": "sky lighting background"}
#: The flat colour those rays see (about the clear sky's mean, so the scene's light is comparable).
FLAT_COLOUR = (0.3, 0.4, 0.6, 1.0)
#: The suffix of the configurations whose non-camera rays see the camera's Precise sky (what Atmos did before the
#: Precise sky view: the A/B of the lighting group).
SKY_LIT = "-sky-lit"
#: The suffix of the configurations whose camera rays see the table's own Precise sky everywhere (what they saw
#: before the camera sky view of December 2026: the A/B of the "Atmos Sky View" group).
TABLE_SKY = "-table-sky"
#: The effect off with Blender's own Sky Texture as the world: what an artist renders without Atmos.
SKY_TEXTURE = "off-sky-texture"


def use_sky_texture(scene, enable: bool) -> None:
    """Feed the valley world's Background from a Blender Sky Texture at the valley's sun (or unlink it again)."""
    tree = scene.world.node_tree
    plain = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBackground" and TAG not in n.keys())
    texture = tree.nodes.get("Bench Sky Texture")
    if not enable:
        if texture is not None:
            tree.nodes.remove(texture)
        return
    if texture is None:
        texture = tree.nodes.new("ShaderNodeTexSky")
        texture.name = "Bench Sky Texture"
        types = {item.identifier for item in texture.bl_rna.properties["sky_type"].enum_items}
        texture.sky_type = "MULTIPLE_SCATTERING" if "MULTIPLE_SCATTERING" in types else "NISHITA"
        texture.sun_elevation = math.radians(valley.SUN_ELEVATION_DEG)
        texture.sun_rotation = math.radians(90.0 - valley.SUN_AZIMUTH_DEG)
    tree.links.new(texture.outputs["Color"], plain.inputs["Color"])


def configure(scene, config: str, preset: str) -> int:
    """Put ``scene`` into one configuration (not timed); the aerial group's node count (0 when off)."""
    api.disable(scene)
    use_sky_texture(scene, config == SKY_TEXTURE)
    if config.startswith("off"):
        return 0
    level = config.split("-")[0]
    per_pixel = "-per-pixel" in config
    flat = next((tag for suffix, tag in FLAT_SUFFIXES.items() if config.endswith(suffix)), None)
    api.enable(scene, preset=preset, render_mode="PER_PIXEL" if per_pixel else "COMPOSITOR", quality=level.upper())
    if config == "fast-sky-only":
        scene.render.use_compositing = False
        for view_layer in scene.view_layers:
            for aov in list(view_layer.aovs):
                view_layer.aovs.remove(aov)
        return 0
    if config.endswith(SKY_LIT):
        tree = scene.world.node_tree
        tagged = {n.get(TAG): n for n in tree.nodes if TAG in n.keys()}
        mix, camera_sky = tagged["sky mix"], tagged["sky background"]
        tree.links.new(camera_sky.outputs["Background"], mix.inputs[1])
    if config.endswith(TABLE_SKY) or flat == "sky background":   # the camera rays past the sky view's band
        tree = scene.world.node_tree
        tagged = {n.get(TAG): n for n in tree.nodes if TAG in n.keys()}
        tree.links.new(tagged["sky background"].outputs["Background"], tagged["sky mix"].inputs[2])
    if flat is not None:        # that background's colour no longer comes from its Atmos group
        background = next(n for n in scene.world.node_tree.nodes if n.get(TAG) == flat)
        for link in list(background.inputs["Color"].links):
            scene.world.node_tree.links.remove(link)
        background.inputs["Color"].default_value = FLAT_COLOUR
    if config.endswith("aerial-only"):
        tree = scene.world.node_tree
        plain = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBackground" and TAG not in n.keys())
        for output in (n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputWorld"):  # Atmos adds a Cycles one
            tree.links.new(plain.outputs["Background"], output.inputs["Surface"])
    if per_pixel:   # no aerial node runs per sample: the compositor group's nodes, once per pixel
        return len(bpy.data.node_groups["Atmos Aerial Composite (Per Pixel)"].nodes)
    return len(bpy.data.node_groups["Atmos Aerial Perspective"].nodes)


def timed_render(scene) -> float:
    began = time.perf_counter()
    bpy.ops.render.render(write_still=False, scene=scene.name)
    return time.perf_counter() - began


def bench_engine(engine: str, args: argparse.Namespace, results: list[dict] | None = None) -> list[str]:
    """Time every configuration in ``engine``; the table rows, and one dict per configuration appended to
    ``results`` (``--json``)."""
    scene = build(args, engine)
    configs = CONFIGS + (SKY_TEXTURE,) + (DECOMPOSED if args.decompose else ())
    if args.only:
        configs = tuple(args.only.split(","))
        unknown = sorted(set(configs) - set(CONFIGS + (SKY_TEXTURE,) + DECOMPOSED))
        if unknown or "off" not in configs:
            raise SystemExit(f"--only: unknown configuration(s) {unknown}, or 'off' missing (the baseline)")
    nodes, first = {}, {}
    for config in configs:
        nodes[config] = configure(scene, config, args.preset)
        first[config] = timed_render(scene)
        print(f"{engine} {config}: first (untimed) render {first[config]:.2f} s", flush=True)
    times: dict[str, list[float]] = {config: [] for config in configs}
    for repeat in range(args.repeats):
        order = configs[repeat % len(configs):] + configs[:repeat % len(configs)]
        for config in order:
            configure(scene, config, args.preset)
            if engine == "eevee":
                timed_render(scene)  # a changed tree recompiles: the untimed render absorbs it
            times[config].append(timed_render(scene))
            print(f"{engine} repeat {repeat + 1}/{args.repeats} {config}: {times[config][-1]:.2f} s", flush=True)
    api.disable(scene)
    base = statistics.median(times["off"])
    sky_base = statistics.median(times[SKY_TEXTURE]) if SKY_TEXTURE in times else None
    rows = []
    for config in configs:
        median = statistics.median(times[config])
        paired = statistics.median(t / off for t, off in zip(times[config], times["off"]))
        if results is not None:
            results.append({"engine": engine, "config": config, "nodes": nodes[config], "median_s": median,
                            "ratio_off": median / base, "paired_ratio_off": paired,
                            "ratio_sky_texture": None if sky_base is None else median / sky_base,
                            "first_s": first[config], "times_s": times[config]})
        rows.append(f"| {engine} | {config} | {nodes[config]} | {median:.2f} s | {median / base:.2f} "
                    f"({paired:.2f}) | {'-' if sky_base is None else f'{median / sky_base:.2f}'} | "
                    f"{first[config]:.2f} s | " + ", ".join(f"{t:.2f}" for t in times[config]) + " s |")
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--engines", default="cycles,eevee")
    parser.add_argument("--resolution", type=lambda t: tuple(int(p) for p in t.lower().split("x")), default=(320, 180))
    parser.add_argument("--samples", type=int, default=64)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--threads", type=int, default=2, help="render threads")
    parser.add_argument("--preset", default="clear")
    parser.add_argument("--decompose", action="store_true", help="also time Fast's sky alone and aerial alone")
    parser.add_argument("--only", help="comma-separated configurations to time instead (must include 'off'), e.g. "
                                       "off,fast-per-pixel-aerial-only,fast-aerial-only")
    parser.add_argument("--json", type=Path, help="also write the results as JSON to this file (./run bench)")
    args = parser.parse_args(argv)
    atmos_addon.register()
    load_before = " / ".join(f"{v:.1f}" for v in os.getloadavg())
    rows, results = [], []
    for engine in args.engines.split(","):
        rows += bench_engine(engine.strip(), args, results)
    width, height = args.resolution
    print(f"\nBlender {bpy.app.version_string}, valley {width}x{height} px, {args.samples} samples, Compositor mode, "
          f"preset '{args.preset}', {args.threads} threads; {os.cpu_count()} CPU cores (nproc), {cpu_model()}, "
          f"{platform.system()} {platform.release()}; load average before {load_before}, after "
          f"{' / '.join(f'{v:.1f}' for v in os.getloadavg())}\n")
    print("| engine | level | aerial nodes | median render | ratio to off (median of the per-repeat ratios) "
          "| ratio to off with Blender's Sky Texture "
          "| first render (shader compile) | single renders |")
    print("|---|---|---:|---:|---:|---:|---:|---|")
    print("\n".join(rows))
    if args.json is not None:
        args.json.write_text(json.dumps({"blender": bpy.app.version_string, "resolution": [width, height],
                                         "samples": args.samples, "threads": args.threads, "rows": results}))
    atmos_addon.unregister()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
