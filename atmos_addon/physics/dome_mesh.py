# SPDX-License-Identifier: GPL-3.0-or-later
"""The virtual sky dome as a closed triangle mesh around the camera, for Cycles' exact volume absorption.

The aerial perspective and the sky use, per species i (molecules, aerosols), the path length inside the
virtual dome: b_i = min(s, R_i(v)), with R_i the dome distance of :func:`.sky.dome_distance_approx`
(Hoffman & Preetham 2002, GDC slides "Virtual sky dome"; elevation clamped at the horizon, so below it the
dome is the sphere of radius R_i(0)). The set {camera + r v : r < R_i(v)} is a closed region that is
star-shaped around the camera: filled with a homogeneous absorber of coefficient beta_i, a ray from the
camera loses exactly exp(-beta_i b_i) inside it. This module builds that surface as a mesh (m, camera at
the origin, +z up):

- rings of constant elevation, spaced adaptively so that a planar facet between two rings meets every ray
  of the rings' azimuth within ``tolerance`` (relative) of R_i (the dome is almost the plane z = H_i
  overhead and bends down to R_i(0) = H_i sqrt(pi R_p / (2 H_i)) at the horizon; planar facets are exact
  for the plane, so the rings crowd near the horizon only);
- ``azimuth_segments`` vertices per ring; a chord between two azimuths is short of the circle by
  1 - cos(pi / N), so every radius is scaled by 2 / (1 + cos(pi / N)) and the azimuthal error swings
  evenly between +-(1 - cos(pi / N)) / 2 (+-1.9e-5 for N = 256) instead of one-sided;
- below the horizon ``below_rings`` rings of the sphere R_i(0) (radii scaled the same way for the chords
  between rings), a single vertex at each pole, faces ordered so that normals point outward (away from
  the camera).

Pure numpy, float64; no bpy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .sky import chapman_approx

#: Default relative tolerance of the facets along elevation (the azimuth adds its own, see module docstring).
DEFAULT_TOLERANCE = 2.0e-5
DEFAULT_AZIMUTH_SEGMENTS = 256
DEFAULT_BELOW_RINGS = 64


def dome_radius(elevation_rad: np.ndarray | float, planet_radius_m: float, scale_height_m: float) -> np.ndarray:
    """R(e) = H Ch_approx(R_p / H, sin(max(e, 0))), m: the dome distance the shader nodes evaluate."""
    mu = np.sin(np.clip(np.asarray(elevation_rad, dtype=float), 0.0, 0.5 * math.pi))
    return scale_height_m * chapman_approx(planet_radius_m / scale_height_m, mu)


def chord_distance(e1: float, r1: float, e2: float, r2: float, elevation_rad: np.ndarray) -> np.ndarray:
    """Distance along elevation ``elevation_rad`` to the straight segment between (e1, r1) and (e2, r2), polar."""
    p1 = np.array([r1 * math.cos(e1), r1 * math.sin(e1)])
    edge = np.array([r2 * math.cos(e2), r2 * math.sin(e2)]) - p1
    d = np.stack([np.cos(elevation_rad), np.sin(elevation_rad)], axis=-1)
    numerator = p1[0] * edge[1] - p1[1] * edge[0]
    return numerator / (d[..., 0] * edge[1] - d[..., 1] * edge[0])


def _chord_error(e1: float, e2: float, planet_radius_m: float, scale_height_m: float) -> float:
    """Largest relative error of the chord between rings e1 < e2 against R, at interior elevations."""
    probes = e1 + (e2 - e1) * np.linspace(0.0, 1.0, 9)[1:-1]
    r1, r2 = dome_radius(np.array([e1, e2]), planet_radius_m, scale_height_m)
    exact = dome_radius(probes, planet_radius_m, scale_height_m)
    return float(np.max(np.abs(chord_distance(e1, float(r1), e2, float(r2), probes) / exact - 1.0)))


def ring_elevations(planet_radius_m: float, scale_height_m: float, tolerance: float = DEFAULT_TOLERANCE,
                    max_rings: int = 4096) -> np.ndarray:
    """Elevations (rad) of the rings from the horizon (0) to the zenith (pi/2), adaptively bisected."""
    if not (planet_radius_m > 0.0 and scale_height_m > 0.0 and tolerance > 0.0):
        raise ValueError("dome rings need a planet radius, a scale height and a tolerance > 0")
    pending = list(zip(np.linspace(0.0, 0.5 * math.pi, 9)[:-1], np.linspace(0.0, 0.5 * math.pi, 9)[1:]))
    done: list[float] = [0.5 * math.pi]
    while pending:
        e1, e2 = pending.pop()
        if _chord_error(e1, e2, planet_radius_m, scale_height_m) > tolerance and len(done) + len(pending) < max_rings:
            middle = 0.5 * (e1 + e2)
            pending.extend([(e1, middle), (middle, e2)])
        else:
            done.append(e1)
    return np.array(sorted(done))


@dataclass(frozen=True)
class DomeMesh:
    """A closed, outward-oriented triangle mesh: ``vertices`` (n, 3) in m, ``triangles`` (m, 3) vertex indices."""

    vertices: np.ndarray
    triangles: np.ndarray
    horizon_radius_m: float


def dome_mesh(planet_radius_m: float, scale_height_m: float, *, tolerance: float = DEFAULT_TOLERANCE,
              azimuth_segments: int = DEFAULT_AZIMUTH_SEGMENTS, below_rings: int = DEFAULT_BELOW_RINGS) -> DomeMesh:
    """The dome of one species (scale height ``scale_height_m``) around a camera at the origin (module docstring)."""
    if azimuth_segments < 8 or below_rings < 2:
        raise ValueError("a dome mesh needs at least 8 azimuth segments and 2 rings below the horizon")
    n = int(azimuth_segments)
    above = ring_elevations(planet_radius_m, scale_height_m, tolerance)
    below = -0.5 * math.pi * np.arange(below_rings - 1, 0, -1) / below_rings
    elevations = np.concatenate([below, above[:-1]])  # bottom to top, without the poles
    radii = dome_radius(elevations, planet_radius_m, scale_height_m) * (2.0 / (1.0 + math.cos(math.pi / n)))
    step_below = 0.25 * math.pi / below_rings  # half the angle between rings of the sphere below the horizon
    radii[elevations < 0.0] *= 2.0 / (1.0 + math.cos(step_below))
    phi = 2.0 * math.pi * np.arange(n) / n
    ring_xy = radii[:, None] * np.cos(elevations)[:, None]
    ring_z = np.broadcast_to((radii * np.sin(elevations))[:, None], (len(radii), n))
    rings = np.stack([ring_xy * np.cos(phi)[None, :], ring_xy * np.sin(phi)[None, :], ring_z], axis=-1)
    zenith = dome_radius(0.5 * math.pi, planet_radius_m, scale_height_m)
    nadir = dome_radius(0.0, planet_radius_m, scale_height_m)
    vertices = np.concatenate([[[0.0, 0.0, -float(nadir)]], rings.reshape(-1, 3), [[0.0, 0.0, float(zenith)]]])
    top = len(vertices) - 1
    count = len(elevations)

    def index(ring: np.ndarray, k: np.ndarray) -> np.ndarray:
        return 1 + ring * n + (k % n)

    k = np.arange(n)
    triangles = [np.stack([np.zeros(n, dtype=int), index(0, k + 1), index(0, k)], axis=-1)]  # bottom fan
    for ring in range(count - 1):
        a, b = index(ring, k), index(ring, k + 1)
        c, d = index(ring + 1, k + 1), index(ring + 1, k)
        triangles += [np.stack([a, b, c], axis=-1), np.stack([a, c, d], axis=-1)]
    last = count - 1
    triangles.append(np.stack([index(last, k), index(last, k + 1), np.full(n, top)], axis=-1))  # top fan
    return DomeMesh(vertices=vertices, triangles=np.concatenate(triangles).astype(np.int32),
                    horizon_radius_m=float(nadir))
