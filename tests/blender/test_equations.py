# SPDX-License-Identifier: GPL-3.0-or-later
"""One source per equation: the very functions that build the node groups, run on the numpy backend of the graph
builder (:class:`atmos_addon.node_groups.graph.ArrayBuilder`), give the physics core's values on thousands of rays.

The renders' side of the proof is in ``test_node_groups.py``: every parity render there also equals this
evaluation of its group. Together: what a group renders is what its builder computes, and that is the core.
No renders here; each level is checked on every preset's atmosphere and every feature set.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from atmos_addon import presets
from atmos_addon.node_groups import aerial_perspective, parameters, sky
from atmos_addon.node_groups.graph import ArrayBuilder
from atmos_addon.node_groups.precise import IMAGE_NAME
from atmos_addon.node_groups.sky import SkyFeatures
from atmos_addon.node_groups.terms import AerialFeatures
from atmos_addon.physics import Atmosphere, sun_irradiance_ground
from atmos_addon.physics.sky import (aerial_distance_clamped, dome_distance_approx, elevation_of, extinction_layered,
                                     inscattering_layered, sky_radiance)

ATMOSPHERES = {name: presets.load(name).atmosphere for name in presets.BUILTIN_NAMES}
FEATURE_SETS = [AerialFeatures(mie, absorption) for mie in (False, True) for absorption in (False, True)]
#: Tolerated relative error of the builder's float32 evaluation against the float64 core, per level. Measured on
#: these rays (bpy 5.2.3, numpy 2): Fast F_ex 2e-6, L_in 8e-6 beyond the first metres, where 1 - T rounds (the
#: graph keeps an absolute error of about 6e-8 E_sun Phi there, ``terms.scattering_terms``).
RELATIVE_TOLERANCE = {"fast": 5.0e-5, "precise": 5.0e-5}
#: The absolute part of the in-scattering's tolerance, times E_sun (1 - T rounds to 6e-8 in float32).
ABSOLUTE_TOLERANCE_PER_E_SUN = 2.0e-6
#: Below float32's smallest normal number a transmittance flushes to 0 (overcast's longest rays: 1e-40).
FLOAT32_SMALLEST_NORMAL = float(np.finfo(np.float32).tiny)


def rays(count: int, seed: int = 7) -> tuple[np.ndarray, np.ndarray]:
    """Unit directions over the whole sphere and distances from 1 m to 1000 km (log-uniform)."""
    rng = np.random.default_rng(seed)
    directions = rng.normal(size=(count, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    return directions, 10.0 ** rng.uniform(0.0, 6.0, count)


def with_features(atm: Atmosphere, features: AerialFeatures) -> Atmosphere:
    """The atmosphere a group built without some terms describes: those terms are 0."""
    return atm.replace(mie_scattering=atm.mie_scattering if features.mie else 0.0,
                       mie_absorption=atm.mie_absorption if features.absorption else 0.0)


def values(atm: Atmosphere, sun, e_sun, *, metres_per_unit: float = 1.0) -> dict:
    """The parameters as the add-on writes them for ``atm`` and the sun (``parameters.shader_parameter_values``)."""
    return parameters.shader_parameter_values(
        beta_rayleigh=atm.rayleigh_scattering, beta_mie=atm.mie_scattering, beta_mie_absorption=atm.mie_absorption,
        mie_g=atm.mie_g, sun_direction=sun, sun_irradiance=e_sun, metres_per_unit=metres_per_unit,
        planet_radius=atm.planet_radius, rayleigh_scale_height=atm.rayleigh_scale_height,
        mie_scale_height=atm.mie_scale_height)


def assert_close(got: np.ndarray, want: np.ndarray, e_sun, what: str, absolute: bool = False,
                 level: str = "fast") -> float:
    """``got`` within the level's :data:`RELATIVE_TOLERANCE` of ``want`` (plus the absolute floor for
    in-scattering, and float32's smallest normal number); the worst relative error."""
    assert got.shape == want.shape and np.all(np.isfinite(got)), what
    floor = (ABSOLUTE_TOLERANCE_PER_E_SUN * np.asarray(e_sun) if absolute else 0.0) + FLOAT32_SMALLEST_NORMAL
    excess = np.abs(got - want) - (RELATIVE_TOLERANCE[level] * np.abs(want) + floor)
    assert excess.max() <= 0.0, (f"{what}: worst |got - want| beyond tolerance by {excess.max():.2e} at ray "
                                 f"{np.unravel_index(excess.argmax(), excess.shape)}")
    return float((np.abs(got - want) / np.maximum(np.abs(want), 1e-30)).max())


@pytest.mark.parametrize("name", sorted(ATMOSPHERES))
@pytest.mark.parametrize("features", FEATURE_SETS, ids=lambda f: f.key)
def test_the_fast_group_evaluates_the_cores_layered_dome(name, features):
    atm = with_features(ATMOSPHERES[name], features)
    directions, distances = rays(4000)
    for elevation in (30.0, 3.0, -2.0):
        sun = np.array([0.0, math.cos(math.radians(elevation)), math.sin(math.radians(elevation))])
        e_sun = sun_irradiance_ground(math.radians(max(elevation, 0.0)), atm)
        for metres_per_unit in (1.0, 25.0):
            f_ex, l_in = aerial_perspective.evaluate(features, values(atm, sun, e_sun, metres_per_unit=metres_per_unit),
                                                     distance_units=distances / metres_per_unit,
                                                     view_direction=directions)
            s_r, s_m = aerial_distance_clamped(distances, elevation_of(directions), atm,
                                               dome=lambda e, a, h: dome_distance_approx(e, a, h, np.float32))
            label = f"{name} {features.key} sun {elevation} deg {metres_per_unit} m/unit"
            assert_close(f_ex, extinction_layered(s_r, s_m, atm), e_sun, f"F_ex {label}")
            assert_close(l_in, inscattering_layered(s_r, s_m, directions @ sun, atm, e_sun), e_sun, f"L_in {label}",
                         absolute=True)


def test_the_precise_group_samples_the_table_as_the_core_does(addon):
    """The Precise graph's texel fetches, on the image the add-on packs, are ``physics.precise.evaluate``."""
    import bpy

    from atmos_addon.blender.apply import precise_tables
    from atmos_addon.physics.precise import bake_tile, evaluate

    atm = ATMOSPHERES["clear"]
    directions, distances = rays(3000, seed=5)
    for camera_altitude, elevation in ((2.0, 20.0), (1800.0, 2.0)):
        sun = np.array([0.0, math.cos(math.radians(elevation)), math.sin(math.radians(elevation))])
        e_sun = sun_irradiance_ground(math.radians(elevation), atm)
        tile = bake_tile(atm, camera_altitude, math.radians(elevation))
        image = precise_tables.write_tiles([tile])
        pixels = np.empty(image.size[0] * image.size[1] * 4, dtype=np.float32)
        image.pixels.foreach_get(pixels)
        table = values(atm, sun, e_sun)
        table.update({parameters.PRECISE_TILE: (0.0, 0.0, camera_altitude),
                      parameters.PRECISE_SCALE: (tile.max_distance_m, atm.atmosphere_height, 0.0),
                      parameters.PRECISE_ATLAS: (float(image.size[0]), float(image.size[1]), 1.0)})
        assert tile.vertical_columns   # a still camera's tile: each row's columns from its vertical ray
        for features in (AerialFeatures(level="precise"), AerialFeatures(mie=False, level="precise")):
            f_ex, l_in = aerial_perspective.evaluate(
                features, table, distance_units=distances, view_direction=directions,
                images={IMAGE_NAME: pixels.reshape(image.size[1], image.size[0], 4)})
            # The table holds A_M all the same: a graph without Mie leaves that block out.
            core_tile = tile if features.mie else dataclasses.replace(tile, a_mie=np.zeros_like(tile.a_mie))
            want_f, want_l = evaluate(core_tile, directions, sun, distances, atm, np.float64)
            label = f"camera {camera_altitude} m sun {elevation} deg {features.key}"
            assert_close(f_ex, want_f, e_sun, f"F_ex {label}")
            assert_close(l_in, want_l, e_sun, f"L_in {label}", absolute=True)
    assert bpy.data.images.get(IMAGE_NAME) is not None


@pytest.mark.parametrize("keys", [((2.0, 8.0), (150.0, 6.0), (400.0, 5.0)), ((30.0, 8.0), (30.0, 6.0), (30.0, 5.0))],
                         ids=["camera and sun", "sun alone"])
def test_the_blending_precise_group_samples_two_key_tiles_as_the_core_blends_them(addon, keys):
    """An animated camera or sun: the graph built with ``blend`` reads the frame's key tile and the next one, a tile
    height up in the image, and blends every texel by the weight in ``atmos_precise_scale``; that is sampling
    ``physics.precise.blend_tiles`` (the camera's own altitude mapping the rows). A camera whose altitude moves has
    key tiles whose columns all start at the camera (``atmos_precise_atlas``'s z 0); under a sun alone they start at
    each row's vertical ray (z 1), as a still scene's."""
    from atmos_addon.blender.apply import precise_tables
    from atmos_addon.physics.precise import bake_tile, blend_tiles, evaluate, shared_max_distance

    atm = ATMOSPHERES["clear"]
    directions, distances = rays(3000, seed=7)
    d_max = shared_max_distance([h for h, _ in keys], atm)
    vertical = len({h for h, _ in keys}) == 1
    tiles = [bake_tile(atm, h, math.radians(e), max_distance_m=d_max, vertical_columns=vertical) for h, e in keys]
    image = precise_tables.write_tiles(tiles)
    pixels = np.empty(image.size[0] * image.size[1] * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    for segment, weight, fraction in ((0, 0.3, 0.3), (1, 0.75, 0.75), (1, 1.0, 1.0)):
        altitude = keys[segment][0] + fraction * (keys[segment + 1][0] - keys[segment][0])
        elevation = math.radians(keys[segment][1] + weight * (keys[segment + 1][1] - keys[segment][1]))
        sun = np.array([0.0, math.cos(elevation), math.sin(elevation)])
        e_sun = sun_irradiance_ground(elevation, atm)
        origin = precise_tables.tile_origin(segment)
        table = values(atm, sun, e_sun)
        table.update({parameters.PRECISE_TILE: (float(origin[0]), float(origin[1]), altitude),
                      parameters.PRECISE_SCALE: (d_max, atm.atmosphere_height, weight),
                      parameters.PRECISE_ATLAS: (float(image.size[0]), float(image.size[1]), float(vertical))})
        f_ex, l_in = aerial_perspective.evaluate(
            AerialFeatures(level="precise", blend=True), table, distance_units=distances, view_direction=directions,
            images={IMAGE_NAME: pixels.reshape(image.size[1], image.size[0], 4)})
        blended = blend_tiles(tiles[segment], tiles[segment + 1], weight, altitude, atm)
        want_f, want_l = evaluate(blended, directions, sun, distances, atm, np.float64)
        label = f"segment {segment} w {weight} camera {altitude} m"
        assert_close(f_ex, want_f, e_sun, f"F_ex {label}")
        assert_close(l_in, want_l, e_sun, f"L_in {label}", absolute=True)
        if weight == 0.3:   # not the first key alone: the second key's texels count
            alone_f, alone_l = evaluate(dataclasses.replace(tiles[segment], camera_radius_m=blended.camera_radius_m),
                                        directions, sun, distances, atm, np.float64)
            assert np.max(np.abs(alone_l - want_l)) > 10 * np.max(np.abs(l_in - want_l))


@pytest.mark.parametrize("name", sorted(ATMOSPHERES))
@pytest.mark.parametrize("ground", ("BLACK", "ALBEDO"))
def test_the_sky_group_evaluates_the_cores_dome_sky(name, ground):
    atm = ATMOSPHERES[name]
    directions, _ = rays(4000, seed=3)
    albedo = parameters.DEFAULT_GROUND_ALBEDO if ground == "ALBEDO" else 0.0
    for elevation in (45.0, 2.0):
        sun = np.array([0.2, math.cos(math.radians(elevation)), math.sin(math.radians(elevation))])
        sun /= np.linalg.norm(sun)
        e_sun = sun_irradiance_ground(math.asin(sun[2]), atm)
        radiance = sky.evaluate(SkyFeatures(ground=ground), values(atm, sun, e_sun), view_direction=directions,
                                is_camera_ray=0.0)   # no disk: the core's sky_radiance has none
        want = sky_radiance(directions, sun, atm, e_sun, ground_albedo=albedo,
                            dome=lambda e, a, h: dome_distance_approx(e, a, h, np.float32))
        assert_close(radiance, want, e_sun, f"{name} {ground} sun {elevation} deg", absolute=True)


def test_the_sun_disk_is_in_the_sky_group_for_camera_rays_only():
    atm = ATMOSPHERES["clear"]
    sun = np.array([0.0, math.cos(math.radians(30.0)), math.sin(math.radians(30.0))])
    e_sun = sun_irradiance_ground(math.radians(30.0), atm)
    table = values(atm, sun, e_sun)
    with_disk = sky.evaluate(SkyFeatures(), table, view_direction=sun[None, :], is_camera_ray=1.0)
    without = sky.evaluate(SkyFeatures(), table, view_direction=sun[None, :], is_camera_ray=0.0)
    solid_angle = 4.0 * math.pi * math.sin(parameters.DEFAULT_SUN_ANGULAR_RADIUS_RAD / 2.0) ** 2
    centre = (1.0 / (1.0 - parameters.DEFAULT_SUN_LIMB_DARKENING / 3.0)) / solid_angle   # limb darkening's mean
    assert np.allclose(with_disk - without, np.asarray(e_sun) * centre, rtol=1e-4)


def test_the_numpy_builder_computes_what_blenders_nodes_compute():
    """Blender's conventions the backend keeps: a divide by 0 gives 0, the Gamma node leaves channels <= 0 as they
    are and gives 1 for an exponent of 0, a missing parameter reads 0, and no node is ever made."""
    g = ArrayBuilder({"atmos_x": (1.0, 2.0, 3.0)}, {"view_distance": np.array([2.0, 0.0])})
    assert np.array_equal(g.div(1.0, g.shading_input("view_distance")), [0.5, 0.0])
    r, gr, b = g.power_per_channel((np.array(4.0), np.array(-2.0), np.array(0.0)), 0.5)
    assert (float(r), float(gr), float(b)) == (2.0, -2.0, 0.0)
    assert all(float(c) == 1.0 for c in g.power_per_channel((np.array(-2.0),) * 3, 0.0))
    assert g.array(g.attribute("atmos_missing")).tolist() == [0.0, 0.0, 0.0]
    assert g.array(g.attribute("atmos_x")).tolist() == [1.0, 2.0, 3.0]
    with pytest.raises(TypeError):
        g.node("ShaderNodeMath")


def test_the_compositor_builder_writes_a_colour_as_one_vector():
    """The Per Pixel group's builder: a colour's arithmetic is one Vector Math node (not one Math node per channel),
    arithmetic on constants builds nothing, three copies of one scalar are that scalar (its link broadcasts it), a
    socket is separated once however often it is asked, and the parameters are the sockets it was given."""
    import bpy

    from atmos_addon.node_groups.graph import COMPOSITOR_SEPARATE_XYZ, CompositorBuilder

    tree = bpy.data.node_groups.new("Compositor builder", "CompositorNodeTree")
    try:
        group_in = tree.nodes.new("NodeGroupInput")
        tree.interface.new_socket("Beta", in_out="INPUT", socket_type="NodeSocketVector")
        tree.interface.new_socket("s", in_out="INPUT", socket_type="NodeSocketFloat")
        beta, s = group_in.outputs["Beta"], group_in.outputs["s"]
        g = CompositorBuilder(tree, {"atmos_beta": beta})
        assert g.attribute("atmos_beta") == beta
        before = len(tree.nodes)
        assert g.mul((1.0, 2.0, 3.0), 2.0) == (2.0, 4.0, 6.0)
        assert g.scale((1.0, 2.0, 3.0), -1.0) == (-1.0, -2.0, -3.0)
        assert g.combine(0.5, 0.5, 0.5) == (0.5, 0.5, 0.5) and g.combine(s, s, s) == s
        assert len(tree.nodes) == before
        tau = g.scale(beta, s)
        f_ex = g.power_per_channel(g.mul(tau, (2.0, 2.0, 2.0)), 0.5)
        assert [(n.bl_idname, n.operation) for n in tree.nodes[before:]] == [
            ("ShaderNodeVectorMath", "SCALE"), ("ShaderNodeVectorMath", "MULTIPLY"), ("ShaderNodeVectorMath", "POWER")]
        assert g.separate(f_ex) == g.separate(f_ex)
        assert sum(n.bl_idname == COMPOSITOR_SEPARATE_XYZ for n in tree.nodes) == 1
        with pytest.raises(TypeError):
            g.texture(None, 0.0, 0.0)
    finally:
        bpy.data.node_groups.remove(tree)
