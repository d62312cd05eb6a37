# SPDX-License-Identifier: GPL-3.0-or-later
"""Phase functions: normalisation, orientation of the Mie lobe, shapes and extreme anisotropy."""

import numpy as np
import pytest

from atmos_addon.physics import Atmosphere, inscattering, phase_hg, phase_rayleigh

#: numpy 2.0 renamed trapz to trapezoid; numpy 2.5 (beside bpy 5.3) has no trapz. Blender 4.2-5.0 use numpy 1.26.
_trapezoid = np.trapezoid if hasattr(np, "trapezoid") else np.trapz


def _sphere_integral(phase, n=20001):
    """2 pi * integral of phase(mu) over [-1, 1], on meshes graded geometrically toward mu = +-1."""
    gap = np.concatenate([[0.0], np.geomspace(1e-14, 1.0, n)])  # distance from the pole, 0..1
    total = 0.0
    for pole in (1.0, -1.0):
        mu = pole * (1.0 - gap)
        total += _trapezoid(phase(mu), gap)
    return 2.0 * np.pi * total


def test_rayleigh_is_normalised_and_symmetric():
    assert _sphere_integral(phase_rayleigh) == pytest.approx(1.0, rel=1e-6)
    assert phase_rayleigh(0.3) == pytest.approx(phase_rayleigh(-0.3))
    assert phase_rayleigh(1.0) == pytest.approx(2.0 * phase_rayleigh(0.0))


@pytest.mark.parametrize("g", [-0.99, -0.9, -0.5, 0.0, 0.3, 0.76, 0.9, 0.99])
def test_henyey_greenstein_is_normalised(g):
    assert _sphere_integral(lambda mu: phase_hg(mu, g)) == pytest.approx(1.0, rel=1e-4)


def test_positive_g_points_the_lobe_at_the_sun():
    mu = np.linspace(-1.0, 1.0, 2001)
    assert np.argmax(phase_hg(mu, 0.76)) == mu.size - 1
    assert np.argmax(phase_hg(mu, -0.76)) == 0
    # The paper's eq. 19 in-scattering with the default haze is brightest looking at the sun.
    l_in = inscattering(5000.0, mu, Atmosphere(), [1.0, 1.0, 1.0])
    assert np.all(np.argmax(l_in, axis=0) == mu.size - 1)


def test_per_channel_g_adds_a_trailing_axis():
    mu = np.linspace(-1.0, 1.0, 7).reshape(7, 1) * np.ones((1, 5))
    g = np.array([0.1, 0.5, 0.9])
    values = phase_hg(mu, g)
    assert values.shape == (7, 5, 3)
    np.testing.assert_allclose(values[..., 2], phase_hg(mu, 0.9))
    assert phase_hg(mu, 0.5).shape == (7, 5)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_extreme_anisotropy_stays_finite_and_exact_at_the_peak(dtype):
    for g in (0.999, -0.999):
        values = phase_hg(np.array([-1.0, 0.0, 1.0]), g, dtype)
        assert values.dtype == dtype and np.all(np.isfinite(values)) and np.all(values > 0)
        peak = (1.0 + abs(g)) / (4.0 * np.pi * (1.0 - abs(g)) ** 2)
        assert values[2 if g > 0 else 0] == pytest.approx(peak, rel=1e-3 if dtype == np.float32 else 1e-9)


def test_g_of_one_is_rejected():
    with pytest.raises(ValueError, match="g"):
        phase_hg(0.0, 1.0)
