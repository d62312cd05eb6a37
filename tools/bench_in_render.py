# SPDX-License-Identifier: GPL-3.0-or-later
"""Render-time cost of the two modes on the sample valley: effect off, Compositor mode, In-Render mode.

    .venv/bpy-5.2.3/bin/python tools/bench_in_render.py [--resolution 320x180] [--samples 64] [--repeats 3]

Method. The valley (``sample_scenes/valley.py``) is built once at the given resolution and rendered with Cycles
on the CPU: ``samples`` samples per pixel with adaptive sampling off (every configuration traces the same
number of camera paths), a fixed seed, denoising off, the scene's own bounces and pixel filter, ``threads``
render threads. Three configurations of the same file:

- off: Atmos disabled (the valley's plain world);
- Compositor: ``api.enable(scene, preset)`` (AOVs in the materials, the combining node in the compositor,
  the Atmos sky);
- In-Render: ``api.enable(scene, preset, render_mode="IN_RENDER")`` (the two dome volumes, the emission in
  every material, the compensated Atmos sky).

Each repeat renders the three once, the order rotated from one repeat to the next, so that slow drift of the
machine (other load, thermal) falls on all three alike; one untimed 1-sample render comes first (kernel
loading). The time is the wall time of ``bpy.ops.render.render`` (scene sync, BVH build, path tracing and,
in Compositor mode, the compositor; no file is written); the switch between configurations is not timed.
The CPU time of the process over the same call (``time.process_time``: all render threads) is given too: it
moves less than the wall time when other work shares the cores. The table gives the medians over the
repeats, their ratios to "off", and every single wall time. The dome
rows give the vertex and triangle counts of the objects in the "Atmos In-Render" collection.

``--breakdown`` adds renders (after the repeats, ``repeats`` rounds, medians) that split the cost: each
configuration at 1 sample (what does not grow with the samples: sync, BVH, compositor), In-Render with the
two domes hidden from the render (``hide_render``: the materials' emission and the compensated world without
the volumes), and Compositor mode with compositing off (the AOVs without the compositor). Not a test:
nothing fails.
"""

from __future__ import annotations

import argparse
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
from atmos_addon.blender import facts
from atmos_addon.blender.apply import in_render  # noqa: E402
from atmos_addon.sample_scenes import valley  # noqa: E402

CONFIGS = ("off", "Compositor", "In-Render")


def _resolution(text: str) -> tuple[int, int]:
    width, height = (int(part) for part in text.lower().split("x"))
    return width, height


def build(args: argparse.Namespace):
    scene = valley.build(args.resolution)
    render = scene.render
    render.resolution_percentage = 100
    render.threads_mode = "FIXED"
    render.threads = args.threads
    cycles = scene.cycles
    cycles.device = "CPU"
    cycles.samples = args.samples
    cycles.use_adaptive_sampling = False
    cycles.use_denoising = False
    cycles.seed = args.seed
    cycles.use_animated_seed = False
    return scene


def configure(scene, config: str, preset: str) -> None:
    """Put ``scene`` into one configuration (not timed)."""
    if config == "off":
        api.disable(scene)
    elif config == "Compositor":
        if scene.atmos.enabled and scene.atmos.render_mode != "COMPOSITOR":
            api.disable(scene)
        api.enable(scene, preset=preset, render_mode="COMPOSITOR")
    else:
        if scene.atmos.enabled and scene.atmos.render_mode != "IN_RENDER":
            api.disable(scene)
        api.enable(scene, preset=preset, render_mode="IN_RENDER")
        if not in_render.is_installed(scene):
            raise SystemExit(f"In-Render mode did not install: {facts.plan_of(scene).notes}")


def timed_render(scene) -> tuple[float, float]:
    """(wall time, CPU time of this process: all render threads) of one render, in s."""
    began, began_cpu = time.perf_counter(), time.process_time()
    bpy.ops.render.render(write_still=False, scene=scene.name)
    return time.perf_counter() - began, time.process_time() - began_cpu


def dome_sizes() -> list[tuple[str, int, int]]:
    collection = bpy.data.collections.get(in_render.COLLECTION_NAME)
    if collection is None:
        return []
    return [(obj.name, len(obj.data.vertices), len(obj.data.polygons)) for obj in collection.objects
            if obj.type == "MESH"]


def breakdown(scene, args: argparse.Namespace) -> str:
    """Renders that split the cost (module docstring), ``repeats`` rounds; a markdown table of medians."""
    times: dict[str, list[tuple[float, float]]] = {}
    for _ in range(args.repeats):
        for config in CONFIGS:
            configure(scene, config, args.preset)
            scene.cycles.samples = 1
            times.setdefault(f"{config}, 1 sample", []).append(timed_render(scene))
        scene.cycles.samples = args.samples
        configure(scene, "In-Render", args.preset)
        domes = bpy.data.collections[in_render.COLLECTION_NAME].objects
        for obj in domes:
            obj.hide_render = True
        times.setdefault(f"In-Render, domes hidden, {args.samples} samples", []).append(timed_render(scene))
        for obj in domes:
            obj.hide_render = False
        configure(scene, "Compositor", args.preset)
        scene.render.use_compositing = False
        times.setdefault(f"Compositor, compositing off, {args.samples} samples", []).append(timed_render(scene))
        scene.render.use_compositing = True
    lines = ["| render (breakdown) | median wall time | median CPU time | single renders, wall |",
             "|---|---:|---:|---|"]
    for label, runs in times.items():
        lines.append(f"| {label} | {statistics.median(t[0] for t in runs):.2f} s | "
                     f"{statistics.median(t[1] for t in runs):.2f} s | "
                     + ", ".join(f"{t[0]:.2f}" for t in runs) + " s |")
    return "\n".join(lines)


def markdown(times: dict[str, list[tuple[float, float]]], domes) -> str:
    wall = {config: [t[0] for t in runs] for config, runs in times.items()}
    cpu = {config: [t[1] for t in runs] for config, runs in times.items()}
    base, base_cpu = statistics.median(wall["off"]), statistics.median(cpu["off"])
    lines = [f"| configuration (Blender {bpy.app.version_string}) | median wall time | ratio to off "
             f"| median CPU time | ratio to off | single renders, wall |", "|---|---:|---:|---:|---:|---|"]
    for config in CONFIGS:
        median, median_cpu = statistics.median(wall[config]), statistics.median(cpu[config])
        lines.append(f"| {config} | {median:.2f} s | {median / base:.2f} | {median_cpu:.2f} s | "
                     f"{median_cpu / base_cpu:.2f} | " + ", ".join(f"{t:.2f}" for t in wall[config]) + " s |")
    lines += ["", "| dome object | vertices | triangles |", "|---|---:|---:|"]
    lines += [f"| {name} | {vertices} | {triangles} |" for name, vertices, triangles in domes]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolution", type=_resolution, default=(320, 180), help="WIDTHxHEIGHT")
    parser.add_argument("--samples", type=int, default=64)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=2, help="Cycles render threads")
    parser.add_argument("--preset", default="clear")
    parser.add_argument("--breakdown", action="store_true", help="add the single renders that split the cost")
    args = parser.parse_args(argv)
    atmos_addon.register()
    load_before = " / ".join(f"{v:.1f}" for v in os.getloadavg())
    scene = build(args)
    samples = scene.cycles.samples
    scene.cycles.samples = 1
    timed_render(scene)  # kernel loading, untimed
    scene.cycles.samples = samples
    times: dict[str, list[tuple[float, float]]] = {config: [] for config in CONFIGS}
    domes = []
    for repeat in range(args.repeats):
        order = CONFIGS[repeat % 3:] + CONFIGS[:repeat % 3]
        for config in order:
            configure(scene, config, args.preset)
            if config == "In-Render":
                domes = dome_sizes()
            seconds, cpu_seconds = timed_render(scene)
            times[config].append((seconds, cpu_seconds))
            print(f"repeat {repeat + 1}/{args.repeats} {config}: {seconds:.2f} s wall, {cpu_seconds:.2f} s CPU",
                  flush=True)
    extra = breakdown(scene, args) if args.breakdown else None
    width, height = args.resolution
    print(f"\nBlender {bpy.app.version_string}, valley {width}x{height} px, {args.samples} samples (adaptive off), "
          f"seed {args.seed}, denoising off, {args.threads} threads, preset '{args.preset}'; "
          f"{os.cpu_count()} CPU cores (nproc), {cpu_model()}, {platform.system()} {platform.release()}; "
          f"load average before the run {load_before}, after {' / '.join(f'{v:.1f}' for v in os.getloadavg())}\n")
    print(markdown(times, domes))
    if extra:
        print("\n" + extra)
    atmos_addon.unregister()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
