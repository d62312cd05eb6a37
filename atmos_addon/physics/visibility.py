# SPDX-License-Identifier: GPL-3.0-or-later
"""Meteorological visibility: what the haze setting promises, what the atmosphere gives, what each level renders.

Koschmieder (1924; the WMO's definition of meteorological optical range, WMO-No. 8): in a homogeneous atmosphere
under a horizontally uniform light field, a black target at distance d seen against the horizon sky behind it has
the apparent contrast

    C(d) = (L_sky - L_target) / L_sky = exp(-beta_ex d),

so contrast falls to the eye's threshold of 2 % at the visibility V = -ln(0.02) / beta_ex = 3.912 / beta_ex
(beta_ex at 550 nm). Atmos's Haze setting is V at the ground (``blender/simple_controls.py``).

The real atmosphere is not homogeneous along a horizontal view: the ray climbs away from the curved ground, the
haze (scale height about 1 km) thins, and the horizon sky is the light of the whole path, not of an endless layer
at sea-level density. For a black target, L_target is exactly the in-scattering L_in(d) in front of it, so

    C(d) = 1 - L_in(d) / L_sky.

The complete reference (:func:`reference_contrast`) evaluates it by Monte Carlo over every scattering order;
:func:`level_contrast` evaluates it as each quality level renders it (the aerial group and the world sky of that
level, from the functions the node groups are tested against).
Lengths m, angles rad unless named _deg. Numpy only.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from .atmosphere import Atmosphere
from .balanced import inscattering_balanced, sun_optical_depths_ground
from .multiple_scattering_reference import trace_paths
from .rayleigh import rayleigh_coefficients
from .precise import bake_tile, sky_from_tile
from .precise import evaluate as evaluate_precise
from .spectrum import channel_value_at
from .sky import aerial_distance_clamped, atmosphere_at_altitude, dome_distance_approx, inscattering_layered
from .sky import sky_radiance as dome_sky_radiance
from .reference import single_scattering
from .sun import sun_irradiance_ground

#: The contrast threshold of Koschmieder's visibility (WMO: 0.05 for the meteorological optical range; the
#: haze setting and the presets use Koschmieder's 0.02).
CONTRAST_THRESHOLD = 0.02
#: -ln(CONTRAST_THRESHOLD) = 3.912: V = KOSCHMIEDER_CONSTANT / beta_ex(550 nm).
KOSCHMIEDER_CONSTANT = -math.log(CONTRAST_THRESHOLD)
#: The channel nearest 550 nm (G).
GREEN = 1
#: Wavelength at which visibility is defined, nm.
VISIBILITY_WAVELENGTH_NM = 550.0

#: The levels :func:`level_contrast` knows ("precise+ms": Precise with its multiple-scattering term).
LEVELS = ("fast", "balanced", "precise", "precise+ms")


def extinction_at_550(channel_wavelengths_nm: ArrayLike, *species: ArrayLike) -> float:
    """The sum of per-channel coefficients (any one unit), each species read at 550 nm from its channels
    (:func:`~atmos_addon.physics.spectrum.channel_value_at`; the G channel stands for 547.4 nm)."""
    return sum(channel_value_at(VISIBILITY_WAVELENGTH_NM, channel_wavelengths_nm, values) for values in species)


def extinction_550_per_m(atm: Atmosphere) -> float:
    """Sea-level extinction coefficient of ``atm`` at 550 nm, 1/m (:func:`extinction_at_550` of its Rayleigh
    scattering, aerosol scattering and aerosol absorption)."""
    return extinction_at_550(atm.wavelengths_nm, atm.rayleigh_scattering, atm.mie_scattering, atm.mie_absorption)


def visibility_m(atm: Atmosphere) -> float:
    """Koschmieder's visibility 3.912 / beta_ex(550 nm) of ``atm`` at sea level, m."""
    return KOSCHMIEDER_CONSTANT / extinction_550_per_m(atm)


#: Absorption / scattering ratio given to haze that has none to copy (the clear default: albedo 0.91).
DEFAULT_HAZE_ABSORPTION_RATIO = 0.1


def haze_absorption_ratio(scattering: ArrayLike, absorption: ArrayLike) -> np.ndarray:
    """Each channel's haze absorption / scattering, (3,): a channel without scattering takes the mean ratio, a haze
    without any scattering :data:`DEFAULT_HAZE_ABSORPTION_RATIO` (or 0 when it absorbs)."""
    scattering = np.asarray(scattering, dtype=np.float64)
    absorption = np.asarray(absorption, dtype=np.float64)
    if np.all(scattering <= 0.0):
        return np.full(3, DEFAULT_HAZE_ABSORPTION_RATIO if np.all(absorption <= 0.0) else 0.0)
    fallback = float(np.sum(absorption) / max(np.sum(scattering), 1e-30))
    return np.where(scattering > 0.0, absorption / np.where(scattering > 0.0, scattering, 1.0), fallback)


def haze_colour_of(scattering: ArrayLike) -> np.ndarray:
    """The haze's colour: its scattering per channel over its largest channel, (3,); white where there is no haze."""
    scattering = np.asarray(scattering, dtype=np.float64)
    peak = float(scattering.max())
    return np.ones(3) if peak <= 0.0 else scattering / peak


def haze_extinction_for_visibility(visibility: float, channel_wavelengths_nm: ArrayLike,
                                   rayleigh_per_m: ArrayLike) -> float:
    """The haze's sea-level extinction at 550 nm, 1/m, that gives the visibility ``visibility`` m over the air
    ``rayleigh_per_m``: 3.912 / V - beta_R(550), not below 0 (a visibility longer than clean air allows gets no
    haze)."""
    rayleigh_550 = channel_value_at(VISIBILITY_WAVELENGTH_NM, channel_wavelengths_nm, rayleigh_per_m)
    return max(KOSCHMIEDER_CONSTANT / max(float(visibility), 1e-9) - rayleigh_550, 0.0)


def haze_for_extinction(haze_extinction_550_per_m: float, channel_wavelengths_nm: ArrayLike, shape: ArrayLike,
                        absorption_ratio: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """The haze's scattering and absorption per channel, 1/m, of colour ``shape`` (scattering proportional to it)
    with absorption / scattering ``absorption_ratio`` per channel, whose extinction at 550 nm is
    ``haze_extinction_550_per_m``: the split of one visibility into the haze's coefficients.

    Scattering s shape_c and absorption s shape_c a_c, with s chosen so that (shape + shape a) read at 550 nm
    (:func:`extinction_at_550`) times s is the extinction asked for; a shape without extinction gives no haze.
    """
    shape = np.asarray(shape, dtype=np.float64)
    ratio = np.asarray(absorption_ratio, dtype=np.float64)
    unit_550 = extinction_at_550(channel_wavelengths_nm, shape, shape * ratio)
    scale = float(haze_extinction_550_per_m) / unit_550 if unit_550 > 0.0 else 0.0
    return shape * scale, shape * ratio * scale


def relative_air_density(channel_wavelengths_nm: ArrayLike, rayleigh_per_m: ArrayLike) -> float:
    """Air density relative to standard sea-level air (288.15 K, 101325 Pa; Bodhaine et al. 1999): the Rayleigh
    coefficient at 550 nm over standard air's at the same channel wavelengths (1 = Earth at sea level)."""
    standard = channel_value_at(VISIBILITY_WAVELENGTH_NM, channel_wavelengths_nm,
                                rayleigh_coefficients(np.asarray(channel_wavelengths_nm, dtype=np.float64)))
    return channel_value_at(VISIBILITY_WAVELENGTH_NM, channel_wavelengths_nm, rayleigh_per_m) / standard


def koschmieder_contrast(distance_m: ArrayLike, visibility: float) -> np.ndarray:
    """exp(-3.912 d / V): a black target's contrast in the homogeneous atmosphere of visibility ``visibility`` m."""
    return np.exp(-KOSCHMIEDER_CONSTANT * np.asarray(distance_m, dtype=np.float64) / float(visibility))


def view_direction(elevation_deg: float, azimuth_from_sun_deg: float) -> np.ndarray:
    """Unit view direction, z up, the sun's azimuth along +x."""
    e, a = math.radians(elevation_deg), math.radians(azimuth_from_sun_deg)
    return np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])


def sun_direction(elevation_deg: float) -> np.ndarray:
    """Unit vector toward the sun at ``elevation_deg``, azimuth +x."""
    e = math.radians(elevation_deg)
    return np.array([math.cos(e), 0.0, math.sin(e)])


def reference_contrast(atm: Atmosphere, distances_m: ArrayLike, view_dir: ArrayLike, sun_dir: ArrayLike, *,
                       camera_altitude_m: float = 2.0, ground_albedo: ArrayLike = 0.0,
                       max_order: int | None = None, paths: int = 20_000, seed: int = 0
                       ) -> tuple[np.ndarray, np.ndarray]:
    """A black target's contrast per channel at each distance, (k, 3), and its standard error (k, 3), every
    scattering order up to ``max_order``; the camera at ``camera_altitude_m`` looks along ``view_dir``.

    Along the view ray the transfer equation splits the horizon sky at the target's place x_d:
    L_sky(0) = L_in(d) + F_ex(d) L_sky(x_d), so C = 1 - L_in(d) / L_sky(0) = F_ex(d) L_sky(x_d) / L_sky(0): the
    transmittance (deterministic, :func:`~.reference.single_scattering`) times the ratio of the sky seen along the
    same direction from the target's place and from the camera (two Monte Carlo estimates, ``paths`` per channel
    each). Koschmieder's law is the case L_sky(x_d) = L_sky(0). Estimating C as a product keeps its relative
    noise that of the two skies (about 1 %), where 1 - L_in / L_sky would carry L_sky's noise into a small C.
    """
    distances = np.atleast_1d(np.asarray(distances_m, dtype=np.float64))
    view = np.asarray(view_dir, dtype=np.float64)
    view = view / np.linalg.norm(view)
    camera = np.array([0.0, 0.0, float(camera_altitude_m)])
    n = int(paths)
    channel = np.repeat(np.arange(3), n)
    common = dict(ground_albedo=ground_albedo, max_order=max_order)

    def sky_from(origin: np.ndarray, stream: int) -> tuple[np.ndarray, np.ndarray]:
        samples = trace_paths(origin, np.tile(view, (3 * n, 1)), channel, sun_dir, atm, seed=seed + stream,
                              **common).reshape(3, n)
        return samples.mean(axis=1), samples.std(axis=1, ddof=1) / math.sqrt(n)

    near, near_error = sky_from(camera, 0)
    contrast, error = np.empty((distances.size, 3)), np.empty((distances.size, 3))
    for k, distance in enumerate(distances):
        f_ex = single_scattering(camera_altitude_m, view, float(distance), sun_dir, atm, n_steps=2001,
                                 n_sun_steps=3)[0]
        far, far_error = sky_from(camera + distance * view, k + 1)
        contrast[k] = f_ex * far / near
        error[k] = contrast[k] * np.sqrt((far_error / far) ** 2 + (near_error / near) ** 2)
    return contrast, error


def level_contrast(level: str, atm: Atmosphere, distances_m: ArrayLike, view_dir: ArrayLike, sun_dir: ArrayLike, *,
                   camera_altitude_m: float = 2.0) -> np.ndarray:
    """A black target's contrast 1 - L_in(d) / L_sky per channel, (k, 3), as ``level`` (:data:`LEVELS`) renders it:

    * fast: the layered dome (the aerial group's lengths min(d, R_i) and the world's dome sky, float32 domes as
      the nodes compute them); balanced: the curved-ray aerial group (the sun raised to each piece's altitude)
      under the same dome sky; precise, precise+ms: the frame's table for both (``physics.precise``).
    """
    distances = np.atleast_1d(np.asarray(distances_m, dtype=np.float64))
    view = np.asarray(view_dir, dtype=np.float64)
    sun = np.asarray(sun_dir, dtype=np.float64)
    views = np.tile(view, (distances.size, 1))
    sun_elevation = math.asin(max(min(float(sun[2]), 1.0), -1.0))
    e_sun = sun_irradiance_ground(max(sun_elevation, 0.0), atm)
    mu = views @ sun
    if level in ("precise", "precise+ms"):
        tile = bake_tile(atm, camera_altitude_m, sun_elevation, multiple_scattering=level == "precise+ms")
        _, l_in = evaluate_precise(tile, views, sun, distances, atm, np.float64)
        _, sky, _ = sky_from_tile(tile, view[None], sun, atm, np.float64)
        return 1.0 - l_in / sky[0]
    if level not in ("fast", "balanced"):
        raise ValueError(f"unknown level {level!r}; expected one of {LEVELS}")

    def dome(elevation, atmosphere, altitude):
        return dome_distance_approx(elevation, atmosphere, altitude, np.float32)

    sky = dome_sky_radiance(view, sun, atm, e_sun, altitude_m=camera_altitude_m, dome=dome)
    if level == "fast":
        s_r, s_m = aerial_distance_clamped(distances, math.asin(float(view[2])), atm, camera_altitude_m, dome=dome)
        l_in = inscattering_layered(s_r, s_m, mu, atmosphere_at_altitude(atm, camera_altitude_m), e_sun)
    else:
        taus = sun_optical_depths_ground(sun_elevation, atm, e_sun)
        l_in = inscattering_balanced(camera_altitude_m, views, distances, mu, atm, e_sun, sun_optical_depths=taus)
    return 1.0 - l_in / sky
