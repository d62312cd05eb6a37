# SPDX-License-Identifier: GPL-3.0-or-later
"""How much of the default's error against the complete reference is the reference's own noise: the default
(Precise with multiple scattering) against the Monte Carlo reference of every scattering order at more paths and
other seeds than ``tools/bench_accuracy.py`` traces.

    .venv/bpy-5.2.3/bin/python tools/measure_complete_noise.py --cases aircraft,blue_hour --paths 4000,16000 \\
        [--seeds 11,12]

For each case, path count (per ray and channel; the low-sun cases trace ``bench_accuracy.LOW_SUN_PATH_FACTOR``
times as many, as the bench does) and seed: the worst ray's luminance error and CIE xy distance (the bench's
measures), the reference's largest standard error (% of L_in), and how many of the case's ray-channels differ from
the reference by more than three standard errors. Prints a markdown table; not a test.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from atmos_addon.physics.precise import evaluate as evaluate_precise  # noqa: E402
from atmos_addon.physics.quality import (BENCH_CASES, COMPLETE_ONLY_CASES, complete_reference,  # noqa: E402
                                         errors_of, precise_tile)
from bench_accuracy import LOW_SUN_PATH_FACTOR  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cases", required=True, help="comma-separated case names (physics.quality's)")
    parser.add_argument("--paths", default="4000,16000", help="comma-separated paths per ray and channel")
    parser.add_argument("--seeds", default="11", help="comma-separated seeds (11: the bench's)")
    args = parser.parse_args()
    cases = {case.name: case for case in BENCH_CASES + COMPLETE_ONLY_CASES}
    print("| case | paths | seed | luminance max % | xy max | noise, max % of L_in | ray-channels beyond 3 sigma | s |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for name in args.cases.split(","):
        case = cases[name]
        value = evaluate_precise(precise_tile(case, True), case.view_dirs, case.sun_dir, case.distances_m,
                                 case.atmosphere, np.float64)
        for paths in (int(p) for p in args.paths.split(",")):
            traced = paths * (LOW_SUN_PATH_FACTOR if case.grazing else 1)
            for seed in (int(s) for s in args.seeds.split(",")):
                start = time.perf_counter()
                f_ex, l_in, error = complete_reference(case, traced, seed)
                err = errors_of(case, value, (f_ex, l_in))
                noise = 100.0 * float(np.max(error / np.maximum(l_in, 1e-30)))
                beyond = int(np.sum(np.abs(value[1] - l_in) > 3.0 * np.maximum(error, 1e-30)))
                print(f"| {name} | {traced} | {seed} | {100 * float(err['luminance_max']):.2f} | "
                      f"{float(err['xy_max']):.4f} | {noise:.2f} | {beyond} of {l_in.size} | "
                      f"{time.perf_counter() - start:.0f} |", flush=True)


if __name__ == "__main__":
    main()
