# SPDX-License-Identifier: GPL-3.0-or-later
"""Presets in Blender, the panel and the contact sheet.

* Registration is symmetric with the preset, contact-sheet and panel classes in.
* Every panel and menu draws for every built-in preset (a recording layout checks each property,
  operator, menu and icon name against Blender's own tables).
* The library operators apply, save, rename, delete, import and export; bad files are refused by
  name of file, field and rule, and leave the scene exactly as it was.
* Every built-in preset renders without NaN in Cycles and Eevee with the effect on.
* The contact sheet has the right size, distinct cells and labels, and restores the scene after
  success and after a cancel.
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path
from types import SimpleNamespace

import bpy
import numpy as np
import pytest

import atmos_addon
from atmos_addon import plan as plan_module
from atmos_addon import presets
from atmos_addon.blender.ui import contact_sheet, preset_ops, panel as ui_panel
from atmos_addon.blender import facts, orchestrator, registration, scene_reading, settings_io
from atmos_addon.physics.visibility import extinction_550_per_m

from render_utils import EEVEE_ENGINE, ENGINES, make_camera, make_plane, render_to_array, set_engine

BUILTINS = presets.BUILTIN_NAMES
OUR_MODULES = ("atmos_addon",)


# --------------------------------------------------------------------------------------------------------------
# Fixtures and helpers


pytestmark = pytest.mark.usefixtures("addon")


def add_sun(scene, elevation_deg: float = 40.0):
    light = bpy.data.lights.new("Sun", "SUN")
    lamp = bpy.data.objects.new("Sun", light)
    scene.collection.objects.link(lamp)
    lamp.rotation_euler = (math.radians(90.0 - elevation_deg), 0.0, math.radians(30.0))
    bpy.context.view_layer.update()
    return lamp


def sun_elevation_deg(scene) -> float:
    bpy.context.view_layer.update()
    direction, _ = scene_reading.sun_direction(scene)
    return math.degrees(math.asin(float(direction[2])))


def _plain(value):
    if isinstance(value, str) or not hasattr(value, "__len__"):
        return value
    return tuple(_plain(item) for item in value)


def snapshot(scene) -> dict:
    """Every scene.atmos value, the skipped list, the sun lamps' matrices and the render settings we might touch."""
    settings = scene.atmos
    values = {prop.identifier: _plain(getattr(settings, prop.identifier)) for prop in settings.bl_rna.properties
              if prop.type != "COLLECTION" and prop.identifier != "rna_type"}
    values["skipped"] = tuple((item.name, item.reason) for item in settings.skipped_materials)
    bpy.context.view_layer.update()
    values["suns"] = tuple((obj.name, _plain(obj.matrix_world)) for obj in scene.objects
                           if obj.type == "LIGHT" and obj.data.type == "SUN")
    render = scene.render
    values["render"] = (render.engine, render.resolution_x, render.resolution_y, render.resolution_percentage,
                        render.filepath, render.image_settings.file_format, render.image_settings.color_mode,
                        render.image_settings.color_depth, scene.cycles.samples)
    values["objects"] = tuple(sorted(obj.name for obj in scene.objects))
    lamp_state = scene.get("atmos_sun_lamp")
    values["lamp_state"] = lamp_state.to_dict() if hasattr(lamp_state, "to_dict") else lamp_state
    if scene.world is not None:
        values["world"] = (scene.world.name, scene.world.cycles.sampling_method,
                           scene.world.cycles.sample_map_resolution)
    return values


def assert_settings_match(scene, atm) -> None:
    back = settings_io.atmosphere_from_settings(scene.atmos)
    for _prop, field, _factor in settings_io.FIELD_MAP:
        np.testing.assert_allclose(np.asarray(getattr(back, field), dtype=float),
                                   np.asarray(getattr(atm, field), dtype=float), rtol=1e-6, err_msg=field)


def tiny_scene(scene, engine: str, width: int, height: int):
    """A camera looking at a far grey plane and the sky, a sun lamp, the effect on."""
    make_camera(scene, location=(0.0, 0.0, 2.0), rotation_euler=(math.radians(85.0), 0.0, 0.0),
                clip_start=0.5, clip_end=5000.0)
    material = bpy.data.materials.new("Ground")
    material.diffuse_color = (0.3, 0.3, 0.3, 1.0)
    make_plane(scene, "Ground", [(-3000.0, 50.0, 0.0), (3000.0, 50.0, 0.0), (3000.0, 4000.0, 0.0),
                                 (-3000.0, 4000.0, 0.0)], material)
    add_sun(scene)
    set_engine(scene, engine, width=width, height=height)
    scene.render.use_compositing = True  # the effect composites its passes
    if engine == "CYCLES":
        scene.cycles.samples = 4
        scene.cycles.max_bounces = 2
    scene.atmos.distance_scale = 5.0
    orchestrator.enable_effect(scene)
    if scene.world is not None and engine == "CYCLES":
        # the sky world's default importance map (1024 x 512 evaluations of the sky shader) costs ~20 s
        # per render on 2 cores; a coarse map changes nothing these tests look at
        scene.world.cycles.sampling_method = "MANUAL"
        scene.world.cycles.sample_map_resolution = 64


# --------------------------------------------------------------------------------------------------------------
# Registration


def _our_handlers() -> list[str]:
    found = []
    for name in dir(bpy.app.handlers):
        handlers = getattr(bpy.app.handlers, name)
        if isinstance(handlers, list):
            found += [f"{name}:{f.__name__}" for f in handlers if getattr(f, "__module__", "").startswith(OUR_MODULES)]
    return found


def test_register_unregister_twice_leaves_nothing_behind():
    ours = (*preset_ops.CLASSES, *contact_sheet.CLASSES, *ui_panel.CLASSES)
    assert set(ours) <= set(registration.CLASSES)
    handlers = _our_handlers()
    for _ in range(2):
        atmos_addon.unregister()
        assert not hasattr(bpy.types.Scene, "atmos")
        assert not any(cls.is_registered for cls in registration.CLASSES)
        assert not [name for name in dir(bpy.types) if name.startswith(("ATMOS_", "Atmos"))]
        assert _our_handlers() == []
        atmos_addon.register()
        assert all(cls.is_registered for cls in registration.CLASSES)
        assert _our_handlers() == handlers
        for cls in ours:
            if issubclass(cls, bpy.types.Operator):
                module, name = cls.bl_idname.split(".")
                assert hasattr(getattr(bpy.ops, module), name)
                assert {"REGISTER", "UNDO"} <= set(cls.bl_options), cls.bl_idname


def test_extension_package_and_user_directory(user_presets):
    assert preset_ops.extension_package("bl_ext.user_default.atmos.atmos_addon.blender") == "bl_ext.user_default.atmos"
    assert preset_ops.extension_package("atmos_addon.blender") == ""
    with pytest.raises(ValueError):
        preset_ops.extension_package("somewhere.else")
    # from a source checkout: the folder given to presets.set_user_directory
    assert preset_ops.user_directory() == user_presets


# --------------------------------------------------------------------------------------------------------------
# Drawing with a recording layout


_ICONS = set(bpy.types.UILayout.bl_rna.functions["prop"].parameters["icon"].enum_items.keys())


class RecordingLayout:
    """Stands in for ``UILayout``: records calls, returns itself for sub-layouts, checks every name it is given."""

    def __init__(self, calls: list):
        object.__setattr__(self, "calls", calls)

    def __setattr__(self, name, value):
        self.calls.append(("set", name, value))

    def _check(self, kwargs):
        if "icon" in kwargs:
            assert kwargs["icon"] in _ICONS, f"unknown icon {kwargs['icon']!r}"
        if "text" in kwargs:
            assert isinstance(kwargs["text"], str)

    def prop(self, data, name, **kwargs):
        assert name in data.bl_rna.properties.keys(), f"{type(data).__name__} has no property {name!r}"
        self._check(kwargs)
        if "placeholder" in kwargs:
            assert isinstance(kwargs["placeholder"], str)
            self.calls.append(("placeholder", name, kwargs["placeholder"]))
        self.calls.append(("prop", name, kwargs.get("text")))

    def operator(self, idname, **kwargs):
        module, name = idname.split(".")
        assert hasattr(getattr(bpy.ops, module), name), f"no operator {idname}"
        self._check(kwargs)
        self.calls.append(("operator", idname, kwargs.get("text")))
        known = getattr(getattr(bpy.ops, module), name).get_rna_type().properties.keys()
        calls = self.calls

        class Properties:
            def __setattr__(self, key, value):
                assert key in known, f"{idname} has no property {key!r}"
                calls.append(("operator property", idname, key, value))

        return Properties()

    def menu(self, menu, **kwargs):
        assert isinstance(getattr(bpy.types, menu, None), type), f"no menu {menu}"
        self._check(kwargs)
        self.calls.append(("menu", menu, kwargs.get("text")))

    def label(self, **kwargs):
        self._check(kwargs)
        self.calls.append(("label", kwargs.get("text")))

    def separator(self, **kwargs):
        self.calls.append(("separator",))

    def _sub(self, *args, **kwargs):
        self.calls.append(("layout",))
        return self

    row = column = box = split = grid_flow = column_flow = _sub


def draw_everything(scene, screen=None) -> list:
    calls: list = []
    context = SimpleNamespace(scene=scene, screen=screen)
    for cls in ui_panel.CLASSES:
        fake = SimpleNamespace(layout=RecordingLayout(calls), bl_idname=cls.bl_idname)
        if issubclass(cls, bpy.types.Panel) and not cls.poll(context):
            continue
        if hasattr(cls, "draw_header"):
            cls.draw_header(fake, context)
        cls.draw(fake, context)
    return calls


def test_every_panel_draws_for_every_builtin_preset(user_presets):
    scene = bpy.context.scene
    add_sun(scene)
    for name in BUILTINS:
        assert bpy.ops.atmos.preset_apply(name=name) == {"FINISHED"}
        calls = draw_everything(scene)
        menus = [call for call in calls if call[0] == "menu"]
        assert ("menu", "ATMOS_MT_presets", name.title()) in menus
        applies = [call[3] for call in calls if call[:3] == ("operator property", "atmos.preset_apply", "name")]
        assert applies == list(BUILTINS)
    # with a user preset current, edited values, the effect on and a skipped material
    assert bpy.ops.atmos.preset_add(name="Mine") == {"FINISHED"}
    scene.atmos.visibility_km = 12.0
    orchestrator.enable_effect(scene)
    item = scene.atmos.skipped_materials.add()
    item.name, item.reason = "Odd", "no output node"
    calls = draw_everything(scene)
    assert ("menu", "ATMOS_MT_presets", "Mine (modified)") in calls
    assert ("label", "Odd: no output node") in calls
    assert ("label", scene.atmos.status_quality) in calls and scene.atmos.status_quality.startswith("Precise")


def _drawn_labels(calls: list, settings) -> list[str]:
    """The texts drawn in the property-split label column: each property's label (its text, else its name;
    booleans are drawn in the value column and left out), the R/G/B rows' "<label> R", "G", "B" included."""
    labels = []
    properties = settings.bl_rna.properties
    for call in calls:
        if call[0] == "prop" and call[1] in properties.keys():
            prop = properties[call[1]]
            if prop.type == "BOOLEAN" or call[2] == "":   # Mode is a menu now, its label in the column
                continue
            labels.append(call[2] if call[2] is not None else prop.name)
    return labels


def test_labels_fit_the_default_width_and_channels_are_labelled(user_presets):
    """Issue 29: at the Properties editor's default width the label column cut "Rayleigh (1/km)", "Mie Anisotropy",
    "Top Irradiance"...; every label the panels draw, in every quality, measured with Blender's own font code
    (``blf``), fits :data:`panel.LABEL_WIDTH_LIMIT_PX`, and per-channel values are R, G, B rows with a unit."""
    import blf

    scene = bpy.context.scene
    add_sun(scene)
    blf.size(0, 11)
    seen = set()
    for quality in ("FAST", "PRECISE", "AUTO"):
        scene.atmos.quality = quality
        labels = _drawn_labels(draw_everything(scene), scene.atmos)
        for label in labels:
            width = blf.dimensions(0, label)[0]
            assert width <= ui_panel.LABEL_WIDTH_LIMIT_PX, f"label {label!r} is {width:.0f} px wide"
        seen.update(labels)
    assert {"Air, 1/km R", "Haze, 1/km R", "Absorb, 1/km R", "Haze g R", "Space, W/m\u00b2 R", "Channels, nm R", "G",
            "B"} <= seen
    assert blf.dimensions(0, "Rayleigh (1/km) R")[0] > ui_panel.LABEL_WIDTH_LIMIT_PX   # the test can fail


def test_the_world_surface_slot_reads_plainly(user_presets):
    """Issue 29: the World tab's Surface slot showed "Atmos Sky (camera rays: analytic; other rays: table)" and
    "Atmos Sky Ray Switch | Is Camera Ray". Every node Atmos adds to the world has a short label without
    implementation words, under 115 px (GUI Blender 5.2.2 at the default width cut "Atmos Sky and Lighting" in the
    slot and showed "Atmos Sky Background" whole, tools/verify_panel.py), in both engines."""
    import blf

    from atmos_addon import api
    from atmos_addon.blender.apply import world as world_applier

    blf.size(0, 11)
    for engine in ("CYCLES", EEVEE_ENGINE):
        bpy.ops.wm.read_factory_settings(use_empty=True)
        scene = bpy.context.scene
        scene.render.engine = engine
        make_camera(scene)
        add_sun(scene)
        api.enable(scene, preset="clear")
        labels = [node.label for node in scene.world.node_tree.nodes if node.get(world_applier.TAG)]
        assert labels and (engine != "CYCLES" or "Atmos Sky + Light" in labels), labels
        for label in labels:
            assert blf.dimensions(0, label)[0] <= 115.0, label   # "Atmos Sky and Lighting" was cut
            assert not any(word in label.lower() for word in ("analytic", "table", "switch", "camera rays")), label
        # what the slot's rows show for the nodes linked into the surface: the label, with " | socket" when the node
        # has several outputs ("Atmos Sky Background", 124 px, showed whole; 127 px was cut)
        tree = scene.world.node_tree
        output = next(node for node in tree.nodes
                      if node.bl_idname == "ShaderNodeOutputWorld" and node.is_active_output)
        surface = output.inputs["Surface"].links[0].from_node
        shown = [surface.label] + [
            link.from_node.label + (f" | {link.from_socket.name}" if len(link.from_node.outputs) > 1 else "")
            for link in tree.links if link.to_node == surface]
        for text in shown:
            assert blf.dimensions(0, text)[0] <= 124.0, text


def test_the_switch_comes_first_on_the_world_tab(user_presets):
    """The main panel has no header (Blender keeps header-less panels at the top of the region, above Surface), so
    its first row is the switch, labelled, and no header draws it."""
    cls = ui_panel.ATMOS_PT_atmosphere
    assert "HIDE_HEADER" in cls.bl_options and not hasattr(cls, "draw_header")
    calls: list = []
    cls.draw(SimpleNamespace(layout=RecordingLayout(calls), bl_idname=cls.bl_idname),
             SimpleNamespace(scene=bpy.context.scene))
    props = [call for call in calls if call[0] == "prop"]
    assert props[0][1:3] == ("enabled", "Atmosphere"), props[:2]


def test_sub_panels_grey_out_while_the_effect_is_off(user_presets):
    """Issue 29: with the effect off every sub-panel (and the Sky box) greys its contents, as Blender does under a
    header checkbox; with it on they are active."""
    scene = bpy.context.scene
    add_sun(scene)
    context = SimpleNamespace(scene=scene)
    for enabled in (False, True):
        if enabled:
            orchestrator.enable_effect(scene)
        for cls in ui_panel.CLASSES:
            if not issubclass(cls, bpy.types.Panel) or cls.bl_idname in ("ATMOS_PT_atmosphere",
                                                                         "ATMOS_PT_atmosphere_look"):
                continue
            calls: list = []
            fake = SimpleNamespace(layout=RecordingLayout(calls), bl_idname=cls.bl_idname)
            cls.draw(fake, context)
            actives = [call[2] for call in calls if call[:2] == ("set", "active")]
            assert actives and actives[0] is enabled, (cls.bl_idname, enabled, actives)


def test_the_lamp_field_shows_the_lamp_in_use(user_presets):
    """Issue 29: with no lamp picked the Lamp field named nothing while Atmos used the first sun lamp; it now shows
    that lamp as its placeholder, and nothing once a lamp is picked."""
    scene = bpy.context.scene
    assert ("placeholder", "sun_object", "None: Atmos adds one") in draw_everything(scene)
    sun = add_sun(scene)
    assert ("placeholder", "sun_object", sun.name) in draw_everything(scene)
    scene.atmos.sun_object = sun
    assert ("placeholder", "sun_object", "") in draw_everything(scene)


def test_quality_and_mode_are_in_one_place(user_presets):
    """Issue 29: Quality showed twice (a dropdown and a static "Quality" sub-panel); mode and level now live in the
    Quality sub-panel only, and Look Development no longer repeats the preset menu's Import / Export."""
    scene = bpy.context.scene
    add_sun(scene)
    drawn = {}
    context = SimpleNamespace(scene=scene)
    for cls in ui_panel.CLASSES:
        if issubclass(cls, bpy.types.Panel):
            calls: list = []
            cls.draw(SimpleNamespace(layout=RecordingLayout(calls), bl_idname=cls.bl_idname), context)
            drawn[cls.bl_idname] = calls
    owners = {name: [panel for panel, calls in drawn.items() if any(c[:2] == ("prop", name) for c in calls)]
              for name in ("quality", "render_mode")}
    assert owners == {"quality": ["ATMOS_PT_atmosphere_quality"], "render_mode": ["ATMOS_PT_atmosphere_quality"]}
    look = drawn["ATMOS_PT_atmosphere_look"]
    assert not any(c[0] == "operator" and c[1] in ("atmos.preset_import", "atmos.preset_export") for c in look)


# --------------------------------------------------------------------------------------------------------------
# The library operators


def test_the_panel_says_what_the_viewport_shows(user_presets):
    """One line under the mode row, from what GUI Blender 4.3.2 and 5.2.2 showed (docs/viewport.md): Eevee's
    viewport compositor gets the AOVs, Cycles' gets no passes, In-Render is shading (Cycles)."""
    scene = bpy.context.scene
    add_sun(scene)
    expected = {
        ("CYCLES", "COMPOSITOR"): "Cycles viewport: no haze",
        ("CYCLES", "PER_PIXEL"): "Cycles viewport: no haze",
        ("CYCLES", "IN_RENDER"): "haze shows in Rendered shading",
        (EEVEE_ENGINE, "COMPOSITOR"): "Compositor to Always",
        (EEVEE_ENGINE, "IN_RENDER"): "Compositor to Always",   # Eevee renders it as Compositor
        ("BLENDER_WORKBENCH", "PER_PIXEL"): "This engine renders no Atmos haze",
    }
    for (engine, mode), words in expected.items():
        scene.render.engine, scene.atmos.render_mode = engine, mode
        assert words in ui_panel.viewport_note(scene), (engine, mode, ui_panel.viewport_note(scene))
        assert ("label", ui_panel.viewport_note(scene)) not in draw_everything(scene)   # off: no viewport line
    orchestrator.enable_effect(scene)
    scene.render.engine, scene.atmos.render_mode = "CYCLES", "COMPOSITOR"
    assert ("label", ui_panel.viewport_note(scene)) in draw_everything(scene)
    # Eevee's hint shows only while no 3D viewport has its compositor on Always (issue 29)
    scene.render.engine = EEVEE_ENGINE
    hint = ("label", ui_panel.viewport_note(scene))
    for setting, shown in (("DISABLED", True), ("CAMERA", True), ("ALWAYS", False)):
        shading = SimpleNamespace(use_compositor=setting)
        screen = SimpleNamespace(areas=[SimpleNamespace(type="VIEW_3D", spaces=[
            SimpleNamespace(type="VIEW_3D", shading=shading)])])
        assert (hint in draw_everything(scene, screen=screen)) is shown, setting
    # every line the main panel can show fits the default width (blf, Blender's font code)
    import blf

    blf.size(0, 11)
    lines = [ui_panel.OFF_LINE] + [plan_module.viewport_note(engine, mode) for engine in
                                   ("CYCLES", EEVEE_ENGINE, "BLENDER_WORKBENCH") for mode in plan_module.MODES]
    from atmos_addon.physics.quality import Level, level_summary

    lines += [f"{level.value.capitalize()}: {level_summary(level, multiple, mode)}" for level in Level
              for multiple in (False, True) for mode in plan_module.MODES]
    for line in lines:
        assert blf.dimensions(0, line)[0] <= ui_panel.LINE_WIDTH_LIMIT_PX, line


def test_the_panel_says_why_the_mode_differs_and_when_eevee_shows_a_flat_sky(user_presets):
    """With OSL on in Cycles the panel says the haze is applied In-Render and why; with a camera clip range over
    Eevee's limit it says to raise Clip Start (and by how much); otherwise neither line is drawn."""
    scene = bpy.context.scene
    add_sun(scene)
    camera = make_camera(scene, clip_start=0.1, clip_end=1000.0)
    labels = lambda: [call[1] for call in draw_everything(scene) if call[0] == "label"]  # noqa: E731
    scene.render.engine = "CYCLES"
    assert not any("Open Shading" in text or "Clip Start" in text for text in labels() if text)
    scene.cycles.shading_system = True
    assert any(text and text.startswith("Open Shading Language is on") for text in labels())
    scene.cycles.shading_system = False
    scene.render.engine = EEVEE_ENGINE
    camera.data.clip_end = 5.0e6
    assert "Eevee renders the sky one flat colour: raise Clip Start to at least 0.312 m" in " ".join(
        text for text in labels() if text)   # a note is drawn over several lines (wrapped to the panel's width)
    camera.data.clip_start = 1.0
    assert not any(text and "Clip Start" in text for text in labels())


def test_notes_are_wrapped_to_the_default_width(user_presets):
    """Every note the panel can show (OSL, Eevee's clip range, keyed settings) is drawn whole over lines that each fit
    the default width (Blender's font code, ``blf``), where one label cut it ("Open Shading Language is on: Cy...")."""
    import blf

    scene = bpy.context.scene
    add_sun(scene)
    camera = make_camera(scene, clip_start=0.1, clip_end=5.0e6)
    scene.render.engine = EEVEE_ENGINE
    scene.atmos.keyframe_insert("mie_scattering_per_km", frame=1)
    notes = facts.plan_of(scene).notes
    assert any(note.startswith("Camera Clip End") for note in notes)
    assert any(note.startswith("Keyframed or driven") for note in notes)
    scene.render.engine = "CYCLES"
    scene.cycles.shading_system = True
    notes += (plan_module.NOTE_OSL,)
    blf.size(0, ui_panel.UI_FONT_PX)
    assert blf.dimensions(0, plan_module.NOTE_OSL)[0] > ui_panel.LINE_WIDTH_LIMIT_PX   # the test can fail
    drawn = [call[1] for call in draw_everything(scene) if call[0] == "label" and call[1]]
    scene.render.engine = EEVEE_ENGINE
    scene.cycles.shading_system = False
    drawn += [call[1] for call in draw_everything(scene) if call[0] == "label" and call[1]]
    for note in notes:
        lines = ui_panel.wrapped(note)
        assert " ".join(lines) == note
        assert all(blf.dimensions(0, line)[0] <= ui_panel.LINE_WIDTH_LIMIT_PX for line in lines), lines
        assert all(line in drawn for line in lines), (note, drawn)
    camera.data.clip_start = 1.0


def test_apply_preset_sets_settings_within_float32_and_the_sun(user_presets):
    scene = bpy.context.scene
    add_sun(scene, 40.0)
    for name in BUILTINS:
        before = sun_elevation_deg(scene)
        assert bpy.ops.atmos.preset_apply(name=name) == {"FINISHED"}
        preset = presets.load(name)
        assert_settings_match(scene, preset.atmosphere)
        assert scene.atmos.preset_name == name
        expected = before if preset.sun_elevation_deg is None else preset.sun_elevation_deg
        assert sun_elevation_deg(scene) == pytest.approx(expected, abs=1e-3), name
        assert not preset_ops.is_modified(scene)


def test_a_fresh_tick_shows_the_clear_presets_own_numbers(user_presets):
    bpy.ops.wm.read_factory_settings(use_empty=True)   # no world, no sun: Atmos adds them
    scene = bpy.context.scene
    scene.atmos.enabled = True
    assert scene.atmos.preset_name == "clear" and not preset_ops.is_modified(scene)
    assert_settings_match(scene, presets.load("clear").atmosphere)
    assert round(scene.atmos.visibility_km, 1) == 70.0   # the preset's stated visibility, in km


def test_a_holdout_that_differs_between_view_layers_is_named_in_the_panel_with_its_edge_error(user_presets):
    """Held out in every rendered view layer, the objects are marked and their edges exact: no note. Held out in one
    layer and not in another that renders too, they are not, and the panel names the error."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    make_camera(scene)
    held = bpy.data.collections.new("Foreground")
    scene.collection.children.link(held)
    make_plane(bpy.context.scene, "Plate", [(-1, 5, -1), (1, 5, -1), (1, 5, 1), (-1, 5, 1)])
    plate = bpy.data.objects["Plate"]
    for collection in plate.users_collection:
        collection.objects.unlink(plate)
    held.objects.link(plate)
    scene.atmos.enabled = True
    assert plan_module.NOTE_HOLDOUT not in facts.plan_of(scene).notes
    scene.view_layers[0].layer_collection.children["Foreground"].holdout = True
    assert plan_module.NOTE_HOLDOUT not in facts.plan_of(scene).notes
    scene.view_layers.new("Beauty")   # renders too, and holds nothing out
    assert plan_module.NOTE_HOLDOUT in facts.plan_of(scene).notes
    lines = [call[1] for call in draw_everything(scene) if call[0] == "label"]
    assert " ".join(ui_panel.wrapped(plan_module.NOTE_HOLDOUT)) == " ".join(
        line for line in lines if line in ui_panel.wrapped(plan_module.NOTE_HOLDOUT))


def test_eevees_depth_of_field_and_motion_blur_are_named_in_the_panel(user_presets):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    make_camera(scene)
    scene.render.engine = EEVEE_ENGINE
    scene.atmos.enabled = True
    assert not any(note.startswith("Eevee blurs") for note in facts.plan_of(scene).notes)
    scene.camera.data.dof.use_dof = True
    scene.render.use_motion_blur = True
    (note,) = [note for note in facts.plan_of(scene).notes if note.startswith("Eevee blurs")]
    assert "depth of field up to 31 %" in note and "motion blur up to 26 %" in note
    scene.render.engine = "CYCLES"
    assert not any(note.startswith("Eevee blurs") for note in facts.plan_of(scene).notes)


def test_planet_lengths_show_in_kilometres(user_presets):
    """The panel's Planet and Air Top fields are km views of the metre settings the presets and the core keep:
    reading gives the preset's metres / 1000, writing sets the metres (and so the atmosphere)."""
    settings = bpy.context.scene.atmos
    bpy.ops.atmos.preset_apply(name="mars")
    mars = presets.load("mars").atmosphere
    assert settings.planet_radius_km == pytest.approx(mars.planet_radius / 1000.0, rel=1e-6)
    assert settings.atmosphere_height_km == pytest.approx(mars.atmosphere_height / 1000.0, rel=1e-6)
    settings.planet_radius_km = 6000.0
    settings.atmosphere_height_km = 80.0
    assert settings.planet_radius == pytest.approx(6.0e6, rel=1e-6)
    assert settings.atmosphere_height == pytest.approx(8.0e4, rel=1e-6)


def test_haze_and_air_density_read_and_write_the_coefficients(user_presets):
    settings = bpy.context.scene.atmos
    bpy.ops.atmos.preset_apply(name="clear")
    assert settings.air_density == pytest.approx(1.0, rel=1e-5)
    clear = presets.load("clear").atmosphere  # the channels stand for 648.1, 547.4, 443.1 nm: read at 550 nm
    assert settings.visibility_km == pytest.approx(3.912 / extinction_550_per_m(clear) / 1000.0, rel=1e-5)
    assert settings.visibility_km == pytest.approx(70.0, rel=2e-4)  # the preset's stated visibility
    ratio = np.divide(settings.mie_absorption_per_km, settings.mie_scattering_per_km)
    colour = np.asarray(clear.mie_scattering) / np.max(clear.mie_scattering)
    np.testing.assert_allclose(settings.haze_colour, colour, rtol=1e-5)
    settings.visibility_km = 10.0
    assert settings.visibility_km == pytest.approx(10.0, rel=1e-4)
    np.testing.assert_allclose(settings.haze_colour, colour, rtol=1e-5)   # the haze keeps its colour
    np.testing.assert_allclose(np.divide(settings.mie_absorption_per_km, settings.mie_scattering_per_km), ratio,
                               rtol=1e-5)
    settings.haze_colour = (1.0, 0.8, 0.5)   # a warm dust: the visibility and the absorption ratios stay
    np.testing.assert_allclose(settings.haze_colour, (1.0, 0.8, 0.5), rtol=1e-5)
    assert settings.visibility_km == pytest.approx(10.0, rel=1e-4)
    np.testing.assert_allclose(np.divide(settings.mie_absorption_per_km, settings.mie_scattering_per_km), ratio,
                               rtol=1e-5)
    settings.haze_colour = (0.0, 0.0, 0.0)   # black has no tint: clamped, the haze stays a haze of that visibility
    assert settings.visibility_km == pytest.approx(10.0, rel=1e-4)
    assert min(settings.mie_scattering_per_km) > 0.0
    rayleigh = np.array(settings.rayleigh_scattering_per_km)
    settings.air_density = 0.5
    np.testing.assert_allclose(settings.rayleigh_scattering_per_km, rayleigh * 0.5, rtol=1e-5)
    assert preset_ops.is_modified(bpy.context.scene)


def test_save_round_trips_rename_and_delete(user_presets):
    scene = bpy.context.scene
    add_sun(scene, 25.0)
    bpy.ops.atmos.preset_apply(name="overcast")
    scene.atmos.visibility_km = 7.0
    scene.atmos.mie_g = (0.5, 0.6, 0.7)
    assert bpy.ops.atmos.preset_add(name="Look A", include_sun=True) == {"FINISHED"}
    saved = snapshot(scene)
    assert (user_presets / "Look A.toml").is_file() and "Look A" in presets.names(user_presets)
    assert scene.atmos.preset_name == "Look A"
    preset = presets.load("Look A", user_presets)
    assert preset.sun_elevation_deg == pytest.approx(25.0, abs=1e-3)
    with pytest.raises(RuntimeError, match="exists"):
        bpy.ops.atmos.preset_add(name="Look A")
    assert bpy.ops.atmos.preset_add(name="Look A", include_sun=True, overwrite=True) == {"FINISHED"}
    with pytest.raises(RuntimeError, match="built-in"):
        bpy.ops.atmos.preset_add(name="Clear")

    bpy.ops.atmos.preset_apply(name="mars")
    assert bpy.ops.atmos.preset_apply(name="Look A") == {"FINISHED"}
    back = snapshot(scene)
    for key in saved:  # the float32 settings come back bit for bit through float64 and TOML
        if key not in ("status_sun", "suns"):
            assert back[key] == saved[key], key
    assert sun_elevation_deg(scene) == pytest.approx(25.0, abs=1e-3)

    assert bpy.ops.atmos.preset_rename(name="Look A", new_name="Look B") == {"FINISHED"}
    assert presets.names(user_presets)[-1] == "Look B" and scene.atmos.preset_name == "Look B"
    assert not (user_presets / "Look A.toml").exists()
    with pytest.raises(RuntimeError, match="built-in"):
        bpy.ops.atmos.preset_rename(name="sunset", new_name="dusk")
    with pytest.raises(RuntimeError, match="built-in"):
        bpy.ops.atmos.preset_remove(name="clear")
    assert (presets.BUILTIN_DIRECTORY / "clear.toml").is_file()
    assert bpy.ops.atmos.preset_remove(name="Look B") == {"FINISHED"}
    assert presets.names(user_presets) == list(BUILTINS) and scene.atmos.preset_name == ""


def test_import_and_export(user_presets, tmp_path):
    scene = bpy.context.scene
    bpy.ops.atmos.preset_apply(name="sunset")
    scene.atmos.air_density = 1.3
    current = settings_io.atmosphere_from_settings(scene.atmos)
    exported = tmp_path / "out" / "Dusty dusk.toml"
    assert bpy.ops.atmos.preset_export(filepath=str(exported)) == {"FINISHED"}
    assert presets.validate_file(exported).name == "Dusty dusk"
    library = tmp_path / "out" / "mars copy.toml"
    assert bpy.ops.atmos.preset_export(filepath=str(library), name="mars") == {"FINISHED"}
    assert library.read_bytes() == (presets.BUILTIN_DIRECTORY / "mars.toml").read_bytes()

    bpy.ops.atmos.preset_apply(name="clear")
    assert bpy.ops.atmos.preset_import(filepath=str(exported)) == {"FINISHED"}
    assert (user_presets / "Dusty dusk.toml").read_bytes() == exported.read_bytes()
    assert scene.atmos.preset_name == "Dusty dusk"
    assert_settings_match(scene, current)
    with pytest.raises(RuntimeError, match="exists"):
        bpy.ops.atmos.preset_import(filepath=str(exported))
    assert bpy.ops.atmos.preset_import(filepath=str(exported), overwrite=True, apply=False) == {"FINISHED"}


_GOOD_HEAD = 'schema_version = 1\n[preset]\nname = "bad"\n[sun]\nelevation_deg = 12.0\n'
BAD_FILES = {
    "syntax error": ('schema_version = 1\n[preset\nname = "bad"\n', "line 2", "TOML syntax error"),
    "unknown field": (_GOOD_HEAD + '[atmosphere]\nmie_scatter_per_m = [1e-5, 1e-5, 1e-5]\n',
                      "[atmosphere] mie_scatter_per_m", "did you mean 'mie_scattering_per_m'"),
    "wrong type": (_GOOD_HEAD + '[atmosphere]\nmie_g = "forward"\n', "[atmosphere] mie_g", "must be a number"),
    "out of range": (_GOOD_HEAD + '[atmosphere]\nplanet_radius_m = 10.0\n', "[atmosphere] planet_radius_m",
                     "must be in"),
    "outside the settings": (_GOOD_HEAD + '[atmosphere]\nmie_g = 0.9995\n', "[atmosphere] mie_g",
                             "outside what Atmos settings hold"),
    "huge file": (_GOOD_HEAD + "#" * (70 * 1024) + "\n", "file size", "over the 64 KiB limit"),
}


@pytest.mark.parametrize("kind", BAD_FILES)
def test_bad_preset_files_are_refused_and_change_nothing(user_presets, tmp_path, kind):
    text, field, rule = BAD_FILES[kind]
    scene = bpy.context.scene
    add_sun(scene, 33.0)
    bpy.ops.atmos.preset_apply(name="overcast")
    scene.atmos.visibility_km = 5.0
    before = snapshot(scene)
    bad = tmp_path / "bad.toml"
    bad.write_text(text, encoding="utf-8")
    with pytest.raises(RuntimeError) as raised:
        bpy.ops.atmos.preset_import(filepath=str(bad))
    message = str(raised.value)
    assert "bad.toml" in message and field in message and rule in message, message
    assert not (user_presets / "bad.toml").exists()
    assert snapshot(scene) == before
    # the same file already in the library: applying it by name is refused the same way
    user_presets.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(bad, user_presets / "bad.toml")
    with pytest.raises(RuntimeError) as raised:
        bpy.ops.atmos.preset_apply(name="bad")
    assert field in str(raised.value) and rule in str(raised.value)
    assert snapshot(scene) == before


# --------------------------------------------------------------------------------------------------------------
# Rendering


@pytest.mark.parametrize("engine", ENGINES)
def test_every_builtin_renders_without_nan(user_presets, engine):
    scene = bpy.context.scene
    tiny_scene(scene, engine, 16, 16)
    means = []
    for name in BUILTINS:
        assert bpy.ops.atmos.preset_apply(name=name) == {"FINISHED"}
        image = render_to_array(scene)
        assert np.all(np.isfinite(image)), f"{name} in {engine}: NaN or infinity"
        means.append(image[..., :3].mean(axis=(0, 1)))
    assert np.ptp(np.array(means), axis=0).max() > 1e-3  # the presets change the picture


def _cells(sheet: np.ndarray, rows: int, columns: int, cell: tuple[int, int]):
    width, height = cell
    strip = contact_sheet.label_height(width)
    for row in range(rows):
        for column in range(columns):
            top, left = row * (height + strip), column * width
            yield (sheet[top:top + height, left:left + width, :3],
                   sheet[top + height:top + height + strip, left:left + width, :3])


def _read_png(path: Path) -> np.ndarray:
    image = bpy.data.images.load(str(path), check_existing=False)
    width, height = image.size
    pixels = np.empty(width * height * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    bpy.data.images.remove(image)
    return pixels.reshape(height, width, 4)[::-1]


def test_contact_sheet_size_cells_labels_and_scene_restored(user_presets, tmp_path):
    scene = bpy.context.scene
    tiny_scene(scene, "CYCLES", 16, 16)
    bpy.ops.atmos.preset_apply(name="sunset")
    scene.atmos.visibility_km = 30.0
    before = snapshot(scene)
    seen = []
    path = contact_sheet.render_contact_sheet(scene, ["clear", "mars"], [60.0, 5.0], cell_size=(32, 18),
                                              output_path=tmp_path / "sheet.png",
                                              progress=lambda done, total: seen.append((done, total)), samples=4)
    assert snapshot(scene) == before
    assert seen == [(1, 4), (2, 4), (3, 4), (4, 4)]
    expected = contact_sheet.sheet_size(2, 2, (32, 18))
    assert expected == (64, 2 * (18 + contact_sheet.label_height(32)))
    assert tuple(bpy.data.images[contact_sheet.IMAGE_NAME].size) == expected
    sheet = _read_png(path)
    assert (sheet.shape[1], sheet.shape[0]) == expected
    cells = list(_cells(sheet, 2, 2, (32, 18)))
    means = np.array([cell.mean(axis=(0, 1)) for cell, _ in cells])
    for i in range(4):
        for j in range(i + 1, 4):
            assert np.abs(means[i] - means[j]).max() > 2.0 / 255.0, (i, j, means)
    background = np.array(contact_sheet.LABEL_BACKGROUND[:3])
    for _, strip in cells:
        assert (np.abs(strip - background).max(axis=-1) > 0.1).sum() >= 10  # some ink in every label


def test_contact_sheet_cancel_and_bad_preset_restore_the_scene(user_presets, tmp_path):
    scene = bpy.context.scene
    tiny_scene(scene, "CYCLES", 16, 16)
    bpy.ops.atmos.preset_apply(name="overcast")
    before = snapshot(scene)
    done = []
    with pytest.raises(contact_sheet.ContactSheetCancelled):
        contact_sheet.render_contact_sheet(scene, ["clear", "mars"], [60.0, 5.0], cell_size=(32, 18),
                                           output_path=tmp_path / "cancelled.png", samples=1,
                                           progress=lambda d, t: done.append(d), should_cancel=lambda: bool(done))
    assert done == [1]
    assert not (tmp_path / "cancelled.png").exists()
    assert snapshot(scene) == before
    with pytest.raises(presets.PresetError):
        contact_sheet.render_contact_sheet(scene, ["clear", "no such preset"], [10.0], cell_size=(16, 16))
    assert snapshot(scene) == before


def test_contact_sheet_operator_runs_synchronously_in_background(user_presets, tmp_path):
    scene = bpy.context.scene
    tiny_scene(scene, "CYCLES", 16, 16)
    bpy.data.objects.remove(scene.objects["Sun"])  # the sheet creates a sun lamp to point, then removes it
    orchestrator.update(scene)  # what the depsgraph handler does in the UI
    before = snapshot(scene)
    out = tmp_path / "op.png"
    assert bpy.ops.atmos.contact_sheet(presets="clear, sunset", elevations="30", cell_width=16, cell_height=8,
                                       samples=1, filepath=str(out)) == {"FINISHED"}
    assert out.is_file() and tuple(bpy.data.images[contact_sheet.IMAGE_NAME].size) == (16, 2 * (8 + 9))
    assert snapshot(scene) == before
    with pytest.raises(RuntimeError, match="not a number"):
        bpy.ops.atmos.contact_sheet(elevations="high", filepath=str(out))
