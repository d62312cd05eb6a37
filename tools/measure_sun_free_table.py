# SPDX-License-Identifier: GPL-3.0-or-later
"""Issue 28's "no re-bake": a table that depends on neither the camera nor the sun, measured against Atmos's tile.

    .venv/bpy-5.2.3/bin/python tools/measure_sun_free_table.py [--presets clear mars] [--size 32 128 32 8]
        [--single-scattering] [--json out.json]

Atmos's Precise tile is camera-centred: a function of the camera's altitude h_c and the sun's elevation e_s, so a
change of either bakes a tile again (0.3-0.4 s on 2 cores). The table that depends on neither is Bruneton &
Neyret's (2008; the 2017 implementation's parametrisation and sizes): the in-scattered light S(x, v) of the whole
ray from any point x in any direction v to the top of the atmosphere or the ground, a 4-D function of the point's
radius r, the view's zenith cosine mu, the sun's zenith cosine mu_s there and nu = v . l, stored as a 3-D texture
of 32 r x 128 mu x (32 mu_s x 8 nu). Aerial perspective between the camera x and a surface point p on the ray is
then a difference of two lookups,

    L_in(x -> p) = S(x, v) - T(x, p) S(p, v),

exact for exact S (the ray's integral split at p), with p's lookup on the same half of the mu axis (ground or sky)
as the camera's. This script builds that table from the same integrals as the tile (:func:`precise.ray_integrals`:
the same single scattering, multiple scattering source and ozone), samples it as a GPU's texture filter would (in
float32: quadrilinear, the 2017 texel-centre mappings), and compares both it and Atmos's tile with the integrals
taken directly along each segment (the same 65-sample rule, so what is measured is each table's own error: its
parametrisation, its interpolation and, for Bruneton's, the cancellation of the difference). T(x, p) is taken
exact here (a transmittance table would add its own error). It prints, per preset and distance band, the error of
L_in (phase functions applied, worst channel) relative to L_in and as a fraction of the sky at the horizon in the
segment's azimuth (what a surface fades to, every order of scattering: what an eye sees of the error) at the median,
99th percentile and maximum, how many segments the 4-D table makes negative (by 0.01 % of that sky or more), the
4-D table's build time on this machine's threads and its size; also the tile as it would be with its multiple
scattering in a block of its own (emulated: :func:`tile_with_a_multiple_scattering_block`); ``--single-scattering``
leaves the multiple scattering out of the truth, the tile and the 4-D table. ``docs/quality.md`` ("A table without
the camera and the sun") reports a run.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

REPO_ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO_ROOT))

from atmos_addon import presets  # noqa: E402
from atmos_addon.physics import precise  # noqa: E402
from atmos_addon.physics.phase import phase_hg, phase_rayleigh  # noqa: E402

#: Bruneton 2017's scattering texture: r, mu, mu_s and nu samples.
R_SIZE, MU_SIZE, MU_S_SIZE, NU_SIZE = 32, 128, 32, 8
#: The lowest sun zenith cosine the table holds (Bruneton's mu_s_min for Earth: the sun 12 deg below the horizon).
MU_S_MIN = math.cos(math.radians(102.0))
CAMERA_ALTITUDES_M = (2.0, 100.0, 1000.0)
SUN_ELEVATIONS_DEG = (30.0, 5.0, 1.0, -3.0)
VIEW_ELEVATIONS_DEG = (-10.0, -2.0, -0.3, 0.3, 2.0, 10.0, 45.0, 89.0)
AZIMUTHS_DEG = (0.0, 60.0, 120.0, 180.0)
DISTANCES_M = (30.0, 100.0, 300.0, 1e3, 3e3, 1e4, 3e4, 1e5)
BANDS_M = ((0.0, 300.0), (300.0, 3e3), (3e3, 3e4), (3e4, 1e6))


def _unit_from_coord(u, n):
    return (u - 0.5 / n) / (1.0 - 1.0 / n)


def _coord_from_unit(x, n):
    return 0.5 / n + x * (1.0 - 1.0 / n)


def _safe_sqrt(x):
    return np.sqrt(np.maximum(x, 0.0))


class Geometry:
    """Bruneton 2017's mappings between (r, mu, mu_s, nu) and texture coordinates, for one planet."""

    def __init__(self, atm) -> None:
        self.bottom = atm.planet_radius
        self.top = atm.planet_radius + atm.atmosphere_height
        self.h = math.sqrt(self.top ** 2 - self.bottom ** 2)

    def distance_to_top(self, r, mu):
        return np.maximum(-r * mu + _safe_sqrt(r * r * (mu * mu - 1.0) + self.top ** 2), 0.0)

    def texel_parameters(self):
        """(r, mu, mu_s, nu, hits the ground) at every texel centre, each (R, MU, MU_S, NU)."""
        u_r = (np.arange(R_SIZE) + 0.5) / R_SIZE
        u_mu = (np.arange(MU_SIZE) + 0.5) / MU_SIZE
        u_mu_s = (np.arange(MU_S_SIZE) + 0.5) / MU_S_SIZE
        u_nu = np.arange(NU_SIZE) / (NU_SIZE - 1)
        rho = self.h * _unit_from_coord(u_r, R_SIZE)[:, None]
        r = np.sqrt(rho * rho + self.bottom ** 2)
        ground = (u_mu < 0.5)[None, :]
        with np.errstate(divide="ignore", invalid="ignore"):
            d_min, d_max = r - self.bottom, rho
            d = d_min + (d_max - d_min) * _unit_from_coord(1.0 - 2.0 * u_mu[None, :], MU_SIZE / 2)
            mu_ground = np.where(d == 0.0, -1.0, np.clip(-(rho * rho + d * d) / (2.0 * r * d), -1.0, 1.0))
            d_min, d_max = self.top - r, rho + self.h
            d = d_min + (d_max - d_min) * _unit_from_coord(2.0 * u_mu[None, :] - 1.0, MU_SIZE / 2)
            mu_sky = np.where(d == 0.0, 1.0, np.clip((self.h ** 2 - rho * rho - d * d) / (2.0 * r * d), -1.0, 1.0))
        mu = np.where(ground, mu_ground, mu_sky)                                  # (R, MU)
        x_mu_s = _unit_from_coord(u_mu_s, MU_S_SIZE)
        d_min, d_max = self.top - self.bottom, self.h
        big_a = (self.distance_to_top(self.bottom, MU_S_MIN) - d_min) / (d_max - d_min)
        a = (big_a - x_mu_s * big_a) / (1.0 + x_mu_s * big_a)
        d = d_min + np.minimum(a, big_a) * (d_max - d_min)
        mu_s = np.where(d == 0.0, 1.0, np.clip((self.h ** 2 - d * d) / (2.0 * self.bottom * d), -1.0, 1.0))
        nu = np.clip(u_nu * 2.0 - 1.0, -1.0, 1.0)
        shape = (R_SIZE, MU_SIZE, MU_S_SIZE, NU_SIZE)
        r4 = np.broadcast_to(r[:, :, None, None], shape)
        mu4 = np.broadcast_to(mu[:, :, None, None], shape)
        mu_s4 = np.broadcast_to(mu_s[None, None, :, None], shape)
        spread = np.sqrt(np.maximum((1.0 - mu4 * mu4) * (1.0 - mu_s4 * mu_s4), 0.0))
        nu4 = np.clip(nu[None, None, None, :], mu4 * mu_s4 - spread, mu4 * mu_s4 + spread)
        return r4, mu4, mu_s4, nu4, np.broadcast_to(ground[:, :, None, None], shape)

    def coordinates(self, r, mu, mu_s, nu, ground):
        """Continuous texel coordinates (r, mu, mu_s, nu) of each lookup: index space, texel centres at integers."""
        rho = _safe_sqrt(r * r - self.bottom ** 2)
        u_r = _coord_from_unit(rho / self.h, R_SIZE)
        r_mu = r * mu
        disc = r_mu * r_mu - r * r + self.bottom ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            d = -r_mu - _safe_sqrt(disc)
            d_min, d_max = r - self.bottom, rho
            x = np.where(d_max == d_min, 0.0, (d - d_min) / (d_max - d_min))
            u_ground = 0.5 - 0.5 * _coord_from_unit(x, MU_SIZE / 2)
            d = -r_mu + _safe_sqrt(disc + self.h ** 2)
            d_min, d_max = self.top - r, rho + self.h
            u_sky = 0.5 + 0.5 * _coord_from_unit((d - d_min) / (d_max - d_min), MU_SIZE / 2)
        u_mu = np.where(ground, u_ground, u_sky)
        d = self.distance_to_top(self.bottom, mu_s)
        d_min, d_max = self.top - self.bottom, self.h
        a = (d - d_min) / (d_max - d_min)
        big_a = (self.distance_to_top(self.bottom, MU_S_MIN) - d_min) / (d_max - d_min)
        u_mu_s = _coord_from_unit(np.maximum(1.0 - a / big_a, 0.0) / (1.0 + a), MU_S_SIZE)
        u_nu = (nu + 1.0) / 2.0
        return (u_r * R_SIZE - 0.5, u_mu * MU_SIZE - 0.5, u_mu_s * MU_S_SIZE - 0.5, u_nu * (NU_SIZE - 1))


def build_table(atm, tables, multiple_scattering: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """(S_R, S_M) per unit E_top at every texel, each (R, MU, MU_S, NU, 3) float32; S_R holds S_ms / Phi_R(nu)."""
    geometry = Geometry(atm)
    r, mu, mu_s, nu, ground = geometry.texel_parameters()
    length = np.where(ground, np.maximum(-r * mu - _safe_sqrt(r * r * (mu * mu - 1.0) + geometry.bottom ** 2), 0.0),
                      geometry.distance_to_top(r, mu))
    s_r = np.zeros(r.shape + (3,), np.float32)
    s_m = np.zeros_like(s_r)

    def one_slice(index: int) -> None:
        i, half = divmod(index, 4)
        part = slice(half * MU_SIZE // 4, (half + 1) * MU_SIZE // 4)
        _, j_r, j_m, *_ = precise.ray_integrals(atm, tables, r[i, part], mu[i, part], mu_s[i, part], nu[i, part],
                                                length[i, part], multiple_scattering=multiple_scattering)
        s_r[i, part], s_m[i, part] = j_r, j_m

    precise.in_parallel(one_slice, R_SIZE * 4)
    return s_r, s_m


def lookup(table: np.ndarray, coords) -> np.ndarray:
    """``table`` at continuous texel coordinates, quadrilinear, clamped to the edges, in float32."""
    result = 0.0
    corners = []
    for x, n in zip(coords, table.shape[:4]):
        x = np.clip(np.asarray(x, np.float32), 0.0, n - 1)
        low = np.clip(np.floor(x).astype(np.int64), 0, n - 2)
        f = (x - low).astype(np.float32)
        corners.append((low, f))
    for bits in range(16):
        index, weight = [], np.float32(1.0)
        for axis in range(4):
            low, f = corners[axis]
            b = (bits >> axis) & 1
            index.append(low + b)
            weight = weight * (f if b else (1.0 - f))
        result = result + weight[..., None] * table[tuple(index)]
    return result.astype(np.float32)


def tile_with_a_multiple_scattering_block(atm, camera_altitude_m: float, sun_elevation_rad: float, views, sun, d):
    """L_in from the tile as it would be with the multiple scattering in a block of its own, stored without the
    division by each cell's Rayleigh phase and added after the phase functions (a variant the shader does not have:
    emulated from the tile and its single-scattering twin, sampled as the shader samples its blocks)."""
    full = precise.bake_tile(atm, camera_altitude_m, sun_elevation_rad)
    single = precise.bake_tile(atm, camera_altitude_m, sun_elevation_rad, multiple_scattering=False)
    shape = full.shape
    r_c = full.camera_radius_m
    r_p = (atm.planet_radius + precise.row_altitudes(shape, atm))[:, None, None]
    column = precise.cell_distances(shape, full.max_distance_m, r_p[:, 0, 0] - r_c, full.vertical_columns)[:, None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        sin_e = np.where(column > 0.0, (r_p * r_p - r_c * r_c - column * column) / (2.0 * r_c * column), 0.0)
    sin_e = np.clip(sin_e, -1.0, 1.0)
    azimuth = np.linspace(0.0, np.pi, shape.azimuths)[None, :, None]
    cell_nu = (np.sqrt(1.0 - sin_e * sin_e) * np.cos(azimuth) * math.cos(sun_elevation_rad)
               + sin_e * math.sin(sun_elevation_rad))                                   # each cell's own nu
    a_ms = (np.asarray(full.a_rayleigh) - np.asarray(single.a_rayleigh)) * phase_rayleigh(cell_nu)[..., None]
    to_top = precise.distance_to_top(views[:, 2], camera_altitude_m, atm)
    row, az, col = precise.table_coordinates(single, views, sun, np.minimum(d, to_top), atm, np.float64)
    nu = views @ sun
    f_ex, _ = precise.evaluate(single, views, sun, d, atm, np.float64)
    light = (phase_rayleigh(nu)[:, None] * precise.sample(single.a_rayleigh, row, az, col, np.float64)
             + phase_hg(nu, atm.mie_g) * precise.sample(single.a_mie, row, az, col, np.float64)
             + precise.sample(a_ms, row, az, col, np.float64))
    return light * (1.0 - f_ex)


def samples(atm, camera_altitude_m: float, sun_elevation_deg: float):
    """(view directions (N, 3), distances (N,)) of the study's segments from a camera at that altitude: every
    elevation x azimuth x distance whose point lies above the ground and below the top."""
    views, distances = [], []
    for e in VIEW_ELEVATIONS_DEG:
        for a in AZIMUTHS_DEG:
            v = (math.cos(math.radians(e)) * math.cos(math.radians(a)),
                 math.cos(math.radians(e)) * math.sin(math.radians(a)), math.sin(math.radians(e)))
            length, _ = precise.sky_path_length(np.array(v[2]), camera_altitude_m, atm)
            for d in DISTANCES_M:
                if d <= float(length) * 0.999:
                    views.append(v)
                    distances.append(d)
    return np.array(views), np.array(distances)


def compare(atm, tables, table, camera_altitude_m: float, sun_elevation_deg: float,
            multiple_scattering: bool = True) -> dict:
    """Relative errors of L_in (worst channel) of the tile and of the 4-D table, and the distances, of one camera and
    sun."""
    views, d = samples(atm, camera_altitude_m, sun_elevation_deg)
    e_s = math.radians(sun_elevation_deg)
    sun = np.array([math.cos(e_s), 0.0, math.sin(e_s)])
    nu = views @ sun
    r_c = atm.planet_radius + camera_altitude_m
    mu = views[:, 2]
    tau, truth = precise.ray_inscattering(atm, tables, r_c, mu, math.sin(e_s), nu, d,
                                          multiple_scattering=multiple_scattering)
    phase_r, phase_m = phase_rayleigh(nu)[:, None], phase_hg(nu, atm.mie_g)
    e_top = np.asarray(atm.sun_irradiance_top)

    tile = precise.bake_tile(atm, camera_altitude_m, e_s, multiple_scattering=multiple_scattering)
    _, tile_light = precise.evaluate(tile, views, sun, d, atm)
    block = (tile_with_a_multiple_scattering_block(atm, camera_altitude_m, e_s, views, sun, d)
             if multiple_scattering else tile_light)

    geometry = Geometry(atm)
    _, hits = precise.sky_path_length(mu, camera_altitude_m, atm)
    r_p = np.sqrt(d * d + 2.0 * r_c * mu * d + r_c * r_c)
    mu_p = (r_c * mu + d) / r_p
    mu_s_p = (r_c * math.sin(e_s) + d * nu) / r_p
    at_camera = geometry.coordinates(np.full_like(d, r_c), mu, np.full_like(d, math.sin(e_s)), nu, hits)
    at_point = geometry.coordinates(r_p, mu_p, mu_s_p, nu, hits)
    s_r, s_m = table
    t = np.exp(-tau).astype(np.float32)
    l_r = lookup(s_r, at_camera) - t * lookup(s_r, at_point)
    l_m = lookup(s_m, at_camera) - t * lookup(s_m, at_point)
    four_d = (e_top * (phase_r * l_r + phase_m * l_m)).astype(np.float32)
    # what a surface fades to: the sky at the horizon in the segment's azimuth (its ray to the top)
    across = np.hypot(views[:, 0], views[:, 1])
    flat = views[:, :2] / np.maximum(across, 1e-9)[:, None]
    flat[across < 1e-6] = (1.0, 0.0)
    nu_h = flat @ sun[:2]
    to_top = precise.distance_to_top(np.zeros_like(d), camera_altitude_m, atm)
    _, haze = precise.ray_inscattering(atm, tables, r_c, 0.0, math.sin(e_s), nu_h, to_top)   # every order: what is seen
    lit = truth > 1e-4 * haze     # relative errors where L_in is 0.01 % of that sky or more (not in the shadow)
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = np.maximum(truth, 1e-30)
        return {"distance_m": d, "tile": np.max(np.where(lit, np.abs(tile_light - truth) / scale, 0.0), axis=-1),
                "table_4d": np.max(np.where(lit, np.abs(four_d - truth) / scale, 0.0), axis=-1),
                "tile_vs_haze": np.max(np.abs(tile_light - truth) / haze, axis=-1),
                "tile_ms_block_vs_haze": np.max(np.abs(block - truth) / haze, axis=-1),
                "table_4d_vs_haze": np.max(np.abs(four_d - truth) / haze, axis=-1),
                "negative_4d": np.any(four_d < -1e-4 * haze, axis=-1)}   # below 0 by 0.01 % of that sky or more


def summary(errors: np.ndarray) -> dict:
    return {"median": float(np.median(errors)), "p99": float(np.percentile(errors, 99)), "max": float(np.max(errors))}


def main() -> None:
    global R_SIZE, MU_SIZE, MU_S_SIZE, NU_SIZE
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--presets", nargs="+", default=["clear", "mars"])
    parser.add_argument("--json", type=Path)
    parser.add_argument("--size", nargs=4, type=int, metavar=("R", "MU", "MU_S", "NU"),
                        default=(R_SIZE, MU_SIZE, MU_S_SIZE, NU_SIZE), help="the 4-D table's samples (a variant)")
    parser.add_argument("--single-scattering", action="store_true",
                        help="leave the multiple scattering out of the truth, the tile and the 4-D table")
    args = parser.parse_args()
    R_SIZE, MU_SIZE, MU_S_SIZE, NU_SIZE = args.size
    if MU_SIZE % 8:
        parser.error("MU must be a multiple of 8 (the build's blocks)")
    report = {"workers": precise.WORKERS, "size": list(args.size), "multiple_scattering": not args.single_scattering,
              "presets": {}}
    for name in args.presets:
        atm = presets.load(name).atmosphere
        tables = precise.atmosphere_tables(atm)
        start = time.perf_counter()
        multiple = not args.single_scattering
        table = build_table(atm, tables, multiple)
        build_s = time.perf_counter() - start
        runs = [compare(atm, tables, table, h, e, multiple) for h in CAMERA_ALTITUDES_M for e in SUN_ELEVATIONS_DEG]
        d = np.concatenate([run["distance_m"] for run in runs])
        bands = {}
        for low, high in BANDS_M:
            inside = (d >= low) & (d < high)
            bands[f"{low:g}-{high:g} m"] = {
                "segments": int(inside.sum()),
                "tile": summary(np.concatenate([run["tile"] for run in runs])[inside]),
                "table_4d": summary(np.concatenate([run["table_4d"] for run in runs])[inside]),
                "tile_vs_haze": summary(np.concatenate([run["tile_vs_haze"] for run in runs])[inside]),
                "tile_ms_block_vs_haze": summary(
                    np.concatenate([run["tile_ms_block_vs_haze"] for run in runs])[inside]),
                "table_4d_vs_haze": summary(np.concatenate([run["table_4d_vs_haze"] for run in runs])[inside]),
                "negative_4d": int(np.concatenate([run["negative_4d"] for run in runs])[inside].sum())}
        report["presets"][name] = {"build_4d_s": build_s, "bands": bands}
        print(f"{name}: 4-D table built in {build_s:.2f} s on {precise.WORKERS} thread(s)")
        for key, what in (("", "of L_in"), ("_vs_haze", "as a fraction of the horizon sky in its azimuth")):
            print(f"  error {what}")
            print("  distances        segments   tile median / p99 / max      4-D table median / p99 / max   negative")
            for band, row in bands.items():
                t, f = row["tile" + key], row["table_4d" + key]
                print(f"  {band:16s} {row['segments']:8d}   {t['median']:7.2%} {t['p99']:8.2%} {t['max']:8.2%}"
                      f"      {f['median']:8.2%} {f['p99']:9.2%} {f['max']:9.2%}   {row['negative_4d']}")
        if not args.single_scattering:
            print("  the tile with its multiple scattering in a block of its own (emulated), as a fraction of that sky")
            for band, row in bands.items():
                b = row["tile_ms_block_vs_haze"]
                print(f"  {band:16s} {row['segments']:8d}   {b['median']:7.2%} {b['p99']:8.2%} {b['max']:8.2%}")
    texels = R_SIZE * MU_SIZE * MU_S_SIZE * NU_SIZE
    report["texels_4d"] = texels
    report["megabytes_4d_rgba_two_images"] = texels * 2 * 4 * 4 / 1e6
    report["megabytes_tile"] = precise.DEFAULT_SHAPE.altitudes * precise.DEFAULT_SHAPE.width * 4 * 4 / 1e6
    print(f"4-D table: {texels} texels, {report['megabytes_4d_rgba_two_images']:.1f} MB as two float RGBA images "
          f"(Rayleigh, Mie); a tile {report['megabytes_tile']:.2f} MB")
    if args.json:
        args.json.write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
