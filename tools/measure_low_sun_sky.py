# SPDX-License-Identifier: GPL-3.0-or-later
"""Sky luminance at a low sun, per level's sky: the virtual-dome sky (Fast and Balanced) against the Precise table's.

    .venv/bpy-5.2.3/bin/python tools/measure_low_sun_sky.py [--presets overcast,clear] [--elevations 20,10,5,2]

For each preset and sun elevation, the luminance Y = 0.2126 R + 0.7152 G + 0.0722 B (Rec. 709) of the sky
radiance (units of the sun lamp's strength per steradian) at the zenith, 10 deg above the horizon away from the
sun and 10 deg above it toward the sun, for a camera 2 m up:

* dome: ``physics.sky.sky_radiance`` with the ground-level E_sun (``physics.sun.sun_irradiance_ground``), the sky
  the Fast and Balanced levels render. Every point of its dome is lit by the sun as seen from the ground;
* Precise, single: the Precise table's sky (``physics.precise.sky_from_tile``), which sees the sun from each
  point of the ray through the curved atmosphere;
* Precise, multiple: the same with Hillaire 2020's multiple-scattering term (the *Multiple Scattering* setting).

It explains the README's known limit: under a thick haze (overcast) the ground-level sun is nearly gone below
5 deg, so the dome sky goes black, while the upper air still sees the sun. Numpy only; prints a Markdown table.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from atmos_addon import presets  # noqa: E402
from atmos_addon.physics.precise import bake_tile, sky_from_tile  # noqa: E402
from atmos_addon.physics.sky import sky_radiance  # noqa: E402
from atmos_addon.physics.sun import sun_irradiance_ground  # noqa: E402

#: Rec. 709 luminance weights (Blender's default scene-linear space).
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
#: Elevation of the two horizon views, degrees.
VIEW_ELEVATION_DEG = 10.0
CAMERA_ALTITUDE_M = 2.0


def views() -> np.ndarray:
    """Zenith, 10 deg up away from the sun, 10 deg up toward it (the sun lies along +y)."""
    e = math.radians(VIEW_ELEVATION_DEG)
    return np.array([[0.0, 0.0, 1.0], [0.0, -math.cos(e), math.sin(e)], [0.0, math.cos(e), math.sin(e)]])


def measure(preset: str, elevation_deg: float) -> dict[str, np.ndarray]:
    """Luminances (zenith, away, toward) of the three skies, and the ground E_sun's luminance."""
    atmosphere = presets.load(preset).atmosphere
    elevation = math.radians(elevation_deg)
    sun = np.array([0.0, math.cos(elevation), math.sin(elevation)])
    e_sun = sun_irradiance_ground(elevation, atmosphere)
    result = {"E_sun": np.atleast_1d(e_sun @ LUMINANCE),
              "dome": sky_radiance(views(), sun, atmosphere, e_sun, altitude_m=CAMERA_ALTITUDE_M) @ LUMINANCE}
    for label, multiple in (("Precise, single", False), ("Precise, multiple", True)):
        tile = bake_tile(atmosphere, CAMERA_ALTITUDE_M, elevation, multiple_scattering=multiple)
        _, radiance, _ = sky_from_tile(tile, views(), sun, atmosphere, np.float64)
        result[label] = radiance @ LUMINANCE
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--presets", default="overcast,clear")
    parser.add_argument("--elevations", default="20,10,5,2", help="sun elevations, degrees")
    args = parser.parse_args(argv)
    print("| preset | sun | ground E_sun Y | sky | zenith | 10 deg up, away | 10 deg up, toward |")
    print("|---|---:|---:|---|---:|---:|---:|")
    for preset in args.presets.split(","):
        for elevation in (float(e) for e in args.elevations.split(",")):
            values = measure(preset.strip(), elevation)
            for label in ("dome", "Precise, single", "Precise, multiple"):
                zenith, away, toward = values[label]
                print(f"| {preset} | {elevation:g} deg | {values['E_sun'][0]:.3g} | {label} | {zenith:.4g} | "
                      f"{away:.4g} | {toward:.4g} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
