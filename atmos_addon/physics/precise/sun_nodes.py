# SPDX-License-Identifier: GPL-3.0-or-later
"""The sun zenith cosines at which the multiple-scattering table is built (:class:`SunCosineNodes`): crowded at the
terminator, where the light falls by orders of magnitude within a few degrees of sun, even in the sun's elevation by
day, and how a cosine between them is read (its fractional node index, linear in the elevation).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike


#: The sun cosines beyond which the multiple-scattering table's nodes leave the terminator's spacing, as a share of
#: n = (resolution - 1) / 2: with 33 (n = 16) K = 10 nodes a side up to 23 deg.
TERMINATOR_SHARE = 0.625
#: How fast the band's cells grow away from the horizon: the k-th node of K lies at
#: band (exp(a k / K) - 1) / (exp(a) - 1), each cell exp(a / K) times the one before (1.22x with K = 10).
TERMINATOR_GROWTH = 2.0


@dataclass(frozen=True)
class SunCosineNodes:
    """The sun zenith cosines of the multiple-scattering table's nodes, and where a cosine falls between them.

    Around the terminator, K = 0.625 n nodes a side (n = (``resolution`` - 1) / 2) whose elevations grow
    geometrically from the horizon to +-23 deg (mu_s = +-(K / n)^2): e_k = 23 deg (exp(a k / K) - 1) /
    (exp(a) - 1) with a = :data:`TERMINATOR_GROWTH`, 0.8, 1.8, 3.0, 4.4, 6.2, 8.3, 11.0, 14.2, 18.1, 23.0 deg with
    n = 16 (the light falls by orders of magnitude within a few degrees of sun below the horizon and changes fastest
    there). Above that band K cells even in the sun's elevation up to the zenith (6.7 deg with n = 16); below it one
    cell to the nadir, where no light is left (the clear sky's mean radiance with the sun 23 deg below is 1e-10 of its
    most at that altitude on the ground and 4e-7 at 100 km; Mars's 4e-6 on the ground, 3e-3 at 100 km, where its air
    is thinnest). With half the resolution (17: the first look's tables) the nodes are every other one of these.

    A band even in sqrt|mu_s|, mu_s = +-(k / n)^2 (0.2, 0.9, 2.0, 3.6, 5.6, 8.1 ... deg), crowds within a degree
    of the horizon and leaves 2 deg cells where the blue hour lies. Against the same table at resolution 129, over
    suns 9 deg below the horizon to the zenith (the luminance of what a camera 2 m up sees at 1 km, 30 km and of the
    sky, 5 view elevations x 3 azimuths), its interpolation is off by up to 9.5 /
    12.2 / 3.2 / 11.7 % (clear, overcast, Mars, sunset presets) with the sun 1-6 deg down, where these nodes give
    5.8 / 7.4 / 2.8 / 7.1 %; from 1 deg down to 3 deg up 1.6 / 1.6 / 0.6 / 2.0 % -> 1.2 / 1.0 / 0.4 / 1.3 %; 3-30
    deg 1.5 / 1.6 / 1.1 / 1.9 % -> 0.8 / 1.4 / 0.9 / 1.1 %; 6-9 deg down 17 / 39 / 7.4 / 20 % -> 13 / 27 / 6.0 /
    16 %; the day's cells are the same. Against the complete reference the blue hour is 5.3 % with that band, 3.8 %
    with these nodes.
    Even in sqrt|mu_s| over the whole range (mu_s = sign(u) u^2, u even in -1 .. 1), the last cell would run from a
    sun 61.5 deg up to the zenith, where the view's azimuth from the sun means nothing, so a sun 80 deg up would read
    a horizontal view 88 % from the zenith node, which holds no difference between toward and away from the sun:
    Mars at noon 1.05x too bright away from the sun and 0.96x toward it (4.8 % against the complete reference at
    64 000 paths; 0.3 % with even day cells).

    Between two nodes a cosine's fractional index is linear in the sun's elevation (read linearly in sqrt|mu_s|,
    the same nodes give the overcast 1 deg sun 3.8 % instead of 2.4 %, the Martian sunset 6.0 % instead of 5.5 %,
    the blue hour's chromaticity 0.0101 instead of 0.0099, its luminance 5.3 % instead of 5.5 %)."""

    resolution: int = 33

    def __post_init__(self) -> None:
        if self.resolution < 9 or self.resolution % 2 == 0:
            raise ValueError(f"the sun-cosine resolution must be odd and at least 9, not {self.resolution}")

    @functools.cached_property
    def _layout(self) -> tuple[int, int]:
        """(n, K): n = (resolution - 1) / 2, the terminator's cells a side."""
        n = (self.resolution - 1) // 2
        return n, max(2, round(TERMINATOR_SHARE * n))

    @functools.cached_property
    def cosines(self) -> np.ndarray:
        """mu_s of the nodes, ascending, from -1 to 1: 1 + K + 1 + K + K of them."""
        n, k = self._layout
        edge = math.asin((k / n) ** 2)    # 23.0 deg: the band's edge, mu_s = (K / n)^2
        side = edge * np.expm1(TERMINATOR_GROWTH * np.arange(1, k + 1) / k) / math.expm1(TERMINATOR_GROWTH)
        elevations = np.concatenate([[-0.5 * np.pi], -side[::-1], [0.0], side,
                                     np.linspace(edge, 0.5 * np.pi, k + 1)[1:]])
        result = np.sin(elevations)
        result.flags.writeable = False
        return result

    def __len__(self) -> int:
        return len(self.cosines)

    @functools.cached_property
    def elevations(self) -> np.ndarray:
        """The nodes' sun elevations, rad."""
        result = np.arcsin(self.cosines)
        result.flags.writeable = False
        return result

    def index(self, cos_zenith: ArrayLike) -> np.ndarray:
        """The fractional node index of sun zenith cosines (clamped to -1 .. 1), linear in the sun's elevation between
        two nodes."""
        elevation = np.arcsin(np.clip(np.asarray(cos_zenith, dtype=np.float64), -1.0, 1.0))
        return np.interp(elevation, self.elevations, np.arange(len(self.cosines), dtype=np.float64))
