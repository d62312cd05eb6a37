# SPDX-License-Identifier: GPL-3.0-or-later
"""What the default (Precise with multiple scattering) shows: the sky's colour at the zenith and 3 deg above the
horizon toward the sun, per preset and sun elevation, for a camera 2 m up.

    .venv/bpy-5.2.3/bin/python validation/measure_default_sky.py

The issue's checklist for the default: a blue clear zenith at noon; at a 5 deg sun a blue zenith over a golden
horizon; a blue hour that is blue (zenith B > G > R with the sun 2-6 deg below the horizon); an overcast sky still
lit at a 1 deg sun; Mars butterscotch by day with a blue glow around the setting sun. Radiances from
``physics.precise.sky_radiance`` (the Precise level's integrand with its multiple-scattering table, three channels,
the presets' ozone: 300 DU on Earth, none on Mars), in W/(m^2 sr) of the sun lamp's strength unit. Numpy only;
prints a Markdown table. The physics test ``tests/physics/test_default_look.py`` holds the checklist.
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from atmos_addon import presets  # noqa: E402
from atmos_addon.physics import precise  # noqa: E402

#: (preset, sun elevations deg) measured.
CASES = (("clear", (60, 20, 5, 1, -2, -4, -6)), ("overcast", (20, 5, 1)), ("mars", (60, 5, 1)))


def direction(elevation_deg: float) -> np.ndarray:
    """Unit vector toward +y at ``elevation_deg`` above the horizon, z up."""
    e = math.radians(elevation_deg)
    return np.array([0.0, math.cos(e), math.sin(e)])


def sky_colours(preset: str, sun_elevation_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """(zenith RGB, RGB 3 deg above the horizon toward the sun) of the default sky, W/(m^2 sr)."""
    atm = presets.load(preset).atmosphere
    sun = direction(sun_elevation_deg)
    views = np.stack([np.array([0.0, 0.0, 1.0]), direction(3.0)])
    zenith, horizon = precise.sky_radiance(views, sun, atm, camera_altitude_m=2.0)
    return zenith, horizon


def main() -> None:
    start = time.perf_counter()
    print("| preset | sun deg | zenith R, G, B | zenith B/R | zenith B > G > R | horizon toward the sun R, G, B |")
    print("|---|---:|---|---:|---|---|")
    for preset, elevations in CASES:
        for elevation in elevations:
            zenith, horizon = sky_colours(preset, elevation)
            order = "yes" if zenith[2] > zenith[1] > zenith[0] else "no"
            print(f"| {preset} | {elevation} | {', '.join(f'{v:.3g}' for v in zenith)} | "
                  f"{zenith[2] / zenith[0]:.2f} | {order} | {', '.join(f'{v:.3g}' for v in horizon)} |")
    print(f"\n({time.perf_counter() - start:.0f} s)")


if __name__ == "__main__":
    main()
