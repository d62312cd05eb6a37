# SPDX-License-Identifier: GPL-3.0-or-later
"""Time what an atmosphere edit and a sun move bake at the Precise level: the per-atmosphere tables (sun
transmittance, multiple scattering) and one tile, per preset, on this machine's threads and on one, interleaved.

    .venv/bpy-5.2.3/bin/python tools/bench_tables.py [--repeats 3] [--json FILE]

Each repeat edits the preset's haze by a hair (Mie scattering x 1.0001 per repeat), so the tables are built anew
as after a slider change (the sun table's geometry is kept, as it is then), then bakes a tile for a camera 100 m up
and the sun at 5 deg. Physics only (numpy, no Blender): the add-on's bake adds the image write. Prints medians in
seconds as a Markdown table. Not a test: nothing fails.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from atmos_addon import presets  # noqa: E402
from atmos_addon.physics import precise  # noqa: E402
from atmos_addon.physics.precise import parallel  # noqa: E402

PRESETS = ("clear", "overcast", "sunset", "mars")


def one_edit(name: str, scale: float) -> tuple[float, float]:
    """(tables s, tile s) after an edit of ``name``'s haze by ``scale``."""
    base = presets.load(name).atmosphere
    atm = base.replace(mie_scattering=base.mie_scattering * scale)
    start = time.perf_counter()
    precise.atmosphere_tables(atm, precise.DEFAULT_GROUND_ALBEDO)
    tables = time.perf_counter() - start
    start = time.perf_counter()
    precise.integrate_tile(atm, 100.0, math.radians(5.0))
    return tables, time.perf_counter() - start


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", type=Path, help="also write the medians as JSON to this file (./run bench)")
    args = parser.parse_args()
    threads = parallel.WORKERS
    counts = (1, threads) if threads > 1 else (1,)
    times = {(workers, name): [] for workers in counts for name in PRESETS}
    one_edit("clear", 0.5)                                   # imports, the sun table's geometry
    for repeat in range(args.repeats):
        for workers in counts:
            parallel.WORKERS = workers
            for name in PRESETS:
                times[(workers, name)].append(one_edit(name, 1.0 + 1e-4 * (repeat + 1) * (1 + counts.index(workers))))
    parallel.WORKERS = threads
    medians = {f"{name}/{workers}": [statistics.median(tables for tables, _ in times[(workers, name)]),
                                     statistics.median(tile for _, tile in times[(workers, name)])]
               for workers in counts for name in PRESETS}
    print(markdown({"threads": threads, "repeats": args.repeats, "medians": medians}))
    if args.json:
        args.json.write_text(json.dumps({"threads": threads, "repeats": args.repeats, "medians": medians}))
    return 0


def markdown(result: dict) -> str:
    """The Markdown table of a run's JSON (``./run bench`` prints it in docs/benchmarks.md)."""
    counts = sorted({int(key.split("/")[1]) for key in result["medians"]})
    label = {w: f"{w} thread{'s' if w > 1 else ''}" for w in counts}
    lines = ["| preset | " + " | ".join(f"tables, {label[w]} | tile, {label[w]}" for w in counts) + " |",
             "|---|" + "---:|---:|" * len(counts)]
    for name in PRESETS:
        cells = [f"{value:.2f} s" for w in counts for value in result["medians"][f"{name}/{w}"]]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + (f"\n\nMedians of {result['repeats']} interleaved repeats; {result['threads']} worker "
                               f"thread(s) on this machine (`precise.parallel.WORKERS`).")


if __name__ == "__main__":
    raise SystemExit(main())
