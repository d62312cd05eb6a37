# SPDX-License-Identifier: GPL-3.0-or-later
"""The rays the multiple-scattering table marches from its nodes (``scattering.MultipleScatteringTable``): from a
node at altitude h, in each marched direction w of the grid (``directions.marched_half``) and for every sun cosine
of its nodes, to the ground or the top in S steps, t = length u^2 with u at the steps' middles (crowded at the node,
where the air is densest for the rays that climb).

Along a ray T' is the transmittance with the haze's extinction less f beta_M n_M (delta-Eddington:
``directions.forward_fraction``), T_c the transmittance less only the cone of the haze's peak the grid cannot
resolve (``directions.grid_forward_fraction``), sigma_s' = beta_R n_R + (1 - f) beta_M n_M the scattering that turns
light. Each step's point p has sun zenith cosine mu_s(p) = (x . sun) / |x|, x = (0, 0, r_0) + t w, and the ray's
direction is measured against p's local zenith up_p and its horizontal toward the sun sun_p (:class:`Rays`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..atmosphere import Atmosphere
from .directions import forward_fraction, grid_forward_fraction, mie_g
from .transmittance import local_extinction

#: Unknowns per node of the multiple-scattering solve: the mean radiance J and its first moment H (up, sun).
MOMENTS = 3


@dataclass(frozen=True)
class RayFan:
    """What the rays from every node share: their directions, the nodes' sun cosines and the steps."""

    directions: np.ndarray    #: (D, 3) the marched directions w (x's frame: z up, the sun in the x-z plane toward +x)
    sun_cosines: np.ndarray   #: (M,) mu_s of the nodes
    along: np.ndarray         #: (M, D) sun . w
    steps: np.ndarray         #: (S,) u at the steps' middles: t = length u^2
    albedo: np.ndarray        #: (3,) the Lambertian ground's albedo


def ray_fan(directions: np.ndarray, sun_cosines: np.ndarray, n_steps: int, albedo: np.ndarray) -> RayFan:
    """The :class:`RayFan` of ``directions`` (D, 3) under suns of zenith cosines ``sun_cosines`` (M,), ``n_steps``
    steps a ray."""
    sun_dirs = np.stack([np.sqrt(1.0 - sun_cosines ** 2), np.zeros_like(sun_cosines), sun_cosines], axis=-1)
    return RayFan(directions=directions, sun_cosines=sun_cosines, along=sun_dirs @ directions.T,
                  steps=(np.arange(n_steps) + 0.5) / n_steps, albedo=albedo)


@dataclass(frozen=True)
class Rays:
    """The rays the multiple-scattering table marches from the nodes of one altitude, in each marched direction
    (D) for every sun cosine (M), with S steps each (arrays as marked)."""

    altitude_m: np.ndarray        #: (D, S) altitude of each step's midpoint
    sun_cosine: np.ndarray        #: (M, D, S) sun zenith cosine there
    step_scattering: np.ndarray   #: (D, S, 3) T' sigma_s' dt: the step's scattering seen from the node (delta split)
    step_rayleigh: np.ndarray     #: (D, S, 3) T' beta_R n_R dt
    step_mie: np.ndarray          #: (D, S, 3) T' beta_M n_M dt
    radius_m: np.ndarray          #: (D, S) radius of each step's midpoint
    to_ground: np.ndarray         #: (D, 3) T'_ground albedo where the ray meets the ground, else 0
    ground_radius_m: np.ndarray   #: (D,) radius where the ray ends
    ground_sun_cosine: np.ndarray  #: (M, D) sun zenith cosine at the ray's end
    view_up: np.ndarray            #: (D, S) w . up_p: the ray's direction against the local zenith at each step
    toward_sun: np.ndarray         #: (M, D, S) w . sun_p: against the horizontal toward the sun there (0 under it)
    first_rayleigh: np.ndarray     #: (D, S, 3) T_c beta_R n_R dt: T_c the transmittance less the forward cone only
    first_mie: np.ndarray          #: (D, S, 3) T_c beta_M n_M dt
    first_to_ground: np.ndarray    #: (D, 3) T_c,ground albedo where the ray meets the ground, else 0


def march_rays(atm: Atmosphere, fan: RayFan, altitude_m: float) -> Rays:
    """March the rays of ``fan`` from the nodes at ``altitude_m`` (m): the module docstring's quantities at each
    step's midpoint, and where each ray ends."""
    c = fan.directions[:, 2]
    r_ground, top = atm.planet_radius, atm.atmosphere_height
    r0 = r_ground + altitude_m
    t_top = -r0 * c + np.sqrt(np.maximum(r0 * r0 * (c * c - 1.0) + (r_ground + top) ** 2, 0.0))
    disc_ground = r0 * r0 * (c * c - 1.0) + r_ground ** 2
    hits = (c < 0.0) & (disc_ground >= 0.0)
    length = np.where(hits, -r0 * c - np.sqrt(np.maximum(disc_ground, 0.0)), t_top)   # (D,)
    u = fan.steps                                  # steps crowd at the node: t = length u^2, dt = 2 u du length
    t = length[:, None] * u * u                                                     # (D, S)
    dt = (length[:, None] * (2.0 * u / u.size))[..., None]
    radius = np.sqrt(np.maximum(r0 * r0 + 2.0 * r0 * c[:, None] * t + t * t, 0.0))
    h = np.maximum(radius - r_ground, 0.0)
    n_r, n_m = np.exp(-h / atm.rayleigh_scale_height)[..., None], np.exp(-h / atm.mie_scale_height)[..., None]
    extinction = local_extinction(atm, n_r, n_m, h)

    def carried(kept: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(T dt to each step's midpoint (D, S, 3), T to the ray's end (D, 3)), where ``kept`` of the haze's
        scattering goes on as if not scattered."""
        step = (extinction - kept * atm.mie_scattering * n_m) * dt
        through = np.cumsum(step, axis=1)
        return np.exp(-(through - 0.5 * step)) * dt, np.exp(-through[:, -1])

    forward = forward_fraction(atm)                # delta-Eddington: the haze's forward peak does not attenuate
    seen, to_end = carried(forward)                                                 # T'
    seen_first, to_end_first = carried(grid_forward_fraction(atm))                 # T_c: all but the forward cone
    turning = atm.rayleigh_scattering * n_r + (1.0 - forward) * atm.mie_scattering * n_m   # sigma_s'
    r_end = np.sqrt(np.maximum(r0 * r0 + 2.0 * r0 * c * length + length * length, 0.0))
    # sun zenith cosine along the rays, for every sun position: (x . sun) / |x|, x = (0, 0, r0) + t w
    mu_s = fan.sun_cosines
    sun_cosine = (r0 * mu_s[:, None, None] + t[None] * fan.along[..., None]) / radius
    view_up = (t + r0 * c[:, None]) / np.maximum(radius, 1.0)
    across = np.sqrt(np.maximum(1.0 - sun_cosine * sun_cosine, 0.0))
    toward_sun = np.where(across > 1e-6, (fan.along[..., None] - sun_cosine * view_up[None])
                          / np.maximum(across, 1e-6), 0.0)
    return Rays(altitude_m=h, sun_cosine=sun_cosine,
                step_scattering=seen * turning,
                step_rayleigh=seen * atm.rayleigh_scattering * n_r, step_mie=seen * atm.mie_scattering * n_m,
                radius_m=radius,
                to_ground=np.where(hits[:, None], to_end * fan.albedo, 0.0),
                ground_radius_m=r_end, ground_sun_cosine=(r0 * mu_s[:, None] + length * fan.along) / r_end,
                view_up=view_up, toward_sun=toward_sun,
                first_rayleigh=seen_first * atm.rayleigh_scattering * n_r,
                first_mie=seen_first * atm.mie_scattering * n_m,
                first_to_ground=np.where(hits[:, None], to_end_first * fan.albedo, 0.0))


def emission(atm: Atmosphere, rays: Rays) -> np.ndarray:
    """(3, M, D, S, 3): what each step of the rays sends back to their node per unit J, H_up and H_sun at the
    step: T' dt times sigma_s' (the delta-Eddington scattering, ``directions.forward_fraction``), and times
    3 (g - f) beta_M n_M (w . up_p) and 3 (g - f) beta_M n_M (w . sun_p), where up_p and sun_p are the local
    zenith and the horizontal toward the sun at the step. A medium that scatters with mean cosine g' turns a
    field J + 3 H . w into J + 3 g' H . w; sigma_s' g' = (1 - f) beta_M g' = (g - f) beta_M for the haze, and
    Rayleigh's mean cosine is 0."""
    up = rays.view_up[None]                                                         # (1, D, S)
    moment = 3.0 * (mie_g(atm) - forward_fraction(atm)) * rays.step_mie             # (D, S, 3)
    shape = rays.sun_cosine.shape + (3,)
    return np.stack([np.broadcast_to(rays.step_scattering[None], shape),
                     np.broadcast_to(moment[None] * up[..., None], shape),
                     moment[None] * rays.toward_sun[..., None]])
