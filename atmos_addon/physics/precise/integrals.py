# SPDX-License-Identifier: GPL-3.0-or-later
"""The Precise level's integrand along straight rays: what a tile's cells hold (:func:`ray_integrals`), the light a
ray in-scatters (:func:`ray_inscattering`), and the sky along whole rays by brute force (:func:`sky_radiance`).

Per colour channel, a ray from radius r_c along the unit direction v, t in m along it, nu = v . l:

    tau(d)  = integral_0^d beta_ex(h(t)) dt                                          optical depth; F_ex = exp(-tau)
    J_i(d)  = integral_0^d beta_i n_i(h(t)) T_sun(x(t)) exp(-tau(t)) dt          i = R, M (scattering, no phase)
    J_ms(d) = integral_0^d (beta_R n_R S_R + beta_M n_M S_M)(h(t), mu_s(t), v) exp(-tau(t)) dt

with r(t) = sqrt(r_c^2 + 2 r_c t sin e + t^2), the sun zenith cosine mu_s(t) = (r_c sin e_s + t nu) / r(t), T_sun
from ``transmittance.SunTransmittanceTable`` (0 in the planet's shadow) and S_R, S_M the multiple scattering of
``scattering.MultipleScatteringTable``. nu is constant along a straight ray, so the phase functions leave the
integrals: L_in = E_top [Phi_R(nu) J_R + Phi_HG(nu, g) J_M + J_ms]. Simpson's rule in w = sqrt(t / d) (dense near
the start), the optical depth to each sample by the trapezoid rule on the same samples.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..atmosphere import Atmosphere
from ..phase import phase_hg, phase_rayleigh
from .layout import sky_path_length
from .scattering import DEFAULT_GROUND_ALBEDO
from .tables import atmosphere_tables
from .transmittance import local_extinction


def simpson_weights(n: int) -> np.ndarray:
    """Composite Simpson weights for n (odd) equally spaced samples on [0, 1]."""
    weights = np.ones(n)
    weights[1:-1:2], weights[2:-1:2] = 4.0, 2.0
    return weights / (3.0 * (n - 1))


#: Samples along each table ray (odd: Simpson's rule in w = sqrt(t / d)).
RAY_SAMPLES = 65


def ray_integrals(atm: Atmosphere, tables: tuple, radius_m: ArrayLike, view_cos_zenith: ArrayLike,
                  sun_cos_zenith: ArrayLike, nu: ArrayLike, length_m: ArrayLike, *,
                  multiple_scattering: bool = True) -> tuple[np.ndarray, ...]:
    """The integrals of the module docstring along straight rays, per unit E_top: each ray starts at radius
    ``radius_m`` with view and sun zenith cosines ``view_cos_zenith`` and ``sun_cos_zenith`` there, nu = v . l, and
    is ``length_m`` long (arrays that broadcast, shape (...)); ``tables``: (sun transmittance, multiple scattering),
    :func:`atmosphere_tables`. Returns (tau, J_R, J_M, the Rayleigh and Mie scattering and the extinction at the
    start), each (..., 3); J_R holds J_ms / Phi_R(nu) with ``multiple_scattering``. Simpson's rule in
    w = sqrt(t / d) on :data:`RAY_SAMPLES` samples (dense near the start), the optical depth to each sample by the
    trapezoid rule on the same samples, rescaled to the Simpson total. ``bake.integrate_tile`` integrates its
    cells with it; pass each input in its smallest shape (the tile's geometry is (H, 1, D), its angles (H, A, D):
    the geometry's arrays stay small)."""
    sun_table, ms_table = tables
    r_c, sin_e, sin_s, nu, d = (np.asarray(x, dtype=np.float64)[..., None]
                                for x in (radius_m, view_cos_zenith, sun_cos_zenith, nu, length_m))
    w = np.linspace(0.0, 1.0, RAY_SAMPLES)
    t = d * w * w                                                                     # (..., S)
    radius = np.sqrt(np.maximum(r_c * r_c + 2.0 * r_c * t * sin_e + t * t, 0.0))
    h = np.maximum(radius - atm.planet_radius, 0.0)
    n_r, n_m = np.exp(-h / atm.rayleigh_scale_height)[..., None], np.exp(-h / atm.mie_scale_height)[..., None]
    beta_ex = local_extinction(atm, n_r, n_m, h)                                      # (..., S, 3)
    dt_dw = (2.0 * d * w)[..., None]                                                  # (..., S, 1)
    dw = w[1] - w[0]
    f = beta_ex * dt_dw
    tau_to = np.concatenate([np.zeros_like(f[..., :1, :]),
                             np.cumsum(0.5 * (f[..., 1:, :] + f[..., :-1, :]) * dw, axis=-2)], axis=-2)
    view_t = np.exp(-tau_to)
    tau = np.sum(f * simpson_weights(RAY_SAMPLES)[:, None], axis=-2)                 # (..., 3)
    view_t = np.where(tau_to > 0.0, np.exp(-tau_to * (tau[..., None, :] / np.maximum(tau_to[..., -1:, :], 1e-300))),
                      view_t)                                                         # rescaled to the Simpson total
    mu_s = (r_c * sin_s + t * nu) / np.maximum(radius, 1.0)
    sun_t = sun_table(radius, mu_s)                                                   # 0 in the planet's shadow
    weights = (simpson_weights(RAY_SAMPLES)[:, None] * dt_dw)
    j_r = np.sum(weights * view_t * atm.rayleigh_scattering * n_r * sun_t, axis=-2)
    j_m = np.sum(weights * view_t * atm.mie_scattering * n_m * sun_t, axis=-2)
    start_r = atm.rayleigh_scattering * n_r[..., 0, :] * sun_t[..., 0, :]
    if multiple_scattering:
        view_z = (r_c * sin_e + t) / np.maximum(radius, 1.0)                           # local zenith cosine of the ray
        view_x = (nu - mu_s * view_z) / np.sqrt(np.maximum(1.0 - mu_s * mu_s, 1e-12))   # ... toward the sun
        s_r, s_m = ms_table.scattered(np.broadcast_to(h, mu_s.shape), mu_s, view_z, view_x)
        source = atm.rayleigh_scattering * n_r * s_r + atm.mie_scattering * n_m * s_m
        phase = phase_rayleigh(nu)
        j_r = j_r + np.sum(weights * view_t * source, axis=-2) / phase
        start_r = start_r + source[..., 0, :] / phase
    start_m = atm.mie_scattering * n_m[..., 0, :] * sun_t[..., 0, :]
    return tau, j_r, j_m, start_r, start_m, beta_ex[..., 0, :]


def ray_inscattering(atm: Atmosphere, tables: tuple, radius_m: ArrayLike, view_cos_zenith: ArrayLike,
                     sun_cos_zenith: ArrayLike, nu: ArrayLike, length_m: ArrayLike, *,
                     multiple_scattering: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """(tau, L_in), each (..., 3), along the rays of :func:`ray_integrals` (same arguments), the phase functions
    applied as the shader applies them to the table: L_in = E_top [Phi_R(nu) J_R + Phi_HG(nu, g) J_M] (W/(m^2 sr)).
    What the tile's cells hold before the division by 1 - exp(-tau), for any ray: the yardstick of the table (the
    tests)."""
    tau, j_r, j_m, *_ = ray_integrals(atm, tables, radius_m, view_cos_zenith, sun_cos_zenith, nu, length_m,
                                      multiple_scattering=multiple_scattering)
    nu = np.asarray(nu, dtype=np.float64)
    light = phase_rayleigh(nu)[..., None] * j_r + phase_hg(nu, atm.mie_g) * j_m
    return tau, np.asarray(atm.sun_irradiance_top) * light


def sky_radiance(view_dir: ArrayLike, sun_dir: ArrayLike, atm: Atmosphere, *, camera_altitude_m: float = 0.0,
                 multiple_scattering: bool = True, ground_albedo=DEFAULT_GROUND_ALBEDO,
                 n_samples: int = 513) -> np.ndarray:
    """Sky radiance in W/(m^2 sr) per channel, (..., 3), along unit view directions ``view_dir`` (..., 3), z up.

    The Precise level's integrand along whole rays from a camera at ``camera_altitude_m`` (m, clamped at 0) to
    the atmosphere's top, or to the ground below the horizon (no ground reflection, no sun disk):

        L = E_top integral T_view(t) [(beta_R n_R Phi_R(nu) + beta_M n_M Phi_HG(nu, g)) T_sun
                                      + beta_R n_R S_R + beta_M n_M S_M] dt

    with nu = view . sun, T_sun from :class:`SunTransmittanceTable` (the planet's shadow included) and, with
    ``multiple_scattering``, the multiple scattering S_R, S_M of :class:`MultipleScatteringTable`
    (``ground_albedo``). Simpson's rule in w = sqrt(t / length) on ``n_samples`` (odd) samples, as the table
    cells of ``bake.bake_tile``. What the comparison with Blender's own sky models uses
    (``tools/compare_sky_texture.py``): with ``multiple_scattering=False`` it is the brute-force single scattering
    of ``validation.reference`` with the sun's optical depth from a table instead of a march.
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
    f = local_extinction(atm, n_r, n_m, h) * dt_dw
    dw = w[1] - w[0]
    tau_to = np.concatenate([np.zeros_like(f[..., :1, :]),
                             np.cumsum(0.5 * (f[..., 1:, :] + f[..., :-1, :]) * dw, axis=-2)], axis=-2)
    nu = np.clip(views @ sun, -1.0, 1.0)[..., None]                                     # (..., 1)
    mu_s = (r_c * sun[2] + t * nu) / np.maximum(radius, 1.0)                            # sun zenith cosine
    sun_t = sun_table(radius, mu_s)                                                     # (..., S, 3)
    phase_r, phase_m = phase_rayleigh(nu)[..., None], phase_hg(nu, atm.mie_g)      # (N, 1, 1), (N, 1, 3)
    source = (atm.rayleigh_scattering * n_r * phase_r + atm.mie_scattering * n_m * phase_m) * sun_t
    if multiple_scattering:
        view_z = (r_c * c[..., None] + t) / np.maximum(radius, 1.0)
        view_x = (nu - mu_s * view_z) / np.sqrt(np.maximum(1.0 - mu_s * mu_s, 1e-12))
        s_r, s_m = ms_table.scattered(h, mu_s, view_z, view_x)
        source = source + atm.rayleigh_scattering * n_r * s_r + atm.mie_scattering * n_m * s_m
    weights = simpson_weights(n_samples)[:, None] * dt_dw
    radiance = atm.sun_irradiance_top * np.sum(weights * np.exp(-tau_to) * source, axis=-2)
    return radiance.reshape(given.shape[:-1] + (3,))
