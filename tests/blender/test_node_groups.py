# SPDX-License-Identifier: GPL-3.0-or-later
"""The "Atmos Aerial Perspective" node group: parity with the physics core in Cycles and Eevee, rebuild rules.

Parity scene: a perspective camera, emissive planes at known distances showing the group's
Transmittance (top half of the image) and Inscattering times a known gain (bottom half). Each pixel
is one sample at the pixel centre, so the expected value is the physics core's float32 result for the
pixel-centre ray. Cycles must agree within 0.2 %, Eevee within 1 % (Eevee's render result is half
float: about 0.05 % for values of order 0.1-1), relative to max(|expected|, 1e-4).
"""

from __future__ import annotations

import math
import time

import bpy
import numpy as np
import pytest

import render_utils as ru
from atmos_addon.physics import Atmosphere, inscattering
from atmos_addon.physics.sky import (aerial_distance_clamped, dome_distance_approx, elevation_of,
                                     extinction_layered, inscattering_layered)
from atmos_addon.node_groups import (AERIAL_PARAMETER_NAMES, GROUP_NAME, OUTPUT_INSCATTERING,
                         OUTPUT_TRANSMITTANCE, AerialFeatures, clear_shader_parameters, describe_features,
                         ensure_aerial_perspective_group, node_count, read_shader_parameters, write_shader_parameters)
from atmos_addon.node_groups import parts, stamps
from atmos_addon.node_groups.parameters import fcurves_of, remove_fcurve
from atmos_addon.node_groups.aerial_perspective import NODE_COUNTS

WIDTH, HEIGHT = 12, 8
FOV = math.radians(60.0)
DEPTHS_UNITS = (300.0, 3000.0, 20000.0)  # one plane per third of the image
GAIN_NUMERATOR = 1000.0  # inscattering is shown times 1000 / depth, of order 0.01-1
SUN_IRRADIANCE = (3.0, 3.5, 4.0)
ATMOSPHERE = Atmosphere(mie_g=(0.7, 0.76, 0.8))
TOLERANCE = {"CYCLES": 2e-3, ru.EEVEE_ENGINE: 1e-2}
#: Errors are relative to max(|expected|, this): Eevee's half-float film keeps 11 bits down to 6e-5 and
#: fewer below (the 200 km plane's blue transmittance is 2e-6), so tiny values are compared absolutely.
RELATIVE_FLOOR = 1e-4
PARITY_ERRORS: dict[str, float] = {}


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def _write(scene, atm: Atmosphere, sun_direction, metres_per_unit: float, sun_irradiance=SUN_IRRADIANCE) -> None:
    write_shader_parameters(scene, beta_rayleigh=atm.rayleigh_scattering, beta_mie=atm.mie_scattering,
                            beta_mie_absorption=atm.mie_absorption, mie_g=atm.mie_g, sun_direction=sun_direction,
                            sun_irradiance=sun_irradiance, metres_per_unit=metres_per_unit)


def _new_material(name: str) -> bpy.types.Material:
    """A node-based material (``use_nodes`` is implied, and deprecated, from Blender 5.0)."""
    material = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        material.use_nodes = True
    return material


def _weighted_emission_material(group: bpy.types.ShaderNodeTree) -> bpy.types.Material:
    """Emission = Transmittance * w_T + Inscattering * w_L, the weights read from object properties.

    A 0/1 weight selects exactly (x * 1 + y * 0 = x), unlike a Mix node's a + t (b - a).
    """
    material = _new_material("Atmos Test")
    nodes, links = material.node_tree.nodes, material.node_tree.links
    nodes.clear()
    group_node = nodes.new("ShaderNodeGroup")
    group_node.node_tree = group
    weights = []
    for name in ("atmos_test_w_t", "atmos_test_w_l"):
        attribute = nodes.new("ShaderNodeAttribute")
        attribute.attribute_type = "OBJECT"
        attribute.attribute_name = name
        weights.append(attribute.outputs["Fac"])
    products = []
    for output, weight in zip((OUTPUT_TRANSMITTANCE, OUTPUT_INSCATTERING), weights):
        multiply = nodes.new("ShaderNodeVectorMath")
        multiply.operation = "SCALE"
        links.new(group_node.outputs[output], multiply.inputs[0])
        links.new(weight, multiply.inputs["Scale"])
        products.append(multiply.outputs["Vector"])
    add = nodes.new("ShaderNodeVectorMath")
    add.operation = "ADD"
    links.new(products[0], add.inputs[0])
    links.new(products[1], add.inputs[1])
    emission = nodes.new("ShaderNodeEmission")
    emission.inputs["Strength"].default_value = 1.0
    links.new(add.outputs["Vector"], emission.inputs["Color"])
    output = nodes.new("ShaderNodeOutputMaterial")
    links.new(emission.outputs["Emission"], output.inputs["Surface"])
    return material


def _parity_scene(features: AerialFeatures = AerialFeatures(), location=(0.0, 0.0, 0.0),
                  rotation_euler=(math.radians(95.0), 0.0, math.radians(20.0))):
    """Camera looking along +Y (tilted a little), six planes: three depths x (transmittance, inscattering)."""
    scene = ru.reset_scene()
    camera = ru.make_camera(scene, location=location, rotation_euler=rotation_euler, fov_rad=FOV,
                            clip_start=10.0, clip_end=1.0e5)
    bpy.context.view_layer.update()
    material = _weighted_emission_material(ensure_aerial_perspective_group(features))
    to_world = np.array(camera.matrix_world, dtype=np.float64)
    half_w = math.tan(FOV / 2.0)
    half_h = half_w * HEIGHT / WIDTH
    for column, depth in enumerate(DEPTHS_UNITS):
        x0, x1 = (-1.0 + 2.0 * column / 3.0) * half_w * depth, (-1.0 + 2.0 * (column + 1) / 3.0) * half_w * depth
        for half, (y0, y1) in enumerate(((0.0, half_h * depth), (-half_h * depth, 0.0))):
            local = np.array([(x0, y0, -depth, 1.0), (x1, y0, -depth, 1.0), (x1, y1, -depth, 1.0),
                              (x0, y1, -depth, 1.0)])
            plane = ru.make_plane(scene, f"plane {depth:g} {half}", (local @ to_world.T)[:, :3], material)
            plane["atmos_test_w_t"] = 1.0 if half == 0 else 0.0
            plane["atmos_test_w_l"] = 0.0 if half == 0 else GAIN_NUMERATOR / depth
    return scene, camera


def _expected(camera, metres_per_unit: float, sun_direction, atm: Atmosphere = ATMOSPHERE) -> np.ndarray:
    """The physics core's float32 value for every pixel-centre ray of the parity scene, (HEIGHT, WIDTH, 3)."""
    directions = ru.pixel_centre_directions(camera, WIDTH, HEIGHT)
    forward = -np.array(camera.matrix_world.to_3x3().col[2], dtype=np.float64)
    cos_to_axis = directions @ forward
    depth = np.repeat(np.array(DEPTHS_UNITS), WIDTH // 3)[np.newaxis, :]
    distance_m = depth / cos_to_axis * metres_per_unit
    mu = directions @ _unit(sun_direction)
    # Lengths clamped to the virtual sky dome (float32 domes, as the nodes compute them): the 200 km plane
    # lies beyond the dome above the horizon, the nearer planes do not.
    s_r, s_m = aerial_distance_clamped(distance_m, elevation_of(directions), atm,
                                       dome=lambda e, a, h: dome_distance_approx(e, a, h, np.float32))
    transmittance = extinction_layered(s_r, s_m, atm, np.float32)
    light = inscattering_layered(s_r, s_m, mu, atm, SUN_IRRADIANCE, np.float32)
    gain = (GAIN_NUMERATOR / depth)[..., np.newaxis]
    top = np.arange(HEIGHT)[:, np.newaxis, np.newaxis] < HEIGHT // 2
    return np.where(top, transmittance, light * gain)


def _builder_image(scene, camera, features: AerialFeatures, metres_per_unit: float) -> np.ndarray:
    """What the group's own builder computes for the parity scene's pixel-centre rays, on the graph builder's
    numpy backend (:func:`atmos_addon.node_groups.aerial_perspective.evaluate`) with the parameters the scene holds
    and the Precise table's pixels as Blender stores them: the render must equal it (one source per equation)."""
    from atmos_addon.node_groups import aerial_perspective
    from atmos_addon.node_groups.precise import IMAGE_NAME

    directions, distance_m, depth = _parity_rays(camera, metres_per_unit)
    distance_units = distance_m / metres_per_unit
    origin = np.array(camera.matrix_world.translation, dtype=np.float64)
    values = {name: value for name, value in read_shader_parameters(scene).items() if value is not None}
    images = {}
    if IMAGE_NAME in bpy.data.images:
        table = bpy.data.images[IMAGE_NAME]
        pixels = np.empty(table.size[0] * table.size[1] * 4, dtype=np.float32)
        table.pixels.foreach_get(pixels)
        images[IMAGE_NAME] = pixels.reshape(table.size[1], table.size[0], 4)
    transmittance, light = aerial_perspective.evaluate(
        features, values, distance_units=distance_units.reshape(-1), view_direction=directions.reshape(-1, 3),
        position=(origin + directions * distance_units[..., np.newaxis]).reshape(-1, 3), images=images)
    shape = directions.shape
    return _parity_image(transmittance.reshape(shape), light.reshape(shape), depth)


def _relative_error(image: np.ndarray, expected: np.ndarray, engine: str, case: str) -> float:
    """The worst relative error of a render against the core (floored at RELATIVE_FLOOR), asserted finite and
    under the engine's tolerance; ``case`` names the render in the failure message."""
    relative = np.abs(image - expected) / np.maximum(np.abs(expected), RELATIVE_FLOOR)
    assert np.all(np.isfinite(image))
    assert relative.max() < TOLERANCE[engine], (
        f"{engine} {case}: worst relative error {relative.max():.2e} at pixel "
        f"{np.unravel_index(relative.argmax(), relative.shape)}")
    return float(relative.max())


@pytest.mark.parametrize("engine", ru.ENGINES)
def test_parity_with_physics_core(engine):
    scene, camera = _parity_scene()
    ru.set_engine(scene, engine, width=WIDTH, height=HEIGHT)
    forward = -np.array(camera.matrix_world.to_3x3().col[2], dtype=np.float64)
    toward_view = _unit(forward + np.array([0.1, 0.0, 0.12]))  # about 9 deg from the view axis
    away = _unit([-0.3, -0.8, 0.5])
    worst = 0.0
    # Parameters change between renders without touching the tree (Eevee keeps its compiled shader).
    for metres_per_unit, sun in ((1.0, toward_view), (1.0, away), (10.0, toward_view)):
        _write(scene, ATMOSPHERE, sun, metres_per_unit)
        image = ru.render_to_array(scene)[..., :3]
        expected = _expected(camera, metres_per_unit, sun)
        case = f"m/unit {metres_per_unit} sun {sun.round(3).tolist()}"
        worst = max(worst, _relative_error(image, expected, engine, case))
        _relative_error(image, _builder_image(scene, camera, AerialFeatures(), metres_per_unit), engine,
                        f"{case}, against its builder")
    PARITY_ERRORS[engine] = worst
    print(f"\n{engine} (Blender {bpy.app.version_string}): worst relative error {worst:.2e}")


def test_rayleigh_only_group_matches_core_in_cycles():
    atm = Atmosphere(mie_scattering=0.0, mie_absorption=0.0)
    scene, camera = _parity_scene(AerialFeatures(mie=False, absorption=False))
    ru.set_engine(scene, "CYCLES", width=WIDTH, height=HEIGHT)
    sun = _unit([0.2, 0.9, 0.3])
    _write(scene, atm, sun, 2.0)
    image = ru.render_to_array(scene)[..., :3]
    expected = _expected(camera, 2.0, sun, atm)
    np.testing.assert_allclose(image, expected, rtol=2e-3, atol=1e-7)


@pytest.mark.parametrize("engine", ru.ENGINES)
def test_finite_at_zero_coefficients_zero_distance_and_large_distance(engine):
    """No NaN/Inf: zero coefficients, a plane at the near clip, 1e7 m, |g| = 0.999 with mu = +-1."""
    scene = ru.reset_scene()
    ru.make_camera(scene, fov_rad=math.radians(40.0), clip_start=0.01, clip_end=100.0)
    material = _weighted_emission_material(ensure_aerial_perspective_group(AerialFeatures()))
    near, far = 0.0101, 99.0  # Camera at the origin looking down -Z; left half near, right half far.
    for name, depth, x0, x1 in (("near", near, -1.0, 0.0), ("far", far, 0.0, 1.0)):
        corners = [(x0 * depth, -depth, -depth), (x1 * depth, -depth, -depth), (x1 * depth, depth, -depth),
                   (x0 * depth, depth, -depth)]
        plane = ru.make_plane(scene, name, corners, material)
        plane["atmos_test_w_t"] = 1.0  # shows F_ex + L_in
        plane["atmos_test_w_l"] = 1.0
    ru.set_engine(scene, engine, width=5, height=5)  # odd: the centre pixel looks exactly down the axis
    zero = (0.0, 0.0, 0.0)
    forward, backward = (0.0, 0.0, -1.0), (0.0, 0.0, 1.0)
    cases = [
        dict(beta_rayleigh=zero, beta_mie=zero, beta_mie_absorption=zero, mie_g=0.0, sun_direction=forward,
             metres_per_unit=1.0),
        dict(beta_rayleigh=zero, beta_mie=zero, beta_mie_absorption=zero, mie_g=0.999, sun_direction=forward,
             metres_per_unit=1.0e5),
        dict(beta_rayleigh=(5.8e-6, 1.35e-5, 3.31e-5), beta_mie=(2e-5,) * 3, beta_mie_absorption=(2e-6,) * 3,
             mie_g=0.999, sun_direction=forward, metres_per_unit=1.0e5),  # far plane at 9.9e6 m
        dict(beta_rayleigh=(5.8e-6, 1.35e-5, 3.31e-5), beta_mie=(2e-5,) * 3, beta_mie_absorption=zero,
             mie_g=-0.999, sun_direction=backward, metres_per_unit=1.0e5),
        dict(beta_rayleigh=(5.8e-6, 1.35e-5, 3.31e-5), beta_mie=(2e-5,) * 3, beta_mie_absorption=(2e-6,) * 3,
             mie_g=0.999, sun_direction=backward, metres_per_unit=1.0e-3),  # near plane at 1e-5 m
    ]
    for case in cases:
        write_shader_parameters(scene, sun_irradiance=SUN_IRRADIANCE, **case)
        image = ru.render_to_array(scene)[..., :3]
        assert np.all(np.isfinite(image)), f"{engine}: non-finite pixels for {case}"
        assert np.all(image >= 0.0), f"{engine}: negative pixels for {case}"
        if case["beta_rayleigh"] == zero:  # transmittance 1, no in-scattering
            np.testing.assert_allclose(image, 1.0, rtol=0, atol=1e-6)


def test_ensure_group_rebuilds_only_when_stale():
    ru.reset_scene()
    features = AerialFeatures(mie=True, absorption=True)
    tree = ensure_aerial_perspective_group(features)
    assert tree.name == GROUP_NAME
    assert tree["atmos_version"] == stamps.AERIAL.version and tree["atmos_features"] == "rayleigh+mie+abs"
    before = [(node.name, node.as_pointer()) for node in tree.nodes]
    again = ensure_aerial_perspective_group(features)
    assert again.as_pointer() == tree.as_pointer()
    assert [(node.name, node.as_pointer()) for node in again.nodes] == before

    # A material's group node keeps its links across a rebuild for other features and a stale version.
    material = _new_material("user")
    group_node = material.node_tree.nodes.new("ShaderNodeGroup")
    group_node.node_tree = tree
    emission = material.node_tree.nodes.new("ShaderNodeEmission")
    material.node_tree.links.new(group_node.outputs[OUTPUT_INSCATTERING], emission.inputs["Color"])
    rebuilt = ensure_aerial_perspective_group(AerialFeatures(mie=False, absorption=True))
    assert rebuilt.as_pointer() == tree.as_pointer() and rebuilt["atmos_features"] == "rayleigh+abs"
    tree["atmos_version"] = stamps.AERIAL.version - 1
    rebuilt = ensure_aerial_perspective_group(AerialFeatures(mie=False, absorption=True))
    assert rebuilt["atmos_version"] == stamps.AERIAL.version
    assert len(bpy.data.node_groups) == 1
    assert emission.inputs["Color"].is_linked
    assert emission.inputs["Color"].links[0].from_socket.name == OUTPUT_INSCATTERING
    outputs = [item.name for item in rebuilt.interface.items_tree if item.item_type == "SOCKET"]
    assert outputs == [OUTPUT_TRANSMITTANCE, OUTPUT_INSCATTERING]


def test_features_build_only_the_terms_needed():
    ru.reset_scene()
    counts, hg_nodes, attributes = {}, {}, {}
    for mie in (False, True):
        for absorption in (False, True):
            features = AerialFeatures(mie=mie, absorption=absorption)
            tree = ensure_aerial_perspective_group(features)
            counts[features.key] = node_count(tree)
            hg_nodes[features.key] = sum(1 for n in parts.inline_nodes(tree) if n.label == "Phi_HG")
            attributes[features.key] = {n.attribute_name for n in parts.inline_nodes(tree)
                                        if n.bl_idname == "ShaderNodeAttribute"}
            assert describe_features(features).endswith(f": {counts[features.key]} nodes")
    assert counts == {key: count for key, count in NODE_COUNTS.items() if "+precise" not in key}
    assert hg_nodes == {"rayleigh": 0, "rayleigh+abs": 0, "rayleigh+mie": 1, "rayleigh+mie+abs": 1}
    assert counts["rayleigh"] < counts["rayleigh+abs"] < counts["rayleigh+mie"] < counts["rayleigh+mie+abs"]
    assert "atmos_beta_mie" not in attributes["rayleigh+abs"] and "atmos_mie_g" not in attributes["rayleigh"]
    assert "atmos_beta_mie_absorption" not in attributes["rayleigh+mie"]
    assert attributes["rayleigh+mie+abs"] == set(AERIAL_PARAMETER_NAMES)   # the Fast graph reads every one
    full = NODE_COUNTS["rayleigh+mie+abs"]
    assert describe_features(AerialFeatures(True, True)) == f"Fast, Rayleigh + Mie + absorption: {full} nodes"
    with pytest.raises(ValueError, match="level"):   # retired in December 2026
        AerialFeatures(level="balanced")
    for mie in (False, True):
        for absorption in (False, True):
            for blend in (False, True):
                features = AerialFeatures(mie=mie, absorption=absorption, level="precise", blend=blend)
                tree = ensure_aerial_perspective_group(features)
                counts[features.key] = node_count(tree)
                attributes[features.key] = {n.attribute_name for n in parts.inline_nodes(tree)
                                            if n.bl_idname == "ShaderNodeAttribute"}
                textures = [n for n in parts.inline_nodes(tree) if n.bl_idname == "ShaderNodeTexImage"]
                assert len(textures) == (2 if blend else 1) * (20 if mie else 12), features.key   # blend: twice
    assert counts == NODE_COUNTS
    # Precise: absorption lives in the table (no extra nodes); Mie adds the HG phase and the A_M block's taps
    assert counts["rayleigh+abs+precise"] == counts["rayleigh+precise"] < counts["rayleigh+mie+precise"]
    assert attributes["rayleigh+mie+abs+precise"] == {
        "atmos_precise_tile", "atmos_precise_scale", "atmos_precise_atlas", "atmos_planet_radius",
        "atmos_sun_direction", "atmos_metres_per_unit", "atmos_mie_g"}


def test_parameters_round_trip_validate_and_clear():
    scene = ru.reset_scene()
    write_shader_parameters(scene, beta_rayleigh=(5.8e-6, 1.35e-5, 3.31e-5), beta_mie=2e-5, beta_mie_absorption=0.0,
                            mie_g=1.5, sun_direction=(0.0, 3.0, 4.0), sun_irradiance=(3.0, 3.5, 4.0),
                            metres_per_unit=0.01)
    values = read_shader_parameters(scene)
    assert values["atmos_sun_direction"] == pytest.approx((0.0, 0.6, 0.8))
    assert values["atmos_mie_g"] == pytest.approx((0.999,) * 3)
    assert values["atmos_beta_mie"] == pytest.approx((2e-5,) * 3)
    assert values["atmos_metres_per_unit"] == pytest.approx(0.01)
    with pytest.raises(ValueError, match="atmos_beta_rayleigh"):
        write_shader_parameters(scene, beta_rayleigh=(-1.0, 0.0, 0.0), beta_mie=0.0, beta_mie_absorption=0.0,
                                mie_g=0.0, sun_direction=(0, 0, 1), sun_irradiance=1.0, metres_per_unit=1.0)
    with pytest.raises(ValueError, match="zero length"):
        write_shader_parameters(scene, beta_rayleigh=0.0, beta_mie=0.0, beta_mie_absorption=0.0,
                                mie_g=0.0, sun_direction=(0, 0, 0), sun_irradiance=1.0, metres_per_unit=1.0)
    scene.keyframe_insert('["atmos_sun_direction"]', frame=1)
    clear_shader_parameters(scene)
    assert all(value is None for value in read_shader_parameters(scene).values())
    assert scene.animation_data.action is None or not fcurves_of(scene.animation_data.action)


def test_fcurves_of_lists_each_curve_once():
    """Blender 4.4-4.5 show a layered action's first slot as ``action.fcurves`` as well as in its channelbag: each
    curve is listed once, so removing one never leaves a second entry pointing at freed memory (4.5.15 once read
    such an entry's data path as garbage in CI)."""
    scene = ru.reset_scene()
    scene["atmos_test_vector"] = (1.0, 2.0, 3.0)
    scene["atmos_test_scalar"] = 1.0
    scene.keyframe_insert('["atmos_test_vector"]', frame=1)
    scene.keyframe_insert('["atmos_test_scalar"]', frame=1)
    action = scene.animation_data.action
    curves = fcurves_of(action)
    assert sorted((c.data_path, c.array_index) for c in curves) == [
        ('["atmos_test_scalar"]', 0), ('["atmos_test_vector"]', 0), ('["atmos_test_vector"]', 1),
        ('["atmos_test_vector"]', 2)]
    remove_fcurve(action, next(c for c in curves if c.data_path == '["atmos_test_vector"]'))
    assert len(fcurves_of(action)) == 3


def test_keyframed_sun_direction_renders_per_frame_in_cycles():
    """Animated parameters evaluate per frame in a render: farms need no add-on for an animated sun."""
    scene = ru.reset_scene()
    ru.make_camera(scene, fov_rad=math.radians(30.0), clip_start=1.0, clip_end=1.0e4)
    material = _weighted_emission_material(ensure_aerial_perspective_group(AerialFeatures()))
    plane = ru.make_plane(scene, "wall", [(-1e3, -1e3, -1e3), (1e3, -1e3, -1e3), (1e3, 1e3, -1e3), (-1e3, 1e3, -1e3)],
                          material)
    plane["atmos_test_w_t"] = 0.0
    plane["atmos_test_w_l"] = 1.0
    ru.set_engine(scene, "CYCLES", width=5, height=5)  # odd: the centre pixel looks down the axis
    atm = ATMOSPHERE
    suns = {1: _unit([0.0, 0.0, -1.0]), 11: _unit([0.0, 1.0, 0.0])}
    for frame, sun in suns.items():
        _write(scene, atm, sun, 1.0)
        scene.keyframe_insert('["atmos_sun_direction"]', frame=frame)
    for frame in (1, 6, 11):
        scene.frame_set(frame)
        sun = _unit(scene["atmos_sun_direction"])  # between keys: interpolated, normalised by the group
        assert frame != 6 or 0.1 < sun[1] < 0.9
        centre = ru.render_to_array(scene)[2, 2, :3]
        mu = float(np.dot(_unit([0.0, 0.0, -1.0]), sun))
        np.testing.assert_allclose(centre, inscattering(1.0e3, mu, atm, SUN_IRRADIANCE, np.float32), rtol=2e-3)


def test_render_utils_reads_linear_values():
    """The helper returns the scene-linear render (no view transform): an emission of 0.25 reads 0.25."""
    scene = ru.reset_scene()
    ru.make_camera(scene)
    material = _new_material("grey")
    emission = material.node_tree.nodes.new("ShaderNodeEmission")
    emission.inputs["Color"].default_value = (0.25, 2.0, 1e-4, 1.0)
    material.node_tree.links.new(emission.outputs[0], material.node_tree.nodes["Material Output"].inputs["Surface"])
    ru.make_plane(scene, "wall", [(-50, -50, -5), (50, -50, -5), (50, 50, -5), (-50, 50, -5)], material)
    scene.view_settings.view_transform = "Standard"
    ru.set_engine(scene, "CYCLES", width=6, height=4)
    start = time.time()
    image = ru.render_to_array(scene)
    assert image.shape == (4, 6, 4)
    np.testing.assert_allclose(image[..., :3], np.broadcast_to((0.25, 2.0, 1e-4), (4, 6, 3)), rtol=1e-6)
    assert time.time() - start < 30.0


def _write_parameters(scene, atm: Atmosphere, sun_direction, metres_per_unit: float) -> None:
    """Parameters as the add-on writes them, E_sun the ground sun of the atmosphere."""
    from atmos_addon.physics import sun_irradiance_ground

    sun = _unit(sun_direction)
    write_shader_parameters(scene, beta_rayleigh=atm.rayleigh_scattering, beta_mie=atm.mie_scattering,
                            beta_mie_absorption=atm.mie_absorption, mie_g=atm.mie_g, sun_direction=sun,
                            sun_irradiance=sun_irradiance_ground(math.asin(sun[2]), atm),
                            metres_per_unit=metres_per_unit, planet_radius=atm.planet_radius,
                            rayleigh_scale_height=atm.rayleigh_scale_height, mie_scale_height=atm.mie_scale_height)


def _parity_rays(camera, metres_per_unit: float):
    """(unit directions, distances m, plane depths in units) of the parity scene's pixel-centre rays."""
    directions = ru.pixel_centre_directions(camera, WIDTH, HEIGHT)
    forward = -np.array(camera.matrix_world.to_3x3().col[2], dtype=np.float64)
    depth = np.repeat(np.array(DEPTHS_UNITS), WIDTH // 3)[np.newaxis, :]
    return directions, depth / (directions @ forward) * metres_per_unit, depth


def _parity_image(transmittance, light, depth) -> np.ndarray:
    """What the parity scene shows: transmittance in the top half, in-scattering times 1000 / depth below."""
    gain = (GAIN_NUMERATOR / depth)[..., np.newaxis]
    top = np.arange(HEIGHT)[:, np.newaxis, np.newaxis] < HEIGHT // 2
    return np.where(top, transmittance, light * gain)


# -- Precise ---------------------------------------------------------------------------------------------

#: (camera location, rotation, metres per unit, origin altitude m, sun direction): a drone 2 km up looking down
#: past a low sun, and a plateau camera looking at planes 3-200 km away with the sun behind.
PRECISE_CASES = (
    ((0.0, 0.0, 200.0), (math.radians(60.0), 0.0, math.radians(20.0)), 1.0, 1800.0, (0.3, 0.8, 0.2)),
    ((0.0, 0.0, 10.0), (math.radians(95.0), 0.0, math.radians(-30.0)), 10.0, 500.0, (-0.2, -0.9, 0.35)),
)


def _write_precise(scene, atm: Atmosphere, sun_direction, metres_per_unit: float, origin_altitude: float, camera):
    """Parameters and the one-tile table as the add-on writes them; returns the tile."""
    from atmos_addon.blender.apply import precise_tables
    from atmos_addon.physics.precise import bake_tile

    _write_parameters(scene, atm, sun_direction, metres_per_unit)
    sun = _unit(sun_direction)
    altitude = origin_altitude + camera.matrix_world.translation.z * metres_per_unit
    tile = bake_tile(atm, altitude, math.asin(sun[2]))
    image = precise_tables.write_tiles([tile])
    precise_tables._write_parameters(scene, (0, 0), altitude, tile, atm.atmosphere_height, tuple(image.size))
    return tile


def _expected_precise(camera, metres_per_unit: float, sun_direction, tile, atm: Atmosphere = ATMOSPHERE):
    """``physics.precise.evaluate`` in float32 for every pixel-centre ray of the parity scene, (HEIGHT, WIDTH, 3)."""
    from atmos_addon.physics.precise import evaluate

    directions, distance_m, depth = _parity_rays(camera, metres_per_unit)
    transmittance, light = evaluate(tile, directions, _unit(sun_direction), distance_m, atm, np.float32)
    return _parity_image(transmittance, light, depth)


@pytest.mark.parametrize("engine", ru.ENGINES)
def test_precise_group_matches_physics_core(engine):
    """The Precise graph samples the packed table exactly as ``physics.precise.evaluate`` does."""
    worst = 0.0
    for location, rotation, metres_per_unit, origin, sun in PRECISE_CASES:
        scene, camera = _parity_scene(AerialFeatures(level="precise"), location, rotation)
        ru.set_engine(scene, engine, width=WIDTH, height=HEIGHT)
        tile = _write_precise(scene, ATMOSPHERE, sun, metres_per_unit, origin, camera)
        image = ru.render_to_array(scene)[..., :3]
        expected = _expected_precise(camera, metres_per_unit, sun, tile)
        worst = max(worst, _relative_error(image, expected, engine, f"camera {location}"))
        _relative_error(image, _builder_image(scene, camera, AerialFeatures(level="precise"), metres_per_unit),
                        engine, f"camera {location}, against its builder")
    print(f"\n{engine} Precise (Blender {bpy.app.version_string}): worst relative error {worst:.2e}")


@pytest.mark.parametrize("engine", ru.ENGINES)
def test_precise_group_at_the_extremes_is_finite_and_matches_the_core(engine):
    """Sun at -5, 0 and 0.5 deg, a camera at 50 km and above the atmosphere, 1e6 m per unit (planes 3e8 to
    2e10 m away, clamped to the table's last column): finite, non-negative, transmittance in [0, 1], and equal to
    the float32 sampler."""
    scene, camera = _parity_scene(AerialFeatures(level="precise"))
    ru.set_engine(scene, engine, width=WIDTH, height=HEIGHT)
    for elevation, metres_per_unit, origin in ((-5.0, 1.0, 0.0), (0.0, 10.0, 0.0), (0.5, 10.0, 0.0),
                                               (30.0, 1.0, 50_000.0), (30.0, 10.0, 150_000.0), (20.0, 1.0e6, 0.0)):
        e = math.radians(elevation)
        sun = (0.0, math.cos(e), math.sin(e))
        tile = _write_precise(scene, ATMOSPHERE, sun, metres_per_unit, origin, camera)
        image = ru.render_to_array(scene)[..., :3]
        label = f"{engine} sun {elevation} deg, {metres_per_unit:g} m/unit, origin {origin:g} m"
        assert np.all(np.isfinite(image)) and np.all(image >= 0.0), label
        assert np.all(image[: HEIGHT // 2] <= 1.0 + 1e-6), label
        expected = _expected_precise(camera, metres_per_unit, sun, tile)
        relative = np.abs(image - expected) / np.maximum(np.abs(expected), RELATIVE_FLOOR)
        assert relative.max() < TOLERANCE[engine], f"{label}: worst relative error {relative.max():.2e}"
