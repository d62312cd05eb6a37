# SPDX-License-Identifier: GPL-3.0-or-later
"""The dome sky as a function of the view elevation times the phase functions: the world's lighting table.

The virtual-dome sky of :mod:`.sky` (camera on the ground, :func:`~.sky.dome_distance_approx`, the layered dome)
is linear in the two phase functions, and everything else in it depends on the view direction v only through
its z component:

    L_sky(v, l) = E_sun [A_R(v_z) Phi_R(mu) + A_M(v_z) Phi_HG(mu, g)] + (v_z < 0) L_ground F_ex(v_z)

    A_R = (1 - T(a)) beta_R / beta_ex + T(a) (1 - T_R(t_R))
    A_M = (1 - T(a)) beta_M / beta_ex + T(a) beta_M / beta_M,ex (1 - T_M(t_M))
    F_ex = T(a) T_R(t_R) T_M(t_M)

per channel, with mu = v . l, the dome distances R_R, R_M at the elevation asin(max(v_z, 0)), a = min(R_R, R_M),
t_i = R_i - a, T(a) = exp(-beta_ex a), T_R(t) = exp(-beta_R t), T_M(t) = exp(-beta_M,ex t), beta_ex = beta_R +
beta_M,ex and L_ground = albedo E_sun max(l_z, 0) / pi (the ratios are 0 where their denominator is; so is
their numerator). These are :func:`.sky.inscattering_layered` and :func:`.sky.extinction_layered` with b_i = R_i
and phi1 cancelled against the slab lengths, the form the shader nodes use (``atmos_addon.node_groups.aerial_perspective.
scattering_terms``). A_R, A_M and F_ex lie in [0, 1] and depend only on the atmosphere: not on the sun, its
irradiance or the ground. Below the horizon they keep their horizon values (the elevation is clamped).

So the three colours are tabulated once per atmosphere over u = sqrt(max(v_z, 0)) (:data:`SKY_TABLE_SIZE`
samples, u = 0 .. 1; the square root spends the samples near the horizon, where the domes change fastest) and
the world shader rebuilds the sky per ray from three table lookups and the two phase functions, evaluated
exactly (no tabulated forward peak, so any g is safe): a fraction of the nodes of the analytic sky. Atmos uses
it for the rays that light the scene (Cycles' light samples of the world, rays escaping after a bounce), not
for camera rays, which keep the analytic sky and its exact agreement with the aerial perspective at the
horizon. Rebuilt per atmosphere only: a moving sun changes mu, l_z and E_sun, which stay in the shader.

Units: lengths m, coefficients 1/m; A_R, A_M dimensionless (radiance per unit E_sun and unit phase); F_ex
dimensionless. Numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from .atmosphere import Atmosphere
from .phase import clamp_cosine, phase_hg, phase_rayleigh
from .sky import dome_distance_approx, ground_radiance

#: Samples of the table over u = sqrt(max(v_z, 0)) in [0, 1]: Blender's curve mappings keep 257 table entries
#: (CM_TABLE + 1), so the samples sit on them.
SKY_TABLE_SIZE = 257


@dataclass(frozen=True)
class SkyLightingTable:
    """A_R, A_M and F_ex of the module docstring at u = ``coordinate`` (arrays (N,) and (N, 3), float64)."""

    coordinate: np.ndarray
    scattering_rayleigh: np.ndarray
    scattering_mie: np.ndarray
    transmittance: np.ndarray


def table_coordinate(view_z: ArrayLike) -> np.ndarray:
    """u = sqrt(max(v_z, 0)) for the z component of the unit view direction (clipped to [0, 1])."""
    return np.sqrt(np.clip(np.asarray(view_z, dtype=np.float64), 0.0, 1.0))


def _ratio(numerator: np.ndarray, denominator: np.ndarray) -> np.ndarray:
    """numerator / denominator per channel, 0 where the denominator is 0."""
    return np.divide(numerator, denominator, out=np.zeros_like(numerator), where=denominator > 0.0)


def sky_lighting_table(atm: Atmosphere, size: int = SKY_TABLE_SIZE) -> SkyLightingTable:
    """Tabulate A_R, A_M, F_ex (module docstring) at ``size`` evenly spaced u in [0, 1], in float64."""
    if size < 2:
        raise ValueError(f"the sky table needs at least 2 samples; got {size}")
    u = np.linspace(0.0, 1.0, size)
    r_rayleigh, r_mie = dome_distance_approx(np.arcsin(u * u), atm)
    shared = np.minimum(r_rayleigh, r_mie)[:, np.newaxis]
    tail_rayleigh = r_rayleigh[:, np.newaxis] - shared
    tail_mie = r_mie[:, np.newaxis] - shared
    beta_rayleigh, beta_mie, beta_mie_ex = atm.rayleigh_scattering, atm.mie_scattering, atm.mie_extinction
    beta_ex = beta_rayleigh + beta_mie_ex
    t_shared = np.exp(-beta_ex * shared)
    scattered_shared = -np.expm1(-beta_ex * shared)
    scattered_rayleigh = -np.expm1(-beta_rayleigh * tail_rayleigh)
    scattered_mie = -np.expm1(-beta_mie_ex * tail_mie)
    return SkyLightingTable(
        coordinate=u,
        scattering_rayleigh=scattered_shared * _ratio(beta_rayleigh, beta_ex) + t_shared * scattered_rayleigh,
        scattering_mie=(scattered_shared * _ratio(beta_mie, beta_ex)
                        + t_shared * _ratio(beta_mie, beta_mie_ex) * scattered_mie),
        transmittance=t_shared * np.exp(-beta_rayleigh * tail_rayleigh) * np.exp(-beta_mie_ex * tail_mie),
    )


def _lookup(table: SkyLightingTable, values: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Linear interpolation of a table colour at u (..., ) -> (..., 3), as the shader's curve lookup."""
    return np.stack([np.interp(u, table.coordinate, values[:, c]) for c in range(3)], axis=-1)


def sky_radiance_from_table(view_dir: ArrayLike, sun_dir: ArrayLike, atm: Atmosphere, sun_irradiance: ArrayLike,
                            table: SkyLightingTable, ground_albedo: ArrayLike = 0.0) -> np.ndarray:
    """The sky from the table (module docstring), (..., 3): what the world's lighting branch computes.

    Equal to :func:`.sky.sky_radiance` with ``dome=dome_distance_approx`` (camera on the ground) at the table's
    samples; between them, linear interpolation in u (``tests/physics/test_sky_table.py`` bounds the error).
    """
    view = np.asarray(view_dir, dtype=np.float64)
    view = view / np.linalg.norm(view, axis=-1, keepdims=True)
    sun = np.asarray(sun_dir, dtype=np.float64)
    sun = sun / np.linalg.norm(sun, axis=-1, keepdims=True)
    u = table_coordinate(view[..., 2])
    mu = clamp_cosine(np.sum(view * sun, axis=-1))
    e_sun = np.maximum(np.asarray(sun_irradiance, dtype=np.float64), 0.0)
    phase_mie = phase_hg(mu, atm.mie_g)
    if np.ndim(atm.mie_g) == 0:  # a scalar g gives mu's shape; a per-channel g adds the channel axis itself
        phase_mie = phase_mie[..., np.newaxis]
    radiance = e_sun * (_lookup(table, table.scattering_rayleigh, u) * phase_rayleigh(mu)[..., np.newaxis]
                        + _lookup(table, table.scattering_mie, u) * phase_mie)
    if np.any(np.asarray(ground_albedo) != 0.0):
        below = (view[..., 2] < 0.0)[..., np.newaxis]
        ground = ground_radiance(sun, e_sun, ground_albedo) * _lookup(table, table.transmittance, u)
        radiance = radiance + np.where(below, ground, 0.0)
    return radiance
