# SPDX-License-Identifier: GPL-3.0-or-later
"""The accuracy bench: the quality levels (:class:`~atmos_addon.physics.quality.Level`) measured against the
brute-force references, in the situations a user meets.

Levels as the bench evaluates them (:func:`evaluate`)
    * FAST: Hoffman & Preetham 2002, eq. 19 (:mod:`~atmos_addon.physics.aerial_perspective`).
    * BALANCED: exponential densities along the (curved) ray in closed form (:mod:`validation.balanced`);
      measured here only, not a level the add-on builds (``atmos_addon.physics.quality``).
    * PRECISE: the camera-centred table the shader samples (:mod:`~atmos_addon.physics.precise`), with its
      multiple-scattering term off: the reference is single scattering; what the term adds is reported
      separately (``tools/bench_accuracy.py``).

Bench
    :data:`BENCH_CASES` are the situations a user meets, as data: camera altitude, sun, and sample rays
    (view elevation, azimuth from the sun, distance). :func:`reference` integrates single scattering by brute
    force (:func:`~validation.reference.single_scattering`, spherical planet, sun transmittance from
    every point, planet shadow); :func:`errors` compares a level with it. :func:`complete_reference` is the
    same rays with every scattering order (Monte Carlo), which the single-scattering reference leaves out (most
    of the light: docs/quality.md's second table); :func:`errors_of` compares any (F_ex, L_in) with either, in
    the pixel's luminance and chromaticity too. :data:`COMPLETE_ONLY_CASES` (blue hour, overcast at a low sun)
    are measured against it alone. The Auto choice reads the bench's pixel errors
    (:data:`~atmos_addon.physics.quality.MEASURED_PIXEL_ERROR`, written by ``tools/bench_accuracy.py``).

Error measure
    Relative error with a floor, e = |x - x_ref| / max(|x_ref|, floor), per ray and channel, then the max and
    the mean over the case's rays. Floors: transmittance F_ex 0.01 (an error below 1 % of full transmittance
    is invisible whatever F_ex is); radiances (L_in and the pixel) 1 % of the case's brightest reference
    pixel channel, so a channel that is nearly black in an otherwise bright image does not dominate.
    The pixel is L = L0 F_ex + L_in for a grey Lambertian surface of albedo 0.3 lit by the ground sun:
    L0 = 0.3 / pi * E_sun(ground) * max(sin(sun elevation), 0) (facing up, nothing else lights it); both the
    level and the reference see the same L0.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from atmos_addon.physics.aerial_perspective import extinction, inscattering
from atmos_addon.physics.atmosphere import Atmosphere
from atmos_addon.physics.precise import DEFAULT_GROUND_ALBEDO, bake_tile
from atmos_addon.physics.precise import evaluate as evaluate_precise
from atmos_addon.physics.quality import Level
from atmos_addon.physics.spectrum import DEFAULT_OZONE_COLUMN_DU, LINEAR_REC709_TO_XYZ, chromaticity_xy
from atmos_addon.physics.sun import sun_irradiance_ground
from atmos_addon.presets import load
from validation.balanced import (CURVATURE_PIECES, PER_PIXEL_PIECES, PER_PIXEL_SUN_AT, extinction_balanced,
                                 inscattering_balanced, sun_optical_depths_ground)
from validation.multiple_scattering_reference import inscattering_mc
from validation.reference import single_scattering

#: Levels with an evaluator, cheapest first (every level has one): the bench measures these.
IMPLEMENTED_LEVELS = tuple(Level)
#: Albedo of the grey Lambertian test surface of the pixel error.
BENCH_ALBEDO = 0.3
#: Floor of the transmittance in the relative error (absolute transmittance units).
TRANSMITTANCE_FLOOR = 0.01
#: Floor of radiances in the relative error, as a fraction of the case's brightest reference pixel channel.
RADIANCE_FLOOR_FRACTION = 0.01
#: Reference sample counts (view ray, each sun-ray segment): 1e-5 relative agreement with 2001 / 513.
REFERENCE_STEPS = (1001, 257)
#: The low-sun cases (``BenchCase.grazing``) trace this many times the paths of the complete reference: their light
#: comes along long paths with many orders, so 4000 paths left 8-23 % noise on their darkest rays.
LOW_SUN_PATH_FACTOR = 6


@dataclass(frozen=True)
class BenchCase:
    """One bench situation: an atmosphere preset, a camera altitude, the sun and sample view rays.

    ``rays`` holds (view elevation deg, view azimuth from the sun's azimuth deg, distance m). ``grazing``
    marks cases whose paths see a grazing sun (sunsets): the Balanced target exempts them.
    """

    name: str
    description: str
    preset: str
    camera_altitude_m: float
    sun_elevation_deg: float
    rays: tuple[tuple[float, float, float], ...]
    grazing: bool = False

    @functools.cached_property
    def atmosphere(self) -> Atmosphere:
        """The case's atmosphere: ``"clear"`` is what the settings' defaults describe (the default
        :class:`Atmosphere` with the Earth's ozone, :data:`~atmos_addon.physics.spectrum.DEFAULT_OZONE_COLUMN_DU`),
        other names are presets."""
        if self.preset == "clear":
            return Atmosphere(ozone_column_du=DEFAULT_OZONE_COLUMN_DU)
        return load(self.preset).atmosphere

    @property
    def sun_dir(self) -> np.ndarray:
        """Unit vector toward the sun (azimuth 0 = +x), z up."""
        e = np.radians(self.sun_elevation_deg)
        return np.array([np.cos(e), 0.0, np.sin(e)])

    @property
    def view_dirs(self) -> np.ndarray:
        """Unit view directions, (n, 3)."""
        e, a = (np.radians([r[i] for r in self.rays]) for i in (0, 1))
        return np.stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)], axis=-1)

    @property
    def distances_m(self) -> np.ndarray:
        """Distances to the targets along the rays, m, (n,)."""
        return np.array([r[2] for r in self.rays])

    @property
    def sun_irradiance(self) -> np.ndarray:
        """Ground-level sun irradiance E_sun (the slides' choice for the whole ray), (3,)."""
        return sun_irradiance_ground(np.radians(self.sun_elevation_deg), self.atmosphere)

    @property
    def surface_radiance(self) -> np.ndarray:
        """L0 of the grey albedo-0.3 Lambertian surface facing up, lit by the ground sun, (3,)."""
        cos_sun = max(np.sin(np.radians(self.sun_elevation_deg)), 0.0)
        return BENCH_ALBEDO / np.pi * self.sun_irradiance * cos_sun


def _grid(elevations_deg, azimuths_deg, distances_m) -> tuple[tuple[float, float, float], ...]:
    return tuple((float(e), float(a), float(d)) for e in elevations_deg for a in azimuths_deg for d in distances_m)


def _ground_hit(altitude_m: float, elevation_deg: float, planet_radius_m: float) -> float:
    """Distance from ``altitude_m`` along a descending ray to the spherical ground, m."""
    r0, c = planet_radius_m + altitude_m, np.sin(np.radians(elevation_deg))
    return float(-r0 * c - np.sqrt(r0 * r0 * c * c - (r0 * r0 - planet_radius_m ** 2)))


def _horizon_rays(altitude_m: float, planet_radius_m: float, azimuths_deg) -> tuple[tuple[float, float, float], ...]:
    """Rays toward the geometric horizon (tangent to the ground), to a quarter, half and all of the way."""
    r0 = planet_radius_m + altitude_m
    dip = -np.degrees(np.arccos(planet_radius_m / r0))
    tangent = float(np.sqrt(r0 * r0 - planet_radius_m ** 2))
    return _grid([dip], azimuths_deg, [0.25 * tangent, 0.5 * tangent, 0.999 * tangent])


_EARTH_R = Atmosphere().planet_radius
_MARS_R = 3_389_500.0
_VISTA_DISTANCES = (100.0, 1000.0, 5000.0, 10_000.0, 30_000.0)

#: The benchmark situations.
BENCH_CASES: tuple[BenchCase, ...] = (
    BenchCase("ground_vista", "camera 2 m, level views 100 m to 30 km, sun 40 deg", "clear", 2.0, 40.0,
              _grid([0.0, 1.0], [45.0, 180.0], _VISTA_DISTANCES)),
    BenchCase("distant_range", "camera 2 m, mountains 50 to 150 km away, sun 40 deg", "clear", 2.0, 40.0,
              _grid([0.0, 0.5, 1.5], [90.0], [50_000.0, 100_000.0, 150_000.0])),
    BenchCase("drone", "camera 2 km looking down 45 deg to the ground, sun 45 deg", "clear", 2000.0, 45.0,
              _grid([-45.0], [0.0, 90.0, 180.0], [500.0, 1500.0, _ground_hit(2000.0, -45.0, _EARTH_R)])),
    BenchCase("aircraft", "camera 10 km looking at the geometric horizon (357 km), sun 30 deg", "clear", 10_000.0,
              30.0, _horizon_rays(10_000.0, _EARTH_R, [0.0, 90.0, 180.0])),
    BenchCase("sunset_toward", "camera 2 m, sun 1 deg, level views toward the sun", "clear", 2.0, 1.0,
              _grid([0.0, 1.0], [0.0], _VISTA_DISTANCES), grazing=True),
    BenchCase("sunset_away", "camera 2 m, sun 1 deg, level views away from the sun", "clear", 2.0, 1.0,
              _grid([0.0, 1.0], [180.0], _VISTA_DISTANCES), grazing=True),
    BenchCase("mars_noon", "Mars, camera 2 m, level views 100 m to 50 km, sun 80 deg", "mars", 2.0, 80.0,
              _grid([0.0, 2.0], [45.0, 180.0], (100.0, 1000.0, 10_000.0, 50_000.0))),
    BenchCase("mars_sunset", "Mars, camera 2 m, sun 2 deg, level views toward and away from the sun", "mars", 2.0,
              2.0, _grid([0.0, 2.0], [0.0, 180.0], (100.0, 1000.0, 10_000.0, 50_000.0)), grazing=True),
)

#: Situations measured against the complete reference only (``tools/bench_accuracy.py``'s second table): light
#: that single scattering mostly misses, so the single-scattering bench and the Auto choice leave them out.
COMPLETE_ONLY_CASES: tuple[BenchCase, ...] = (
    BenchCase("blue_hour", "camera 2 m, sun 4 deg below the horizon, views 1 and 10 deg up, toward and away",
              "clear", 2.0, -4.0, _grid([1.0, 10.0], [0.0, 180.0], (1000.0, 10_000.0, 30_000.0)), grazing=True),
    BenchCase("overcast_low_sun", "overcast preset, camera 2 m, sun 1 deg, level views toward and away", "overcast",
              2.0, 1.0, _grid([0.0, 1.0], [0.0, 180.0], (100.0, 1000.0, 5000.0, 10_000.0)), grazing=True),
)
_CASES_BY_NAME = {case.name: case for case in BENCH_CASES + COMPLETE_ONLY_CASES}


def bench_case(name: str) -> BenchCase:
    """The bench case called ``name``."""
    try:
        return _CASES_BY_NAME[name]
    except KeyError:
        raise ValueError(f"unknown bench case {name!r}; expected one of {sorted(_CASES_BY_NAME)}") from None


def evaluate(level: Level, case: BenchCase, dtype=np.float64, sun_at_altitude: bool = True,
             per_pixel: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(F_ex, L_in) of ``level`` for the case's rays, each (n, 3).

    ``sun_at_altitude`` (Balanced only, default on) raises E_sun to its value at the altitude of each piece
    of the ray; ``False`` keeps the ground E_sun of the slides (the bench reports both). ``per_pixel`` (Balanced
    only): the Per Pixel variant (``validation.balanced.PER_PIXEL_PIECES`` pieces, the sun at their middles).
    """
    atm, views, s = case.atmosphere, case.view_dirs, case.distances_m
    mu = views @ case.sun_dir
    e_sun = case.sun_irradiance
    if level is Level.FAST:
        return extinction(s, atm, dtype), inscattering(s, mu, atm, e_sun, dtype)
    if level is Level.BALANCED:
        taus = sun_optical_depths_ground(np.radians(case.sun_elevation_deg), atm, e_sun) if sun_at_altitude else None
        h0 = case.camera_altitude_m
        pieces, sun_at = (PER_PIXEL_PIECES, PER_PIXEL_SUN_AT) if per_pixel else (CURVATURE_PIECES, "lower_end")
        return (extinction_balanced(h0, views, s, atm, dtype, pieces=pieces),
                inscattering_balanced(h0, views, s, mu, atm, e_sun, dtype, sun_optical_depths=taus, pieces=pieces,
                                      sun_at=sun_at))
    if level is Level.PRECISE:
        return evaluate_precise(precise_tile(case), views, case.sun_dir, s, atm, dtype)
    raise ValueError(f"unknown quality level {level!r}; expected one of {[lv.value for lv in Level]}")


@functools.lru_cache(maxsize=None)
def precise_tile(case: BenchCase, multiple_scattering: bool = False):
    """The Precise level's table for the case's camera and sun (single scattering unless asked), cached per case."""
    return bake_tile(case.atmosphere, case.camera_altitude_m, np.radians(case.sun_elevation_deg),
                     multiple_scattering=multiple_scattering)


@functools.lru_cache(maxsize=None)
def reference(case: BenchCase) -> tuple[np.ndarray, np.ndarray]:
    """Brute-force single scattering (F_ex, L_in) for the case's rays, each (n, 3); cached per case.

    The reference sees the sun from every point through the real (curved) atmosphere, not the ground E_sun.
    """
    n_view, n_sun = REFERENCE_STEPS
    results = [single_scattering(case.camera_altitude_m, view, distance, case.sun_dir, case.atmosphere,
                                 n_steps=n_view, n_sun_steps=n_sun)
               for view, distance in zip(case.view_dirs, case.distances_m)]
    f_ex, l_in = (np.array([r[i] for r in results]) for i in (0, 1))
    f_ex.flags.writeable = l_in.flags.writeable = False
    return f_ex, l_in


def relative_error(value: np.ndarray, ref: np.ndarray, floor: float) -> np.ndarray:
    """|value - ref| / max(|ref|, floor), elementwise (see the module docstring for the floors)."""
    return np.abs(value - ref) / np.maximum(np.abs(ref), floor)


def errors(level: Level, case: BenchCase, sun_at_altitude: bool = True, per_pixel: bool = False
           ) -> dict[str, np.ndarray]:
    """Max and mean relative errors per channel (3,) of F_ex, L_in and the pixel L0 F_ex + L_in.

    Keys ``f_ex_max``, ``f_ex_mean``, ``l_in_max``, ``l_in_mean``, ``pixel_max``, ``pixel_mean``; and, over
    rays, ``luminance_max`` (relative error of the pixel's luminance Y, Rec.709 weights, same floor) and
    ``xy_max`` (largest distance between the pixel's CIE 1931 chromaticity and the reference's).
    """
    f_ex, l_in = evaluate(level, case, sun_at_altitude=sun_at_altitude, per_pixel=per_pixel)
    return errors_of(case, (f_ex, l_in), reference(case))


#: Ground albedo (R, G, B) of the complete reference: the one the Precise level's multiple-scattering table
#: assumes (``physics.precise.DEFAULT_GROUND_ALBEDO``), so the comparison is like with like.
COMPLETE_REFERENCE_GROUND_ALBEDO = DEFAULT_GROUND_ALBEDO
#: Monte Carlo paths per ray and channel of the complete reference, and its seed.
COMPLETE_REFERENCE_PATHS = 4000
COMPLETE_REFERENCE_SEED = 11


@functools.lru_cache(maxsize=None)
def complete_reference(case: BenchCase, paths: int = COMPLETE_REFERENCE_PATHS, seed: int = COMPLETE_REFERENCE_SEED
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(F_ex, L_in, standard error of L_in) for the case's rays, each (n, 3), with every scattering order.

    L_in: the Monte Carlo reference in front of a black target at each ray's distance
    (:func:`~validation.multiple_scattering_reference.inscattering_mc`: all orders, the spherical
    planet, a Lambertian ground of :data:`COMPLETE_REFERENCE_GROUND_ALBEDO`, three channels, the atmosphere's ozone);
    F_ex is deterministic, :func:`reference`'s. Cached per case.
    """
    f_ex, _ = reference(case)
    l_in, error = inscattering_mc(case.view_dirs, case.distances_m, case.sun_dir, case.atmosphere,
                                  camera_altitude_m=case.camera_altitude_m,
                                  ground_albedo=COMPLETE_REFERENCE_GROUND_ALBEDO, paths=paths, seed=seed)
    for array in (l_in, error):
        array.flags.writeable = False
    return f_ex, l_in, error


def errors_of(case: BenchCase, value: tuple[np.ndarray, np.ndarray], ref: tuple[np.ndarray, np.ndarray]
              ) -> dict[str, np.ndarray]:
    """The errors of :func:`errors` for (F_ex, L_in) ``value`` against (F_ex, L_in) ``ref`` of the case's rays."""
    (f_ex, l_in), (f_ref, l_ref) = value, ref[:2]
    l0 = case.surface_radiance
    pixel, pixel_ref = l0 * f_ex + l_in, l0 * f_ref + l_ref
    radiance_floor = max(RADIANCE_FLOOR_FRACTION * float(np.max(pixel_ref)), np.finfo(np.float64).tiny)
    result = {}
    for name, value, ref, floor in (("f_ex", f_ex, f_ref, TRANSMITTANCE_FLOOR), ("l_in", l_in, l_ref, radiance_floor),
                                    ("pixel", pixel, pixel_ref, radiance_floor)):
        err = relative_error(value, ref, floor)
        result[f"{name}_max"], result[f"{name}_mean"] = err.max(axis=0), err.mean(axis=0)
    # What the eye reads: the pixel's luminance (relative, the same floor) and its CIE 1931 chromaticity.
    xyz, xyz_ref = pixel @ LINEAR_REC709_TO_XYZ.T, pixel_ref @ LINEAR_REC709_TO_XYZ.T
    luminance_floor = max(RADIANCE_FLOOR_FRACTION * float(np.max(xyz_ref[:, 1])), np.finfo(np.float64).tiny)
    result["luminance_max"] = np.max(relative_error(xyz[:, 1], xyz_ref[:, 1], luminance_floor))
    # NaN where either pixel is black (no chromaticity): a level that renders black where light is.
    result["xy_max"] = np.max(np.linalg.norm(chromaticity_xy(xyz) - chromaticity_xy(xyz_ref), axis=-1))
    return result


#: Max pixel error of Balanced (retired from the product; the bench still measures it) as the Per Pixel mode
#: evaluated it (``validation.balanced.PER_PIXEL_PIECES`` pieces,
#: the sun at their middles), per case, from ``tools/bench_accuracy.py`` (a test checks it as well).
MEASURED_PIXEL_ERROR_PER_PIXEL: dict[str, float] = {
    "ground_vista": 0.0011,
    "distant_range": 0.0121,
    "drone": 0.0000,
    "aircraft": 0.0060,
    "sunset_toward": 0.2091,
    "sunset_away": 0.4154,
    "mars_noon": 0.0004,
    "mars_sunset": 0.3373,
}
