# SPDX-License-Identifier: GPL-3.0-or-later
"""What the multiple-scattering table's resolution costs and buys: each variant's build time against the default's,
and how far the default level's pixel luminance moves on every accuracy-bench case (the table alone changed).

    .venv/bpy-5.2.3/bin/python tools/measure_ms_resolution.py [--variants "alt32=n_altitudes:32;steps12=n_steps:12"]

A variant is ``name=keyword:value,keyword:value`` of :class:`atmos_addon.physics.precise.MultipleScatteringTable`;
the tiles are integrated afresh with each variant's table (``precise.integrate_tile``'s ``tables``) and
evaluated on the cases' rays. Prints the build time (median over the cases' atmospheres, this machine's threads) and
the largest relative change of luminance per case, %. Not a test: a lead for the atmosphere-edit target.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from atmos_addon.physics import precise  # noqa: E402
from atmos_addon.physics.quality import BENCH_CASES, COMPLETE_ONLY_CASES  # noqa: E402
from atmos_addon.physics.spectrum import LINEAR_REC709_TO_XYZ  # noqa: E402

#: The table before December 2026's (32 altitudes, 24 steps), and coarser ones than the default (24 altitudes,
#: 33 sun cosines, 16 steps since then).
DEFAULT_VARIANTS = ("alt32+steps24=n_altitudes:32,n_steps:24;alt16=n_altitudes:16;steps12=n_steps:12;"
                    "cos25=n_cosines:25")


def parse(text: str) -> dict[str, dict[str, int]]:
    variants = {}
    for item in filter(None, text.split(";")):
        name, _, spec = item.partition("=")
        variants[name] = {key: int(value) for key, value in (part.split(":") for part in spec.split(","))}
    return variants


def luminances(keywords: dict[str, int]) -> tuple[dict[str, np.ndarray], float]:
    """Each case's pixel luminance with a table of ``keywords``, and the table's median build time."""
    cache, builds = {}, []

    def tables(atm):
        if atm not in cache:
            sun = precise.SunTransmittanceTable(atm)
            start = time.perf_counter()
            cache[atm] = (sun, precise.MultipleScatteringTable(atm, sun, precise.DEFAULT_GROUND_ALBEDO, **keywords))
            builds.append(time.perf_counter() - start)
        return cache[atm]

    result = {}
    for case in BENCH_CASES + COMPLETE_ONLY_CASES:
        tile = precise.integrate_tile(case.atmosphere, case.camera_altitude_m, np.radians(case.sun_elevation_deg),
                                      tables=tables(case.atmosphere))
        f_ex, l_in = precise.evaluate(tile, case.view_dirs, case.sun_dir, case.distances_m, case.atmosphere,
                                      np.float64)
        result[case.name] = ((case.surface_radiance * f_ex + l_in) @ LINEAR_REC709_TO_XYZ.T)[:, 1]
    return result, statistics.median(builds)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--variants", default=DEFAULT_VARIANTS)
    args = parser.parse_args()
    base, base_time = luminances({})
    names = list(base)
    print("| table | build, median | " + " | ".join(names) + " |")
    print("|---|---:|" + "---:|" * len(names))
    print(f"| default | {base_time:.2f} s | " + " | ".join("0" for _ in names) + " |", flush=True)
    for name, keywords in parse(args.variants).items():
        values, seconds = luminances(keywords)
        changes = [100.0 * float(np.max(np.abs(values[case] / base[case] - 1.0))) for case in names]
        print(f"| {name} | {seconds:.2f} s | " + " | ".join(f"{c:.2f}" for c in changes) + " |", flush=True)


if __name__ == "__main__":
    main()
