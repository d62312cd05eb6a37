# SPDX-License-Identifier: GPL-3.0-or-later
"""What an enable and a sun move cost in work, not in time (``./run bench`` times them): one enable bakes the
Precise tables once, also where it adds the sun lamp; a sun moved through the API is read off the lamp's own
transform, without evaluating the scene's depsgraph, unless a constraint moves the lamp; the direction read is the
one the render sees either way.
"""

from __future__ import annotations

import math

import bpy
import numpy as np
import pytest

import render_utils as ru
from atmos_addon import api
from atmos_addon.blender import scene_reading
from atmos_addon.blender.apply import precise_tables


def _scene(scene, n_objects: int = 4):
    """A factory-empty scene: a camera and ``n_objects`` triangles of their own mesh and material, no sun."""
    ru.make_camera(scene, rotation_euler=(math.radians(90.0), 0.0, 0.0))
    for index in range(n_objects):
        material = bpy.data.materials.new(f"Material {index}")
        mesh = bpy.data.meshes.new(f"Mesh {index}")
        mesh.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
        mesh.materials.append(material)
        obj = bpy.data.objects.new(f"Object {index}", mesh)
        obj.location = (3.0 * index, 100.0, 0.0)
        scene.collection.objects.link(obj)
    return scene


@pytest.fixture
def bakes(monkeypatch):
    """The tiles each Precise bake wrote, in order (0: its inputs were the last bake's, nothing baked)."""
    counts: list[int] = []
    bake = precise_tables.bake

    def counted(*args, **kwargs):
        counts.append(bake(*args, **kwargs))
        return counts[-1]

    monkeypatch.setattr(precise_tables, "bake", counted)
    return counts


def _probe(scene):
    """A new empty at x = 5: its world matrix reads the identity until the depsgraph evaluates the scene."""
    probe = bpy.data.objects.new("Evaluation probe", None)
    probe.location = (5.0, 0.0, 0.0)
    scene.collection.objects.link(probe)
    return probe


def _evaluated(probe) -> bool:
    return probe.matrix_world.translation.x == pytest.approx(5.0)


def _elevation_deg(scene) -> float:
    """The elevation of the sun Atmos reads, deg."""
    return math.degrees(math.asin(float(scene_reading.sun_direction(scene)[0][2])))


def test_an_enable_that_adds_the_sun_bakes_once(addon, bakes):
    scene = _scene(addon)
    api.enable(scene, preset="clear")
    assert sum(1 for tiles in bakes if tiles) == 1, bakes
    assert scene_reading.sun_object(scene).name == "Atmos Sun"


def test_a_sun_move_reads_the_lamp_without_evaluating_the_scene(addon, bakes):
    scene = _scene(addon)
    api.enable(scene, preset="clear", sun_elevation_deg=20.0, sun_azimuth_deg=10.0)
    bakes.clear()
    probe = _probe(scene)
    api.set_sun(scene, 35.0, 45.0)
    assert not _evaluated(probe), "set_sun evaluated the depsgraph to read a lamp moved by its own transform"
    assert sum(1 for tiles in bakes if tiles) == 1, "the exact table follows the sun at once"
    assert _elevation_deg(scene) == pytest.approx(35.0, abs=1e-3)
    bpy.context.view_layer.update()   # what a render evaluates reads the same direction
    lamp = scene_reading.sun_object(scene)
    evaluated = np.array(lamp.matrix_world.to_3x3().col[2])
    np.testing.assert_allclose(evaluated, scene_reading.sun_direction(scene)[0], atol=1e-6)


def test_a_lamp_moved_by_a_constraint_is_read_from_the_evaluated_scene(addon):
    scene = _scene(addon)
    api.enable(scene, preset="clear", sun_elevation_deg=20.0, sun_azimuth_deg=0.0)
    lamp = scene_reading.sun_object(scene)
    target = bpy.data.objects.new("Sun target", None)
    scene.collection.objects.link(target)
    target.location = (0.0, 1000.0, 1000.0 * math.tan(math.radians(50.0)))   # 50 deg up, due north
    lamp.location = (0.0, 0.0, 0.0)
    track = lamp.constraints.new("TRACK_TO")
    track.target, track.track_axis, track.up_axis = target, "TRACK_Z", "UP_Y"   # +Z (to the sun) at the target
    assert scene_reading.needs_evaluation(scene)
    probe = _probe(scene)
    api.set_sun(scene, 35.0, 45.0)   # the constraint wins: the lamp still looks at the target
    assert _evaluated(probe), "a constrained lamp needs the depsgraph"
    assert _elevation_deg(scene) == pytest.approx(50.0, abs=1e-3)
