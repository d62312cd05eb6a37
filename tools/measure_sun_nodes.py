# SPDX-License-Identifier: GPL-3.0-or-later
"""How far the multiple-scattering table's interpolation between its sun-cosine nodes is from a table with many more
nodes, over suns from 9 deg below the horizon to the zenith: the current layout (``precise.SunCosineNodes``) and
the one before stop 49 (mu_s = +-(k / 16)^2 within 23 deg of the horizon), each at 32 nodes.

    .venv/bpy-5.2.3/bin/python tools/measure_sun_nodes.py [--fine 129] [--presets clear,overcast,mars,sunset]

For each preset and sun elevation (every 0.25 deg from -9 to 3 deg, every 1 deg to 30, every 3 deg to 90) a tile is
baked for a camera 2 m up and the luminance (Rec.709 Y) of L_in read at 1 km, 30 km and along the whole sky ray, in
5 view elevations (0, 1, 5, 20, 60 deg) x 3 azimuths (toward, across, away from the sun); the error of a layout is
the worst relative difference from the table built with ``--fine`` sun cosines (the same method otherwise), where
that light is above 1e-12 of its most. Prints the worst per band of sun elevation, %. Physics only (numpy); about
8 minutes on 2 cores. Not a test: nothing fails.
"""

from __future__ import annotations

import argparse
import functools
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from atmos_addon import presets  # noqa: E402
from atmos_addon.physics import precise  # noqa: E402
from atmos_addon.physics.atmosphere import Atmosphere  # noqa: E402
from atmos_addon.physics.quality import BenchCase  # noqa: E402
from atmos_addon.physics.spectrum import DEFAULT_OZONE_COLUMN_DU  # noqa: E402

ELEVATIONS_DEG = np.concatenate([np.arange(-9.0, 3.0, 0.25), np.arange(3.0, 30.0, 1.0), np.arange(30.0, 90.1, 3.0)])
BANDS_DEG = ((-9.0, -6.0), (-6.0, -1.0), (-1.0, 3.0), (3.0, 30.0), (30.0, 90.1))
VIEWS = tuple((elevation, azimuth, distance) for elevation in (0.0, 1.0, 5.0, 20.0, 60.0)
              for azimuth in (0.0, 90.0, 180.0) for distance in (1000.0, 30_000.0, 5e6))
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


class FormerNodes(precise.SunCosineNodes):
    """The layout until stop 49: mu_s = +-(k / n)^2 for k = 0 .. K, the same day cells and night cell."""

    @functools.cached_property
    def cosines(self) -> np.ndarray:
        n, k = self._layout
        steps = np.arange(-k, k + 1)
        band = np.sign(steps) * (steps / n) ** 2
        day = np.sin(np.linspace(math.asin(band[-1]), 0.5 * np.pi, k + 1)[1:])
        result = np.concatenate([[-1.0], band, day])
        result.flags.writeable = False
        return result


def atmosphere(name: str) -> Atmosphere:
    return Atmosphere(ozone_column_du=DEFAULT_OZONE_COLUMN_DU) if name == "clear" else presets.load(name).atmosphere


def luminances(atm: Atmosphere, sun_nodes: precise.SunCosineNodes) -> np.ndarray:
    """(elevations, views): Y of L_in with the multiple-scattering table built on ``sun_nodes``."""
    sun = precise.SunTransmittanceTable(atm)
    tables = (sun, precise.MultipleScatteringTable(atm, sun, precise.DEFAULT_GROUND_ALBEDO, sun_nodes=sun_nodes))
    rows = []
    for elevation in ELEVATIONS_DEG:
        case = BenchCase("sweep", "", "clear", 2.0, float(elevation), VIEWS)
        tile = precise.integrate_tile(atm, 2.0, math.radians(elevation), tables=tables)
        _, l_in = precise.evaluate(tile, case.view_dirs, case.sun_dir, case.distances_m, atm, np.float64)
        rows.append(l_in @ LUMINANCE)
    return np.array(rows)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fine", type=int, default=129, help="sun-cosine resolution of the yardstick table (odd)")
    parser.add_argument("--presets", default="clear,overcast,mars,sunset")
    args = parser.parse_args()
    layouts = (("former (k / 16)^2", FormerNodes(33)), ("current", precise.SunCosineNodes(33)))
    bands = " | ".join(f"{low:g} to {min(high, 90.0):g} deg" for low, high in BANDS_DEG)
    print(f"| preset | layout | {bands} |\n|---|---|" + "---:|" * len(BANDS_DEG))
    for name in args.presets.split(","):
        atm = atmosphere(name)
        fine = luminances(atm, precise.SunCosineNodes(args.fine))
        visible = fine > 1e-12 * fine.max()
        for label, nodes in layouts:
            error = np.where(visible, np.abs(luminances(atm, nodes) / np.where(visible, fine, 1.0) - 1.0),
                             0.0).max(axis=1)
            cells = [f"{100.0 * error[(ELEVATIONS_DEG >= low) & (ELEVATIONS_DEG < high)].max():.1f}"
                     for low, high in BANDS_DEG]
            print(f"| {name} | {label} | " + " | ".join(cells) + " |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
