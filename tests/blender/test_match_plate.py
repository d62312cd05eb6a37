# SPDX-License-Identifier: GPL-3.0-or-later
"""World > Atmosphere > Look Development > Match Plate (``atmos.match_plate``) on a factory-empty file: a camera and no
world.

The operator reads the plate and masks, takes the field of view and pitch from the scene camera, fits, saves a user
preset, applies it (the atmosphere and the sun) and keeps the comparison image; a refused plate (no sky mask, a
distance of 0) reports one error and leaves the file as it was: no preset, no image, no world, the same settings.
"""

from __future__ import annotations

import math

import bpy
import pytest

from atmos_addon import presets
from atmos_addon.blender.ui import match_plate, preset_ops
from atmos_addon.physics.visibility import visibility_m

import plate_files


def _camera(scene):
    """A level camera looking north (+Y) with the plate's horizontal field of view."""
    data = bpy.data.cameras.new("Camera")
    data.sensor_fit = "HORIZONTAL"
    data.lens = data.sensor_width / (2.0 * math.tan(math.radians(plate_files.FOV_DEG) / 2.0))
    camera = bpy.data.objects.new("Camera", data)
    camera.rotation_euler = (math.pi / 2.0, 0.0, 0.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    bpy.context.view_layer.update()
    return camera


def _settings(scene) -> dict:
    return {name: tuple(value) if hasattr(value, "__len__") else value
            for name, value in ((p.identifier, getattr(scene.atmos, p.identifier))
                                for p in scene.atmos.bl_rna.properties if p.identifier != "rna_type")
            if not isinstance(value, bpy.types.bpy_struct)}


def test_match_plate_saves_and_applies_the_plates_look(addon, user_presets, tmp_path):
    scene = addon
    _camera(scene)
    assert scene.world is None
    paths = plate_files.write_plate(tmp_path)
    fov, pitch, heading = match_plate.camera_view(scene, plate_files.WIDTH, plate_files.HEIGHT)
    assert (fov, pitch, heading) == pytest.approx((plate_files.FOV_DEG, 0.0, 0.0), abs=1e-4)
    result = bpy.ops.atmos.match_plate(filepath=str(paths["plate"]), sky_mask=str(paths["sky"]),
                                       surface_mask_1=str(paths["far"]), distance_1=15_000.0,
                                       surface_mask_2=str(paths["near"]), distance_2=2_000.0, start="CLEAR",
                                       preset_name="Plate Look", apply=True, set_exposure=True)
    assert result == {"FINISHED"}
    saved = presets.load("Plate Look", user_presets)
    truth = plate_files.TRUTH
    assert visibility_m(saved.atmosphere) == pytest.approx(truth.visibility_m, rel=0.10)
    assert saved.sun_elevation_deg == pytest.approx(truth.sun_elevation_deg, abs=1.0)
    assert scene.atmos.preset_name == "Plate Look"
    assert scene.atmos.visibility_km == pytest.approx(visibility_m(saved.atmosphere) / 1000.0, rel=1e-4)
    elevation, _ = preset_ops.current_sun_angles_rad(scene)
    assert math.degrees(elevation) == pytest.approx(saved.sun_elevation_deg, abs=0.01)
    assert scene.view_settings.exposure == pytest.approx(truth.exposure_ev, abs=0.3)
    image = bpy.data.images[match_plate.COMPARISON_IMAGE]
    assert tuple(image.size) == (3 * plate_files.WIDTH, plate_files.HEIGHT)


def test_match_plate_from_the_scene_settings_without_applying(addon, user_presets, tmp_path):
    scene = addon
    _camera(scene)
    paths = plate_files.write_plate(tmp_path)
    before = _settings(scene)
    result = bpy.ops.atmos.match_plate(filepath=str(paths["plate"]), sky_mask=str(paths["sky"]),
                                       surface_mask_1=str(paths["far"]), distance_1=15_000.0,
                                       surface_mask_2=str(paths["near"]), distance_2=2_000.0, start="SCENE",
                                       preset_name="From Scene", apply=False)
    assert result == {"FINISHED"}
    saved = presets.load("From Scene", user_presets)
    assert visibility_m(saved.atmosphere) == pytest.approx(plate_files.TRUTH.visibility_m, rel=0.10)
    assert "from the 'scene' preset" in saved.sources[0]
    assert _settings(scene) == before and scene.world is None   # not applied: the scene as it was
    # a second run under the same name needs Overwrite
    with pytest.raises(RuntimeError, match="exists"):
        bpy.ops.atmos.match_plate(filepath=str(paths["plate"]), sky_mask=str(paths["sky"]),
                                  surface_mask_1=str(paths["near"]), start="SCENE", preset_name="From Scene")


def test_distances_from_the_scene_geometry(addon, user_presets, tmp_path):
    scene = addon
    _camera(scene)
    plate_files.add_walls(scene)
    paths = plate_files.write_plate(tmp_path, walls=True)
    distance = match_plate.scene_distances(scene, plate_files.camera())
    truth = plate_files.plane_distances()
    for name, mask in plate_files.bands().items():
        if name != "sky":
            assert distance[mask] == pytest.approx(truth[name][mask], rel=1e-4)
    result = bpy.ops.atmos.match_plate(filepath=str(paths["plate"]), sky_mask=str(paths["sky"]),
                                       use_scene_geometry=True, geometry_mask=str(paths["ground"]), start="CLEAR",
                                       preset_name="From Geometry", apply=False)
    assert result == {"FINISHED"}
    saved = presets.load("From Geometry", user_presets)
    assert visibility_m(saved.atmosphere) == pytest.approx(plate_files.TRUTH.visibility_m, rel=0.10)
    assert saved.sun_elevation_deg == pytest.approx(plate_files.TRUTH.sun_elevation_deg, abs=1.0)


def test_a_refused_plate_reports_once_and_changes_nothing(addon, user_presets, tmp_path):
    scene = addon
    _camera(scene)
    paths = plate_files.write_plate(tmp_path)
    before = _settings(scene)
    images = len(bpy.data.images)
    for arguments, fragment in (({}, "no sky marked"),
                                ({"sky_mask": str(paths["sky"]), "distance_1": 0.0}, "distance 0 m")):
        with pytest.raises(RuntimeError) as error:   # an operator's ERROR report raises in background mode
            bpy.ops.atmos.match_plate(filepath=str(paths["plate"]), surface_mask_1=str(paths["near"]),
                                      start="CLEAR", preset_name="Refused", **arguments)
        assert fragment in str(error.value)
        assert str(error.value).count("Atmos:") == 1
    assert not (user_presets / "Refused.toml").exists()
    assert scene.world is None and len(bpy.data.images) == images
    assert _settings(scene) == before


def test_match_plate_is_in_the_look_development_panel(addon):
    from types import SimpleNamespace

    from atmos_addon.blender.ui import panel

    class Recorder:
        def __init__(self):
            self.operators = []

        def operator(self, idname, **_options):
            self.operators.append(idname)
            return SimpleNamespace()

    layout = Recorder()
    panel.ATMOS_PT_atmosphere_look.draw(SimpleNamespace(layout=layout), bpy.context)
    assert "atmos.match_plate" in layout.operators
    assert hasattr(bpy.types, "ATMOS_OT_match_plate")
    assert match_plate.ATMOS_OT_match_plate.bl_options == {"REGISTER", "UNDO"}
