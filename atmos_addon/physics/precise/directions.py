# SPDX-License-Identifier: GPL-3.0-or-later
"""The direction grid on which the multiple-scattering table carries light, and the phase-function weights that
scatter a field given on that grid into any view direction.

* The grid (:func:`direction_grid`): Gauss-Legendre zenith cosines on each hemisphere times even azimuths symmetric
  about the sun's; the table marches only the half with w_y > 0 (:func:`marched_half`), the light being symmetric
  about the sun's plane.
* The haze's forward peak: delta-Eddington (Joseph, Wiscombe & Weinman 1976) takes f = max(g, 0)^2 of its scattering
  as not scattered at all (:func:`forward_fraction`); on the grid only the part of the peak above its value at a cut
  angle is (:func:`grid_forward_fraction`, the cut following the haze's g: :func:`grid_cut_deg`).
* The weights (:func:`view_weights`): each view direction's phase functions integrated over each grid cell
  (:func:`cell_weights`), normalised to sum to 1 so that a peaked phase function neither gains nor loses light.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..atmosphere import Atmosphere
from ..phase import phase_hg, phase_rayleigh


def direction_grid(n_zenith: int, n_azimuth: int) -> tuple[np.ndarray, np.ndarray]:
    """(unit vectors (D, 3), solid angles (D,) summing to 4 pi): Gauss-Legendre zenith cosines on each hemisphere
    separately (``n_zenith`` per hemisphere, so the step in radiance at the horizon, sky above and ground below,
    falls between nodes) times ``n_azimuth`` even azimuths at (k + 1/2) 2 pi / n, a set symmetric about the
    azimuth 0 (the sun's)."""
    x, w = np.polynomial.legendre.leggauss(n_zenith)
    z = np.concatenate([-(x + 1.0) * 0.5, (x + 1.0) * 0.5])                         # (2 n_zenith,)
    dz = np.concatenate([w, w]) * 0.5
    phi = 2.0 * np.pi * (np.arange(n_azimuth) + 0.5) / n_azimuth
    across = np.sqrt(1.0 - z * z)[:, None]
    dirs = np.stack(np.broadcast_arrays(across * np.cos(phi), across * np.sin(phi), z[:, None]), axis=-1)
    return dirs.reshape(-1, 3), np.repeat(dz * (2.0 * np.pi / n_azimuth), n_azimuth)


@dataclass(frozen=True)
class MarchedHalf:
    """The half of :func:`direction_grid` with w_y > 0, which the multiple-scattering table marches: the light is
    symmetric about the plane of the zenith and the sun, and so is the grid, so each direction of the other half
    reads its mirror image (the same numbers for half the work)."""

    directions: np.ndarray   #: (D, 3) the marched directions w, in the grid's order
    share: np.ndarray        #: (D, 1) dOmega / 4 pi, counted twice (each direction stands for its mirror too)
    upward: np.ndarray       #: (D,) 2 max(w_z, 0) dOmega: what each direction adds to an irradiance from the sky
    mirror: np.ndarray       #: (2D,) for every direction of the whole grid, its index in the marched half


def marched_half(n_zenith: int, n_azimuth: int) -> MarchedHalf:
    """:class:`MarchedHalf` of :func:`direction_grid` (``n_azimuth`` even: the directions pair up about the sun's
    plane)."""
    if n_azimuth % 2:
        raise ValueError(f"n_azimuth must be even (the directions pair up about the sun's plane), not {n_azimuth}")
    dirs, solid_angle = direction_grid(n_zenith, n_azimuth)                       # (2D, 3), (2D,)
    marched = dirs[:, 1] > 0.0
    ring, azimuth = np.divmod(np.arange(len(dirs)), n_azimuth)
    mirror = ring * (n_azimuth // 2) + np.minimum(azimuth, n_azimuth - 1 - azimuth)
    directions = dirs[marched]
    return MarchedHalf(directions=directions, share=(2.0 * solid_angle[marched] / (4.0 * np.pi))[:, None],
                       upward=2.0 * np.maximum(directions[:, 2], 0.0) * solid_angle[marched], mirror=mirror)

#: The forward peak of the haze's phase function within an angle of straight on is carried as not scattered when the
#: table scatters the first order once more (:func:`grid_forward_fraction`); the rest is scattered on the direction
#: grid. A narrower cut sends light the grid cannot place (its azimuth step is 22.5 deg) off the sun's line, a wider
#: one keeps too much of it on that line. The angle grows with the haze's g (:func:`grid_cut_deg`): this many degrees
#: at :data:`GRID_CUT_REFERENCE_G`, the Earth presets' clear haze (the bench's day, sunset and blue-hour cases).
GRID_FORWARD_CUT_DEG = 30.0
#: The haze g at which the cut is :data:`GRID_FORWARD_CUT_DEG`.
GRID_CUT_REFERENCE_G = 0.76
#: How the cut grows with g, deg per unit of g (6 deg per 0.1), and its bounds, deg (the range the bench swept).
GRID_CUT_DEG_PER_G = 60.0
GRID_CUT_RANGE_DEG = (20.0, 35.0)


def grid_cut_deg(g: ArrayLike) -> np.ndarray:
    """The forward cut per channel, deg: :data:`GRID_FORWARD_CUT_DEG` + :data:`GRID_CUT_DEG_PER_G` (g - 0.76), within
    :data:`GRID_CUT_RANGE_DEG`.

    Why it follows g: one angle for every channel (30 deg) leaves Mars's dust (g 0.63 / 0.68 / 0.78) with red and
    green 2-6 % too bright and blue 2-10 % too dark at a 2 deg sun (5.6 % in luminance against 192 000 reference
    paths); a narrower cut for all channels darkens red and green but blue too (25 deg: 3.3 %, xy 0.0124). Swept
    per channel, the less forward a channel's haze, the narrower the cut it wants (Mars 25 / 25 / 30 deg: 3.6 %, xy
    0.0073; the overcast's g 0.6 is best at 20 deg, 3.5 % against 3.8 %). This line through them gives Mars
    22.2 / 25.2 / 31.2 deg (3.65 %, xy 0.0058) and every case of g 0.76 the 30 deg cut (docs/quality.md)."""
    g = np.asarray(g, dtype=np.float64)
    return np.clip(GRID_FORWARD_CUT_DEG + GRID_CUT_DEG_PER_G * (g - GRID_CUT_REFERENCE_G), *GRID_CUT_RANGE_DEG)


def grid_forward_fraction(atm: Atmosphere) -> np.ndarray:
    """f_c (3,): the share of the haze's scattering above the Henyey-Greenstein value at the cut
    (:func:`grid_cut_deg`) inside that cone (the peak the direction grid cannot resolve), per channel
    (:func:`cone_fraction`)."""
    return cone_fraction(mie_g(atm))


def _cut_cosine(g: np.ndarray) -> np.ndarray:
    """cos of :func:`grid_cut_deg` per channel (3,)."""
    return np.cos(np.radians(grid_cut_deg(g)))


def _hg_at_cut(g: np.ndarray) -> np.ndarray:
    """Henyey-Greenstein at each channel's own cut (3,): the diagonal of every cut against every channel's g."""
    return np.diagonal(phase_hg(_cut_cosine(g), g)).copy()


def cone_fraction(g: np.ndarray) -> np.ndarray:
    """:func:`grid_forward_fraction` of Henyey-Greenstein g (3,); 0 where g <= 0 (no forward peak). Closed form, mu_c
    the channel's cut cosine: 2 pi integral_{mu_c}^1 (Phi(mu) - Phi(mu_c)) dmu, with
    2 pi integral_{mu_c}^1 Phi dmu = (1 - g^2) / (2 g) (1 / (1 - g) - 1 / sqrt(1 + g^2 - 2 g mu_c))."""
    g = np.asarray(g, dtype=np.float64)
    safe = np.where(g > 0.0, g, 0.5)
    mu_c = _cut_cosine(safe)
    cone = (1.0 - safe ** 2) / (2.0 * safe) * (1.0 / (1.0 - safe) - 1.0 / np.sqrt(1.0 + safe ** 2 - 2.0 * safe * mu_c))
    flat = 2.0 * np.pi * (1.0 - mu_c) * _hg_at_cut(safe)
    return np.where(g > 0.0, np.maximum(cone - flat, 0.0), 0.0)


def cut_phase_hg(mu: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Henyey-Greenstein (..., 3) with its forward cone (within each channel's cut, :func:`grid_cut_deg`, where
    g > 0) flattened to the value at the cone's edge: the part of the phase function left once
    :func:`grid_forward_fraction` is taken out (not normalised)."""
    mu = np.asarray(mu)
    safe = np.where(g > 0.0, g, 0.5)
    return np.where((mu[..., None] > _cut_cosine(safe)) & (g > 0.0), _hg_at_cut(safe), phase_hg(mu, g))


def cell_weights(views: np.ndarray, n_zenith: int, n_azimuth: int, phase: Callable, sub: int = 8) -> np.ndarray:
    """(V, D, ...): ``phase(v . w')`` averaged over each cell of :func:`direction_grid` (``sub`` x ``sub``
    directions even in the zenith cosine and the azimuth within the cell), times the cell's solid angle: the integral
    of the phase function over each cell, the weight a field constant over the cell takes. Read at the cells' centres
    instead, a lobe narrower than a cell is weighed by where the centres fall (the haze's g 0.78 summed to 0.95-1.00
    over the grid before normalising, by view direction); with the cell averages alone the accuracy bench's
    Martian sunset is 16.7 % against 18.7 % with the centres (measured with the second order as a P1 field)."""
    _, w = np.polynomial.legendre.leggauss(n_zenith)
    edges = np.concatenate([[0.0], np.cumsum(w * 0.5)])               # the Gauss-Legendre cells of z in 0..1
    u = (np.arange(sub) + 0.5) / sub
    z_up = edges[:-1, None] + np.diff(edges)[:, None] * u             # (n_zenith, sub), the grid's order
    z = np.concatenate([-z_up, z_up])
    phi = 2.0 * np.pi * (np.arange(n_azimuth)[:, None] + u) / n_azimuth
    total = 0.0
    for a in range(sub):
        across = np.sqrt(np.maximum(1.0 - z[:, a] ** 2, 0.0))[:, None]
        for b in range(sub):
            cells = np.stack(np.broadcast_arrays(across * np.cos(phi[:, b]), across * np.sin(phi[:, b]),
                                                 z[:, a][:, None]), axis=-1).reshape(-1, 3)
            total = total + phase(views @ cells.T)
    _, solid_angle = direction_grid(n_zenith, n_azimuth)
    return total / (sub * sub) * solid_angle.reshape((1, -1) + (1,) * (np.ndim(total) - 2))


@functools.lru_cache(maxsize=8)
def view_weights(n_zenith: int, n_azimuth: int, n_view_cosines: int, n_view_azimuths: int,
                 haze_g: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The view grid (V, 3) and, per view direction, the weights that scatter the light of each grid direction into it
    (:func:`cell_weights`, each row normalised to 1): Rayleigh (V, D), the haze (V, D, 3), and the haze less its
    forward cone (V, D, 3, normalised then times 1 - f_c: :func:`grid_forward_fraction`). Cached: they depend on the
    grid and the haze's g only (0.1 s)."""
    view_z = np.linspace(-1.0, 1.0, n_view_cosines)[:, None]
    view_a = np.linspace(0.0, np.pi, n_view_azimuths)[None, :]
    across = np.sqrt(1.0 - view_z ** 2)
    views = np.stack(np.broadcast_arrays(across * np.cos(view_a), across * np.sin(view_a), view_z),
                     axis=-1).reshape(-1, 3)
    g = np.asarray(haze_g)
    rayleigh = cell_weights(views, n_zenith, n_azimuth, phase_rayleigh)
    mie = cell_weights(views, n_zenith, n_azimuth, lambda mu: phase_hg(mu, g))
    cut = cell_weights(views, n_zenith, n_azimuth, lambda mu: cut_phase_hg(mu, g))
    kept = 1.0 - cone_fraction(g)
    result = (views, rayleigh / rayleigh.sum(axis=1, keepdims=True), mie / mie.sum(axis=1, keepdims=True),
              cut / cut.sum(axis=1, keepdims=True) * kept)
    for array in result:
        array.flags.writeable = False
    return result


def forward_fraction(atm: Atmosphere) -> np.ndarray:
    """f = max(g, 0)^2 (3,): the share of the haze's scattering that the multiple-scattering table treats as not
    scattered at all (delta-Eddington: Joseph, Wiscombe & Weinman 1976, "The Delta-Eddington Approximation for
    Radiative Flux Transfer"). Henyey-Greenstein's forward peak is cut off as a delta function, f of the scattering:
    that light goes on in its direction as if it had not scattered (the haze's extinction less f beta_M), and the
    rest scatters with mean cosine g' = (g - f) / (1 - f), a field the first moment describes far better than the
    peaked whole. A haze that scatters backward (g <= 0) has no forward peak to cut: f = 0 (g^2 there would give
    |g'| > 1: at g -0.9 a negative table whose higher orders are darker than the first)."""
    return np.maximum(mie_g(atm), 0.0) ** 2


def mie_g(atm: Atmosphere) -> np.ndarray:
    """The haze's Henyey-Greenstein g per channel (3,)."""
    return np.broadcast_to(np.asarray(atm.mie_g, dtype=np.float64), (3,))
