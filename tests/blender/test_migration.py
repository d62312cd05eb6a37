# SPDX-License-Identifier: GPL-3.0-or-later
"""A .blend saved by an earlier release opens, upgrades in place and renders the same (the way the VRM add-on tests
its node-group migrations).

``data/atmos_addba16.blend`` was written by main at addba16 (the release before the Blender-layer redesign) with
``tools/make_release_blend.py``, saved by Blender 4.5.15, with the pixels that release rendered beside it: two
scenes, Compositor mode at the Fast level and Per Pixel mode at the Balanced level, emissive planes against the
Atmos sky. ``data/atmos_7df8acd.blend`` (the release before the Precise sky view, same tool with ``--precise``)
adds a third scene at the Precise level with multiple scattering. Opened with today's add-on, every Atmos node group
must carry today's stamp (:mod:`atmos_addon.node_groups.stamps`), rebuilt in place (no second copy, the compositor's and
materials' links kept), none may read as edited, and every scene must render as it did (Cycles, pixel centres:
emission and sky only, no sampling noise). The Per Pixel scenes were saved at the Balanced level, retired in
December 2026: they open at Fast, which shares Balanced's sky, and their compositor group node loses the drivers of
the inputs only Balanced read.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import bpy
import numpy as np
import pytest

from atmos_addon.blender import group_integrity
from atmos_addon.node_groups import registry, stamps
import render_utils as ru

DATA = Path(__file__).resolve().parent / "data"
#: The stored releases and the scenes each file holds.
RELEASES = {"addba16": ("Compositor", "Per Pixel"), "7df8acd": ("Compositor", "Per Pixel", "Precise")}


def _former_columns(bake_tile):
    """``bake_tile`` with the Precise table's distance columns as before December 2026 (stop 55): D (k / (N_d - 1))^2
    for every row (``physics.precise.Tile.vertical_columns`` False; the shader reads that from the atlas parameter).
    Today's columns start at each row's vertical ray, which moves the stored 7df8acd file's renders by 2.1e-4 (its
    Compositor scene): the migration test renders with the former ones, so that it checks what the upgrade keeps."""
    def baked(*args, **options):
        return bake_tile(*args, **{**options, "vertical_columns": False})
    return baked


#: Ozone's cross-section per channel before the spectral channels (December 2026), m^2: the channel means with the
#: negative lobes cut. Today's (physics.spectrum.OZONE_CHANNEL_CROSS_SECTION_M2) keep them: red 23 % more, blue none,
#: which moves a scene with ozone by up to 1.2 % (the stored 7df8acd scenes carry 300 DU). The migration test renders
#: with the former values, so that it checks what the upgrade keeps: settings, node groups, links and tables.
FORMER_OZONE_CHANNEL_CROSS_SECTION_M2 = np.array([4.00209963e-25, 2.97481703e-25, 3.07292543e-26])


pytestmark = pytest.mark.usefixtures("addon")


@pytest.mark.parametrize("release", RELEASES)
def test_a_file_of_an_earlier_release_upgrades_in_place_and_renders_the_same(release, tmp_path, monkeypatch):
    from atmos_addon.physics import atmosphere

    monkeypatch.setattr(atmosphere, "OZONE_CHANNEL_CROSS_SECTION_M2", FORMER_OZONE_CHANNEL_CROSS_SECTION_M2)
    from atmos_addon.blender.apply import precise_tables
    monkeypatch.setattr(precise_tables, "bake_tile", _former_columns(precise_tables.bake_tile))
    source = tmp_path / f"atmos_{release}.blend"
    shutil.copy(DATA / source.name, source)   # opened from a copy: the test never rewrites the stored file
    bpy.ops.wm.open_mainfile(filepath=str(source))
    assert group_integrity.edited_groups(force=True) == []   # rebuilt or kept as built, none reads as hand-edited
    managed = registry.managed_trees()
    assert {kind for kind, _ in managed} >= {stamps.AERIAL, stamps.SKY, stamps.SURFACE, stamps.COMPOSITE,
                                             stamps.PER_PIXEL, stamps.SKY_LIGHTING}
    for kind, tree in managed:   # every group upgraded to today's stamp, in place: no second copy of a group
        assert tree[stamps.KIND_KEY] == kind.name and tree[stamps.VERSION_KEY] == kind.version, tree.name
        if kind in stamps.PART_KINDS:   # one group per part (by name), as for every other kind
            assert sum(t.get(stamps.FEATURES_KEY) == tree[stamps.FEATURES_KEY] for k, t in managed if k == kind) == 1
        else:
            assert kind.per_world or sum(k == kind for k, _ in managed) == 1, tree.name
    for scene_name in RELEASES[release]:
        scene = bpy.data.scenes[scene_name]
        assert scene.atmos.enabled
        expected = np.load(DATA / f"atmos_{release}_{scene_name.lower().replace(' ', '_')}.npy")
        image = ru.render_to_array(scene)[..., :3]
        difference = float(np.max(np.abs(image - expected)))
        print(f"\n{release} {scene_name}: max abs difference to the release's render {difference:.2e}")
        assert difference <= 1e-4, scene_name
    _assert_balanced_upgraded_to_fast(bpy.data.scenes["Per Pixel"])
    if "Precise" in RELEASES[release]:
        _assert_the_precise_sky_view_came_in(bpy.data.scenes["Precise"])


def _assert_balanced_upgraded_to_fast(scene) -> None:
    """A scene saved at the retired Balanced level (Per Pixel mode): Fast, no Balanced parameter left, and the
    compositor group node driven on exactly today's inputs, every driver valid (the camera-z and sun-depth drivers
    of before would point at other sockets)."""
    from atmos_addon.blender.apply import compositor
    from atmos_addon.node_groups import parameters, per_pixel

    assert scene.atmos.quality == "FAST" and scene.atmos.render_mode == "PER_PIXEL"
    assert not any(name in scene for name in parameters.RETIRED_PARAMETER_NAMES)
    tree = compositor.current_tree(scene)
    node = tree.nodes[compositor.COMPOSITE_NODE]
    assert node.node_tree[stamps.FEATURES_KEY] == "rayleigh+mie+abs"
    linked = {link.to_socket.name for link in tree.links if link.to_node == node}
    assert linked == {name for name, _, _ in per_pixel.IMAGE_INPUTS}   # the interface shrank, the links stayed
    drivers = [c for c in tree.animation_data.drivers if c.data_path.startswith(f'nodes["{node.name}"].inputs[')]
    assert len(drivers) == sum(size for _, _, size in per_pixel.PARAMETER_SOCKETS) + 1   # and Film Transparent's
    assert all(c.driver.is_valid for c in drivers)


def _assert_the_precise_sky_view_came_in(scene) -> None:
    """A Precise scene saved before the sky view (7df8acd: Cycles' non-camera rays saw the camera's Precise sky, the
    tiles had no sky-view block) opens with its world's lighting group rebuilt for the Precise level, those rays
    routed to it and the table re-baked with the sky view (the camera's pixels, checked above, stay the same)."""
    from atmos_addon.blender.apply import world
    from atmos_addon.physics.precise import DEFAULT_SHAPE

    tagged = {node.get("atmos_tag"): node for node in world.tagged_nodes(scene.world)}
    lighting = tagged[world.LIGHTING_TAG].node_tree
    assert lighting[stamps.FEATURES_KEY].endswith("+precise+ground")
    mix = tagged[world.MIX_TAG]
    assert mix.inputs[1].links[0].from_node == tagged[world.LIGHTING_BACKGROUND_TAG]
    image = bpy.data.images["Atmos Precise Table"]
    assert tuple(image.size) == (DEFAULT_SHAPE.width, DEFAULT_SHAPE.altitudes)
    assert [node.image for node in lighting.nodes if node.bl_idname == "ShaderNodeTexImage"] == [image, image]


def test_settings_saved_before_the_default_changed_keep_their_value(addon, tmp_path):
    # December 2026 the default became Precise with multiple scattering (issue 27); it was Fast without (and then the
    # mode became Per Pixel, issue 28; it was Compositor). Blender
    # writes a setting into the file only once it is set, and one never set reads as today's default, so a scene
    # saved earlier with the defaults would switch level on opening. Enabling now writes both explicitly; a file
    # without them (saved before) gets the former defaults back on load (atmos_addon.blender.migration).
    from atmos_addon import api
    from atmos_addon.blender import facts, migration
    from atmos_addon.physics.spectrum import SUN_TOP_RGB

    scene = addon
    ru.make_camera(scene, rotation_euler=(1.5, 0.0, 0.0))
    api.enable(scene)
    settings = scene.atmos
    assert (settings.quality, settings.multiple_scattering) == ("PRECISE", True)
    assert settings.ozone_column_du == pytest.approx(300.0)
    assert all(settings.is_property_set(name) for name in migration.FORMER_DEFAULTS)
    np.testing.assert_allclose(settings.wavelengths_nm, [648.1, 547.4, 443.1], rtol=1e-6)  # the spectral channels
    np.testing.assert_allclose(settings.sun_irradiance_top, 4.5 * SUN_TOP_RGB, rtol=1e-6)
    assert facts.plan_of(scene).level == "precise" and facts.plan_of(scene).multiple_scattering
    assert settings.render_mode == "PER_PIXEL" and facts.plan_of(scene).mode == "PER_PIXEL"   # issue 28
    today = tmp_path / "today.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(today))

    bpy.ops.wm.open_mainfile(filepath=str(today))
    settings = bpy.context.scene.atmos
    assert (settings.quality, settings.multiple_scattering) == ("PRECISE", True)
    assert settings.ozone_column_du == pytest.approx(300.0)

    assert settings.render_mode == "PER_PIXEL"

    settings.property_unset("ozone_column_du")  # saved by the first complete-model release: Precise, no ozone yet,
    settings.property_unset("render_mode")      # the Compositor mode
    between = tmp_path / "between.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(between))
    bpy.ops.wm.open_mainfile(filepath=str(between))
    settings = bpy.context.scene.atmos
    assert (settings.quality, settings.multiple_scattering, settings.ozone_column_du) == ("PRECISE", True, 0.0)
    assert settings.render_mode == "COMPOSITOR" and facts.plan_of(bpy.context.scene).mode == "COMPOSITOR"
    settings.property_unset("ozone_column_du")
    settings.property_unset("render_mode")

    for name in ("mie_scattering_per_km", "mie_absorption_per_km", "preset_name"):   # before the Clear preset's haze
        settings.property_unset(name)
    grey = tmp_path / "grey_haze.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(grey))
    bpy.ops.wm.open_mainfile(filepath=str(grey))
    settings = bpy.context.scene.atmos
    np.testing.assert_allclose(settings.mie_scattering_per_km, [0.033] * 3, rtol=1e-6)
    np.testing.assert_allclose(settings.mie_absorption_per_km, [0.0033] * 3, rtol=1e-6)
    assert settings.preset_name == ""
    for name in ("mie_scattering_per_km", "mie_absorption_per_km", "preset_name"):
        settings.property_unset(name)

    settings.property_unset("quality")          # as a file saved before the change holds them: never set
    settings.property_unset("multiple_scattering")
    for name in ("wavelengths_nm", "rayleigh_scattering_per_km", "sun_irradiance_top"):  # before the spectral channels
        settings.property_unset(name)
    older = tmp_path / "older.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(older))
    bpy.ops.wm.open_mainfile(filepath=str(older))
    scene = bpy.context.scene
    assert (scene.atmos.quality, scene.atmos.multiple_scattering) == ("FAST", False)
    assert scene.atmos.ozone_column_du == 0.0
    np.testing.assert_allclose(scene.atmos.wavelengths_nm, [680.0, 550.0, 440.0])  # the channels it was saved with
    np.testing.assert_allclose(scene.atmos.sun_irradiance_top, [4.5, 4.5, 4.5])
    np.testing.assert_allclose(scene.atmos.rayleigh_scattering_per_km, [0.004848, 0.011488, 0.028712], rtol=1e-3)
    assert facts.plan_of(scene).level == "fast"

    bpy.ops.wm.read_factory_settings(use_empty=True)   # a new scene that never enabled Atmos gets today's defaults
    assert (bpy.context.scene.atmos.quality, bpy.context.scene.atmos.multiple_scattering) == ("PRECISE", True)
    assert bpy.context.scene.atmos.ozone_column_du == pytest.approx(300.0)
    np.testing.assert_allclose(bpy.context.scene.atmos.wavelengths_nm, [648.1, 547.4, 443.1], rtol=1e-6)
    assert bpy.context.scene.atmos.render_mode == "PER_PIXEL"
    assert bpy.context.scene.atmos.preset_name == "clear"
    np.testing.assert_allclose(bpy.context.scene.atmos.mie_scattering_per_km, [0.03336, 0.04155, 0.05469], rtol=1e-6)


def test_a_scene_saved_at_the_retired_balanced_level_opens_at_fast(addon, tmp_path, capsys):
    """Balanced was retired in December 2026 (off the Pareto front against the complete reference): a file that
    stores it (the Quality enum's number 1) opens at Fast with a note on the console, its Balanced parameters and
    their keys removed; a scene with the effect off is upgraded too; the API and the CLI refuse the name and say
    what replaced it."""
    from atmos_addon import api
    from atmos_addon.node_groups import parameters

    scene = addon
    ru.make_camera(scene, rotation_euler=(1.5, 0.0, 0.0))
    api.enable(scene)
    off = bpy.data.scenes.new("Off")
    for target in (scene, off):
        target.atmos["quality"] = 1                  # what a file saved at Balanced holds
    for name in parameters.RETIRED_PARAMETER_NAMES:  # and the parameters Balanced read, keyed
        scene[name] = 0.5
        scene.keyframe_insert(f'["{name}"]', frame=1)
    saved, name = tmp_path / "balanced.blend", scene.name
    bpy.ops.wm.save_as_mainfile(filepath=str(saved))
    capsys.readouterr()
    bpy.ops.wm.open_mainfile(filepath=str(saved))
    scene, off = bpy.data.scenes[name], bpy.data.scenes["Off"]
    assert (scene.atmos.quality, off.atmos.quality) == ("FAST", "FAST")
    assert facts_level(scene) == "fast"
    assert not any(name in scene for name in parameters.RETIRED_PARAMETER_NAMES)
    paths = {c.data_path for c in parameters.fcurves_of(scene.animation_data.action)}
    assert not any(name in path for path in paths for name in parameters.RETIRED_PARAMETER_NAMES), paths
    out = capsys.readouterr().out
    assert f"Atmos: scene '{scene.name}': the Balanced quality level was retired" in out and "opens at Fast" in out
    with pytest.raises(api.AtmosError, match="Balanced quality level was retired.*'PRECISE'"):
        api.enable(scene, quality="BALANCED")
    with pytest.raises(api.AtmosError, match="must be one of 'FAST', 'PRECISE', 'AUTO'"):
        api.enable(scene, quality="EXACT")
    assert scene.atmos.quality == "FAST"


def facts_level(scene) -> str:
    from atmos_addon.blender import facts

    return facts.plan_of(scene).level
