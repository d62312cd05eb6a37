# SPDX-License-Identifier: GPL-3.0-or-later
"""Render cost of this checkout against another one (before/after a change), interleaved.

    .venv/bpy-5.2.3/bin/python tools/bench_checkouts.py --before OLD_CHECKOUT [--modes PER_PIXEL,COMPOSITOR]
        [--rounds 5] [--resolution 320x180] [--samples 64]

Each round renders the sample valley once with each checkout's ``atmos_addon`` per mode, in a fresh process (so
neither inherits the other's caches), the order alternating between rounds; each process renders once untimed
(Cycles loads its kernels, the tables bake) and then times one ``bpy.ops.render.render`` (Cycles on the CPU,
``--threads`` threads, adaptive sampling and denoising off, a fixed seed, the default preset and level). Printed:
per mode the median time of each checkout and the median of the rounds' after/before ratios.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent

CHILD = """
import json, sys, time
sys.path.insert(0, {source!r})
import bpy
import atmos_addon
from atmos_addon import api
from atmos_addon.sample_scenes import valley
atmos_addon.register()
scene = valley.build(resolution=({width}, {height}))
scene.render.engine = "CYCLES"
scene.cycles.device, scene.cycles.samples, scene.cycles.seed = "CPU", {samples}, 0
scene.cycles.use_adaptive_sampling = scene.cycles.use_denoising = False
scene.render.threads_mode, scene.render.threads = "FIXED", {threads}
scene.atmos.render_mode = {mode!r}
api.enable(scene)
bpy.ops.render.render(scene=scene.name)
start = time.perf_counter()
bpy.ops.render.render(scene=scene.name)
print("ATMOS_TIME " + json.dumps(time.perf_counter() - start))
"""


def timed(source: Path, mode: str, args) -> float:
    width, height = (int(v) for v in args.resolution.split("x"))
    code = CHILD.format(source=str(source.resolve()), width=width, height=height, samples=args.samples,
                        threads=args.threads, mode=mode)
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    line = next(line for line in result.stdout.splitlines() if line.startswith("ATMOS_TIME "))
    return float(json.loads(line.split(" ", 1)[1]))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", type=Path, required=True, help="the other checkout (its atmos_addon)")
    parser.add_argument("--modes", default="PER_PIXEL,COMPOSITOR")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--resolution", default="320x180")
    parser.add_argument("--samples", type=int, default=64)
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args(argv)
    for mode in args.modes.split(","):
        times = {"before": [], "after": []}
        for index in range(args.rounds):
            order = (("before", args.before), ("after", REPO_ROOT))
            for name, source in (order if index % 2 == 0 else order[::-1]):
                times[name].append(timed(source, mode, args))
            print(f"{mode} round {index + 1}: before {times['before'][-1]:.3f} s, after {times['after'][-1]:.3f} s",
                  flush=True)
        ratios = [a / b for a, b in zip(times["after"], times["before"])]
        print(f"{mode}: before {statistics.median(times['before']):.3f} s, after "
              f"{statistics.median(times['after']):.3f} s, after / before {statistics.median(ratios):.3f} "
              f"(median of {args.rounds} rounds' ratios; range {min(ratios):.3f}-{max(ratios):.3f})", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
