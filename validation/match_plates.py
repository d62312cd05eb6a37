# SPDX-License-Identifier: GPL-3.0-or-later
"""Plates the fit's own model makes, for Match Plate's round trips (``tests/physics/test_match.py``,
``tools/measure_match.py``, ``docs/match.md``): a look rendered at every marked pixel with noise, the sRGB transfer and
8-bit quantisation, and random looks within the Earth presets' ranges. Not shipped: the add-on fits plates, it does not
make them."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike

from atmos_addon.physics import match
from atmos_addon.physics.atmosphere import Atmosphere
from atmos_addon.physics.sky import dome_distance_approx, sky_radiance
from atmos_addon.physics.spectrum import channel_value_at
from atmos_addon.physics.sun import sun_irradiance_ground
from atmos_addon.physics.visibility import (KOSCHMIEDER_CONSTANT, VISIBILITY_WAVELENGTH_NM, haze_absorption_ratio,
                                            haze_for_extinction, relative_air_density)



def synthetic_plate(look: match.Look, camera: match.PlateCamera,
                    regions: Sequence[tuple[str, np.ndarray, float | np.ndarray | None]], surface_radiance: ArrayLike,
                    *, noise: float = 0.0, srgb: bool = False, seed: int = 0, bits: int = 8) -> match.Plate:
    """A plate the model itself makes: ``regions`` as (name, mask, distance m or None for sky), one surface radiance
    L0 for every surface, relative Gaussian noise ``noise`` per pixel and channel, and with ``srgb`` the sRGB transfer
    and ``bits``-bit quantisation (the pixels then come back decoded to linear, clip level 1). Pixels outside every
    region are mid grey."""
    rng = np.random.default_rng(seed)
    image = np.full((camera.height, camera.width, 3), 0.18)
    plate_regions = []
    for name, mask, distance in regions:
        region = match.Region(name, np.asarray(mask, dtype=bool), distance)
        plate_regions.append(region)
    plate = match.Plate(image, camera, tuple(plate_regions))
    radiance = np.asarray(surface_radiance, dtype=np.float64)
    rendered = match.render_plate(plate, look, {"ground": radiance})
    inside = ~np.isnan(rendered)
    image = np.where(inside, rendered, image)
    if noise > 0.0:
        image = image * (1.0 + noise * rng.standard_normal(image.shape))
    if not srgb:
        return replace(plate, pixels=image)
    levels = 2 ** bits - 1
    encoded = np.round(match.linear_to_srgb(image) * levels) / levels
    return replace(plate, pixels=match.srgb_to_linear(encoded), clip_level=1.0)


#: The ranges the round trip draws from: the built-in Earth presets' span (clear, overcast, sunset).
ROUND_TRIP_VISIBILITY_M = (10_000.0, 70_000.0)
ROUND_TRIP_ANGSTROM = (0.0, 1.3)
ROUND_TRIP_G = (0.6, 0.8)
ROUND_TRIP_SUN_ELEVATION_DEG = (2.0, 60.0)
ROUND_TRIP_AIR_DENSITY = (1.0, 1.0)
ROUND_TRIP_DISTANCES_M = (2_000.0, 20_000.0)


def round_trip_case(seed: int, start: Atmosphere, *, width: int = 192, height: int = 108, noise: float = 0.01
                    ) -> tuple[match.Plate, match.Look, np.ndarray]:
    """A plate of a random look within the Earth presets' ranges (:data:`ROUND_TRIP_VISIBILITY_M` and the rest; the
    haze's absorption and scale height and the ozone are ``start``'s): sky above the horizon and the same sunlit ground
    (a random albedo) at two distances below it, 1 % noise, an exposure that puts the brightest pixels near 0.6, the
    sRGB transfer and 8 bits. Returns (plate, the true look, the ground's true radiance L0)."""
    rng = np.random.default_rng(seed)
    wavelengths = start.wavelengths_nm
    start_density = relative_air_density(wavelengths, start.rayleigh_scattering)
    alpha = rng.uniform(*ROUND_TRIP_ANGSTROM)
    shape = (np.asarray(wavelengths) / VISIBILITY_WAVELENGTH_NM) ** -alpha
    density = rng.uniform(*ROUND_TRIP_AIR_DENSITY)
    rayleigh = np.asarray(start.rayleigh_scattering) * density / start_density
    visibility = math.exp(rng.uniform(*np.log(ROUND_TRIP_VISIBILITY_M)))
    rayleigh_550 = channel_value_at(VISIBILITY_WAVELENGTH_NM, wavelengths, rayleigh)
    scattering, absorption = haze_for_extinction(KOSCHMIEDER_CONSTANT / visibility - rayleigh_550, wavelengths, shape,
                                                 haze_absorption_ratio(start.mie_scattering, start.mie_absorption))
    atm = start.replace(rayleigh_scattering=rayleigh, mie_scattering=scattering, mie_absorption=absorption,
                        mie_g=rng.uniform(*ROUND_TRIP_G))
    heading = rng.uniform(0.0, 360.0)
    look = match.Look(atm, rng.uniform(*ROUND_TRIP_SUN_ELEVATION_DEG), heading + rng.uniform(-150.0, 150.0), 0.0)
    camera = match.PlateCamera(width, height, rng.uniform(40.0, 70.0), pitch_deg=rng.uniform(-1.0, 4.0),
                               heading_deg=heading)
    rows = np.arange(height)[:, None] * np.ones((1, width))
    horizon = height * 0.55
    masks = [("sky", rows < horizon - 0.08 * height, None),
             ("far ground", (rows >= horizon + 0.02 * height) & (rows < horizon + 0.12 * height),
              ROUND_TRIP_DISTANCES_M[1]),
             ("near ground", rows >= horizon + 0.2 * height, ROUND_TRIP_DISTANCES_M[0])]
    # The ground lit as a level Lambertian surface of a random albedo: the sun's E_sun sin(e) and the sky, taken as
    # uniform at its zenith radiance (pi L_zenith of irradiance), over pi.
    e_sun = sun_irradiance_ground(math.radians(look.sun_elevation_deg), atm)
    zenith = sky_radiance(np.array([0.0, 0.0, 1.0]), match.sun_direction(look.sun_elevation_deg, look.sun_azimuth_deg),
                          atm, e_sun, dome=dome_distance_approx)
    radiance = rng.uniform(0.05, 0.3, 3) * (e_sun * math.sin(math.radians(look.sun_elevation_deg)) / math.pi + zenith)
    probe = synthetic_plate(look, camera, masks, radiance)
    marked = np.any([mask for _, mask, _ in masks], axis=0)
    exposure = math.log2(0.6 / float(np.percentile(probe.pixels[marked], 99.5)))
    look = replace(look, exposure_ev=exposure)
    return (synthetic_plate(look, camera, masks, radiance, noise=noise, srgb=True, seed=seed + 1000), look,
            radiance)
