# SPDX-License-Identifier: GPL-3.0-or-later
"""Brute-force yardstick for multiple scattering: backward Monte Carlo path tracing in a spherical shell.

Independent of the product's approximation (:mod:`~atmos_addon.physics.precise` is not used): every
scattering order is followed explicitly, with the true phase functions, a spherical planet and a Lambertian
ground. Geometry as in :mod:`~validation.reference`: z up, the camera at (0, 0, h), the planet's
centre at (0, 0, -R) (internally positions are kept relative to the centre), the atmosphere ending at
radius R + ``atm.atmosphere_height``.

The estimator. The radiance reaching the camera along a view ray obeys the integral form of the radiative
transfer equation,

    L(x, d) = T(x, b) L_b + integral_0^l T(x, x + t d) sigma_s(x + t d) L_s(x + t d, d) dt,
    L_s(p, d) = Phi(p, d . s) E_sun T_sun(p) + integral over the sphere of Phi(p, d . w) L(p, w) dw,

with T the transmittance, sigma_s = beta_R rho_R + beta_M rho_M the local scattering coefficient, Phi the
mixture (sigma_R Phi_R + sigma_M Phi_HG) / sigma_s, s the direction to the sun and L_b the radiance at the
segment's end (space radiance at the top; at the ground albedo / pi times the irradiance). Paths start at the
camera, one colour channel per path, and each term is estimated by sampling with its own density:

* Free flight. The optical depth along each straight segment (to the top sphere or the ground) is a
  trapezoid sum on nodes t = t_p + c s^3, s uniform, which crowd at the segment's lowest point t_p (the
  perigee, or the end that is lowest) where the exponential densities change fastest; the Jacobian 3 c s^2
  vanishes there, so the rule loses no order at that end (relative error 1e-7 for rays from the ground,
  1e-4 for rays grazing a perigee, against 40001-sample Simpson sums). A collision distance
  is drawn by inverting that optical depth, so its density is T(t) sigma_ex(t): the weight T sigma_s / pdf
  is the single-scattering albedo sigma_s / sigma_ex at the collision (absorption: Mie absorption and the
  optional ``extra_absorption`` callback, e.g. ozone). Segments that leave through the top are *forced* to
  collide (the distance is drawn conditioned on t < l, weight 1 - T(l)) and add T(l) L_space
  deterministically, so an optically thin sky is not mostly empty samples. Segments that end on the ground
  reach it with the analog probability T(l).
* Next-event estimation toward the sun at every vertex: Phi(d . s) E_sun T_sun at a volume vertex,
  albedo / pi max(n . s, 0) E_sun T_sun at the ground; T_sun is the same trapezoid optical depth along the
  sun ray, 0 where the ray meets the planet. The sun itself is a delta (never hit by a sampled direction),
  so there is no double counting.
* Continuation: the species is picked with probability sigma_R / sigma_s vs sigma_M / sigma_s and the new
  direction drawn from its phase function (Rayleigh by inverting its cubic CDF, Henyey-Greenstein by the
  closed-form inverse, g > 0 forward as in :mod:`~atmos_addon.physics.phase`): the density equals Phi, so the weight is
  unchanged. At the ground the direction is cosine-distributed and the weight is multiplied by the albedo.
* Russian roulette once a weight falls below ``ROULETTE_FRACTION`` of its first-vertex weight: survival
  probability w / (fraction w_1), survivors divided by it, so the expectation is unchanged.

Every sampling density equals (or is divided out of) the integrand it stands for, and roulette preserves
expectations, so each path's sum is an unbiased estimate of the series over scattering orders, up to the
quadrature of optical depths (distances follow the trapezoid optical depth, the albedo is taken at the point):
about 1e-4 relative at most with the default ``n_nodes``, far below the noise of 1e4 paths. The standard
error returned is that of the mean over independent paths. ``max_order = n`` keeps light scattered at most
n times (n vertices, volume or ground); ``max_order = 1`` is single scattering, the integral of
:func:`~validation.reference.single_scattering`.

Limits: the sun is a point (its disk and the direct beam are not part of the sky radiance), straight rays
(no refraction), a Lambertian ground, one colour channel per path (no spectral sharing of paths).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike

from atmos_addon.physics.atmosphere import Atmosphere
from atmos_addon.physics.phase import phase_hg, phase_rayleigh

#: Russian roulette starts when a path's weight falls below this fraction of its first-vertex weight.
ROULETTE_FRACTION = 0.1
#: Paths traced per block (bounds the memory of the (paths, nodes) optical-depth arrays).
BLOCK_PATHS = 8192
#: Safety cap on the number of segments of one path (roulette ends paths long before).
MAX_SEGMENTS = 100_000

ExtraAbsorption = Callable[[np.ndarray], np.ndarray]


def _coefficients(altitude_m: np.ndarray, channel: np.ndarray, atm: Atmosphere,
                  extra_absorption: ExtraAbsorption | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rayleigh scattering, Mie scattering and total extinction of each path's channel at ``altitude_m``, 1/m.

    ``channel`` broadcasts against ``altitude_m`` (one colour channel per path).
    """
    rho_r = np.exp(-altitude_m / atm.rayleigh_scale_height)
    rho_m = np.exp(-altitude_m / atm.mie_scale_height)
    sigma_r = atm.rayleigh_scattering[channel] * rho_r
    sigma_m = atm.mie_scattering[channel] * rho_m
    sigma_ex = sigma_r + sigma_m + atm.mie_absorption[channel] * rho_m
    if atm.ozone_column_du > 0.0:
        sigma_ex = sigma_ex + atm.ozone_absorption[channel] * Atmosphere.ozone_density(altitude_m)
    if extra_absorption is not None:
        extra = np.asarray(extra_absorption(altitude_m), dtype=np.float64)
        sigma_ex = sigma_ex + np.take_along_axis(extra, np.broadcast_to(channel, altitude_m.shape)[..., None],
                                                 axis=-1)[..., 0]
    return sigma_r, sigma_m, sigma_ex


def _segment_length(position_m: np.ndarray, direction: np.ndarray, atm: Atmosphere
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Radius, local zenith cosine, length (to the ground or the top sphere, m) and ground hit of each ray."""
    radius = np.linalg.norm(position_m, axis=-1)
    mu = np.einsum("ij,ij->i", position_m, direction) / radius
    planet, top = atm.planet_radius, atm.planet_radius + atm.atmosphere_height
    perigee_sq = radius * radius * (1.0 - mu * mu)
    ground = (mu < 0.0) & (perigee_sq < planet * planet)
    to_ground = -radius * mu - np.sqrt(np.maximum(planet * planet - perigee_sq, 0.0))
    to_top = -radius * mu + np.sqrt(np.maximum(top * top - perigee_sq, 0.0))
    return radius, mu, np.maximum(np.where(ground, to_ground, to_top), 0.0), ground


def _march(radius_m: np.ndarray, mu: np.ndarray, length_m: np.ndarray, channel: np.ndarray, atm: Atmosphere,
           extra_absorption: ExtraAbsorption | None, n_nodes: int, xi: np.ndarray | None = None,
           forced: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """Optical depth of each segment and, given uniform ``xi``, a sampled free-flight distance.

    Nodes t = t_p + c s^3 (s uniform on [-cbrt(t_p / c), cbrt((l - t_p) / c)], c = max(t_p, l - t_p))
    crowd at the lowest point t_p; the optical depth tau(t) is the cumulative trapezoid sum in s of
    sigma_ex(t(s)) dt/ds, linear in t between nodes. The distance solves tau(t) = -ln(1 - xi) (analog: the
    segment's length if that exceeds tau(l)) or, where ``forced``, tau(t) = -ln(1 - xi (1 - exp(-tau(l)))).
    """
    tau_total = np.empty(radius_m.shape)
    distance = np.empty(radius_m.shape) if xi is not None else None
    for start in range(0, radius_m.size, BLOCK_PATHS):
        block = slice(start, start + BLOCK_PATHS)
        r0, mu0, length = radius_m[block, None], mu[block, None], length_m[block, None]
        low = np.clip(-r0 * mu0, 0.0, length)
        scale = np.maximum(np.maximum(low, length - low), 1e-30)
        s_low, s_high = -np.cbrt(low / scale), np.cbrt((length - low) / scale)
        s = s_low + (s_high - s_low) * np.linspace(0.0, 1.0, n_nodes)
        t = low + scale * s ** 3
        altitude = np.sqrt(np.maximum(r0 * r0 + t * t + 2.0 * r0 * t * mu0, 0.0)) - atm.planet_radius
        integrand = _coefficients(altitude, channel[block, None], atm, extra_absorption)[2] * 3.0 * scale * s * s
        step = s[:, 1:2] - s[:, 0:1]
        tau = np.concatenate([np.zeros_like(step), np.cumsum(0.5 * step * (integrand[:, 1:] + integrand[:, :-1]),
                                                             axis=1)], axis=1)
        tau_total[block] = tau[:, -1]
        if xi is not None:
            absorbed = np.where(forced[block], -np.expm1(-tau[:, -1]), 1.0)
            target = np.minimum(-np.log1p(-xi[block] * absorbed), tau[:, -1])[:, None]
            k = np.clip((tau < target).sum(axis=1) - 1, 0, n_nodes - 2)[:, None]
            tau_k, tau_next = (np.take_along_axis(tau, k + i, axis=1)[:, 0] for i in (0, 1))
            t_k, t_next = (np.take_along_axis(t, k + i, axis=1)[:, 0] for i in (0, 1))
            width = tau_next - tau_k
            fraction = np.where(width > 0.0, np.clip((target[:, 0] - tau_k) / np.where(width > 0.0, width, 1.0),
                                                     0.0, 1.0), 0.5)
            distance[block] = t_k + fraction * (t_next - t_k)
    return tau_total, distance


def _sun_transmittance(position_m: np.ndarray, channel: np.ndarray, sun_dir: np.ndarray, atm: Atmosphere,
                      extra_absorption: ExtraAbsorption | None = None, n_nodes: int = 97) -> np.ndarray:
    """Transmittance toward the sun from planet-centred points (n, 3), one channel each; 0 in the planet's shadow."""
    direction = np.broadcast_to(sun_dir, position_m.shape)
    radius, mu, length, shadow = _segment_length(position_m, direction, atm)
    tau, _ = _march(radius, mu, np.where(shadow, 0.0, length), channel, atm, extra_absorption, n_nodes)
    return np.where(shadow, 0.0, np.exp(-tau))


def _orthonormal_basis(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing unit ``axis`` (n, 3) to a right-handed basis (Duff et al. 2017)."""
    x, y, z = axis[:, 0], axis[:, 1], axis[:, 2]
    sign = np.where(z >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + z)
    b = x * y * a
    return (np.stack([1.0 + sign * x * x * a, sign * b, -sign * x], axis=-1),
            np.stack([b, sign + y * y * a, -y], axis=-1))


def _rotate(axis: np.ndarray, cos_theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """The unit vector at polar angle arccos(cos_theta) from ``axis`` and azimuth ``phi`` around it."""
    u, v = _orthonormal_basis(axis)
    sin_theta = np.sqrt(np.maximum(1.0 - cos_theta * cos_theta, 0.0))
    return ((sin_theta * np.cos(phi))[:, None] * u + (sin_theta * np.sin(phi))[:, None] * v
            + cos_theta[:, None] * axis)


def sample_rayleigh_cosine(xi: np.ndarray) -> np.ndarray:
    """Cosines with density 2 pi Phi_R(mu) = 3/8 (1 + mu^2) on [-1, 1] from uniform ``xi`` (Cardano's root).

    The CDF (mu^3 + 3 mu + 4) / 8 = xi is the depressed cubic mu^3 + 3 mu + q = 0 with q = 4 - 8 xi, whose one
    real root is cbrt(-q/2 + sqrt(q^2/4 + 1)) + cbrt(-q/2 - sqrt(q^2/4 + 1)).
    """
    half_q = 2.0 - 4.0 * np.asarray(xi, dtype=np.float64)
    root = np.sqrt(half_q * half_q + 1.0)
    return np.clip(np.cbrt(-half_q + root) + np.cbrt(-half_q - root), -1.0, 1.0)


def sample_hg_cosine(xi: np.ndarray, g: ArrayLike) -> np.ndarray:
    """Cosines with density 2 pi Phi_HG(mu, g) from uniform ``xi``; g > 0 forward (mu -> 1), as
    :func:`~atmos_addon.physics.phase.phase_hg`.

    Inverse of the CDF: mu = (1 + g^2 - ((1 - g^2) / (1 - g + 2 g xi))^2) / (2 g); uniform for |g| < 1e-6.
    """
    xi, g = np.broadcast_arrays(np.asarray(xi, dtype=np.float64), np.asarray(g, dtype=np.float64))
    small = np.abs(g) < 1e-6
    g_safe = np.where(small, 1.0, g)
    ratio = (1.0 - g_safe * g_safe) / (1.0 - g_safe + 2.0 * g_safe * xi)
    mu = (1.0 + g_safe * g_safe - ratio * ratio) / (2.0 * g_safe)
    return np.clip(np.where(small, 2.0 * xi - 1.0, mu), -1.0, 1.0)


def _unit_rows(vectors: ArrayLike, name: str) -> np.ndarray:
    """Directions as unit rows (n, 3)."""
    v = np.atleast_2d(np.asarray(vectors, dtype=np.float64))
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    if v.ndim != 2 or v.shape[-1] != 3 or not np.all(norm > 0.0):
        raise ValueError(f"{name} must be a non-zero 3-vector or an (n, 3) array of them; got shape {v.shape}")
    return v / norm


def trace_paths(origins_m: ArrayLike, directions: ArrayLike, channel: ArrayLike, sun_dir: ArrayLike,
                atm: Atmosphere, *, sun_irradiance_top: ArrayLike | None = None, ground_albedo: ArrayLike = 0.0,
                space_radiance: ArrayLike = 0.0, max_order: int | None = None,
                extra_absorption: ExtraAbsorption | None = None, seed: int | np.random.Generator = 0,
                n_nodes: int = 97, target_distance_m: ArrayLike | None = None) -> np.ndarray:
    """One radiance sample per path (n,): light reaching ``origins_m`` (camera-style points, z up, planet
    centre at (0, 0, -R)) against each ``directions`` row, in colour ``channel`` (0, 1, 2) of each path.

    The estimator of the module docstring; ``space_radiance`` (per channel) enters isotropically at the top of
    the atmosphere, ``ground_albedo`` (per channel) is Lambertian, ``max_order`` bounds the number of vertices.
    ``target_distance_m`` (per path, m; ``inf`` for none) puts a black surface that far along the first
    segment: the light scattered toward the origin in front of it, L_in of the aerial perspective. The first
    segment then ends there and is forced to collide like a segment leaving through the top (weight 1 - T,
    nothing added for what lies behind); later segments do not see the surface (a target small against the
    light field, the assumption of every aerial-perspective model).
    """
    rng = np.random.default_rng(seed)
    direction = _unit_rows(directions, "directions")
    position = (np.broadcast_to(np.asarray(origins_m, dtype=np.float64), direction.shape)
                + np.array([0.0, 0.0, atm.planet_radius]))
    channel = np.broadcast_to(np.asarray(channel, dtype=np.intp), direction.shape[:1]).copy()
    if np.any((channel < 0) | (channel > 2)):
        raise ValueError("channel must be 0, 1 or 2 (R, G, B)")
    if np.shape(sun_dir) != (3,):
        raise ValueError(f"sun_dir must be a 3-vector; got shape {np.shape(sun_dir)}")
    sun = _unit_rows(sun_dir, "sun_dir")[0]
    if max_order is not None and int(max_order) < 1:
        raise ValueError(f"max_order must be >= 1 or None; got {max_order!r}")
    e_sun = atm.sun_irradiance_top if sun_irradiance_top is None else np.broadcast_to(
        np.asarray(sun_irradiance_top, np.float64), (3,))
    albedo = np.broadcast_to(np.asarray(ground_albedo, np.float64), (3,))
    space = np.broadcast_to(np.asarray(space_radiance, np.float64), (3,))
    if np.any(albedo < 0.0) or np.any(albedo > 1.0):
        raise ValueError(f"ground_albedo must lie in [0, 1]; got {albedo.tolist()}")
    start_altitude = np.linalg.norm(position, axis=-1) - atm.planet_radius
    if np.any(start_altitude < -1e-6) or np.any(start_altitude > atm.atmosphere_height * (1.0 + 1e-9)):
        raise ValueError("the paths must start inside the atmosphere (0 <= altitude <= atm.atmosphere_height)")
    order_limit = MAX_SEGMENTS if max_order is None else int(max_order)
    target = np.full(direction.shape[0], np.inf) if target_distance_m is None else np.broadcast_to(
        np.asarray(target_distance_m, dtype=np.float64), direction.shape[:1])
    if np.any(np.isnan(target)) or np.any(target < 0.0):
        raise ValueError("target_distance_m must be >= 0 (inf for no target)")
    total = np.zeros(direction.shape[0])
    path = np.arange(direction.shape[0])
    weight = np.ones(direction.shape[0])
    first_weight = np.zeros(direction.shape[0])
    for order in range(1, min(order_limit, MAX_SEGMENTS) + 1):
        if path.size == 0:
            break
        radius, mu, length, ground = _segment_length(position, direction, atm)
        blocked = np.zeros(path.size, dtype=bool)
        if order == 1:
            # A target on the ground or the top sphere (to rounding: a bench ray's distance to the ground) is the
            # black surface, not the ground that would reflect light.
            blocked = target < length * (1.0 + 1e-9) + 1e-6
            length, ground = np.where(blocked, target, length), ground & ~blocked
        xi = rng.random(path.size)
        tau, distance = _march(radius, mu, length, channel, atm, extra_absorption, n_nodes, xi, ~ground)
        # Leaving through the top: add the space light and force a collision (weight 1 - T); the same before a
        # black target, which adds nothing.
        total[path] += np.where(ground | blocked, 0.0, weight * np.exp(-tau) * space[channel])  # ids are unique
        weight = np.where(ground, weight, -weight * np.expm1(-tau))
        collide = ~ground | (-np.log1p(-xi) < tau)
        distance = np.where(collide, distance, length)
        position = position + distance[:, None] * direction
        hit_radius = np.linalg.norm(position, axis=-1)
        normal = position / hit_radius[:, None]
        position = np.where(collide[:, None], position, normal * atm.planet_radius)  # snap onto the ground
        altitude = np.maximum(hit_radius - atm.planet_radius, 0.0)
        sigma_r, sigma_m, sigma_ex = _coefficients(altitude, channel, atm, extra_absorption)
        sigma_s = sigma_r + sigma_m
        single_scattering_albedo = np.divide(sigma_s, sigma_ex, out=np.zeros_like(sigma_s), where=sigma_ex > 0.0)
        weight = weight * np.where(collide, single_scattering_albedo, albedo[channel])
        # Next-event estimation toward the sun.
        cos_view_sun = direction @ sun
        g = atm.mie_g[channel]
        hg = np.take_along_axis(phase_hg(cos_view_sun, atm.mie_g), channel[:, None], axis=1)[:, 0]
        phase = (sigma_r * phase_rayleigh(cos_view_sun) + sigma_m * hg) / np.where(sigma_s > 0.0, sigma_s, 1.0)
        # At the ground the albedo is already in the weight: the BRDF times the cosine leaves max(n . s, 0) / pi.
        factor = np.where(collide, phase, np.maximum(normal @ sun, 0.0) / np.pi)
        contributes = (weight > 0.0) & (factor > 0.0)
        if np.any(contributes):
            sun_t = np.zeros(path.size)
            sun_t[contributes] = _sun_transmittance(position[contributes], channel[contributes], sun, atm,
                                                   extra_absorption, n_nodes)
            total[path] += weight * factor * e_sun[channel] * sun_t
        if order >= order_limit:
            break
        # Continue: sample the phase function (volume) or the cosine lobe (ground).
        xi_species, xi_cos, xi_phi, xi_roulette = rng.random((4, path.size))
        rayleigh = xi_species * sigma_s < sigma_r
        cos_theta = np.where(rayleigh, sample_rayleigh_cosine(xi_cos), sample_hg_cosine(xi_cos, g))
        phi = 2.0 * np.pi * xi_phi
        direction = np.where(collide[:, None], _rotate(direction, cos_theta, phi),
                             _rotate(normal, np.sqrt(xi_cos), phi))
        if order == 1:
            first_weight = weight.copy()
        survive = np.minimum(1.0, weight / np.maximum(ROULETTE_FRACTION * first_weight, 1e-300))
        alive = (weight > 0.0) & (xi_roulette < survive)
        weight = weight / np.where(alive, survive, 1.0)
        path, position, direction, channel = path[alive], position[alive], direction[alive], channel[alive]
        weight, first_weight = weight[alive], first_weight[alive]
    return total


def sky_radiance_mc(view_dir: ArrayLike, sun_dir: ArrayLike, atm: Atmosphere, *, camera_altitude_m: float = 0.0,
                    sun_irradiance_top: ArrayLike | None = None, ground_albedo: ArrayLike = 0.0,
                    space_radiance: ArrayLike = 0.0, max_order: int | None = None, paths: int = 20_000,
                    seed: int = 0, extra_absorption: ExtraAbsorption | None = None, n_nodes: int = 97
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Sky radiance (all scattering orders up to ``max_order``) seen from the camera, and its standard error.

    ``view_dir`` (3,) or (k, 3): directions from the camera at (0, 0, ``camera_altitude_m``) (z up);
    ``sun_dir`` toward the sun. Returns radiance and standard error, each (3,) or (k, 3), in the units of
    :func:`~validation.reference.single_scattering`: W m^-2 sr^-1 for ``sun_irradiance_top`` in
    W m^-2 (default ``atm.sun_irradiance_top``). The sun's disk itself is not included. ``paths`` per view
    direction and channel; ``extra_absorption(altitude_m)`` -> (..., 3) 1/m adds a non-scattering absorber.
    """
    return _per_view(view_dir, None, sun_dir, atm, camera_altitude_m=camera_altitude_m,
                     sun_irradiance_top=sun_irradiance_top, ground_albedo=ground_albedo,
                     space_radiance=space_radiance, max_order=max_order, paths=paths, seed=seed,
                     extra_absorption=extra_absorption, n_nodes=n_nodes)


def inscattering_mc(view_dir: ArrayLike, distance_m: ArrayLike, sun_dir: ArrayLike, atm: Atmosphere, *,
                    camera_altitude_m: float = 0.0, sun_irradiance_top: ArrayLike | None = None,
                    ground_albedo: ArrayLike = 0.0, max_order: int | None = None, paths: int = 20_000,
                    seed: int = 0, extra_absorption: ExtraAbsorption | None = None, n_nodes: int = 97
                    ) -> tuple[np.ndarray, np.ndarray]:
    """L_in of the aerial perspective by every scattering order: the light scattered toward the camera in front
    of a black surface ``distance_m`` away along each view (scalar or (k,), m), and its standard error.

    The complete counterpart of the L_in of :func:`~validation.reference.single_scattering` (equal to
    it with ``max_order=1``) and of every quality level; the surface's own light L0 F_ex is the caller's (F_ex
    is deterministic: :func:`~validation.reference.single_scattering`). A distance beyond the top of
    the atmosphere or the ground gives :func:`sky_radiance_mc` with no space light, sample for sample. Other
    arguments and the returned shapes as :func:`sky_radiance_mc`.
    """
    return _per_view(view_dir, distance_m, sun_dir, atm, camera_altitude_m=camera_altitude_m,
                     sun_irradiance_top=sun_irradiance_top, ground_albedo=ground_albedo, space_radiance=0.0,
                     max_order=max_order, paths=paths, seed=seed, extra_absorption=extra_absorption,
                     n_nodes=n_nodes)


def _per_view(view_dir: ArrayLike, distance_m: ArrayLike | None, sun_dir: ArrayLike, atm: Atmosphere, *,
              camera_altitude_m: float, sun_irradiance_top: ArrayLike | None, ground_albedo: ArrayLike,
              space_radiance: ArrayLike, max_order: int | None, paths: int, seed: int,
              extra_absorption: ExtraAbsorption | None, n_nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard error per view and channel of ``paths`` samples each (the two functions above)."""
    views = _unit_rows(view_dir, "view_dir")
    if int(paths) < 2:
        raise ValueError(f"paths must be >= 2; got {paths!r}")
    n = int(paths)
    direction = np.repeat(views, 3 * n, axis=0)
    channel = np.tile(np.repeat(np.arange(3), n), views.shape[0])
    target = None
    if distance_m is not None:
        distances = np.broadcast_to(np.asarray(distance_m, dtype=np.float64), views.shape[:1])
        target = np.repeat(distances, 3 * n)
    origin = np.array([0.0, 0.0, float(camera_altitude_m)])
    samples = trace_paths(origin, direction, channel, sun_dir, atm, sun_irradiance_top=sun_irradiance_top,
                          ground_albedo=ground_albedo, space_radiance=space_radiance, max_order=max_order,
                          extra_absorption=extra_absorption, seed=seed, n_nodes=n_nodes,
                          target_distance_m=target).reshape(-1, 3, n)
    radiance = samples.mean(axis=-1)
    error = samples.std(axis=-1, ddof=1) / np.sqrt(n)
    if np.ndim(view_dir) == 1:
        return radiance[0], error[0]
    return radiance, error


def diffuse_flux_mc(sun_dir: ArrayLike, atm: Atmosphere, *, altitude_m: float = 0.0, upwelling: bool = False,
                    sun_irradiance_top: ArrayLike | None = None, ground_albedo: ArrayLike = 0.0,
                    space_radiance: ArrayLike = 0.0, max_order: int | None = None, paths: int = 20_000,
                    seed: int = 0, extra_absorption: ExtraAbsorption | None = None, n_nodes: int = 97
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Diffuse flux through a horizontal surface at (0, 0, ``altitude_m``), W/m^2 per channel, and its error.

    F = integral over a hemisphere of L(w) |cos| dw = pi E[L] with the view directions w cosine-distributed:
    the upper hemisphere (downwelling sky light, the direct sun excluded) or, with ``upwelling``, the lower
    one (light travelling up: at the top of the atmosphere, everything the planet and its air send back).
    Other arguments as :func:`sky_radiance_mc`; ``paths`` per channel. Over a sphere the balance of fluxes is
    global, not local: from the top of Earth's atmosphere the views within 10 deg below the horizon miss the
    ground, and a white conservative planet reads about 0.965 mu_sun E there.
    """
    if int(paths) < 2:
        raise ValueError(f"paths must be >= 2; got {paths!r}")
    n = int(paths)
    rng = np.random.default_rng(seed)
    xi_cos, xi_phi = rng.random((2, 3 * n))
    up = np.tile([0.0, 0.0, -1.0 if upwelling else 1.0], (3 * n, 1))
    direction = _rotate(up, np.sqrt(xi_cos), 2.0 * np.pi * xi_phi)
    samples = trace_paths(np.array([0.0, 0.0, float(altitude_m)]), direction, np.repeat(np.arange(3), n), sun_dir,
                          atm, sun_irradiance_top=sun_irradiance_top, ground_albedo=ground_albedo,
                          space_radiance=space_radiance, max_order=max_order, extra_absorption=extra_absorption,
                          seed=rng, n_nodes=n_nodes).reshape(3, n)
    return np.pi * samples.mean(axis=-1), np.pi * samples.std(axis=-1, ddof=1) / np.sqrt(n)
