# SPDX-License-Identifier: GPL-3.0-or-later
"""Silhouettes: no outline where a hazed surface meets the sky or another surface.

The composite's equations (``nodes.composite``) evaluated in numpy on pixels made by hand, and the renders of a
scene built from scratch (``silhouette_scenes``: a ridge 20 km away against the sky, a plane 200 m away over it)
against the same render with the atmosphere applied at every sample, in both engines and both AOV modes.
"""

from __future__ import annotations

import numpy as np
import pytest

import render_utils as ru
import silhouette_scenes as ss
from atmos_addon.node_groups import composite
from atmos_addon.node_groups.graph import ArrayBuilder

# -- the equations on pixels made by hand ------------------------------------------------------------------------

RNG = np.random.default_rng(7)
#: Two surfaces and the sky: transmittance, in-scattering and radiance per surface (RGB).
T_NEAR, T_FAR = np.array([0.97, 0.95, 0.92]), np.array([0.46, 0.33, 0.17])
L_NEAR, L_FAR = np.array([0.01, 0.02, 0.04]), np.array([0.18, 0.24, 0.35])
I_NEAR, I_FAR, SKY = np.array([0.2, 0.5, 0.8]), np.array([0.6, 0.4, 0.3]), np.array([0.3, 0.45, 0.7])


def _pixels(near: np.ndarray, far: np.ndarray) -> dict:
    """The passes of pixels covering ``near`` and ``far`` of the two surfaces (the rest is sky), (H, W) shares."""
    cover = near + far
    colour = lambda a, b: near[..., None] * a + far[..., None] * b   # noqa: E731
    sky = (1.0 - cover)[..., None] * SKY
    return {"image": colour(I_NEAR, I_FAR) + sky, "environment": sky, "coverage": cover,
            "transmittance": colour(T_NEAR, T_FAR), "squared": colour(T_NEAR ** 2, T_FAR ** 2),
            "cubed": colour(T_NEAR ** 3, T_FAR ** 3), "inscattering": colour(L_NEAR, L_FAR),
            "exact": colour(I_NEAR * T_NEAR + L_NEAR, I_FAR * T_FAR + L_FAR) + sky}


def _composite(passes: dict, *, film_transparent: float = 0.0, alpha=None, moments: bool = True) -> np.ndarray:
    """The Compositor mode's group (:func:`composite.build_composite_group`'s equations) in numpy."""
    g = ArrayBuilder({}, {})
    channels = lambda a: tuple(np.asarray(a[..., c], np.float32) for c in range(3))   # noqa: E731
    coverage = np.asarray(passes["coverage"], np.float32)
    transmittance = channels(passes["transmittance"])
    sky, surfaces = composite.shown_sky(g, channels(passes["image"]), channels(passes["environment"]),
                                        np.float32(film_transparent))
    zero = tuple(np.zeros_like(coverage) for _ in range(3))
    share_lo, share_hi, t_lo, t_hi = composite.two_point(
        g, coverage, transmittance, channels(passes["squared"]) if moments else zero,
        channels(passes["cubed"]) if moments else zero)
    slope = composite.neighbour_slope(g, surfaces, coverage, transmittance, t_lo, t_hi, share_lo, share_hi)
    out = composite.combine(g, sky=sky, surfaces=surfaces, alpha=np.float32(1.0) if alpha is None else alpha,
                            coverage=coverage, transmittance=transmittance,
                            inscattering=channels(passes["inscattering"]),
                            correction_term=composite.correction(g, coverage, share_lo, share_hi, t_lo, t_hi, slope))
    return g.array(out)


def test_a_surface_against_the_sky_is_exact_at_every_coverage():
    near = np.zeros((5, 5))
    far = RNG.uniform(0.0, 1.0, (5, 5))
    passes = _pixels(near, far)
    np.testing.assert_allclose(_composite(passes), passes["exact"], rtol=2e-5, atol=1e-6)


def test_two_surfaces_in_a_pixel_are_told_apart_by_their_moments_and_neighbours():
    """Pixels that mix the near and the far surface in shares changing across them (an edge): the two
    transmittances come from the moments, the two radiances from the 3 x 3 pixels around; within half a percent
    (the spread the reconstruction gives up to half floats' rounding, ``composite.MOMENT_ROUNDING``)."""
    column = np.linspace(0.0, 1.0, 7)
    near = np.broadcast_to(column, (5, 7)).copy()
    passes = _pixels(near, 1.0 - near)
    out = _composite(passes)
    plain = passes["image"] * passes["transmittance"] + passes["inscattering"]   # the product of the averages
    inside = (slice(1, -1), slice(1, -1))
    assert np.max(np.abs(plain - passes["exact"])[inside]) > 0.02   # what an outline is made of
    np.testing.assert_allclose(out[inside], passes["exact"][inside], rtol=5e-3, atol=1e-5)


def test_film_transparent_composites_the_surfaces_alone():
    """With Film > Transparent the image holds no sky (premultiplied surfaces) while the Environment pass does."""
    near = np.zeros((4, 4))
    far = RNG.uniform(0.0, 1.0, (4, 4))
    passes = _pixels(near, far)
    sky = passes["environment"]
    passes_transparent = dict(passes, image=passes["image"] - sky)
    np.testing.assert_allclose(_composite(passes_transparent, film_transparent=1.0), passes["exact"] - sky,
                               rtol=2e-5, atol=1e-6)


def test_a_holdouts_hole_stays_a_hole_and_a_pixel_nothing_managed_wrote_passes_through():
    near, far = np.zeros((3, 3)), np.ones((3, 3))
    passes = _pixels(near, far)
    hole = dict(passes, image=np.zeros_like(passes["image"]), environment=np.zeros_like(passes["image"]))
    np.testing.assert_array_equal(_composite(hole, alpha=np.zeros((3, 3), np.float32)), 0.0)
    unmanaged = dict(passes, coverage=np.zeros((3, 3)), transmittance=np.zeros((3, 3, 3)),
                     squared=np.zeros((3, 3, 3)), cubed=np.zeros((3, 3, 3)), inscattering=np.zeros((3, 3, 3)))
    np.testing.assert_allclose(_composite(unmanaged), passes["image"], rtol=1e-6)


def test_without_the_moments_a_pixel_of_two_surfaces_gets_the_average():
    """A group node whose moments are not fed (0): one value per pixel, no correction, the product of averages."""
    near = np.broadcast_to(np.linspace(0.0, 1.0, 5), (3, 5)).copy()
    passes = _pixels(near, 1.0 - near)
    expected = passes["image"] * passes["transmittance"] + passes["inscattering"]
    np.testing.assert_allclose(_composite(passes, moments=False), expected, rtol=1e-5, atol=1e-6)


def test_the_two_point_reconstruction_reads_one_value_where_the_moments_hold_one():
    g = ArrayBuilder({}, {})
    value = np.float32(0.37)
    coverage = np.float32(0.8)
    share_lo, share_hi, lo, hi = composite.two_point(g, coverage, coverage * value, coverage * value ** 2,
                                                     coverage * value ** 3)
    assert share_hi == 0.0 and share_lo == 1.0 and lo == pytest.approx(value) and hi == pytest.approx(value)
    # Eevee's half floats: the square and cube rounded to 11 bits still read as one value
    rounded = [np.float32(np.float16(x)) for x in (coverage * value, coverage * value ** 2, coverage * value ** 3)]
    share_lo, share_hi, lo, hi = composite.two_point(g, coverage, *rounded)
    assert share_hi == 0.0 and lo == pytest.approx(value, rel=2e-3)


# -- the renders ----------------------------------------------------------------------------------------------

WIDTH, HEIGHT = 48, 24
SAMPLES = {"CYCLES": 32, ru.EEVEE_ENGINE: 16}
#: The near plane over the far one: the mean edge error at most this (the issue's bound; measured 2.3-2.5 %), and
#: inside the frame the largest at most this (measured 2.3-2.4 %; the frame's own pixels, whose neighbourhood it
#: cuts, reach 20 %).
NEAR_FAR_MEAN, NEAR_FAR_MAX_INSIDE = 0.05, 0.04
#: The ridge against the sky: exact to the render's own noise and the shader's float32 (measured: mean 0.01 % /
#: 0.09-0.11 %, max 0.06 % / 0.23-0.62 %, Cycles / Eevee, whose passes are half floats; Eevee's largest on 5.3).
RIDGE_MEAN, RIDGE_MAX = 0.003, 0.01


@pytest.fixture(scope="module", params=[(engine, mode) for engine in ru.ENGINES
                                        for mode in ("PER_PIXEL", "COMPOSITOR")],
                ids=lambda param: f"{param[0]}-{param[1]}")
def rendered(request):
    engine, mode = request.param
    scene = ss.build(engine, mode, WIDTH, HEIGHT, SAMPLES[engine])
    yield engine, mode, ss.images(scene)
    import atmos_addon

    atmos_addon.unregister()


def test_a_ridge_against_the_sky_has_no_outline(rendered):
    engine, mode, result = rendered
    errors = ss.errors(result, ss.edge_pixels("ridge", result))
    assert errors.size > 40
    assert errors.mean() < RIDGE_MEAN and errors.max() < RIDGE_MAX, (engine, mode, errors.mean(), errors.max())


def test_a_near_surface_over_a_far_one_is_within_the_bound(rendered):
    engine, mode, result = rendered
    edge = ss.edge_pixels("near/far", result)
    errors = ss.errors(result, edge)
    inside = ss.errors(result, ss.inside_frame(edge))
    assert errors.size > 15 and inside.size > 10
    assert errors.mean() < NEAR_FAR_MEAN and inside.max() < NEAR_FAR_MAX_INSIDE, (
        engine, mode, errors.mean(), inside.max())


def test_the_interior_is_the_per_sample_result(rendered):
    engine, mode, result = rendered
    errors = ss.errors(result, ss.interior_pixels(result))
    assert errors.size > 200 and errors.max() < 0.005, (engine, mode, errors.max())


@pytest.mark.parametrize("mode", ("PER_PIXEL", "COMPOSITOR"))
def test_a_held_out_objects_edge_has_no_outline(mode):
    """The near plane held out by its collection after the enable (the depsgraph handler marks it): the far plane's
    edge against the hole is exact like the ridge against the sky (unmarked: 5.5 % mean, 59 % max)."""
    scene = ss.build("CYCLES", mode, WIDTH, HEIGHT, SAMPLES["CYCLES"])   # registers Atmos afresh, as the fixture does
    ss.hold_out(scene, "Near")
    result = ss.images(scene)
    errors = ss.errors(result, ss.edge_pixels("ridge", result))
    assert errors.size > 100
    assert errors.mean() < RIDGE_MEAN and errors.max() < RIDGE_MAX, (mode, errors.mean(), errors.max())
