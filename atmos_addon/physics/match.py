# SPDX-License-Identifier: GPL-3.0-or-later
"""Fit the atmosphere to a photograph (a plate): the parameters whose sky and haze look like the plate's.

The sky and a surface at distance d seen through the haze are one function of the same parameters (the Fast level:
the layered virtual dome of :mod:`.sky`, Hoffman & Preetham 2002):

    sky pixel      P = 2^EV L_sky(v; theta)
    surface pixel  P = 2^EV (L0 F_ex(d, v; theta) + L_in(d, v; theta))

with v the pixel's view direction (from the camera's field of view, pitch and heading), EV the plate's exposure in
stops, L0 the radiance the surface itself sends (unknown, one colour per surface kind: the same forest on a near
and a far ridge) and theta the atmosphere and the sun:

    visibility (the haze's extinction at 550 nm beyond the air's, Koschmieder: V = 3.912 / beta_ex(550)),
    haze colour (its scattering R / G and B / G; the Angstrom exponent is read from it), forward scattering g,
    air density (Rayleigh at 550 nm over standard air's), ozone column, the haze's scale height, sun elevation and
    azimuth, exposure.

The fit is a least-squares problem in these parameters over a few hundred pixels per marked region, each region
weighted alike (its pixels' residuals relative to the region's mean brightness), solved by Levenberg-Marquardt
(Marquardt 1963: damped Gauss-Newton with the damping scaled by diag(J^T J)) with forward-difference Jacobians.
Bounds enter through a logistic transform of each bounded parameter. L0 is linear in the residual and solved in
closed form at every evaluation (variable projection, Golub & Pereyra 1973), so it never slows the search. The
search runs a few iterations from each of the best points of a coarse grid over the sun and the haze's amount (the
exposure and L0 solved linearly there), whose suns lie apart, and goes on from the best.

What the plate cannot tell: the covariance sigma^2 (J^T J)^-1 / (3 :data:`EFFECTIVE_SAMPLES`) at the solution, with
sigma the pixels' relative residual (at least :data:`MODEL_NOISE_FLOOR`: a photograph never matches a single-
scattering model better), gives each parameter's standard error. A parameter whose error passes its tolerance
(:data:`PARAMETERS`), or that runs to a bound, is reported with the parameter it trades with (their correlation): an
atmosphere parameter is then held (at the start preset's value where the rest can make up for it) and the rest
fitted again; the sun and the exposure, with no start value to fall back on, stay free and are reported as
uncertain. An answer is never reported as more precise than the plate allows, and a look that does not reproduce a
region says so (:attr:`Fit.misfit`).

Lengths m, angles deg unless named _rad, radiance in the plate's linear units over 2^EV. Numpy only.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np
from numpy.typing import ArrayLike

from .atmosphere import Atmosphere
from .sky import (aerial_distance_clamped, atmosphere_at_altitude, dome_distance_approx, elevation_of,
                  extinction_layered, inscattering_layered, sky_radiance)
from .spectrum import channel_value_at
from .sun import LUMINANCE_WEIGHTS, sun_irradiance_ground
from .visibility import (KOSCHMIEDER_CONSTANT, VISIBILITY_WAVELENGTH_NM, extinction_550_per_m,
                         haze_absorption_ratio, haze_for_extinction, relative_air_density, visibility_m)

#: Pixels drawn from each region for the fit (spread at random over its mask, a fixed seed): enough for the
#: region's mean and its gradients, few enough that one model evaluation takes about a millisecond.
SAMPLES_PER_REGION = 300
#: Pixels per region on which the final residuals are reported.
REPORT_SAMPLES_PER_REGION = 4000
#: A region needs at least this many usable pixels.
MIN_REGION_PIXELS = 8
#: The smallest relative residual the covariance assumes per measurement (:data:`EFFECTIVE_SAMPLES`): a plate never
#: matches the single-scattering model better than this.
MODEL_NOISE_FLOOR = 0.02
#: Independent measurements per region and channel the covariance counts: a plate's misfit to a single-scattering
#: model is smooth over a region (a gradient, a glow), so its pixels are not independent; 25 is a 5 x 5 pattern.
EFFECTIVE_SAMPLES = 25
#: Fraction of the sky's pixels that may be clipped (at or above 0.98 of the plate's clip level) before the sky
#: counts as overexposed; clipped pixels below it are left out of the fit.
MAX_CLIPPED_SKY_FRACTION = 0.2
#: Relative clip margin: a pixel at or above this fraction of the clip level counts as clipped.
CLIP_MARGIN = 0.98
#: Lowest sun elevation the fit uses, deg: below the horizon the Fast level's single-scattering sky is black.
MIN_SUN_ELEVATION_DEG = 0.2
#: Levenberg-Marquardt limits: iterations, the relative cost decrease that ends it, the largest damping.
MAX_ITERATIONS = 80
COST_TOLERANCE = 1e-6
MAX_DAMPING = 1e10
#: Forward-difference step in the transformed parameters.
JACOBIAN_STEP = 1e-6
#: A bounded parameter whose logistic is within this of 0 or 1 sits on its bound.
AT_BOUND = 1e-4
#: A fit whose worst region's mean colour is further than this from the plate's says so (:attr:`Fit.misfit`).
MISFIT_COLOUR_ERROR = 0.02
#: A held parameter takes the start's value when the refit with it costs at most this times the free fit's.
HOLD_COST_RATIO = 1.1
#: Correlation above which an undetermined parameter is reported as traded against another.
TRADE_CORRELATION = 0.9

#: Sun elevations (deg) and azimuths from the camera's heading (deg) of the starting grid for an unknown sun.
GRID_SUN_ELEVATIONS_DEG = (1.0, 3.0, 6.0, 10.0, 16.0, 25.0, 40.0, 60.0, 80.0)
GRID_SUN_AZIMUTHS_DEG = tuple(float(a) for a in range(0, 360, 30))
#: Visibilities (m) of the starting grid for the haze's amount.
GRID_VISIBILITIES_M = (3_000.0, 12_000.0, 40_000.0, 150_000.0)
#: Starting points the search runs from (the grid's best with their suns apart), and the iterations each gets
#: before the best goes on alone.
STARTS = 5
START_ITERATIONS = 8


class MatchError(ValueError):
    """A plate the fit refuses (no sky marked, an overexposed sky, a distance of zero, ...); the message says what
    is wrong and what to do. Nothing has been changed when it is raised."""


# ---------------------------------------------------------------------------------------------- transfer functions

def srgb_to_linear(values: ArrayLike) -> np.ndarray:
    """The sRGB transfer function undone (IEC 61966-2-1): encoded values in [0, 1] to linear light."""
    v = np.asarray(values, dtype=np.float64)
    return np.where(v <= 0.04045, v / 12.92, ((np.maximum(v, 0.04045) + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(values: ArrayLike) -> np.ndarray:
    """The sRGB transfer function (IEC 61966-2-1): linear light in [0, 1] to encoded values (clipped to [0, 1])."""
    v = np.clip(np.asarray(values, dtype=np.float64), 0.0, 1.0)
    return np.where(v <= 0.0031308, v * 12.92, 1.055 * np.maximum(v, 0.0031308) ** (1.0 / 2.4) - 0.055)


# ---------------------------------------------------------------------------------------------- the plate

@dataclass(frozen=True)
class PlateCamera:
    """The plate's pinhole camera: size in pixels, horizontal field of view, pitch (deg above the horizon), heading
    (the azimuth it looks toward, deg clockwise from +Y, the scene's north) and altitude above the ground (m).
    No roll."""

    width: int
    height: int
    fov_deg: float
    pitch_deg: float = 0.0
    heading_deg: float = 0.0
    altitude_m: float = 0.0

    def __post_init__(self) -> None:
        if int(self.width) < 1 or int(self.height) < 1:
            raise MatchError(f"the plate must have at least one pixel; got {self.width}x{self.height}")
        if not (math.isfinite(self.fov_deg) and 0.0 < self.fov_deg < 179.0):
            raise MatchError(f"the field of view must lie between 0 and 179 degrees; got {self.fov_deg:g}")
        if not (math.isfinite(self.pitch_deg) and -90.0 < self.pitch_deg < 90.0):
            raise MatchError(f"the camera pitch must lie between -90 and 90 degrees; got {self.pitch_deg:g}")
        if not (math.isfinite(self.altitude_m) and self.altitude_m >= 0.0):
            raise MatchError(f"the camera altitude must be >= 0 m; got {self.altitude_m:g}")

    def image_plane(self, rows: ArrayLike, cols: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """(x, y) of pixel centres on the image plane at unit focal length: x right, y up."""
        half = math.tan(math.radians(self.fov_deg) / 2.0) / (self.width / 2.0)
        x = (np.asarray(cols, dtype=np.float64) + 0.5 - self.width / 2.0) * half
        y = (self.height / 2.0 - (np.asarray(rows, dtype=np.float64) + 0.5)) * half
        return x, y

    def axes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The camera's forward, right and up unit vectors in world axes (z up)."""
        p, h = math.radians(self.pitch_deg), math.radians(self.heading_deg)
        forward = np.array([math.sin(h) * math.cos(p), math.cos(h) * math.cos(p), math.sin(p)])
        right = np.array([math.cos(h), -math.sin(h), 0.0])
        return forward, right, np.cross(right, forward)

    def directions(self, rows: ArrayLike, cols: ArrayLike) -> np.ndarray:
        """Unit view directions (n, 3) in world axes of the pixels (rows from the top, columns from the left)."""
        x, y = self.image_plane(rows, cols)
        forward, right, up = self.axes()
        d = forward + x[..., None] * right + y[..., None] * up
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    def range_per_depth(self, rows: ArrayLike, cols: ArrayLike) -> np.ndarray:
        """Distance along each pixel's ray per unit of planar depth (along the camera axis): sqrt(1 + x^2 + y^2)."""
        x, y = self.image_plane(rows, cols)
        return np.sqrt(1.0 + x * x + y * y)


def pitch_from_horizon(horizon_row_fraction: float, width: int, height: int, fov_deg: float) -> float:
    """The camera pitch (deg, up positive) that puts the horizon on the row at ``horizon_row_fraction`` of the plate's
    height from its top (0.5: the middle, a level camera): pitch = atan(-y_h), y_h the row's height on the image
    plane at unit focal length."""
    if not (math.isfinite(horizon_row_fraction) and -1.0 <= horizon_row_fraction <= 2.0):
        raise MatchError(f"the horizon row must be a fraction of the plate's height (0 top, 1 bottom); "
                         f"got {horizon_row_fraction:g}")
    half = math.tan(math.radians(fov_deg) / 2.0) / (width / 2.0)
    y = (height / 2.0 - horizon_row_fraction * height) * half
    return math.degrees(math.atan(-y))


@dataclass(frozen=True)
class Region:
    """A marked part of the plate: the sky (``distance_m`` None), a surface at one distance (m) or a surface with a
    distance per pixel (an (H, W) array: a depth pass, range along the ray). Surfaces of the same ``surface`` name
    share one unknown radiance L0 (mark the same kind of ground at several distances)."""

    name: str
    mask: np.ndarray
    distance_m: float | np.ndarray | None = None
    surface: str = "ground"

    @property
    def is_sky(self) -> bool:
        return self.distance_m is None


@dataclass(frozen=True)
class Plate:
    """A photograph in linear light (H, W, 3), its camera and its marked regions. ``clip_level`` is the value at which
    the plate's pixels saturate (1.0 for a PNG or JPEG), None when they do not (a scene-linear EXR)."""

    pixels: np.ndarray
    camera: PlateCamera
    regions: tuple[Region, ...]
    clip_level: float | None = None


@dataclass(frozen=True)
class Knowns:
    """What is known of the shot: the sun's elevation and azimuth (deg, azimuth clockwise from +Y) and the plate's
    exposure (stops: plate = 2^EV x radiance); None where the fit must find it."""

    sun_elevation_deg: float | None = None
    sun_azimuth_deg: float | None = None
    exposure_ev: float | None = None


@dataclass(frozen=True)
class Look:
    """The atmosphere, the sun and the exposure that make a plate."""

    atmosphere: Atmosphere
    sun_elevation_deg: float
    sun_azimuth_deg: float
    exposure_ev: float = 0.0

    @property
    def visibility_m(self) -> float:
        return visibility_m(self.atmosphere)

    @property
    def air_density(self) -> float:
        atm = self.atmosphere
        return relative_air_density(atm.wavelengths_nm, atm.rayleigh_scattering)

    @property
    def haze_colour(self) -> np.ndarray:
        s = np.asarray(self.atmosphere.mie_scattering, dtype=np.float64)
        return s / s.max() if s.max() > 0.0 else np.ones(3)

    @property
    def angstrom_exponent(self) -> float:
        """The Angstrom exponent alpha of the haze's scattering, beta ~ lambda^-alpha: the least-squares slope of
        ln beta against ln lambda over the three channels."""
        atm = self.atmosphere
        s = np.maximum(np.asarray(atm.mie_scattering, dtype=np.float64), 1e-30)
        return float(-np.polyfit(np.log(atm.wavelengths_nm), np.log(s), 1)[0])

    @property
    def mie_g(self) -> float:
        return float(np.mean(self.atmosphere.mie_g))


# ---------------------------------------------------------------------------------------------- the model

def sun_direction(elevation_deg: float, azimuth_deg: float) -> np.ndarray:
    """Unit vector toward the sun (z up, azimuth clockwise from +Y toward +X)."""
    e, a = math.radians(elevation_deg), math.radians(azimuth_deg)
    return np.array([math.cos(e) * math.sin(a), math.cos(e) * math.cos(a), math.sin(e)])


def atmosphere_terms(directions: np.ndarray, distance_m: np.ndarray, atm: Atmosphere, sun_elevation_deg: float,
                     sun_azimuth_deg: float, altitude_m: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(L_in, F_ex) per pixel, (n, 3) each, at the Fast level: the sky (F_ex 0) where ``distance_m`` is NaN, else a
    surface at that distance (layered dome, :func:`~.sky.inscattering_layered` and :func:`~.sky.extinction_layered`
    with the dome of :func:`~.sky.dome_distance_approx`; E_sun at the camera from :func:`~.sun.sun_irradiance_ground`).
    """
    sun = sun_direction(sun_elevation_deg, sun_azimuth_deg)
    e_sun = sun_irradiance_ground(math.radians(sun_elevation_deg), atm, altitude_m)
    l_in = np.empty((len(directions), 3))
    f_ex = np.zeros((len(directions), 3))
    sky = np.isnan(distance_m)
    if np.any(sky):
        l_in[sky] = sky_radiance(directions[sky], sun, atm, e_sun, altitude_m=altitude_m, dome=dome_distance_approx)
    if not np.all(sky):
        views, d = directions[~sky], distance_m[~sky]
        s_r, s_m = aerial_distance_clamped(d, elevation_of(views), atm, altitude_m, dome=dome_distance_approx)
        local = atmosphere_at_altitude(atm, altitude_m)
        l_in[~sky] = inscattering_layered(s_r, s_m, views @ sun, local, e_sun)
        f_ex[~sky] = extinction_layered(s_r, s_m, local)
    return l_in, f_ex


def render_pixels(directions: np.ndarray, distance_m: np.ndarray, look: Look, surface_radiance: np.ndarray,
                  altitude_m: float = 0.0) -> np.ndarray:
    """Plate values (n, 3) of pixels: 2^EV (L0 F_ex + L_in), ``surface_radiance`` L0 per pixel (n, 3) (0 for sky)."""
    l_in, f_ex = atmosphere_terms(directions, distance_m, look.atmosphere, look.sun_elevation_deg,
                                  look.sun_azimuth_deg, altitude_m)
    return 2.0 ** look.exposure_ev * (np.asarray(surface_radiance, dtype=np.float64) * f_ex + l_in)


# ---------------------------------------------------------------------------------------------- parameters

@dataclass(frozen=True)
class Parameter:
    """One fitted quantity: its name, its label, its bounds in fit coordinates and the standard error beyond which
    the plate counts as not telling it (``tolerance``, in the units ``unit`` of :meth:`Fit.reported`)."""

    name: str
    label: str
    lower: float
    upper: float
    tolerance: float
    unit: str


#: The fitted parameters in fit coordinates: ln of the haze's extinction at 550 nm (1/m), ln of the haze's
#: scattering R / G and B / G, g, ln air density, ozone (DU), sun elevation and azimuth (deg), exposure (stops), ln of
#: the haze's scale height (m). Tolerances: visibility 10 %, colour 10 %, g 0.1, air density 10 %, ozone 75 DU, sun 1
#: and 5 deg, 0.15 stops, scale height 25 %.
PARAMETERS = (
    Parameter("visibility", "visibility", math.log(1e-7), math.log(5e-2), 0.10, "relative"),
    Parameter("haze_red", "haze colour (red)", -4.0, 4.0, 0.10, "relative"),
    Parameter("haze_blue", "haze colour (blue)", -4.0, 4.0, 0.10, "relative"),
    Parameter("mie_g", "forward scattering g", -0.3, 0.95, 0.10, ""),
    Parameter("air_density", "air density", math.log(1e-4), math.log(30.0), 0.10, "relative"),
    Parameter("ozone", "ozone", 0.0, 1000.0, 75.0, "DU"),
    Parameter("sun_elevation", "sun elevation", MIN_SUN_ELEVATION_DEG, 89.5, 1.0, "deg"),
    Parameter("sun_azimuth", "sun azimuth", -math.inf, math.inf, 5.0, "deg"),
    Parameter("exposure", "exposure", -40.0, 40.0, 0.15, "stops"),
    Parameter("haze_height", "haze scale height", math.log(200.0), math.log(20_000.0), 0.25, "relative"),
)
_INDEX = {p.name: i for i, p in enumerate(PARAMETERS)}
#: Parameters without a start value to fall back on when the plate cannot tell them (the start preset has none).
_NO_PRIOR = frozenset(("sun_elevation", "sun_azimuth", "exposure"))
_LOWER = np.array([p.lower for p in PARAMETERS])
_UPPER = np.array([p.upper for p in PARAMETERS])
_BOUNDED = np.isfinite(_LOWER) & np.isfinite(_UPPER)


def _to_u(y: np.ndarray) -> np.ndarray:
    """Fit coordinates to the unbounded ones the search moves in: logit((y - lo) / (hi - lo)) where bounded."""
    u = np.array(y, dtype=np.float64)
    span = _UPPER[_BOUNDED] - _LOWER[_BOUNDED]
    t = np.clip((u[_BOUNDED] - _LOWER[_BOUNDED]) / span, 1e-9, 1.0 - 1e-9)
    u[_BOUNDED] = np.log(t / (1.0 - t))
    return u


def _to_y(u: np.ndarray) -> np.ndarray:
    y = np.array(u, dtype=np.float64)
    span = _UPPER[_BOUNDED] - _LOWER[_BOUNDED]
    y[_BOUNDED] = _LOWER[_BOUNDED] + span / (1.0 + np.exp(-np.clip(u[_BOUNDED], -700.0, 700.0)))
    return y


def _dy_du(u: np.ndarray) -> np.ndarray:
    d = np.ones_like(u)
    s = 1.0 / (1.0 + np.exp(-np.clip(u[_BOUNDED], -700.0, 700.0)))
    d[_BOUNDED] = (_UPPER[_BOUNDED] - _LOWER[_BOUNDED]) * s * (1.0 - s)
    return d


def _logistic(u: np.ndarray) -> np.ndarray:
    s = np.full_like(u, 0.5)
    s[_BOUNDED] = 1.0 / (1.0 + np.exp(-np.clip(u[_BOUNDED], -700.0, 700.0)))
    return s


@dataclass(frozen=True)
class _Template:
    """What the fit keeps of the start atmosphere: everything but the fitted quantities, and the base they scale."""

    start: Atmosphere
    start_density: float
    absorption_ratio: np.ndarray
    start_g_mean: float

    @classmethod
    def of(cls, atm: Atmosphere) -> "_Template":
        density = relative_air_density(atm.wavelengths_nm, atm.rayleigh_scattering)
        if density <= 0.0:
            atm = atm.replace(rayleigh_scattering=None)
            density = relative_air_density(atm.wavelengths_nm, atm.rayleigh_scattering)
        return cls(atm, density, haze_absorption_ratio(atm.mie_scattering, atm.mie_absorption),
                   float(np.mean(atm.mie_g)))

    def start_y(self) -> np.ndarray:
        atm = self.start
        haze = max(extinction_550_per_m(atm) - channel_value_at(VISIBILITY_WAVELENGTH_NM, atm.wavelengths_nm,
                                                               atm.rayleigh_scattering), 1e-7)
        s = np.asarray(atm.mie_scattering, dtype=np.float64)
        red, blue = (math.log(s[0] / s[1]), math.log(s[2] / s[1])) if np.all(s > 0.0) else (0.0, 0.0)
        y = np.array([math.log(haze), red, blue, self.start_g_mean, math.log(self.start_density),
                      atm.ozone_column_du, 20.0, 0.0, 0.0, math.log(atm.mie_scale_height)])
        return np.clip(y, _LOWER + 1e-6 * np.where(_BOUNDED, _UPPER - _LOWER, 0.0),
                       _UPPER - 1e-6 * np.where(_BOUNDED, _UPPER - _LOWER, 0.0))

    def atmosphere(self, y: np.ndarray) -> Atmosphere:
        atm = self.start
        shape = np.array([math.exp(y[1]), 1.0, math.exp(y[2])])
        scattering, absorption = haze_for_extinction(math.exp(y[0]), atm.wavelengths_nm, shape, self.absorption_ratio)
        g = np.clip(np.asarray(atm.mie_g) + (y[3] - self.start_g_mean), -0.99, 0.99)
        rayleigh = np.asarray(atm.rayleigh_scattering) * (math.exp(y[4]) / self.start_density)
        return atm.replace(rayleigh_scattering=rayleigh, mie_scattering=scattering, mie_absorption=absorption,
                           mie_g=g, ozone_column_du=max(float(y[5]), 0.0), mie_scale_height=math.exp(y[9]))

    def look(self, y: np.ndarray) -> Look:
        return Look(self.atmosphere(y), float(y[6]), float(y[7]) % 360.0, float(y[8]))


# ---------------------------------------------------------------------------------------------- samples

@dataclass(frozen=True)
class _Samples:
    """The pixels the fit uses: directions (n, 3), distances (n,) (NaN: sky), values (n, 3), each pixel's region and
    surface index (-1: sky) and its residual weight 1 / (region mean brightness x sqrt(3 n_region))."""

    directions: np.ndarray
    distance: np.ndarray
    values: np.ndarray
    region: np.ndarray
    surface: np.ndarray
    weight: np.ndarray
    region_names: tuple[str, ...]
    surface_names: tuple[str, ...]
    rows: np.ndarray
    cols: np.ndarray

    def per_pixel_scale(self) -> np.ndarray:
        """sqrt(3 n_region) per residual entry: what turns a weighted residual into a pixel's relative one."""
        counts = np.bincount(self.region, minlength=len(self.region_names)).astype(np.float64)
        return np.repeat(np.sqrt(3.0 * counts[self.region]), 3)


def _check_plate(plate: Plate) -> np.ndarray:
    pixels = np.asarray(plate.pixels, dtype=np.float64)
    if pixels.ndim != 3 or pixels.shape[2] < 3:
        raise MatchError(f"the plate must be an RGB image; got an array of shape {pixels.shape}")
    pixels = pixels[..., :3]
    height, width = pixels.shape[:2]
    if (width, height) != (plate.camera.width, plate.camera.height):
        raise MatchError(f"the camera is {plate.camera.width}x{plate.camera.height} px but the plate {width}x{height}")
    if not any(region.is_sky for region in plate.regions):
        raise MatchError("no sky marked: mark the plate's sky (a sky mask) so the fit can see the air's colour")
    names = [region.name for region in plate.regions]
    if len(set(names)) != len(names):
        raise MatchError(f"two regions share a name: {', '.join(names)}")
    return pixels


def _region_pixels(plate: Plate, pixels: np.ndarray, region: Region) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(rows, cols, distance) of a region's usable pixels (finite, unclipped, positive distance); refuses a bad one."""
    mask = np.asarray(region.mask)
    if mask.shape != pixels.shape[:2]:
        raise MatchError(f"region '{region.name}': its mask is {mask.shape[1]}x{mask.shape[0]} px but the plate "
                         f"{pixels.shape[1]}x{pixels.shape[0]}")
    mask = mask.astype(bool)
    if not mask.any():
        raise MatchError(f"region '{region.name}': its mask is empty: mark some pixels (white on black)")
    if region.is_sky:
        distance = np.full(mask.shape, np.nan)
    elif np.ndim(region.distance_m) == 0:
        d = float(region.distance_m)
        if not (math.isfinite(d) and d > 0.0):
            raise MatchError(f"region '{region.name}': distance {d:g} m: give each surface's distance from the camera "
                             "in metres, greater than 0")
        distance = np.full(mask.shape, d)
    else:
        distance = np.asarray(region.distance_m, dtype=np.float64)
        if distance.shape != mask.shape:
            raise MatchError(f"region '{region.name}': its depth is {distance.shape[1]}x{distance.shape[0]} px but "
                             f"the plate {mask.shape[1]}x{mask.shape[0]}")
        bad = mask & ~(np.isfinite(distance) & (distance > 0.0))
        if bad.all() or bad.sum() == mask.sum():
            raise MatchError(f"region '{region.name}': the depth pass has no distance greater than 0 m inside the "
                             "mask: give a depth pass in metres")
        mask = mask & ~bad
    values = pixels[mask]
    usable = np.all(np.isfinite(values), axis=1)
    if plate.clip_level is not None:
        clipped = np.any(values >= CLIP_MARGIN * plate.clip_level, axis=1)
        if region.is_sky and clipped.mean() > MAX_CLIPPED_SKY_FRACTION:
            raise MatchError(f"the sky is overexposed: {100.0 * clipped.mean():.0f} % of its pixels are clipped; use a "
                             "plate exposed for the sky, or a scene-linear EXR")
        usable &= ~clipped
    rows, cols = np.nonzero(mask)
    rows, cols, distance = rows[usable], cols[usable], distance[mask][usable]
    if rows.size < MIN_REGION_PIXELS:
        raise MatchError(f"region '{region.name}': only {rows.size} usable pixels (unclipped, finite); mark at least "
                         f"{MIN_REGION_PIXELS}")
    brightness = float(np.mean(pixels[rows, cols] @ LUMINANCE_WEIGHTS))
    if not brightness > 0.0:
        raise MatchError(f"region '{region.name}' is black: a plate's regions must show some light")
    return rows, cols, distance


def _samples(plate: Plate, per_region: int, seed: int = 0) -> _Samples:
    pixels = _check_plate(plate)
    rng = np.random.default_rng(seed)
    surfaces = sorted({region.surface for region in plate.regions if not region.is_sky})
    parts = []
    for index, region in enumerate(plate.regions):
        rows, cols, distance = _region_pixels(plate, pixels, region)
        if rows.size > per_region:
            pick = np.sort(rng.choice(rows.size, per_region, replace=False))
            rows, cols, distance = rows[pick], cols[pick], distance[pick]
        values = pixels[rows, cols]
        scale = float(np.mean(values))
        weight = np.full(rows.size, 1.0 / (max(scale, 1e-30) * math.sqrt(3.0 * rows.size)))
        surface = -1 if region.is_sky else surfaces.index(region.surface)
        parts.append((rows, cols, distance, values, np.full(rows.size, index), np.full(rows.size, surface), weight))
    rows, cols, distance, values, region_index, surface_index, weight = (np.concatenate(p) for p in zip(*parts))
    return _Samples(plate.camera.directions(rows, cols), distance, values, region_index, surface_index, weight,
                    tuple(region.name for region in plate.regions), tuple(surfaces), rows, cols)


# ---------------------------------------------------------------------------------------------- the residual

def _surface_radiance(samples: _Samples, l_in: np.ndarray, f_ex: np.ndarray, k: float) -> np.ndarray:
    """L0 per surface (m, 3) that minimises the weighted residual for exposure factor k (closed form, >= 0)."""
    radiance = np.zeros((len(samples.surface_names), 3))
    w2 = samples.weight[:, None] ** 2
    for s in range(len(samples.surface_names)):
        on = samples.surface == s
        t = f_ex[on]
        numerator = np.sum(w2[on] * t * (samples.values[on] / k - l_in[on]), axis=0)
        denominator = np.sum(w2[on] * t * t, axis=0)
        radiance[s] = np.maximum(numerator / np.maximum(denominator, 1e-300), 0.0)
    return radiance


def _per_pixel_radiance(samples: _Samples, radiance: np.ndarray) -> np.ndarray:
    per_pixel = np.zeros((len(samples.surface), 3))
    on = samples.surface >= 0
    per_pixel[on] = radiance[samples.surface[on]]
    return per_pixel


class _Problem:
    """The weighted residual as a function of the free parameters (the rest held)."""

    def __init__(self, samples: _Samples, template: _Template, altitude_m: float):
        self.samples = samples
        self.template = template
        self.altitude_m = altitude_m
        self.evaluations = 0
        self._key: bytes | None = None
        self._terms: tuple[np.ndarray, np.ndarray] = (np.zeros((0, 3)), np.zeros((0, 3)))

    def terms(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(L_in, F_ex) of the samples; the exposure does not enter them, so a step in it alone reuses the last."""
        key = np.delete(y, _INDEX["exposure"]).tobytes()
        if key != self._key:
            self.evaluations += 1
            look = self.template.look(y)
            self._terms = atmosphere_terms(self.samples.directions, self.samples.distance, look.atmosphere,
                                           look.sun_elevation_deg, look.sun_azimuth_deg, self.altitude_m)
            self._key = key
        return self._terms

    def residual(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(weighted residual (3n,), L0 per surface) at fit coordinates ``y``."""
        l_in, f_ex = self.terms(y)
        k = 2.0 ** y[_INDEX["exposure"]]
        radiance = _surface_radiance(self.samples, l_in, f_ex, k)
        model = k * (_per_pixel_radiance(self.samples, radiance) * f_ex + l_in)
        return ((model - self.samples.values) * self.samples.weight[:, None]).ravel(), radiance

    def linear_cost(self, y: np.ndarray, exposure_known: bool) -> tuple[float, float]:
        """(cost, exposure in stops) with the exposure (unless known) and L0 solved linearly: the grid's measure."""
        l_in, f_ex = self.terms(y)
        s = self.samples
        w = s.weight[:, None]
        if exposure_known:
            k = 2.0 ** y[_INDEX["exposure"]]
        else:
            columns = [(w * l_in).ravel()]
            for surface in range(len(s.surface_names)):
                for channel in range(3):
                    column = np.zeros_like(f_ex)
                    on = s.surface == surface
                    column[on, channel] = f_ex[on, channel]
                    columns.append((w * column).ravel())
            solution = np.linalg.lstsq(np.stack(columns, axis=1), (w * s.values).ravel(), rcond=None)[0]
            k = float(solution[0])
            if not k > 0.0:
                return math.inf, 0.0
        radiance = _surface_radiance(s, l_in, f_ex, k)
        model = k * (_per_pixel_radiance(s, radiance) * f_ex + l_in)
        r = ((model - s.values) * w).ravel()
        return float(r @ r), math.log2(k)


# ---------------------------------------------------------------------------------------------- Levenberg-Marquardt

def levenberg_marquardt(residual: Callable[[np.ndarray], np.ndarray], x0: ArrayLike, *,
                        max_iterations: int = MAX_ITERATIONS, step: float = JACOBIAN_STEP,
                        progress: Callable[[int], None] | None = None) -> tuple[np.ndarray, float, int]:
    """Minimise |r(x)|^2 from ``x0`` (Marquardt 1963): the step solves (J^T J + lambda diag(J^T J)) dx = -J^T r, with
    J by forward differences (step ``step`` (1 + |x|)), lambda divided by 3 after a step that lowers the cost and
    multiplied by 4 until one does. Ends when a step lowers the cost by less than :data:`COST_TOLERANCE` of it, when
    no damping up to :data:`MAX_DAMPING` lowers it, or after ``max_iterations``. Returns (x, cost, iterations)."""
    x = np.array(x0, dtype=np.float64)
    r = residual(x)
    cost = float(r @ r)
    damping = 1e-3
    iteration = 0
    for iteration in range(1, max_iterations + 1):
        jacobian = _jacobian(residual, x, r, step)
        gradient = jacobian.T @ r
        normal = jacobian.T @ jacobian
        diagonal = np.maximum(np.diag(normal), 1e-12 * max(float(np.max(np.diag(normal))), 1e-300))
        improved = False
        while damping <= MAX_DAMPING:
            try:
                dx = np.linalg.solve(normal + damping * np.diag(diagonal), -gradient)
            except np.linalg.LinAlgError:
                damping *= 4.0
                continue
            x_new = x + dx
            r_new = residual(x_new)
            cost_new = float(r_new @ r_new)
            if np.isfinite(cost_new) and cost_new < cost:
                improved = True
                break
            damping *= 4.0
        if progress is not None:
            progress(iteration)
        if not improved:
            break
        decrease = cost - cost_new
        x, r, cost = x_new, r_new, cost_new
        damping = max(damping / 3.0, 1e-12)
        if decrease <= COST_TOLERANCE * max(cost, 1e-300):
            break
    return x, cost, iteration


def _jacobian(residual: Callable[[np.ndarray], np.ndarray], x: np.ndarray, r: np.ndarray, step: float) -> np.ndarray:
    jacobian = np.empty((r.size, x.size))
    for i in range(x.size):
        h = step * (1.0 + abs(x[i]))
        shifted = x.copy()
        shifted[i] += h
        jacobian[:, i] = (residual(shifted) - r) / h
    return jacobian


# ---------------------------------------------------------------------------------------------- the fit

@dataclass(frozen=True)
class RegionResidual:
    """How well the fit renders one region: the largest channel's error of the region's mean colour, and the pixels'
    root-mean-square residual, both relative to the region's mean brightness in the plate (mean over its pixels and
    channels; 0.01 = 1 %)."""

    name: str
    colour_error: float
    rms_error: float
    pixels: int


@dataclass(frozen=True)
class Fit:
    """A fit's outcome: the look, each surface's radiance L0 (plate units over 2^EV), the residual per region, the
    standard error of each parameter (its reported unit), the parameters the plate cannot tell and why (``held``:
    an atmosphere parameter there is held, at the start's value where the rest can make up for it; the sun and the
    exposure, which have no start value, stay in ``fitted`` and are only reported as uncertain), and its cost."""

    look: Look
    surface_radiance: dict[str, np.ndarray]
    regions: tuple[RegionResidual, ...]
    standard_errors: dict[str, float]
    fitted: tuple[str, ...]
    held: dict[str, str]
    at_bound: tuple[str, ...]
    cost: float
    evaluations: int
    seconds: float

    @property
    def worst_colour_error(self) -> float:
        return max(region.colour_error for region in self.regions)

    @property
    def misfit(self) -> str | None:
        """None when every region's mean colour is within :data:`MISFIT_COLOUR_ERROR` of the plate's; else a line
        that says which region the look does not reproduce and what to try."""
        worst = max(self.regions, key=lambda region: region.colour_error)
        if worst.colour_error <= MISFIT_COLOUR_ERROR:
            return None
        return (f"the fitted look does not reproduce region '{worst.name}' ({100.0 * worst.colour_error:.1f} % off): "
                "the plate's atmosphere differs from the start's in what the fit keeps (the planet, the air's scale "
                "height, the haze's absorption), or a region's distance is wrong; try another start preset")

    def reported(self) -> dict[str, str]:
        """Each parameter's value in words, with its standard error where fitted, e.g. 'visibility 41.2 km +- 3 %'."""
        look = self.look
        values = {
            "visibility": f"visibility {look.visibility_m / 1000.0:.3g} km",
            "haze_red": f"haze colour {', '.join(f'{c:.3f}' for c in look.haze_colour)} (Angstrom alpha "
                        f"{look.angstrom_exponent:.2f})",
            "mie_g": f"g {look.mie_g:.3f}",
            "air_density": f"air density {look.air_density:.3g}",
            "ozone": f"ozone {look.atmosphere.ozone_column_du:.0f} DU",
            "sun_elevation": f"sun elevation {look.sun_elevation_deg:.2f} deg",
            "sun_azimuth": f"sun azimuth {look.sun_azimuth_deg:.1f} deg",
            "exposure": f"exposure {look.exposure_ev:+.2f} stops",
            "haze_height": f"haze scale height {look.atmosphere.mie_scale_height:.0f} m",
        }
        lines = {}
        errors = dict(self.standard_errors)
        if "haze_blue" in errors:
            errors["haze_red"] = max(errors.get("haze_red", 0.0), errors["haze_blue"])
        for name, text in values.items():
            if name in self.held:
                text += f" ({'uncertain' if name in self.fitted else 'held'}: {self.held[name]})"
            elif name in errors and name in self.fitted:
                error = errors[name]
                parameter = PARAMETERS[_INDEX[name]]
                text += f" +- {100.0 * error:.2g} %" if parameter.unit == "relative" else (
                    f" +- {error:.2g} {parameter.unit}".rstrip())
            if name == "haze_red" and "haze_blue" in self.held and name not in self.held:
                text += f" (blue held: {self.held['haze_blue']})"
            lines[name] = text
        return lines


ProgressCallback = Callable[[float, str], None]


def fit(plate: Plate, start: Atmosphere, knowns: Knowns = Knowns(), *, samples_per_region: int = SAMPLES_PER_REGION,
        fit_ozone: bool | None = None, progress: ProgressCallback | None = None, seed: int = 0) -> Fit:
    """Fit the atmosphere, the sun (where not known) and the exposure (where not known) to ``plate``, starting from
    ``start`` (a preset's atmosphere: what is not fitted, the air's scale height, the planet, the sun above the
    atmosphere and the haze's absorption per unit scattering, is kept from it).

    ``fit_ozone`` None fits the ozone column only when the sun is within 10 deg of the horizon (the twilight colour
    that shows it); the covariance holds it anyway where the plate cannot tell it. Raises :class:`MatchError` for a
    plate it cannot use. ``progress(fraction, text)`` is called as it goes.
    """
    began = time.perf_counter()
    report = progress or (lambda fraction, text: None)
    report(0.0, "reading the marked regions")
    samples = _samples(plate, samples_per_region, seed)
    template = _Template.of(start)
    problem = _Problem(samples, template, plate.camera.altitude_m)
    y = template.start_y()
    free = np.ones(len(PARAMETERS), dtype=bool)
    if knowns.sun_elevation_deg is not None:
        if not (math.isfinite(knowns.sun_elevation_deg) and -90.0 <= knowns.sun_elevation_deg <= 90.0):
            raise MatchError(f"the sun elevation must lie in [-90, 90] degrees; got {knowns.sun_elevation_deg:g}")
        if knowns.sun_elevation_deg < MIN_SUN_ELEVATION_DEG:
            raise MatchError(f"sun elevation {knowns.sun_elevation_deg:g} deg: the fit needs the sun at least "
                             f"{MIN_SUN_ELEVATION_DEG:g} deg up (the Fast level's sky is black once it sets)")
        y[_INDEX["sun_elevation"]] = min(knowns.sun_elevation_deg, PARAMETERS[_INDEX["sun_elevation"]].upper)
        free[_INDEX["sun_elevation"]] = False
    if knowns.sun_azimuth_deg is not None:
        y[_INDEX["sun_azimuth"]] = float(knowns.sun_azimuth_deg)
        free[_INDEX["sun_azimuth"]] = False
    if knowns.exposure_ev is not None:
        y[_INDEX["exposure"]] = float(knowns.exposure_ev)
        free[_INDEX["exposure"]] = False
    start_y = y.copy()

    report(0.05, "searching the starting grid")
    starts = _grid_starts(problem, y, knowns, plate.camera.heading_deg)
    held: dict[str, str] = {}
    first = free.copy()
    first[_INDEX["ozone"]] = False
    first[_INDEX["haze_height"]] = False
    tried = []
    for number, point in enumerate(starts):
        report(0.1 + 0.03 * number, f"trying start {number + 1} of {len(starts)}")
        point = _solve(problem, point, first, lambda i: None, START_ITERATIONS)
        tried.append((float(np.sum(problem.residual(point)[0] ** 2)), number, point))
    y = min(tried)[2]
    if fit_ozone is None:
        fit_ozone = y[_INDEX["sun_elevation"]] < 10.0
    if not fit_ozone:
        free[_INDEX["ozone"]] = False
        held["ozone"] = f"kept at the start's {start.ozone_column_du:.0f} DU (the sun is too high for ozone to show)"

    rounds = 0
    while True:
        rounds += 1
        report(min(0.2 + 0.15 * (rounds - 1), 0.8), f"fitting {int(free.sum())} parameters (round {rounds})")
        y = _solve(problem, y, free, lambda i, r=rounds: report(min(0.2 + 0.15 * (r - 1) + 0.003 * i, 0.9),
                                                                f"fitting (round {r}, iteration {i})"))
        errors, correlation, bound = _uncertainty(problem, y, free)
        ratios = {name: errors[name] / PARAMETERS[_INDEX[name]].tolerance for name in errors
                  if name not in bound and name not in held}
        bound = [name for name in bound if name not in held]
        worst = bound[0] if bound else (max(ratios, key=ratios.get) if ratios else None)
        if worst is None or (not bound and ratios[worst] <= 1.0) or rounds > len(PARAMETERS):
            break
        partner = _partner(worst, correlation)
        index = _INDEX[worst]
        if worst in bound:
            reason = "it ran to the bound of its range"
        elif partner is not None:
            reason = (f"the plate cannot tell it from {PARAMETERS[_INDEX[partner[0]]].label} (correlation "
                      f"{partner[1]:+.2f})")
        else:
            reason = f"the plate does not constrain it (standard error {errors[worst]:.2g})"
        if worst in _NO_PRIOR:
            # No value to fall back on: it stays free (what else is held may move it) and is reported as uncertain.
            held[worst] = reason
            continue
        free[index] = False
        # The start's value where the rest can make up for it (the refit's cost within HOLD_COST_RATIO of the
        # free fit's); else the fitted value, which the rest of the fit was found with.
        cost = float(np.sum(problem.residual(y)[0] ** 2))
        trial = y.copy()
        trial[index] = start_y[index]
        trial = _solve(problem, trial, free, lambda i: None)
        if float(np.sum(problem.residual(trial)[0] ** 2)) <= HOLD_COST_RATIO * cost + 1e-12:
            y = trial
            held[worst] = f"{reason}; kept at the start's value"
        else:
            held[worst] = f"{reason}; kept at the fitted value"
    report(0.95, "measuring the residual per region")
    residual, radiance = problem.residual(y)
    look = template.look(y)
    regions = _region_residuals(plate, look, dict(zip(samples.surface_names, radiance)), seed)
    report(1.0, "done")
    return Fit(look=look, surface_radiance=dict(zip(samples.surface_names, radiance)), regions=regions,
               standard_errors=errors, fitted=tuple(p.name for p, f in zip(PARAMETERS, free) if f), held=held,
               at_bound=tuple(bound), cost=float(residual @ residual), evaluations=problem.evaluations,
               seconds=time.perf_counter() - began)


def fits_from_starts(plate: Plate, starts: dict[str, Atmosphere], knowns: Knowns = Knowns(), *,
                     samples_per_region: int = SAMPLES_PER_REGION, progress: ProgressCallback | None = None,
                     seed: int = 0) -> dict[str, Fit]:
    """:func:`fit` from each of ``starts`` (name: atmosphere, e.g. the built-in presets), by name."""
    if not starts:
        raise MatchError("no start atmosphere to fit from")
    report = progress or (lambda fraction, text: None)
    results = {}
    for number, (name, atm) in enumerate(starts.items()):
        def step(fraction: float, text: str, number=number, name=name) -> None:
            report((number + fraction) / len(starts), f"start {name}: {text}")
        results[name] = fit(plate, atm, knowns, samples_per_region=samples_per_region, progress=step, seed=seed)
    return results


def fit_best_start(plate: Plate, starts: dict[str, Atmosphere], knowns: Knowns = Knowns(), *,
                   samples_per_region: int = SAMPLES_PER_REGION, progress: ProgressCallback | None = None,
                   seed: int = 0) -> tuple[str, Fit]:
    """The name and the fit of the start with the lowest cost (:func:`fits_from_starts`: the same pixels and weights
    for every start, so their costs compare)."""
    results = fits_from_starts(plate, starts, knowns, samples_per_region=samples_per_region, progress=progress,
                               seed=seed)
    return min(results.items(), key=lambda pair: pair[1].cost)


def _grid_starts(problem: _Problem, y: np.ndarray, knowns: Knowns, heading_deg: float) -> list[np.ndarray]:
    """The best points of a coarse grid, exposure and L0 solved linearly at each: the unknown sun over
    :data:`GRID_SUN_ELEVATIONS_DEG` x :data:`GRID_SUN_AZIMUTHS_DEG` at the start's haze, then the haze's amount over
    :data:`GRID_VISIBILITIES_M` at the best suns; up to :data:`STARTS` points with the sun apart, best first."""
    elevations = ([y[_INDEX["sun_elevation"]]] if knowns.sun_elevation_deg is not None
                  else list(GRID_SUN_ELEVATIONS_DEG))
    azimuths = ([y[_INDEX["sun_azimuth"]]] if knowns.sun_azimuth_deg is not None
                else [heading_deg + a for a in GRID_SUN_AZIMUTHS_DEG])
    exposure_known = knowns.exposure_ev is not None

    def trial(base: np.ndarray, **values: float) -> tuple[float, np.ndarray]:
        point = base.copy()
        for name, value in values.items():
            point[_INDEX[name]] = value
        cost, exposure = problem.linear_cost(point, exposure_known)
        if not exposure_known:
            point[_INDEX["exposure"]] = exposure
        return cost, point

    suns = sorted((trial(y, sun_elevation=e, sun_azimuth=a) for e in elevations
                   for a in (azimuths if e < 89.0 else azimuths[:1])), key=lambda pair: pair[0])
    atm = problem.template.start
    rayleigh_550 = channel_value_at(VISIBILITY_WAVELENGTH_NM, atm.wavelengths_nm, atm.rayleigh_scattering)
    hazes = [math.log(max(KOSCHMIEDER_CONSTANT / v - rayleigh_550, 1e-7)) for v in GRID_VISIBILITIES_M]
    candidates = sorted(list(suns[:2 * STARTS]) + [trial(point, visibility=h) for _, point in suns[:2 * STARTS]
                                                   for h in hazes], key=lambda pair: pair[0])
    starts: list[np.ndarray] = []
    for _, point in candidates:
        if all(_sun_apart(point, other) for other in starts):
            starts.append(point)
        if len(starts) == STARTS:
            break
    return starts


def _sun_apart(a: np.ndarray, b: np.ndarray) -> bool:
    """True when two points' suns are more than 20 deg apart on the sky."""
    sun_a = sun_direction(a[_INDEX["sun_elevation"]], a[_INDEX["sun_azimuth"]])
    sun_b = sun_direction(b[_INDEX["sun_elevation"]], b[_INDEX["sun_azimuth"]])
    return float(sun_a @ sun_b) < math.cos(math.radians(20.0))


def _solve(problem: _Problem, y: np.ndarray, free: np.ndarray, progress: Callable[[int], None],
           max_iterations: int = MAX_ITERATIONS) -> np.ndarray:
    u = _to_u(y)

    def residual(u_free: np.ndarray) -> np.ndarray:
        full = u.copy()
        full[free] = u_free
        return problem.residual(_to_y(full))[0]

    u_free, _, _ = levenberg_marquardt(residual, u[free], progress=progress, max_iterations=max_iterations)
    u[free] = u_free
    return _to_y(u)


def _uncertainty(problem: _Problem, y: np.ndarray, free: np.ndarray
                 ) -> tuple[dict[str, float], dict[tuple[str, str], float], list[str]]:
    """Standard errors of the free parameters in their reported units, their correlations and those on a bound."""
    u = _to_u(y)
    names = [p.name for p, f in zip(PARAMETERS, free) if f]

    def residual(u_free: np.ndarray) -> np.ndarray:
        full = u.copy()
        full[free] = u_free
        return problem.residual(_to_y(full))[0]

    r = residual(u[free])
    jacobian = _jacobian(residual, u[free], r, JACOBIAN_STEP) / _dy_du(u)[free]
    # The weighted residual is a region's relative error over sqrt(3 n): each region counts as 3 x
    # EFFECTIVE_SAMPLES independent measurements of relative error sigma, however many pixels it has.
    sigma2 = max(float(np.mean((r * problem.samples.per_pixel_scale()) ** 2)), MODEL_NOISE_FLOOR ** 2)
    covariance = sigma2 / (3.0 * EFFECTIVE_SAMPLES) * _inverse_normal(jacobian)
    sd = np.sqrt(np.maximum(np.diag(covariance), 0.0))
    errors = {}
    for i, name in enumerate(names):
        error = float(sd[i])
        if name == "visibility":  # d ln V / d ln beta_haze = -beta_haze / beta_total
            atm = problem.template.atmosphere(y)
            error *= math.exp(y[_INDEX["visibility"]]) / extinction_550_per_m(atm)
        errors[name] = error
    correlation = {}
    for i, a in enumerate(names):
        for k, b in enumerate(names):
            if i < k and sd[i] > 0.0 and sd[k] > 0.0:
                correlation[(a, b)] = float(covariance[i, k] / (sd[i] * sd[k]))
    logistic = _logistic(u)
    bound = [p.name for p, f, s in zip(PARAMETERS, free, logistic)
             if f and _BOUNDED[_INDEX[p.name]] and (s < AT_BOUND or s > 1.0 - AT_BOUND)]
    return errors, correlation, bound


def _inverse_normal(jacobian: np.ndarray) -> np.ndarray:
    """(J^T J)^-1 with the columns scaled to unit length first and eigenvalues floored at 1e-14 of the largest: a
    direction the plate does not see gets a huge variance (a pseudo-inverse would give it none)."""
    norms = np.linalg.norm(jacobian, axis=0)
    scale = 1.0 / np.where(norms > 0.0, norms, 1e-300)
    values, vectors = np.linalg.eigh((jacobian * scale).T @ (jacobian * scale))
    values = np.maximum(values, 1e-14 * max(float(values.max()), 1e-300))
    return (vectors / values) @ vectors.T * np.outer(scale, scale)


def _partner(name: str, correlation: dict[tuple[str, str], float]) -> tuple[str, float] | None:
    pairs = [(b if a == name else a, c) for (a, b), c in correlation.items() if name in (a, b)]
    if not pairs:
        return None
    other, value = max(pairs, key=lambda pair: abs(pair[1]))
    return (other, value) if abs(value) >= TRADE_CORRELATION else None


def _region_residuals(plate: Plate, look: Look, radiance: dict[str, np.ndarray], seed: int
                      ) -> tuple[RegionResidual, ...]:
    samples = _samples(plate, REPORT_SAMPLES_PER_REGION, seed + 1)
    per_pixel = _per_pixel_radiance(samples, np.array([radiance[name] for name in samples.surface_names])
                                    if samples.surface_names else np.zeros((0, 3)))
    model = render_pixels(samples.directions, samples.distance, look, per_pixel, plate.camera.altitude_m)
    result = []
    for index, name in enumerate(samples.region_names):
        on = samples.region == index
        plate_mean = samples.values[on].mean(axis=0)
        brightness = max(float(plate_mean.mean()), 1e-30)
        colour = float(np.max(np.abs(model[on].mean(axis=0) - plate_mean)) / brightness)
        rms = float(np.sqrt(np.mean(((model[on] - samples.values[on]) / max(float(plate_mean.mean()), 1e-30)) ** 2)))
        result.append(RegionResidual(name, colour, rms, int(on.sum())))
    return tuple(result)


# ---------------------------------------------------------------------------------------------- whole images

def render_plate(plate: Plate, look: Look, surface_radiance: dict[str, np.ndarray]) -> np.ndarray:
    """The fitted look rendered at every marked pixel of the plate, (H, W, 3); NaN outside the regions."""
    height, width = plate.camera.height, plate.camera.width
    image = np.full((height, width, 3), np.nan)
    for region in plate.regions:
        mask = np.asarray(region.mask).astype(bool)
        if region.is_sky:
            distance = np.full(mask.shape, np.nan)
            radiance = np.zeros(3)
        else:
            distance = (np.full(mask.shape, float(region.distance_m)) if np.ndim(region.distance_m) == 0
                        else np.asarray(region.distance_m, dtype=np.float64))
            mask = mask & np.isfinite(distance) & (distance > 0.0)
            radiance = surface_radiance.get(region.surface, np.zeros(3))
        rows, cols = np.nonzero(mask)
        if rows.size == 0:
            continue
        image[rows, cols] = render_pixels(plate.camera.directions(rows, cols), distance[rows, cols], look,
                                          np.broadcast_to(radiance, (rows.size, 3)), plate.camera.altitude_m)
    return image


def comparison_image(plate: Plate, rendered: np.ndarray, max_width: int = 1536) -> np.ndarray:
    """Plate | Atmos | difference side by side, display-referred sRGB in [0, 1], (h, 3 w, 3), scaled so the three
    panels together are at most ``max_width`` pixels wide. The difference panel shows |Atmos - plate| x 4 over a
    dark grey; pixels outside the regions show the plate at half brightness in the Atmos panel."""
    pixels = np.asarray(plate.pixels, dtype=np.float64)[..., :3]
    step = max(1, math.ceil(3 * pixels.shape[1] / max_width))
    pixels, rendered = pixels[::step, ::step], rendered[::step, ::step]
    outside = np.isnan(rendered)
    atmos = np.where(outside, 0.5 * pixels, rendered)
    white = max(float(np.nanpercentile(pixels, 99.5)), 1e-30)
    difference = np.where(outside, 0.02 * white, 4.0 * np.abs(np.nan_to_num(rendered) - pixels))
    return np.concatenate([linear_to_srgb(panel / white) for panel in (pixels, atmos, difference)], axis=1)


def describe(fit_result: Fit) -> list[str]:
    """The fit in lines for a terminal or a report: the parameters, what was held and why, the residual per region."""
    lines = list(fit_result.reported().values())
    for region in fit_result.regions:
        lines.append(f"region '{region.name}': colour {100.0 * region.colour_error:.2f} % off, pixels "
                     f"{100.0 * region.rms_error:.2f} % rms ({region.pixels} px)")
    if fit_result.misfit:
        lines.append(f"warning: {fit_result.misfit}")
    return lines


__all__ = [
    "Fit", "Knowns", "Look", "MatchError", "PARAMETERS", "Parameter", "Plate", "PlateCamera", "Region",
    "RegionResidual", "atmosphere_terms", "comparison_image", "describe", "fit", "fit_best_start", "fits_from_starts",
    "levenberg_marquardt",
    "linear_to_srgb", "pitch_from_horizon", "render_pixels", "render_plate", "srgb_to_linear", "sun_direction",
]
