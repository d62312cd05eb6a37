# SPDX-License-Identifier: GPL-3.0-or-later
"""Physics core of Atmos (numpy only, no ``bpy``).

Atmosphere model, phase functions, aerial perspective (Hoffman & Preetham 2002, eq. 19), Chapman optical
depths, ground sunlight and the virtual-dome sky (``sky``). The brute-force references that check them live in
the top-level ``validation`` package, which the extension does not ship.
"""

from . import sky
from .aerial_perspective import (SMALL_OPTICAL_DEPTH, aerial_perspective, extinction, inscattering,
                                 one_minus_exp_over_x)
from .atmosphere import Atmosphere
from .optical_depth import chapman, optical_depth_to_space, relative_air_mass
from .phase import phase_hg, phase_rayleigh
from .rayleigh import rayleigh_coefficients
from .sun import sun_color_and_strength, sun_irradiance_ground

__all__ = [
    "Atmosphere",
    "SMALL_OPTICAL_DEPTH",
    "aerial_perspective",
    "chapman",
    "extinction",
    "inscattering",
    "one_minus_exp_over_x",
    "optical_depth_to_space",
    "phase_hg",
    "phase_rayleigh",
    "rayleigh_coefficients",
    "sky",
    "relative_air_mass",
    "sun_color_and_strength",
    "sun_irradiance_ground",
]
