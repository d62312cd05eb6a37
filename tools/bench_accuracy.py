# SPDX-License-Identifier: GPL-3.0-or-later
"""Accuracy bench of the aerial-perspective quality levels against brute-force single scattering, and against
the complete reference (every scattering order, Monte Carlo).

    .venv/bpy-5.2.3/bin/python tools/bench_accuracy.py [--no-write] [--paths N]

Prints a markdown table (level x case: max / mean relative error of F_ex, L_in and the pixel, see
:mod:`validation.accuracy` for the error measure), writes ``docs/quality.md`` and, if matplotlib
is importable, ``docs/quality_tradeoff.png`` (error against node count). Also prints the
``MEASURED_PIXEL_ERROR`` table that the Auto choice reads (``atmos_addon/physics/quality.py``) and Balanced's Per
Pixel table (``validation/accuracy.py``); then every level against the complete reference
(:func:`validation.accuracy.complete_reference`), with the pixel's luminance and chromaticity errors,
into the second generated block of ``docs/quality.md``. Takes about 30 s plus 60 s per 1000 paths.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO_ROOT))

from atmos_addon.node_groups.aerial_perspective import NODE_COUNTS  # noqa: E402
from atmos_addon.physics.quality import Level  # noqa: E402
from validation.accuracy import (BENCH_CASES, COMPLETE_ONLY_CASES, COMPLETE_REFERENCE_GROUND_ALBEDO,  # noqa: E402
                                 COMPLETE_REFERENCE_PATHS, COMPLETE_REFERENCE_SEED, LOW_SUN_PATH_FACTOR,
                                 complete_reference, errors, errors_of, evaluate, precise_tile, reference)

COMMAND = ".venv/bpy-5.2.3/bin/python tools/bench_accuracy.py"

#: Node counts of the aerial group per level (Rayleigh + Mie + absorption), as built (a test checks NODE_COUNTS);
#: Balanced's graph was removed with the level (retired December 2026): its last count.
LEVEL_NODES = {"fast": NODE_COUNTS["rayleigh+mie+abs"], "balanced": 327,
               "precise": NODE_COUNTS["rayleigh+mie+abs+precise"]}

#: (row label, level, sun at altitude, Per Pixel variant).
ROWS = [("fast", Level.FAST, True, False), ("balanced", Level.BALANCED, True, False),
        ("balanced, per pixel", Level.BALANCED, True, True),
        ("balanced, ground E_sun", Level.BALANCED, False, False), ("precise", Level.PRECISE, True, False)]
QUANTITIES = ("f_ex", "l_in", "pixel")


def _pct(value: float) -> str:
    return f"{100.0 * value:.2f}"


def measure() -> tuple[list[tuple[str, str, dict]], float]:
    """(row label, case name, errors) for every row and case, and the seconds taken."""
    start = time.perf_counter()
    results = []
    for case in BENCH_CASES:
        reference(case)
        for label, level, sun, per_pixel in ROWS:
            results.append((label, case.name, errors(level, case, sun_at_altitude=sun, per_pixel=per_pixel)))
    return results, time.perf_counter() - start


def markdown_table(results) -> str:
    """Level x case: max / mean relative error in % (max over channels) of F_ex, L_in and the pixel."""
    lines = ["| level | case | F_ex max | F_ex mean | L_in max | L_in mean | pixel max | pixel mean |",
             "|---|---|---:|---:|---:|---:|---:|---:|"]
    for label, name, err in results:
        cells = [_pct(err[f"{q}_{stat}"].max()) for q in QUANTITIES for stat in ("max", "mean")]
        lines.append(f"| {label} | {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def measured_table_source(results) -> str:
    """The MEASURED_PIXEL_ERROR literal for atmos_addon/physics/quality.py and MEASURED_PIXEL_ERROR_PER_PIXEL for
    validation/accuracy.py."""
    lines = ["MEASURED_PIXEL_ERROR: dict[tuple[Level, str], float] = {"]
    for label, name, err in results:
        level = {"fast": "FAST", "balanced": "BALANCED", "precise": "PRECISE"}.get(label)
        if level:
            lines.append(f'    (Level.{level}, "{name}"): {float(err["pixel_max"].max()):.4f},')
    lines += ["}", "MEASURED_PIXEL_ERROR_PER_PIXEL: dict[str, float] = {"]
    for label, name, err in results:
        if label == "balanced, per pixel":
            lines.append(f'    "{name}": {float(err["pixel_max"].max()):.4f},')
    return "\n".join(lines + ["}"])


def multiple_scattering_table() -> str:
    """Per case: how much the Precise level's multiple-scattering term adds to L_in (ratio to single scattering
    minus 1, in %, over rays and channels), and the time to bake one table tile."""
    import numpy as np

    from atmos_addon.physics.precise import evaluate as evaluate_precise

    lines = ["| case | L_in added, mean % | L_in added, max % | pixel added, max % | bake s |", "|---|---:|---:|---:|---:|"]
    for case in BENCH_CASES:
        single = evaluate_precise(precise_tile(case), case.view_dirs, case.sun_dir, case.distances_m, case.atmosphere,
                                  np.float64)
        start = time.perf_counter()
        tile = precise_tile(case, True)
        seconds = time.perf_counter() - start
        multiple = evaluate_precise(tile, case.view_dirs, case.sun_dir, case.distances_m, case.atmosphere, np.float64)
        added = multiple[1] / np.maximum(single[1], 1e-30) - 1.0
        l0 = case.surface_radiance
        pixel = (l0 * multiple[0] + multiple[1]) / (l0 * single[0] + single[1]) - 1.0
        lines.append(f"| {case.name} | {100 * added.mean():.0f} | {100 * added.max():.0f} | {100 * pixel.max():.0f} "
                     f"| {seconds:.2f} |")
    return "\n".join(lines)


def _xy(distance: float) -> str:
    return "black" if distance != distance else f"{distance:.4f}"  # NaN: a black pixel has no chromaticity


def complete_table(paths: int) -> tuple[str, float]:
    """Every level (Precise also with its multiple-scattering term) against the complete reference, per case:
    max pixel error (%, over rays and channels), max luminance error (%) and max CIE xy distance; the
    reference's largest standard error (% of L_in). Returns the table and the seconds taken."""
    import numpy as np

    from atmos_addon.physics.precise import evaluate as evaluate_precise

    start = time.perf_counter()
    lines = ["| case | level | pixel max % | luminance max % | xy max | reference noise, max % of L_in |",
             "|---|---|---:|---:|---:|---:|"]
    for case in BENCH_CASES + COMPLETE_ONLY_CASES:
        f_ex, l_in, error = complete_reference(case, paths * (LOW_SUN_PATH_FACTOR if case.grazing else 1),
                                               COMPLETE_REFERENCE_SEED)
        noise = 100.0 * float(np.max(error / np.maximum(l_in, 1e-30)))
        levels = [(level.value, evaluate(level, case)) for level in (Level.FAST, Level.BALANCED, Level.PRECISE)]
        levels.append(("precise + multiple scattering",
                       evaluate_precise(precise_tile(case, True), case.view_dirs, case.sun_dir, case.distances_m,
                                        case.atmosphere, np.float64)))
        for label, value in levels:
            err = errors_of(case, value, (f_ex, l_in))
            lines.append(f"| {case.name} | {label} | {_pct(err['pixel_max'].max())} | "
                         f"{_pct(float(err['luminance_max']))} | {_xy(float(err['xy_max']))} | {noise:.1f} |")
    return "\n".join(lines), time.perf_counter() - start


def write_plot(results, path: Path) -> bool:
    """Pixel error against node count per case; False (and a message) when matplotlib is missing."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed: docs/quality_tradeoff.png not written "
              "(pip install matplotlib into the venv to get it)", file=sys.stderr)
        return False
    nodes = LEVEL_NODES
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for case in BENCH_CASES:
        points = [(nodes[label], err["pixel_max"].max()) for label, name, err in results
                  if name == case.name and label in nodes]
        ax.plot(*zip(*points), marker="o", label=case.name)
    ax.axhline(0.02, color="grey", linestyle="--", linewidth=0.8)
    ax.set_yscale("log")
    ax.set_xlabel("nodes in the aerial-perspective group (render cost: docs/quality.md, Cost)")
    ax.set_ylabel("max relative pixel error")
    ax.set_title("Aerial perspective: accuracy against cost")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    return True


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--no-write", action="store_true", help="print only; do not write docs/")
    parser.add_argument("--paths", type=int, default=COMPLETE_REFERENCE_PATHS,
                        help="Monte Carlo paths per ray and channel of the complete reference")
    args = parser.parse_args(argv)
    results, seconds = measure()
    table = markdown_table(results)
    print(table)
    print(f"\n{len(BENCH_CASES)} cases, {sum(len(c.rays) for c in BENCH_CASES)} rays, {seconds:.1f} s\n")
    print(measured_table_source(results))
    ms_table = multiple_scattering_table()
    print("\nPrecise multiple scattering against Precise single scattering:\n" + ms_table)
    if not args.no_write:
        docs = REPO_ROOT / "docs"
        docs.mkdir(exist_ok=True)
        plot = write_plot(results, docs / "quality_tradeoff.png")
        text = (REPO_ROOT / "docs" / "quality.md").read_text() if (docs / "quality.md").exists() else ""
        start, end = "<!-- bench:begin -->", "<!-- bench:end -->"
        block = (f"{start}\nGenerated by `{COMMAND}` ({seconds:.0f} s). Relative errors in %, max over channels; "
                 f"Fast {LEVEL_NODES['fast']} nodes, Balanced {LEVEL_NODES['balanced']} (retired, its physics model "
                 f"still measured), Precise "
                 f"{LEVEL_NODES['precise']} (Precise measured with its multiple-scattering term off: the reference "
                 f"is single scattering). \"balanced, per pixel\" is Balanced as the Per Pixel mode evaluates it "
                 f"(validation.balanced.PER_PIXEL_PIECES pieces, the sun at their middles).\n\n{table}\n\nWhat Precise's multiple-scattering term adds (ratio to its "
                 f"single scattering, minus 1) and the bake time of one tile (sun and camera tables warm):\n\n"
                 f"{ms_table}\n"
                 # the plot kept where this machine cannot draw it (its errors are single scattering's, whose
                 # model changes far less often than the multiple-scattering term)
                 + ("\n![error against node count](quality_tradeoff.png)\n"
                    if plot or (docs / "quality_tradeoff.png").exists() else "")
                 + end)
        if start in text and end in text:
            text = text[:text.index(start)] + block + text[text.index(end) + len(end):]
        else:
            text = text + "\n" + block + "\n"
        (docs / "quality.md").write_text(text)
    complete, complete_seconds = complete_table(args.paths)
    print("\nAgainst the complete reference (every scattering order):\n" + complete)
    if not args.no_write:
        albedo = ", ".join(f"{a:g}" for a in COMPLETE_REFERENCE_GROUND_ALBEDO)
        block = (f"Generated by `{COMMAND} --paths {args.paths}` ({complete_seconds:.0f} s for this table). The "
                 f"complete reference: every scattering order by Monte Carlo (validation/multiple_scattering_reference."
                 f"inscattering_mc, {args.paths} paths per ray and channel, {LOW_SUN_PATH_FACTOR}x as many for the "
                 f"low-sun cases, seed {COMPLETE_REFERENCE_SEED}), the "
                 f"spherical planet, a Lambertian ground of albedo ({albedo}) as Precise's multiple-scattering table "
                 f"assumes, three channels, the case's ozone (Earth: 300 DU, the default's; Mars: none; the spectrum: "
                 f"docs/reference_sky.md). Pixel: "
                 f"L0 F_ex + L_in of the albedo-0.3 surface, errors as above; luminance: Rec.709 Y of the pixel; xy: "
                 f"CIE 1931 chromaticity distance ('black': the level renders black there). The last column is "
                 f"the reference's own noise.\n\n{complete}\n")
        text = (docs / "quality.md").read_text()
        start, end = "<!-- complete:begin -->", "<!-- complete:end -->"
        if start in text and end in text:
            text = text[:text.index(start) + len(start)] + "\n" + block + text[text.index(end):]
        else:
            text = text + f"\n{start}\n{block}{end}\n"
        (docs / "quality.md").write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
