# SPDX-License-Identifier: GPL-3.0-or-later
"""Spectral reference sky: the Monte Carlo yardstick run wavelength by wavelength, then CIE 1931 -> Rec.709.

:func:`~validation.multiple_scattering_reference.sky_radiance_mc` traces one colour channel per
path in an :class:`~atmos_addon.physics.atmosphere.Atmosphere` of three channels. Here the 48 wavelengths of
:data:`~atmos_addon.physics.spectrum.WAVELENGTHS_NM` are grouped into 16 consecutive triples
(360-380 nm, 390-410 nm, ..., 810-830 nm); each triple is one ``Atmosphere`` whose three "channels" are
three wavelengths, lit by the ASTM G173 spectrum at those wavelengths (W m^-2 nm^-1, so the radiance is
spectral, W m^-2 sr^-1 nm^-1), with ozone as the ``extra_absorption`` callback. The 48 spectral radiances
are then turned into colour by :func:`~atmos_addon.physics.spectrum.spectrum_to_xyz` and
:func:`~atmos_addon.physics.spectrum.xyz_to_linear_rec709` (no 683 lm/W: Y is in W m^-2 sr^-1).

The spectral atmosphere is derived from an RGB one (e.g. the clear preset) by :func:`spectral_coefficients`:

* Rayleigh: :func:`~atmos_addon.physics.spectrum.rayleigh_spectrum_per_m` (Bodhaine et al. 1999, sea level)
  times the ratio of the atmosphere's Rayleigh coefficients to the same formula at its own wavelengths
  (1 for ``earth_standard`` air), with its scale height.
* Aerosol: Angstrom's law through the atmosphere's per-channel aerosol extinction (least squares of
  ln beta_ex against ln lambda over its three wavelengths: beta_ex at 550 nm and the exponent alpha), the
  single-scattering albedo sum(beta_sc) / sum(beta_ex) and the mean Henyey-Greenstein g, constant over
  wavelength; its scale height.
* Ozone: :func:`~atmos_addon.physics.spectrum.ozone_absorption_per_m` (tent profile) for ``ozone_du``.

Each triple draws its own random numbers (seed from ``numpy.random.SeedSequence(seed)``), the same whatever
the ozone or the sun spectrum, so two runs that differ only in those are correlated (their difference is
more precise than either). Paths of different wavelengths are independent, so the variance of any linear
function of the spectrum (X, Y, Z, R, G, B) is the sum of the spectral variances times the squared weights;
ratios (B/R, chromaticity) use the first-order (delta-method) propagation of :func:`ratio_and_stderr`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

import numpy as np
from numpy.typing import ArrayLike

from atmos_addon.physics.atmosphere import Atmosphere
from atmos_addon.physics.rayleigh import rayleigh_coefficients
from atmos_addon.physics.spectrum import (ANGSTROM_REFERENCE_WAVELENGTH_NM, CIE_1931_XYZ_BAR,
                                          OZONE_CROSS_SECTION_M2, SOLAR_IRRADIANCE_TOP_W_M2_NM, WAVELENGTH_STEP_NM,
                                          WAVELENGTHS_NM, XYZ_TO_LINEAR_REC709, ozone_number_density_per_m3,
                                          rayleigh_spectrum_per_m)
from validation.multiple_scattering_reference import sky_radiance_mc

#: Number of wavelength triples (one ``Atmosphere`` each).
N_TRIPLES = WAVELENGTHS_NM.size // 3
#: Indices into :data:`WAVELENGTHS_NM` of each triple, shape (16, 3): consecutive wavelengths.
TRIPLE_INDICES = np.arange(WAVELENGTHS_NM.size).reshape(N_TRIPLES, 3)
#: Weight of each wavelength's spectral value in CIE XYZ, (48, 3): x_bar, y_bar, z_bar times 10 nm.
XYZ_WEIGHTS = CIE_1931_XYZ_BAR * WAVELENGTH_STEP_NM
#: Weight of each wavelength's spectral value in linear Rec.709 RGB, (48, 3).
RGB_WEIGHTS = XYZ_WEIGHTS @ XYZ_TO_LINEAR_REC709.T


def aerosol_angstrom_fit(atmosphere: Atmosphere) -> dict[str, float]:
    """The aerosol of an RGB atmosphere as Angstrom's law: extinction at 550 nm (1/m), alpha, albedo, g.

    Least squares of ln beta_ex = ln beta_550 - alpha ln(lambda / 550 nm) over the three channels; a
    single-scattering albedo sum(beta_sc) / sum(beta_ex) and the mean g. No aerosol gives zeros.
    """
    extinction = np.asarray(atmosphere.mie_extinction, dtype=np.float64)
    g = float(np.mean(atmosphere.mie_g))
    if np.all(extinction == 0.0):
        return {"extinction_550_per_m": 0.0, "alpha": 0.0, "single_scattering_albedo": 1.0, "g": g}
    if np.any(extinction <= 0.0):
        raise ValueError(f"aerosol extinction must be > 0 in every channel or 0 in all; got {extinction.tolist()}")
    x = np.log(np.asarray(atmosphere.wavelengths_nm) / ANGSTROM_REFERENCE_WAVELENGTH_NM)
    slope, intercept = np.polyfit(x, np.log(extinction), 1)
    return {"extinction_550_per_m": float(np.exp(intercept)), "alpha": float(-slope),
            "single_scattering_albedo": float(np.sum(atmosphere.mie_scattering) / np.sum(extinction)), "g": g}


def spectral_coefficients(atmosphere: Atmosphere) -> dict[str, np.ndarray]:
    """Sea-level Rayleigh scattering, aerosol scattering and absorption on :data:`WAVELENGTHS_NM`, 1/m, (48,) each."""
    air_scale = float(np.mean(np.asarray(atmosphere.rayleigh_scattering)
                              / rayleigh_coefficients(np.asarray(atmosphere.wavelengths_nm))))
    aerosol = aerosol_angstrom_fit(atmosphere)
    extinction = aerosol["extinction_550_per_m"] * (
        WAVELENGTHS_NM / ANGSTROM_REFERENCE_WAVELENGTH_NM) ** (-aerosol["alpha"])
    albedo = aerosol["single_scattering_albedo"]
    return {"rayleigh_scattering": rayleigh_spectrum_per_m() * air_scale,
            "mie_scattering": extinction * albedo, "mie_absorption": extinction * (1.0 - albedo)}


def triple_atmospheres(atmosphere: Atmosphere, sun_spectrum: ArrayLike | None = None) -> list[Atmosphere]:
    """The 16 three-wavelength atmospheres of :data:`TRIPLE_INDICES` (without ozone: see :class:`OzoneTriple`).

    Each keeps ``atmosphere``'s scale heights, planet and top; ``sun_irradiance_top`` is ``sun_spectrum``
    (default ASTM G173, W m^-2 nm^-1) at its wavelengths.
    """
    sun = SOLAR_IRRADIANCE_TOP_W_M2_NM if sun_spectrum is None else np.asarray(sun_spectrum, dtype=np.float64)
    if sun.shape != WAVELENGTHS_NM.shape or np.any(sun < 0.0):
        raise ValueError(f"sun_spectrum must hold {WAVELENGTHS_NM.size} values >= 0; got shape {sun.shape}")
    coefficients = spectral_coefficients(atmosphere)
    g = aerosol_angstrom_fit(atmosphere)["g"]
    return [atmosphere.replace(wavelengths_nm=WAVELENGTHS_NM[i],
                               rayleigh_scattering=coefficients["rayleigh_scattering"][i],
                               mie_scattering=coefficients["mie_scattering"][i],
                               mie_absorption=coefficients["mie_absorption"][i], mie_g=g, sun_irradiance_top=sun[i],
                               ozone_column_du=0.0)
            for i in TRIPLE_INDICES]


class OzoneTriple:
    """``extra_absorption`` callback of one triple: ozone absorption (1/m) at its 3 wavelengths, (..., 3).

    A class rather than a closure so that it pickles (the tool may trace triples in worker processes).
    """

    def __init__(self, indices: ArrayLike, ozone_du: float):
        self.indices = np.asarray(indices, dtype=np.intp)
        self.ozone_du = float(ozone_du)
        self.cross_section_m2 = OZONE_CROSS_SECTION_M2[self.indices]

    def __call__(self, altitude_m: np.ndarray) -> np.ndarray:
        # ozone_absorption_per_m(altitude_m, ozone_du)[..., indices], without the other 45 wavelengths.
        return ozone_number_density_per_m3(altitude_m, self.ozone_du)[..., np.newaxis] * self.cross_section_m2


def triple_seeds(seed: int) -> list[int]:
    """One integer seed per triple, derived from ``seed`` (deterministic, independent streams)."""
    return [int(s) for s in np.random.SeedSequence(int(seed)).generate_state(N_TRIPLES, dtype=np.uint32)]


def _trace_triple(job: tuple) -> tuple[np.ndarray, np.ndarray]:
    """Radiance and standard error (k, 3) of one triple: ``sky_radiance_mc`` with the job's arguments."""
    views, sun_dir, atm, indices, ozone_du, kwargs = job
    extra = OzoneTriple(indices, ozone_du) if ozone_du > 0.0 else None
    return sky_radiance_mc(views, sun_dir, atm, extra_absorption=extra, **kwargs)


def spectral_radiance(view_dirs: ArrayLike, sun_dir: ArrayLike, *, atmosphere: Atmosphere | None = None,
                      ozone_du: float = 300.0, ground_albedo: float = 0.3, paths: int = 20_000, seed: int = 0,
                      max_order: int | None = None, camera_altitude_m: float = 0.0,
                      sun_spectrum: ArrayLike | None = None, triples: Iterable[int] | None = None,
                      map_fn: Callable = map, n_nodes: int = 97) -> tuple[np.ndarray, np.ndarray]:
    """Spectral sky radiance on :data:`WAVELENGTHS_NM` and its standard error, each (k, 48), W m^-2 sr^-1 nm^-1.

    ``view_dirs`` (3,) or (k, 3) from the camera at (0, 0, ``camera_altitude_m``), z up; ``sun_dir`` toward
    the sun. ``atmosphere`` (default :class:`Atmosphere`) is turned into spectra by :func:`spectral_coefficients`;
    ozone ``ozone_du`` Dobson units in the tent profile (0: none); a grey Lambertian ground; ``paths`` per view
    and wavelength; all scattering orders unless ``max_order``. ``triples`` restricts the run to some of the 16
    triples (the other wavelengths are NaN); ``map_fn`` maps the per-triple work (e.g. a process pool's
    ``map``: the jobs pickle). The sun's disk is not included.
    """
    if not np.isfinite(ozone_du) or ozone_du < 0.0:
        raise ValueError(f"ozone_du must be finite and >= 0; got {ozone_du!r}")
    views = np.atleast_2d(np.asarray(view_dirs, dtype=np.float64))
    atmospheres = triple_atmospheres(Atmosphere() if atmosphere is None else atmosphere, sun_spectrum)
    seeds = triple_seeds(seed)
    chosen = list(range(N_TRIPLES)) if triples is None else [int(t) for t in triples]
    kwargs = dict(camera_altitude_m=float(camera_altitude_m), ground_albedo=float(ground_albedo),
                  max_order=max_order, paths=int(paths), n_nodes=int(n_nodes))
    jobs = [(views, np.asarray(sun_dir, dtype=np.float64), atmospheres[t], TRIPLE_INDICES[t], float(ozone_du),
             dict(kwargs, seed=seeds[t])) for t in chosen]
    radiance = np.full((views.shape[0], WAVELENGTHS_NM.size), np.nan)
    error = np.full_like(radiance, np.nan)
    for t, (value, stderr) in zip(chosen, map_fn(_trace_triple, jobs), strict=True):
        radiance[:, TRIPLE_INDICES[t]] = value
        error[:, TRIPLE_INDICES[t]] = stderr
    if np.ndim(view_dirs) == 1:
        return radiance[0], error[0]
    return radiance, error


def linear_stderr(spectral_stderr: ArrayLike, weights: ArrayLike) -> np.ndarray:
    """Standard error of ``spectrum @ weights`` for independent spectral errors: sqrt(stderr^2 @ weights^2)."""
    return np.sqrt(np.square(np.asarray(spectral_stderr)) @ np.square(np.asarray(weights)))


def ratio_and_stderr(spectrum: ArrayLike, spectral_stderr: ArrayLike, numerator_weights: ArrayLike,
                     denominator_weights: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """r = (S . a) / (S . b) and its first-order standard error for independent spectral errors.

    dr/dS_i = (a_i - r b_i) / (S . b), so var r = sum_i ((a_i - r b_i) / (S . b))^2 var S_i. E.g. B/R with
    a, b the B and R columns of :data:`RGB_WEIGHTS`; chromaticity x with a = x_bar, b = x_bar + y_bar + z_bar.
    """
    spectrum, stderr = np.asarray(spectrum), np.asarray(spectral_stderr)
    a, b = np.asarray(numerator_weights), np.asarray(denominator_weights)
    denominator = spectrum @ b
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = (spectrum @ a) / denominator
        derivative = (a - ratio[..., None] * b) / denominator[..., None]
    return ratio, np.sqrt(np.sum(np.square(derivative * stderr), axis=-1))


def spectral_sky(view_dirs: ArrayLike, sun_dir: ArrayLike, *, ozone_du: float = 300.0, ground_albedo: float = 0.3,
                 paths: int = 20_000, seed: int = 0, max_order: int | None = None, atmosphere: Atmosphere | None = None,
                 **options) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Linear Rec.709 RGB, CIE 1931 XYZ and the RGB standard error of the spectral reference sky, each (..., 3).

    :func:`spectral_radiance` (``options``: its other keywords) assembled with :data:`XYZ_WEIGHTS` and
    :data:`RGB_WEIGHTS`; units W m^-2 sr^-1 (radiometric, no 683 lm/W). The XYZ error is
    ``linear_stderr(spectral_stderr, XYZ_WEIGHTS)`` from :func:`spectral_radiance`.
    """
    spectrum, stderr = spectral_radiance(view_dirs, sun_dir, atmosphere=atmosphere, ozone_du=ozone_du,
                                         ground_albedo=ground_albedo, paths=paths, seed=seed, max_order=max_order,
                                         **options)
    return spectrum @ RGB_WEIGHTS, spectrum @ XYZ_WEIGHTS, linear_stderr(stderr, RGB_WEIGHTS)
