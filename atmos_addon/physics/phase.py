# SPDX-License-Identifier: GPL-3.0-or-later
"""Phase functions: the angular distribution of singly scattered light, normalised over the sphere (1/sr).

``mu = cos(theta)``, theta the angle between the view direction (from the camera, along the ray
toward the scene) and the direction to the sun: mu = 1 looks straight at the sun. Both functions
integrate to one over the sphere, 2 pi * integral over mu in [-1, 1] of Phi(mu) dmu = 1.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

#: Floor of the Henyey-Greenstein denominator base (1 + g^2 - 2 g mu); keeps |g| -> 1 at mu = +-1 finite.
HG_DENOMINATOR_FLOOR = 1.0e-12


def clamp_cosine(mu: ArrayLike, dtype: DTypeLike = np.float64) -> np.ndarray:
    """A cosine as an array of ``dtype`` clamped to [-1, 1] (rounding in dot products can leave it)."""
    dt = np.dtype(dtype).type
    return np.asarray(np.clip(np.asarray(mu, dtype=dt), dt(-1.0), dt(1.0)), dtype=dt)


def phase_rayleigh(mu: ArrayLike, dtype: DTypeLike = np.float64) -> np.ndarray:
    """Rayleigh phase function Phi_R = 3 / (16 pi) (1 + mu^2), 1/sr (Hoffman & Preetham 2002, eq. 17).

    Same shape as ``mu``; symmetric in forward and backward scattering.
    """
    dt = np.dtype(dtype).type
    mu = clamp_cosine(mu, dt)
    return dt(3.0 / (16.0 * np.pi)) * (dt(1.0) + mu * mu)


def hg_denominator_base(mu: np.ndarray, g: np.ndarray) -> np.ndarray:
    """The base 1 + g^2 - 2 g mu of the Henyey-Greenstein denominator, without cancellation.

    Rewritten as (1 - |g|)^2 + 2 |g| (1 - sign(g) mu): both terms are non-negative, so for |g| -> 1 at
    the lobe's peak (mu = sign(g)) the small result is not the difference of two numbers near 2 (which
    in float32 can round to zero or below). Clamped at :data:`HG_DENOMINATOR_FLOOR`.
    """
    dt = mu.dtype.type
    abs_g = np.abs(g)
    base = (dt(1.0) - abs_g) ** 2 + dt(2.0) * abs_g * (dt(1.0) - np.sign(g) * mu)
    return np.maximum(base, dt(HG_DENOMINATOR_FLOOR))


def phase_hg(mu: ArrayLike, g: ArrayLike, dtype: DTypeLike = np.float64) -> np.ndarray:
    """Henyey-Greenstein phase function, 1/sr (Henyey & Greenstein 1941; Hoffman & Preetham 2002, eq. 18).

        Phi_HG(mu, g) = (1 - g^2) / (4 pi (1 + g^2 - 2 g mu)^(3/2))

    with g > 0 scattering forward (the lobe points at the sun, peak at mu = 1), the convention of
    Blender's volume nodes. The paper's eq. 18 writes (1 - g)^2 in the numerator, which is not
    normalised (a slip), and uses the opposite sign of g (its negative g scatters forward).

    A scalar ``g`` gives the shape of ``mu`` (broadcast with ``g``); a per-channel ``g`` of shape (3,)
    adds a trailing axis of 3: ``mu`` of shape (...) gives (..., 3). ``-1 < g < 1``.
    """
    dt = np.dtype(dtype).type
    mu = clamp_cosine(mu, dt)
    g = np.asarray(g, dtype=dt)
    if np.any(np.abs(g) >= 1.0):
        raise ValueError(f"phase_hg: the anisotropy g must satisfy -1 < g < 1; got {g.tolist()}")
    if g.ndim >= 1:
        mu = mu[..., np.newaxis]
    one_minus_g2 = (dt(1.0) - g) * (dt(1.0) + g)
    base = hg_denominator_base(mu, g)
    return one_minus_g2 / (dt(4.0 * np.pi) * base * np.sqrt(base))
