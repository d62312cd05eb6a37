# SPDX-License-Identifier: GPL-3.0-or-later
"""The Precise quality level: single scattering integrated numerically, plus multiple scattering, baked into a
camera-centred table that the shader samples.

Why a camera-centred table
    For one frame the camera (altitude h_c) and the sun (elevation e_s) are fixed. A camera ray is then fixed
    by its elevation e, its azimuth a from the sun's azimuth (0..pi, mirror-symmetric) and the distance d to
    the surface it hits, so every aerial-perspective quantity is a function of (e, a, d): a 3-D table per
    frame, with no subtraction of two long-ray lookups (Bruneton 2008's S(x) - T S(p), which cancels for
    near objects) and no per-pixel march. An animated camera or sun gets one table ("tile") per frame, all
    in one image the .blend carries, and a keyed tile index, so a farm renders it without Python.

What the table holds, per colour channel (rays start at the camera, t in m along the unit direction v)
    tau(d)  = integral_0^d beta_ex(h(t)) dt, stored as tau / d (1/m)             optical depth; F_ex = exp(-tau)
    A_R(d)  = E_top [J_R(d) + J_ms(d) / Phi_R(nu)] / (1 - exp(-tau(d)))
    A_M(d)  = E_top J_M(d) / (1 - exp(-tau(d)))
    J_i(d)  = integral_0^d beta_i n_i(h(t)) T_sun(x(t)) exp(-tau(t)) dt          i = R, M (scattering, no phase)
    J_ms(d) = integral_0^d (beta_R n_R + beta_M n_M)(h(t)) Psi_ms(h(t), mu_s(t)) exp(-tau(t)) dt

and the shader forms
    F_ex = exp(-tau),    L_in = [Phi_R(nu) A_R + Phi_HG(nu, g) A_M] (1 - exp(-tau))

with nu = v . l (constant along a straight ray, so the phase functions leave the integrals). Dividing by
1 - exp(-tau) when baking (float64, never in the shader: no coloured banding) leaves quantities that are
constant for a homogeneous medium and vary slowly otherwise, so linear interpolation between distance samples
is accurate; the shader's 1 - exp(-tau) = tau phi1(tau) is exact to float32 at every distance. Multiple
scattering is isotropic, so it is stored in the Rayleigh column divided by Phi_R(nu) (as Bruneton 2017 stores
his higher orders).

Geometry (spherical planet, radius R): the camera at radius r_c = R + h_c; a point at distance t has radius
r(t) = sqrt(r_c^2 + 2 r_c t sin e + t^2) and sun zenith cosine mu_s(t) = (r_c sin e_s + t nu) / r(t).
Densities n_i = exp(-max(h, 0) / H_i) (the ground is transparent to the table: a ray continues smoothly
below it, where no visible surface lies). T_sun is 0 where the ray to the sun meets the planet (its shadow).

Table axes (:class:`TableShape`)
    * elevation rows, odd count, the middle row on the frame's horizon dip e_h = -arccos(R / r_c): row
      (u + 1) (N_e - 1) / 2 with u = sign(e - e_h) sqrt(|e - e_h| / (pi/2 -+ e_h)), so rows crowd at the grazing
      rays whose long paths need them (0.09 deg apart next to it with 65 rows);
    * azimuth slices, a = pi j / (N_a - 1), interpolated linearly (the shader's manual blend);
    * distance columns, d_k = D (k / (N_d - 1))^2 with D the longest ray that stays above the ground inside
      the atmosphere (camera to tangent point to the top), d beyond D clamped.
Within one azimuth slice the texture's bilinear filter does (elevation, distance).

Sun transmittance: optical depth to space tau_i = beta_i H_i exp(-h / H_i) Ch(r / H_i, chi)
(:mod:`.optical_depth`), with log Ch interpolated from a table in (altitude, position between the local
horizon and the zenith) (:class:`SunTransmittanceTable`, 0.02 % of tau against direct quadrature).

Multiple scattering: Hillaire 2020 ("A Scalable and Production Ready Sky and Atmosphere Rendering
Technique", section 5.5): the second order L_2 and the transfer f_ms at each (altitude, sun zenith) from an
isotropic phase over the sphere of directions, infinite orders summed as a geometric series,
Psi_ms = L_2 / (1 - f_ms), and the in-scattering sigma_s Psi_ms along the view ray (:func:`multiple_scattering_table`).
The ground reflects the sun as a Lambertian surface of ``ground_albedo``.

Units: lengths m, angles rad, coefficients 1/m, E_top and radiances W/m^2 (per sr for radiances) in Blender's
sun-strength unit. :func:`evaluate` reproduces the shader's float32 sampling step by step.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

from .aerial_perspective import one_minus_exp_over_x
from .atmosphere import Atmosphere
from .optical_depth import chapman
from .phase import phase_hg, phase_rayleigh

#: Ground albedo of the multiple-scattering table when none is given (a grey, green-ish land).
DEFAULT_GROUND_ALBEDO = (0.18, 0.2, 0.15)


@dataclass(frozen=True)
class TableShape:
    """Sample counts of the camera-centred table: target-altitude rows, azimuth slices, distance columns."""

    altitudes: int = 65
    azimuths: int = 8
    distances: int = 32

    def __post_init__(self) -> None:
        if min(self.altitudes, self.azimuths, self.distances) < 2:
            raise ValueError(f"TableShape needs >= 2 samples on every axis; got {self}")

    @property
    def width(self) -> int:
        """Texels across one tile: the extinction block (one slice) and the two in-scattering blocks, px."""
        return self.distances * (1 + 2 * self.azimuths)


#: The shape the add-on bakes (its node graph is built for it).
DEFAULT_SHAPE = TableShape()


def max_distance(camera_altitude_m: float, atm: Atmosphere) -> float:
    """D = sqrt(r_c^2 - R^2) + sqrt(r_top^2 - R^2): the longest ray from the camera that leaves the atmosphere
    without meeting the ground (camera to tangent point to the top), m."""
    r = atm.planet_radius
    r_c = r + max(float(camera_altitude_m), 0.0)
    r_top = r + atm.atmosphere_height
    return math.sqrt(r_c * r_c - r * r) + math.sqrt(r_top * r_top - r * r)


def row_altitudes(shape: TableShape, atm: Atmosphere) -> np.ndarray:
    """Target altitude of each table row, m: top (j / (N_h - 1))^3 (47 m apart at 100 m, 220 m at 1 km)."""
    return atm.atmosphere_height * np.linspace(0.0, 1.0, shape.altitudes) ** 3


def distance_columns(shape: TableShape, d_max_m: float) -> np.ndarray:
    """Distance of each table column, m: D (k / (N_d - 1))^2."""
    return d_max_m * np.linspace(0.0, 1.0, shape.distances) ** 2


def target_altitude(camera_radius_m, cos_zenith, distance_m, planet_radius_m, dtype: DTypeLike = np.float64):
    """Altitude of the point at ``distance_m`` along a ray leaving radius r_c with zenith cosine c, m:
    h_p = h_c + (2 r_c c d + d^2) / (r_p + r_c), r_p = sqrt(r_c^2 + 2 r_c c d + d^2) (no cancellation in float32)."""
    dt = np.dtype(dtype).type
    r_c = dt(camera_radius_m)
    d = np.asarray(distance_m, dtype=dt)
    rise = (dt(2) * r_c * np.asarray(cos_zenith, dtype=dt) + d) * d
    r_p = np.sqrt(np.maximum(r_c * r_c + rise, dt(0)))
    return (r_c - dt(planet_radius_m)) + rise / (r_p + r_c)


class SunTransmittanceTable:
    """exp(-tau to space toward the sun) from any radius r and sun zenith cosine mu, per channel.

    log Ch of each layer is tabulated at altitudes h_j = top (j / (n - 1))^2 and at w_k = (k / (m - 1))^2 of
    the way from the local horizon mu_h(r) = -sqrt(1 - R^2 / r^2) to the zenith, and interpolated bilinearly;
    the factor beta H exp(-h / H) is exact. Below mu_h the ray meets the planet: 0. A radius below the ground
    is taken at the ground (the table's transparent ground, as its densities are).
    """

    def __init__(self, atm: Atmosphere, n_altitudes: int = 96, n_cosines: int = 256) -> None:
        self.atm = atm
        self.n_alt, self.n_mu = n_altitudes, n_cosines
        top = atm.atmosphere_height
        altitude = top * np.linspace(0.0, 1.0, n_altitudes) ** 2
        w = np.linspace(0.0, 1.0, n_cosines) ** 2
        radius = atm.planet_radius + altitude[:, None]
        mu_h = -np.sqrt(np.maximum(1.0 - (atm.planet_radius / radius) ** 2, 0.0))
        mu = np.clip(mu_h + (1.0 - mu_h) * w[None, :], -1.0, 1.0)
        zenith = np.arccos(mu)
        self.log_ch = [np.log(chapman(radius / h, zenith)) for h in (atm.rayleigh_scale_height, atm.mie_scale_height)]

    def __call__(self, radius_m: ArrayLike, cos_zenith: ArrayLike) -> np.ndarray:
        atm = self.atm
        radius = np.clip(np.asarray(radius_m, dtype=np.float64), atm.planet_radius,
                         atm.planet_radius + atm.atmosphere_height)
        mu = np.clip(np.asarray(cos_zenith, dtype=np.float64), -1.0, 1.0)
        mu_h = -np.sqrt(np.maximum(1.0 - (atm.planet_radius / radius) ** 2, 0.0))
        lit = mu >= mu_h
        w = np.clip((mu - mu_h) / (1.0 - mu_h), 0.0, 1.0)
        altitude = radius - atm.planet_radius
        i = np.sqrt(altitude / atm.atmosphere_height) * (self.n_alt - 1)
        k = np.sqrt(w) * (self.n_mu - 1)
        tau = np.zeros(radius.shape + (3,))
        for log_ch, beta, height in ((self.log_ch[0], atm.rayleigh_scattering, atm.rayleigh_scale_height),
                                     (self.log_ch[1], atm.mie_extinction, atm.mie_scale_height)):
            slant = np.exp(_bilinear(log_ch, i, k))
            tau += beta * (height * np.exp(-altitude / height) * slant)[..., None]
        return np.where(lit[..., None], np.exp(-tau), 0.0)


def _bilinear(table: np.ndarray, i: np.ndarray, k: np.ndarray, slice_index=None) -> np.ndarray:
    """Bilinear interpolation at fractional indices (i, k), edge samples clamped (an image texture's filter), of
    a table (rows, columns[, channels]) or, with per-point ``slice_index``, of its slices
    (rows, slices, columns, channels)."""
    columns = table.shape[1] if slice_index is None else table.shape[2]
    i = np.clip(i, 0, table.shape[0] - 1)
    k = np.clip(k, 0, columns - 1)
    i0 = np.minimum(np.floor(i).astype(int), table.shape[0] - 2)
    k0 = np.minimum(np.floor(k).astype(int), columns - 2)
    fi, fk = (i - i0).astype(table.dtype), (k - k0).astype(table.dtype)
    if table.ndim == 3 or slice_index is not None:
        fi, fk = fi[..., None], fk[..., None]

    def at(r, c):
        return table[r, c] if slice_index is None else table[r, slice_index, c]

    return ((1 - fi) * ((1 - fk) * at(i0, k0) + fk * at(i0, k0 + 1))
            + fi * ((1 - fk) * at(i0 + 1, k0) + fk * at(i0 + 1, k0 + 1)))


def _fibonacci_sphere(n: int) -> np.ndarray:
    """n unit vectors spread evenly over the sphere (equal solid angle 4 pi / n each)."""
    j = np.arange(n) + 0.5
    z = 1.0 - 2.0 * j / n
    phi = np.pi * (1.0 + 5.0 ** 0.5) * j
    s = np.sqrt(1.0 - z * z)
    return np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=-1)


class MultipleScatteringTable:
    """Psi_ms(h, mu_s) per channel, per unit sun irradiance above the atmosphere, 1/sr (Hillaire 2020, eq. 5-10).

    At each altitude h_j = top (j / (n - 1))^2 and sun zenith cosine mu_s = sign(u) u^2 (u linear in -1..1, an odd
    count, so mu_s = 0 is a sample and they crowd at the terminator: with 32 linear samples the blue hour's
    Psi_ms, which falls by orders of magnitude within a few degrees of sun below the horizon, was interpolated
    across one cell, 1.5x too bright on average at a sun 4 deg down; 33 crowded samples agree with 256 linear
    ones, ``tools/bench_accuracy.py``), rays in ``n_dirs``
    directions are marched in ``n_steps`` steps to the ground or the top:
        L_2  = (1 / 4 pi) sum_dirs [integral T sigma_s T_sun / (4 pi) dt + T_ground T_sun mu_s,g albedo / pi] dOmega
        f_ms = (1 / 4 pi) sum_dirs [integral T sigma_s dt + T_ground albedo] dOmega,   Psi_ms = L_2 / (1 - f_ms).

    The ground term of f_ms extends Hillaire's: under the same assumption (every point bathed in the same
    isotropic radiance), unit radiance over the ground gives it irradiance pi and a Lambertian radiance albedo
    back, so light bounces between the air and the ground too. Without it the table missed the skylight the
    ground returns: against the complete reference (``tools/bench_accuracy.py``), L_in of the ground vista fell
    from 90 % of the reference at a black ground to 88 % at albedo 0.3; with it, 90 % and 98 %.
    """

    def __init__(self, atm: Atmosphere, sun_table: SunTransmittanceTable, ground_albedo=DEFAULT_GROUND_ALBEDO,
                 n_altitudes: int = 32, n_cosines: int = 33, n_dirs: int = 64, n_steps: int = 40) -> None:
        self.atm = atm
        self.n_alt, self.n_mu = n_altitudes, n_cosines
        albedo = np.asarray(ground_albedo, dtype=np.float64)
        r_ground, top = atm.planet_radius, atm.atmosphere_height
        altitudes = top * np.linspace(0.0, 1.0, n_altitudes) ** 2
        u = np.linspace(-1.0, 1.0, n_cosines)
        mu_s = np.sign(u) * u * u       # crowded at the terminator (mu_s = 0), where Psi_ms changes fastest
        dirs = _fibonacci_sphere(n_dirs)                                            # (D, 3)
        sun_dirs = np.stack([np.sqrt(1.0 - mu_s ** 2), np.zeros_like(mu_s), mu_s], axis=-1)   # (M, 3)
        along = sun_dirs @ dirs.T                                                   # (M, D): sun . dir
        c = dirs[:, 2]                                                              # cos zenith of each direction
        f = (np.arange(n_steps) + 0.5) / n_steps
        psi = np.zeros((n_altitudes, n_cosines, 3))
        for j, altitude in enumerate(altitudes):
            r0 = r_ground + altitude
            t_top = -r0 * c + np.sqrt(np.maximum(r0 * r0 * (c * c - 1.0) + (r_ground + top) ** 2, 0.0))
            disc_ground = r0 * r0 * (c * c - 1.0) + r_ground ** 2
            hits = (c < 0.0) & (disc_ground >= 0.0)
            length = np.where(hits, -r0 * c - np.sqrt(np.maximum(disc_ground, 0.0)), t_top)   # (D,)
            t = length[:, None] * f                                                 # (D, S)
            dt = (length / n_steps)[:, None, None]
            radius = np.sqrt(np.maximum(r0 * r0 + 2.0 * r0 * c[:, None] * t + t * t, 0.0))
            h = np.maximum(radius - r_ground, 0.0)
            n_r, n_m = np.exp(-h / atm.rayleigh_scale_height), np.exp(-h / atm.mie_scale_height)
            sigma_s = atm.rayleigh_scattering * n_r[..., None] + atm.mie_scattering * n_m[..., None]   # (D, S, 3)
            tau_step = (atm.rayleigh_scattering * n_r[..., None] + atm.mie_extinction * n_m[..., None]) * dt
            tau_through = np.cumsum(tau_step, axis=1)
            transmittance = np.exp(-(tau_through - 0.5 * tau_step))                 # to each step's midpoint
            f_ms = np.mean(np.sum(transmittance * sigma_s * dt, axis=1)
                           + np.where(hits[:, None], np.exp(-tau_through[:, -1]) * albedo, 0.0), axis=0)    # (3,)
            # sun zenith cosine at each sample, for every sun position: (x . sun) / |x|, x = (0, 0, r0) + t dir
            mu_point = (r0 * mu_s[:, None, None] + t[None] * along[..., None]) / radius[None]       # (M, D, S)
            t_sun = sun_table(np.broadcast_to(radius, mu_point.shape), mu_point)    # (M, D, S, 3)
            light = np.sum(transmittance * sigma_s * dt * t_sun, axis=2) / (4.0 * np.pi)            # (M, D, 3)
            end = length[:, None] * np.ones(1)
            r_end = np.sqrt(np.maximum(r0 * r0 + 2.0 * r0 * c[:, None] * end + end * end, 0.0))[:, 0]
            mu_ground = (r0 * mu_s[:, None] + length[None] * along) / r_end[None]   # (M, D)
            ground = (np.exp(-tau_through[:, -1]) * albedo / np.pi)[None] * (
                np.maximum(mu_ground, 0.0)[..., None]
                * sun_table(np.broadcast_to(r_end, mu_ground.shape) + 1e-3, mu_ground))
            light = light + np.where(hits[None, :, None], ground, 0.0)
            second_order = np.mean(light, axis=1)                                   # (M, 3)
            psi[j] = second_order / np.maximum(1.0 - f_ms, 1e-6)
        self.psi = psi

    def __call__(self, altitude_m: ArrayLike, cos_zenith: ArrayLike) -> np.ndarray:
        """Psi_ms at altitude ``altitude_m`` (m, clamped to the atmosphere) and sun zenith cosine, (..., 3)."""
        altitude = np.clip(np.asarray(altitude_m, dtype=np.float64), 0.0, self.atm.atmosphere_height)
        i = np.sqrt(altitude / self.atm.atmosphere_height) * (self.n_alt - 1)
        mu = np.clip(np.asarray(cos_zenith, dtype=np.float64), -1.0, 1.0)
        k = (np.sign(mu) * np.sqrt(np.abs(mu)) + 1.0) * 0.5 * (self.n_mu - 1)
        return _bilinear(self.psi, i, k)


@functools.lru_cache(maxsize=8)
def atmosphere_tables(atm: Atmosphere, ground_albedo: tuple[float, float, float] = DEFAULT_GROUND_ALBEDO
                      ) -> tuple[SunTransmittanceTable, MultipleScatteringTable]:
    """The per-atmosphere tables (sun transmittance, multiple scattering), cached: they change with the
    atmosphere's parameters only, never with the sun or the camera."""
    sun_table = SunTransmittanceTable(atm)
    return sun_table, MultipleScatteringTable(atm, sun_table, ground_albedo)


@dataclass(frozen=True, eq=False)
class Tile:
    """One frame's table: ``mean_extinction`` tau / d (1/m), (altitudes, distances, 3), and ``a_rayleigh``,
    ``a_mie`` (W/m^2), (altitudes, azimuths, distances, 3); with the frame's camera radius r_c and largest
    distance D (m) that the shader maps with."""

    shape: TableShape
    camera_radius_m: float
    max_distance_m: float
    mean_extinction: np.ndarray
    a_rayleigh: np.ndarray
    a_mie: np.ndarray

    def pixels(self) -> np.ndarray:
        """The tile as image pixels (altitudes, width, 3): row = altitude, columns = the extinction block
        (distance), then A_R and A_M, each azimuth slice * distances + distance (the add-on's atlas layout)."""
        rows = self.shape.altitudes
        return np.concatenate([self.mean_extinction, self.a_rayleigh.reshape(rows, -1, 3),
                               self.a_mie.reshape(rows, -1, 3)], axis=1)


def _simpson_weights(n: int) -> np.ndarray:
    """Composite Simpson weights for n (odd) equally spaced samples on [0, 1]."""
    weights = np.ones(n)
    weights[1:-1:2], weights[2:-1:2] = 4.0, 2.0
    return weights / (3.0 * (n - 1))


#: Samples along each table ray (odd: Simpson's rule in w = sqrt(t / d)).
RAY_SAMPLES = 65


def bake_tile(atm: Atmosphere, camera_altitude_m: float, sun_elevation_rad: float, *,
              multiple_scattering: bool = True, ground_albedo=DEFAULT_GROUND_ALBEDO,
              shape: TableShape = DEFAULT_SHAPE) -> Tile:
    """Integrate one frame's table (module docstring) for a camera at ``camera_altitude_m`` (m above sea level,
    clamped at 0) and the sun at ``sun_elevation_rad``; ``multiple_scattering=False`` leaves J_ms out.

    Each cell (target altitude h_p, azimuth a, distance d) is its own ray: the elevation follows from the
    triangle (r_c, r_p, d), sin e = (r_p^2 - r_c^2 - d^2) / (2 r_c d), clamped to a vertical ray where the
    altitude cannot be reached at that distance. The ray is integrated by Simpson's rule in w = sqrt(t / d) on
    :data:`RAY_SAMPLES` samples (dense near the camera), the optical depth to each sample by the trapezoid rule
    on the same samples.
    """
    h_c = max(float(camera_altitude_m), 0.0)
    sun_table, ms_table = atmosphere_tables(atm, tuple(float(a) for a in ground_albedo))
    d_max = max_distance(h_c, atm)
    r_c = atm.planet_radius + h_c
    r_p = (atm.planet_radius + row_altitudes(shape, atm))[:, None, None, None]   # (H, 1, 1, 1)
    d = distance_columns(shape, d_max)[None, None, :, None]                       # (1, 1, D, 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        sin_e = np.where(d > 0.0, (r_p * r_p - r_c * r_c - d * d) / (2.0 * r_c * d), 0.0)
    sin_e = np.clip(sin_e, -1.0, 1.0)
    cos_e = np.sqrt(1.0 - sin_e * sin_e)
    azimuth = np.linspace(0.0, np.pi, shape.azimuths)[None, :, None, None]       # (1, A, 1, 1)
    sin_s, cos_s = math.sin(sun_elevation_rad), math.cos(sun_elevation_rad)
    nu = cos_e * np.cos(azimuth) * cos_s + sin_e * sin_s                          # (H, A, D, 1)
    w = np.linspace(0.0, 1.0, RAY_SAMPLES)
    t = d * w * w                                                                 # (1, 1, D, S)
    radius = np.sqrt(np.maximum(r_c * r_c + 2.0 * r_c * t * sin_e + t * t, 0.0))  # (H, 1, D, S)
    h = np.maximum(radius - atm.planet_radius, 0.0)
    n_r, n_m = np.exp(-h / atm.rayleigh_scale_height)[..., None], np.exp(-h / atm.mie_scale_height)[..., None]
    beta_ex = atm.rayleigh_scattering * n_r + atm.mie_extinction * n_m            # (H, 1, D, S, 3)
    dt_dw = (2.0 * d * w)[..., None]                                              # (1, 1, D, S, 1)
    dw = w[1] - w[0]
    f = beta_ex * dt_dw
    tau_to = np.concatenate([np.zeros_like(f[..., :1, :]),
                             np.cumsum(0.5 * (f[..., 1:, :] + f[..., :-1, :]) * dw, axis=-2)], axis=-2)
    view_t = np.exp(-tau_to)
    tau = np.sum(f * _simpson_weights(RAY_SAMPLES)[:, None], axis=-2)             # (H, 1, D, 3)
    view_t = np.where(tau_to > 0.0, np.exp(-tau_to * (tau[..., None, :] / np.maximum(tau_to[..., -1:, :], 1e-300))),
                      view_t)                                                     # rescaled to the Simpson total
    mu_s = (r_c * sin_s + t * nu) / np.maximum(radius, 1.0)                       # (H, A, D, S)
    sun_t = sun_table(np.broadcast_to(radius, mu_s.shape), mu_s)                  # 0 in the planet's shadow
    weights = (_simpson_weights(RAY_SAMPLES)[:, None] * dt_dw)                    # (1, 1, D, S, 1)
    j_r = np.sum(weights * view_t * atm.rayleigh_scattering * n_r * sun_t, axis=-2)
    j_m = np.sum(weights * view_t * atm.mie_scattering * n_m * sun_t, axis=-2)
    start_r = atm.rayleigh_scattering * n_r[..., 0, :] * sun_t[..., 0, :]
    if multiple_scattering:
        sigma_s = atm.rayleigh_scattering * n_r + atm.mie_scattering * n_m
        psi = ms_table(np.broadcast_to(h, mu_s.shape), mu_s)
        phase = phase_rayleigh(nu)                                                 # (H, A, D, 1)
        j_r = j_r + np.sum(weights * view_t * sigma_s * psi, axis=-2) / phase
        start_r = start_r + sigma_s[..., 0, :] * psi[..., 0, :] / phase
    start_m = atm.mie_scattering * n_m[..., 0, :] * sun_t[..., 0, :]
    local_ex = beta_ex[..., 0, :]                                                 # the camera's extinction
    one_minus_t = -np.expm1(-tau)
    small = one_minus_t < 1e-9      # d -> 0: J / (1 - T) -> the local scattering over the local extinction
    with np.errstate(divide="ignore", invalid="ignore"):
        a_r = np.where(small, np.where(local_ex > 0.0, start_r / local_ex, 0.0), j_r / one_minus_t)
        a_m = np.where(small, np.where(local_ex > 0.0, start_m / local_ex, 0.0), j_m / one_minus_t)
        mean_extinction = np.where(d > 0.0, tau / d, local_ex)[:, 0]               # (H, D, 3)
    e_top = atm.sun_irradiance_top
    full = (shape.altitudes, shape.azimuths, shape.distances, 3)
    return Tile(shape, r_c, d_max, np.ascontiguousarray(np.broadcast_to(mean_extinction, full[:1] + full[2:])),
                np.ascontiguousarray(np.broadcast_to(a_r * e_top, full)),
                np.ascontiguousarray(np.broadcast_to(a_m * e_top, full)))


def sky_radiance(view_dir: ArrayLike, sun_dir: ArrayLike, atm: Atmosphere, *, camera_altitude_m: float = 0.0,
                 multiple_scattering: bool = True, ground_albedo=DEFAULT_GROUND_ALBEDO,
                 n_samples: int = 513) -> np.ndarray:
    """Sky radiance in W/(m^2 sr) per channel, (..., 3), along unit view directions ``view_dir`` (..., 3), z up.

    The Precise level's integrand along whole rays from a camera at ``camera_altitude_m`` (m, clamped at 0) to
    the atmosphere's top, or to the ground below the horizon (no ground reflection, no sun disk):

        L = E_top integral T_view(t) [(beta_R n_R Phi_R(nu) + beta_M n_M Phi_HG(nu, g)) T_sun + sigma_s Psi_ms] dt

    with nu = view . sun, T_sun from :class:`SunTransmittanceTable` (the planet's shadow included) and, with
    ``multiple_scattering``, Hillaire 2020's isotropic term Psi_ms of :class:`MultipleScatteringTable`
    (``ground_albedo``). Simpson's rule in w = sqrt(t / length) on ``n_samples`` (odd) samples, as the table
    cells of :func:`bake_tile`. What the comparison with Blender's own sky models uses
    (``tools/compare_sky_texture.py``): with ``multiple_scattering=False`` it is the brute-force single scattering
    of :mod:`.reference` with the sun's optical depth from a table instead of a march.
    """
    if n_samples < 3 or n_samples % 2 == 0:
        raise ValueError(f"n_samples must be odd and >= 3; got {n_samples}")
    given = np.asarray(view_dir, dtype=np.float64)
    views = given.reshape(-1, 3) / np.linalg.norm(given.reshape(-1, 3), axis=-1, keepdims=True)
    sun = np.asarray(sun_dir, dtype=np.float64)
    sun = sun / np.linalg.norm(sun)
    sun_table, ms_table = atmosphere_tables(atm, tuple(float(a) for a in ground_albedo))
    r_ground = atm.planet_radius
    r_c = r_ground + max(float(camera_altitude_m), 0.0)
    c = views[..., 2]
    length = sky_path_length(c, camera_altitude_m, atm)[0][..., None]                  # (..., 1)
    w = np.linspace(0.0, 1.0, n_samples)
    t = length * w * w                                                                  # (..., S)
    radius = np.sqrt(np.maximum(r_c * r_c + 2.0 * r_c * t * c[..., None] + t * t, 0.0))
    h = np.maximum(radius - r_ground, 0.0)
    n_r, n_m = np.exp(-h / atm.rayleigh_scale_height)[..., None], np.exp(-h / atm.mie_scale_height)[..., None]
    dt_dw = (2.0 * length * w)[..., None]                                               # (..., S, 1)
    f = (atm.rayleigh_scattering * n_r + atm.mie_extinction * n_m) * dt_dw
    dw = w[1] - w[0]
    tau_to = np.concatenate([np.zeros_like(f[..., :1, :]),
                             np.cumsum(0.5 * (f[..., 1:, :] + f[..., :-1, :]) * dw, axis=-2)], axis=-2)
    nu = np.clip(views @ sun, -1.0, 1.0)[..., None]                                     # (..., 1)
    mu_s = (r_c * sun[2] + t * nu) / np.maximum(radius, 1.0)                            # sun zenith cosine
    sun_t = sun_table(radius, mu_s)                                                     # (..., S, 3)
    phase_r, phase_m = phase_rayleigh(nu)[..., None], phase_hg(nu, atm.mie_g)      # (N, 1, 1), (N, 1, 3)
    source = (atm.rayleigh_scattering * n_r * phase_r + atm.mie_scattering * n_m * phase_m) * sun_t
    if multiple_scattering:
        source = source + (atm.rayleigh_scattering * n_r + atm.mie_scattering * n_m) * ms_table(h, mu_s)
    weights = _simpson_weights(n_samples)[:, None] * dt_dw
    radiance = atm.sun_irradiance_top * np.sum(weights * np.exp(-tau_to) * source, axis=-2)
    return radiance.reshape(given.shape[:-1] + (3,))


def distance_to_top(cos_zenith: ArrayLike, camera_altitude_m: float, atm: Atmosphere,
                    dtype: DTypeLike = np.float64) -> np.ndarray:
    """Distance from the camera (altitude h_c, clamped at 0) along a ray with zenith cosine c = v_z to the top of
    the atmosphere, m, without cancellation in float32 (the shaders' arithmetic, node for node):

        K = (top - h_c)(2 R + top + h_c) = r_top^2 - r_c^2,   root = sqrt(K + (r_c c)^2)
        K / (r_c c + root)  for c >= 0,   root - r_c c  for c < 0       floored at 0

    (a camera above the top looking away from the atmosphere sees none of it); the denominator is floored at 1 m,
    which keeps the branch not taken finite and changes no real path.
    """
    dt = np.dtype(dtype).type
    c = np.asarray(cos_zenith, dtype=dt)
    radius, top = dt(atm.planet_radius), dt(atm.atmosphere_height)
    h_c = dt(max(float(camera_altitude_m), 0.0))
    r_c_c = (radius + h_c) * c
    top_term = (top - h_c) * (dt(2) * radius + top + h_c)
    root = np.sqrt(np.maximum(top_term + r_c_c * r_c_c, dt(0)))
    up = top_term / np.maximum(root + r_c_c, dt(1))
    return np.maximum(np.where(c < 0, root - r_c_c, up), dt(0)).astype(dt)


def sky_path_length(cos_zenith: ArrayLike, camera_altitude_m: float, atm: Atmosphere,
                    dtype: DTypeLike = np.float64) -> tuple[np.ndarray, np.ndarray]:
    """(length m, hits the ground) of the ray from the camera (altitude h_c, clamped at 0) with zenith cosine
    c = v_z: to the spherical ground where it meets it, else to the top (:func:`distance_to_top`). The ground
    without cancellation in float32 (the sky shader's arithmetic, node for node):

        G = h_c (2 R + h_c) = r_c^2 - R^2,   meets it where c < 0 and (r_c c)^2 >= G,
        at G / (sqrt(max((r_c c)^2 - G, 0)) - r_c c)

    (the denominator floored at 1 m like the top's: a ray that meets the ground has one of at least sqrt(G),
    5 km for a camera 2 m up).
    """
    dt = np.dtype(dtype).type
    c = np.asarray(cos_zenith, dtype=dt)
    radius = dt(atm.planet_radius)
    h_c = dt(max(float(camera_altitude_m), 0.0))
    r_c_c = (radius + h_c) * c
    ground_term = h_c * (dt(2) * radius + h_c)
    ground_disc = r_c_c * r_c_c - ground_term
    hits = (c < 0) & (ground_disc >= 0)
    to_ground = ground_term / np.maximum(np.sqrt(np.maximum(ground_disc, dt(0))) - r_c_c, dt(1))
    to_top = distance_to_top(c, camera_altitude_m, atm, dt)
    return np.maximum(np.where(hits, to_ground, to_top), dt(0)).astype(dt), hits


def sky_from_tile(tile: Tile, view_dir: ArrayLike, sun_dir: ArrayLike, atm: Atmosphere,
                  dtype: DTypeLike = np.float32) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The Precise sky from the frame's table: (F_ex, L_in, hits the ground) along unit ``view_dir`` (..., 3).

    The table holds every ray from the camera to any target; a sky ray is the one whose target is the top of the
    atmosphere, or the ground where the ray meets it: :func:`evaluate` at the :func:`sky_path_length`. So a far
    surface's in-scattering (the aerial perspective at the Precise level) tends to exactly the sky behind it as
    its distance reaches the path's: the same table cells, the same arithmetic. The row is the top's or the
    ground's (row 0) exactly, not the one the target altitude's float32 cube root gives. What the "Atmos Sky" world
    group evaluates at the Precise level (without the sun's disk and the lit ground, which it adds as the dome sky
    does). Against the brute-force :func:`sky_radiance` (the tests): about 1 % mean.
    """
    dt = np.dtype(dtype).type
    views = np.asarray(view_dir, dtype=dt)
    altitude = float(tile.camera_radius_m - atm.planet_radius)
    length, hits = sky_path_length(views[..., 2], altitude, atm, dt)
    row = np.where(hits, dt(0), dt(tile.shape.altitudes - 1))   # the ray ends on the ground or at the top
    f_ex, light = evaluate(tile, views, sun_dir, length, atm, dt, row=row)
    return f_ex, light, hits


def table_coordinates(tile: Tile, view_dir: ArrayLike, sun_dir: ArrayLike, distance_m: ArrayLike, atm: Atmosphere,
                      dtype: DTypeLike = np.float32):
    """(row, azimuth index, distance column) in texels, as the shader computes them from the unit view direction,
    the unit direction to the sun and the distance (m)."""
    dt = np.dtype(dtype).type
    shape = tile.shape
    v = np.asarray(view_dir, dtype=dt)
    s = np.asarray(sun_dir, dtype=dt)
    d = np.maximum(np.asarray(distance_m, dtype=dt), dt(0))
    altitude = target_altitude(tile.camera_radius_m, v[..., 2], d, atm.planet_radius, dtype)
    fraction = np.clip(altitude / dt(atm.atmosphere_height), dt(0), dt(1))
    row = np.power(fraction, dt(1.0 / 3.0)) * dt(shape.altitudes - 1)
    cross = v[..., 0] * s[..., 1] - v[..., 1] * s[..., 0]
    dot = v[..., 0] * s[..., 0] + v[..., 1] * s[..., 1]
    azimuth = np.arctan2(np.abs(cross), dot) * dt((shape.azimuths - 1) / np.pi)
    column = np.minimum(np.sqrt(d / dt(tile.max_distance_m)), dt(1)) * dt(shape.distances - 1)
    return row.astype(dt), azimuth.astype(dt), column.astype(dt)


def sample(quantity: np.ndarray, row: np.ndarray, azimuth: np.ndarray, column: np.ndarray,
           dtype: DTypeLike = np.float32) -> np.ndarray:
    """A quantity (altitudes, azimuths, distances, 3) at fractional texel coordinates: bilinear in (row, column)
    within the two nearest azimuth slices (the texture filter), then linear between the slices."""
    dt = np.dtype(dtype).type
    q = np.asarray(quantity, dtype=dt)
    a0 = np.clip(np.floor(azimuth), 0, q.shape[1] - 2).astype(int)
    fa = (azimuth - a0).astype(dt)[..., None]
    low = _bilinear(q, row, column, a0)
    high = _bilinear(q, row, column, a0 + 1)
    return low + fa * (high - low)


def evaluate(tile: Tile, view_dir: ArrayLike, sun_dir: ArrayLike, distance_m: ArrayLike, atm: Atmosphere,
             dtype: DTypeLike = np.float32, row: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(F_ex, L_in) per channel, (..., 3), sampled from ``tile`` the way the shader samples its image.

    ``view_dir`` (..., 3) and ``sun_dir`` (3,) unit vectors (z up, any azimuth), ``distance_m`` (...) in m; ``atm``
    gives the planet, the table's top and the Mie anisotropy g. A distance beyond the top of the atmosphere is
    taken at the top (:func:`distance_to_top`): a surface out in space is seen through the whole atmosphere, so it
    composites to exactly the Precise sky behind it (:func:`sky_from_tile`). ``row``: the table row where the
    caller knows it (the sky's whole rows) instead of the one of the target's altitude.
    """
    dt = np.dtype(dtype).type
    views = np.asarray(view_dir, dtype=dt)
    to_top = distance_to_top(views[..., 2], float(tile.camera_radius_m - atm.planet_radius), atm, dt)
    d = np.minimum(np.maximum(np.asarray(distance_m, dtype=dt), dt(0)), to_top)
    target_row, azimuth, column = table_coordinates(tile, views, sun_dir, d, atm, dtype)
    row = target_row if row is None else np.broadcast_to(np.asarray(row, dtype=dt), target_row.shape)
    extinction_per_m = _bilinear(np.asarray(tile.mean_extinction, dtype=dt), row, column)
    a_r = sample(tile.a_rayleigh, row, azimuth, column, dtype)
    a_m = sample(tile.a_mie, row, azimuth, column, dtype)
    nu = np.einsum("...i,i->...", views, np.asarray(sun_dir, dtype=dt))
    tau = extinction_per_m * d[..., None]
    f_ex = np.exp(-tau)
    one_minus_t = tau * one_minus_exp_over_x(tau, dtype)
    light = (phase_rayleigh(nu, dtype)[..., None] * a_r + phase_hg(nu, atm.mie_g, dtype) * a_m) * one_minus_t
    return f_ex.astype(dt), light.astype(dt)
