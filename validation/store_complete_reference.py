# SPDX-License-Identifier: GPL-3.0-or-later
"""Store the complete reference of bench cases for the tests: every scattering order by Monte Carlo at many paths
(minutes a case), kept as data so that a test can hold the default to the issue's targets in a second.

    .venv/bpy-5.2.3/bin/python validation/store_complete_reference.py --cases mars_sunset --paths 16000 --seeds 11,12

For each case: ``validation.accuracy.complete_reference`` at ``paths`` per ray and channel (the low-sun cases trace
``validation.accuracy.LOW_SUN_PATH_FACTOR`` times as many, as the bench does) for each seed, averaged over the
seeds (the standard error of the mean: the root of the summed squares over the count), written to
``tests/physics/data/complete_<case>.npz`` with the paths, the seeds and the command. Prints the seconds per seed.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

REPO_ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO_ROOT))

from validation.accuracy import (BENCH_CASES, COMPLETE_ONLY_CASES, LOW_SUN_PATH_FACTOR,  # noqa: E402
                                 complete_reference)

DATA = REPO_ROOT / "tests" / "physics" / "data"


def path_of(case_name: str) -> Path:
    """Where the stored reference of ``case_name`` lives."""
    return DATA / f"complete_{case_name}.npz"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cases", required=True, help="comma-separated case names (validation.accuracy's)")
    parser.add_argument("--paths", type=int, default=16000, help="paths per ray and channel")
    parser.add_argument("--seeds", default="11,12", help="comma-separated seeds")
    args = parser.parse_args()
    cases = {case.name: case for case in BENCH_CASES + COMPLETE_ONLY_CASES}
    seeds = [int(s) for s in args.seeds.split(",")]
    DATA.mkdir(parents=True, exist_ok=True)
    for name in args.cases.split(","):
        case = cases[name]
        traced = args.paths * (LOW_SUN_PATH_FACTOR if case.grazing else 1)
        radiances, errors = [], []
        for seed in seeds:
            start = time.perf_counter()
            _, l_in, error = complete_reference(case, traced, seed)
            radiances.append(l_in)
            errors.append(error)
            print(f"{name}: seed {seed}, {traced} paths a ray and channel, {time.perf_counter() - start:.0f} s",
                  flush=True)
        command = (f".venv/bpy-5.2.3/bin/python validation/store_complete_reference.py --cases {name}"
                   f" --paths {args.paths} --seeds {args.seeds}")
        np.savez(path_of(name), l_in=np.mean(radiances, axis=0),
                 error=np.sqrt(np.sum(np.square(errors), axis=0)) / len(seeds),
                 paths=traced, seeds=np.array(seeds), command=command)
        print(f"wrote {path_of(name).relative_to(REPO_ROOT)}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
