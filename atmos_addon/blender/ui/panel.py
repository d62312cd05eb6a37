# SPDX-License-Identifier: GPL-3.0-or-later
"""The "Atmosphere" panel in World properties, its sub-panels and the preset menus.

Layout (top to bottom): a header switch for the whole effect (aerial perspective, sky, sun lamp);
the preset row (menu of built-in then user presets, + to save, - to delete the current user
preset, a menu for rename/import/export/contact sheet); sub-panels Air and Haze (with Advanced),
Sun, Sky, Quality (mode and level, the one place for both), Aerial Perspective and Look Development.
Labels are short enough for the Properties editor's default width (:data:`LABEL_WIDTH_LIMIT_PX`); the full
story is in each property's tooltip. Per-channel quantities are labelled R, G, B rows with their unit; the
sub-panels grey out while the effect is off. Every control is a property of
``scene.atmos`` or an operator, so edits apply live and undo like any Blender value. The preset
menu is data-driven by :mod:`atmos_addon.presets` (Blender's Python preset files are never used).
"""

from __future__ import annotations

import bpy

from ... import presets
from ...plan import NOTE_IN_RENDER_FAST, VIEWPORT_EEVEE_HINT
from .. import facts, group_integrity, scene_reading
from . import preset_ops


def _settings(context):
    return context.scene.atmos


def preset_label(name: str) -> str:
    """How a preset name shows in the menu: built-ins title-cased ("sunset" -> "Sunset"), user names as typed."""
    return name.title() if presets.is_builtin(name) else name


# --------------------------------------------------------------------------------------------------------------
# Preset menus


class ATMOS_MT_presets(bpy.types.Menu):
    """Atmosphere presets: built-in ones, then yours"""

    bl_label = "Atmosphere Presets"
    bl_idname = "ATMOS_MT_presets"

    def draw(self, context):
        layout = self.layout
        current = _settings(context).preset_name
        names = preset_ops.library_names()
        for index, name in enumerate(names):
            if index == len(presets.BUILTIN_NAMES):
                layout.separator()
            icon = "CHECKMARK" if name == current else "NONE"
            layout.operator("atmos.preset_apply", text=preset_label(name), icon=icon).name = name
        if len(names) == len(presets.BUILTIN_NAMES):
            layout.separator()
            layout.label(text="No user presets yet: + saves the current settings")


class ATMOS_MT_preset_specials(bpy.types.Menu):
    """More preset actions"""

    bl_label = "Preset Actions"
    bl_idname = "ATMOS_MT_preset_specials"

    def draw(self, context):
        layout = self.layout
        current = _settings(context).preset_name
        row = layout.row()
        row.enabled = bool(current) and not presets.is_builtin(current)
        row.operator("atmos.preset_rename", text="Rename Preset...", icon="GREASEPENCIL").name = current
        layout.separator()
        layout.operator("atmos.preset_import", text="Import Preset...", icon="IMPORT")
        layout.operator("atmos.preset_export", text="Export Current Settings...", icon="EXPORT")
        layout.separator()
        layout.operator("atmos.contact_sheet", text="Render Contact Sheet...", icon="IMGDISPLAY")


def draw_preset_row(layout, context) -> None:
    """Blender's preset header: the menu, + and - buttons, and the actions menu."""
    settings = _settings(context)
    current = settings.preset_name
    text = preset_label(current) if current else "Presets"
    if current and preset_ops.is_modified(context.scene):
        text += " (modified)"
    row = layout.row(align=True)
    row.menu("ATMOS_MT_presets", text=text, icon="PRESET")
    row.operator("atmos.preset_add", text="", icon="ADD")
    remove = row.row(align=True)
    remove.enabled = bool(current) and not presets.is_builtin(current)
    remove.operator("atmos.preset_remove", text="", icon="REMOVE").name = current
    row.menu("ATMOS_MT_preset_specials", text="", icon="DOWNARROW_HLT")


# --------------------------------------------------------------------------------------------------------------
# Panels


class _WorldPanel:
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "world"

    @classmethod
    def poll(cls, context):
        return context.scene is not None and getattr(context.scene, "atmos", None) is not None


class _SubPanel(_WorldPanel):
    bl_parent_id = "ATMOS_PT_atmosphere"


def _split(layout):
    """Blender's property-split layout (labels left, values right), no animation decorators."""
    layout.use_property_split = True
    layout.use_property_decorate = False
    return layout


#: Widest label text, px at Blender's 11 px interface font and scale 1, that the property-split label column shows
#: uncut at the Properties editor's default width: Blender's factory layout on a 1920 x 1080 screen gives it 339 px
#: (region 309 px, label room about 92 px at scale 1, measured by tools/verify_panel.py in GUI Blender 5.2.2).
LABEL_WIDTH_LIMIT_PX = 90
#: Widest full-width line with an icon (the main panel's notes) the default width shows uncut, px.
LINE_WIDTH_LIMIT_PX = 230
#: Interface font size, px at scale 1, that :func:`wrapped` measures with.
UI_FONT_PX = 11


def wrapped(text: str, limit_px: float = LINE_WIDTH_LIMIT_PX) -> list[str]:
    """``text`` as lines of whole words, each at most ``limit_px`` wide in Blender's interface font (``blf``): a note
    longer than the panel is drawn over several labels instead of being cut ("Open Shading Language is on: Cy...").
    A single word wider than the limit stays whole on its own line."""
    import blf

    blf.size(0, UI_FONT_PX)
    lines: list[str] = []
    for word in text.split():
        if lines and blf.dimensions(0, f"{lines[-1]} {word}")[0] <= limit_px:
            lines[-1] = f"{lines[-1]} {word}"
        else:
            lines.append(word)
    return lines


#: The main panel's line while the effect is off.
OFF_LINE = "Off: tick the box to add the atmosphere"


def _channels(layout, settings, name: str, label: str) -> None:
    """A per-channel (red, green, blue) quantity as Blender draws a vector (Location X, Y, Z): three aligned rows
    labelled "<label> R", "G", "B", each value at full width. One row of three fields showed "0.0" for 0.0058 at the
    default width (Blender drops digits to fit a narrow field) and, split, no value at all (GUI Blender 5.2.2)."""
    column = layout.column(align=True)
    for index, channel in enumerate("RGB"):
        column.prop(settings, name, index=index, text=f"{label} {channel}" if index == 0 else channel)


def _active_when_on(layout, settings):
    """Grey a sub-panel's contents while the effect is off (as Blender does under a header checkbox)."""
    layout.active = settings.enabled
    return layout


def lamp_placeholder(scene) -> str:
    """What the empty Lamp field shows: the name of the lamp Atmos uses instead (the first sun lamp that renders; the
    field's tooltip says so), or that none is there."""
    lamp = scene_reading.sun_object(scene)
    if scene.atmos.sun_object is not None:
        return ""
    return lamp.name if lamp is not None else "None: Atmos adds one"


def viewport_compositor_always(context) -> bool:
    """True when a 3D viewport of the window shows the viewport compositor always (Eevee then shows the haze in
    Rendered shading, so the hint to switch it on has nothing left to ask)."""
    for area in getattr(getattr(context, "screen", None), "areas", ()):
        if area.type == "VIEW_3D":
            if any(space.type == "VIEW_3D" and space.shading.use_compositor == "ALWAYS" for space in area.spaces):
                return True
    return False


def viewport_note(scene) -> str:
    """What the 3D viewport's Rendered shading shows of the aerial perspective, in one line (the plan's)."""
    return facts.plan_of(scene).viewport


class ATMOS_PT_atmosphere(_WorldPanel, bpy.types.Panel):
    """Physically based aerial perspective, sky and sunlight of the scene."""

    bl_label = "Atmosphere"
    bl_idname = "ATMOS_PT_atmosphere"
    #: No header: Blender keeps header-less panels at the top of the region, right under the World selector, where
    #: the artist looks first (a panel with a header is placed after the World panels the startup file already
    #: holds, Surface, Volume, Mist Pass and Settings, whatever its ``bl_order``). The switch is the first row.
    bl_options = {"HIDE_HEADER"}

    def draw(self, context):
        layout = self.layout
        settings = _settings(context)
        layout.prop(settings, "enabled", text="Atmosphere")
        draw_preset_row(_active_when_on(layout.column(), settings), context)
        plan = facts.plan_of(context.scene)
        for note in plan.notes:
            if note != NOTE_IN_RENDER_FAST:   # that one is part of the quality status line
                icon = "ERROR" if note.startswith(("Camera Clip End", "Keyframed or driven")) else "INFO"
                column = layout.column(align=True)
                for index, line in enumerate(wrapped(note)):
                    column.label(text=line, icon=icon if index == 0 else "BLANK1")
        if not settings.enabled:
            layout.label(text=OFF_LINE, icon="INFO")
        elif not (plan.viewport == VIEWPORT_EEVEE_HINT and viewport_compositor_always(context)):
            layout.label(text=plan.viewport, icon="VIEW3D")


class ATMOS_PT_atmosphere_air(_SubPanel, bpy.types.Panel):
    """Air and haze: the scattering coefficients and the simple controls that set them."""

    bl_label = "Air and Haze"
    bl_idname = "ATMOS_PT_atmosphere_air"

    def draw(self, context):
        settings = _settings(context)
        layout = _active_when_on(_split(self.layout), settings)
        column = layout.column()
        column.prop(settings, "visibility_km", text="Visibility, km")
        column.prop(settings, "haze_colour", text="Haze Colour")
        column.prop(settings, "air_density")


class ATMOS_PT_atmosphere_advanced(_SubPanel, bpy.types.Panel):
    """The coefficients behind Visibility, Haze Colour and Air Density; phase, layer heights, planet and
    channel wavelengths."""

    bl_label = "Advanced"
    bl_idname = "ATMOS_PT_atmosphere_advanced"
    bl_parent_id = "ATMOS_PT_atmosphere_air"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        settings = _settings(context)
        layout = _active_when_on(_split(self.layout), settings)
        column = layout.column()
        _channels(column, settings, "rayleigh_scattering_per_km", "Air, 1/km")
        _channels(column, settings, "mie_scattering_per_km", "Haze, 1/km")
        _channels(column, settings, "mie_absorption_per_km", "Absorb, 1/km")
        column.separator()
        _channels(column, settings, "mie_g", "Haze g")
        column.separator()
        column.prop(settings, "rayleigh_scale_height", text="Air Layer")
        column.prop(settings, "mie_scale_height", text="Haze Layer")
        column.separator()
        column.prop(settings, "planet_radius_km", text="Planet, km")
        column.prop(settings, "atmosphere_height_km", text="Air Top, km")
        column.prop(settings, "ozone_column_du", text="Ozone, DU")
        column.separator()
        _channels(column, settings, "wavelengths_nm", "Channels, nm")


class ATMOS_PT_atmosphere_sun(_SubPanel, bpy.types.Panel):
    """The sun: which lamp, where it is, how bright it is above the air, and what reaches the ground."""

    bl_label = "Sun"
    bl_idname = "ATMOS_PT_atmosphere_sun"

    def draw(self, context):
        settings = _settings(context)
        layout = _active_when_on(_split(self.layout), settings)
        column = layout.column()
        column.prop(settings, "sun_object", text="Lamp", placeholder=lamp_placeholder(context.scene))
        column.prop(settings, "sun_elevation", text="Elevation")
        column.prop(settings, "sun_azimuth", text="Azimuth")
        column.separator()
        _channels(column, settings, "sun_irradiance_top", "Space, W/m\u00b2")
        column.prop(settings, "sun_angular_diameter", text="Diameter")
        column.prop(settings, "sun_limb_darkening", text="Limb Dark.")
        column.separator()
        ground = column.column()
        ground.enabled = False  # results, written by Atmos from the atmosphere and the sun
        ground.prop(settings, "sun_colour_display", text="Ground")
        ground.prop(settings, "sun_strength_display", text="W/m\u00b2")
        column.separator()
        column.prop(settings, "drive_sun_lamp")


class ATMOS_PT_atmosphere_sky(_SubPanel, bpy.types.Panel):
    """The sky world: on/off, and what is below the horizon."""

    bl_label = "Sky"
    bl_idname = "ATMOS_PT_atmosphere_sky"

    def draw_header(self, context):
        _active_when_on(self.layout, _settings(context)).prop(_settings(context), "sky_enabled", text="")

    def draw(self, context):
        settings = _settings(context)
        layout = _split(self.layout)
        layout.active = settings.enabled and settings.sky_enabled
        column = layout.column()
        column.prop(settings, "sky_ground", text="Ground")
        albedo = column.row()
        albedo.active = settings.sky_ground == "ALBEDO"
        albedo.prop(settings, "ground_albedo", text="Albedo")
        if settings.enabled and settings.sky_enabled:
            precise = facts.plan_of(context.scene).sky_level == "precise"
            column.label(text="Sky: Precise table" if precise else "Sky: virtual dome")


class ATMOS_PT_atmosphere_aerial(_SubPanel, bpy.types.Panel):
    """Aerial perspective on objects: the distance scale and what Atmos built and skipped."""

    bl_label = "Aerial Perspective"
    bl_idname = "ATMOS_PT_atmosphere_aerial"

    def draw(self, context):
        settings = _settings(context)
        layout = _active_when_on(_split(self.layout), settings)
        layout.prop(settings, "distance_scale", text="Distance \u00d7")
        layout.operator("atmos.refresh", icon="FILE_REFRESH")
        if not settings.enabled:
            return
        edited = group_integrity.edited_groups()
        if edited:
            box = layout.box()
            for name in edited:
                box.label(text=group_integrity.warning(name), icon="ERROR")
            box.operator("atmos.reset_groups", icon="LOOP_BACK")
        status = layout.column(align=True)
        # what was built, with its node counts (status_built), goes to the report, not the panel
        for line in (settings.status_sun, settings.status_materials, settings.status_objects):
            if line:
                status.label(text=line)
        if len(settings.skipped_materials):
            box = layout.box()
            box.label(text=f"Skipped materials ({len(settings.skipped_materials)})", icon="ERROR")
            for item in settings.skipped_materials:
                box.label(text=f"{item.name}: {item.reason}")


class ATMOS_PT_atmosphere_quality(_SubPanel, bpy.types.Panel):
    """Where the haze is applied (mode) and how accurately (quality level): the one place for both."""

    bl_label = "Quality"
    bl_idname = "ATMOS_PT_atmosphere_quality"

    def draw(self, context):
        settings = _settings(context)
        layout = _active_when_on(_split(self.layout), settings)
        layout.prop(settings, "render_mode", text="Mode")   # a menu: expanded, its three names were cut
        layout.prop(settings, "quality")
        if settings.quality == "AUTO":
            layout.prop(settings, "auto_tolerance")
        if settings.quality == "PRECISE" or (settings.quality == "AUTO" and settings.auto_level == "precise"):
            layout.prop(settings, "origin_altitude", text="Altitude, m")
            layout.prop(settings, "multiple_scattering")
        if settings.enabled and settings.status_quality:
            for line in settings.status_quality.split(". "):   # the level's line, then In-Render's note
                layout.label(text=line)


class ATMOS_PT_atmosphere_look(_SubPanel, bpy.types.Panel):
    """Look development: compare presets and sun elevations side by side, and match a photograph of the location."""

    bl_label = "Look Development"
    bl_idname = "ATMOS_PT_atmosphere_look"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        self.layout.operator("atmos.contact_sheet", icon="IMGDISPLAY")   # import / export: the preset menu
        self.layout.operator("atmos.match_plate", icon="IMAGE_REFERENCE")


CLASSES = (
    ATMOS_MT_presets,
    ATMOS_MT_preset_specials,
    ATMOS_PT_atmosphere,
    ATMOS_PT_atmosphere_air,
    ATMOS_PT_atmosphere_advanced,
    ATMOS_PT_atmosphere_sun,
    ATMOS_PT_atmosphere_sky,
    ATMOS_PT_atmosphere_quality,
    ATMOS_PT_atmosphere_aerial,
    ATMOS_PT_atmosphere_look,
)
