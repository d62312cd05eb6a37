# SPDX-License-Identifier: GPL-3.0-or-later
"""The "Atmosphere" panel in World properties, its sub-panels and the preset menus.

Layout (top to bottom): a header switch for the whole effect (aerial perspective, sky, sun lamp);
the preset row (menu of built-in then user presets, + to save, - to delete the current user
preset, a menu for rename/import/export/contact sheet); sub-panels Air and Haze (with Advanced),
Sun, Sky, Aerial Perspective, Quality and Look Development. Every control is a property of
``scene.atmos`` or an operator, so edits apply live and undo like any Blender value. The preset
menu is data-driven by :mod:`atmos_addon.presets` (Blender's Python preset files are never used).
"""

from __future__ import annotations

import bpy

from ... import presets
from ...plan import NOTE_IN_RENDER_FAST
from .. import facts, group_integrity
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




def viewport_note(scene) -> str:
    """What the 3D viewport's Rendered shading shows of the aerial perspective, in one line (the plan's)."""
    return facts.plan_of(scene).viewport


class ATMOS_PT_atmosphere(_WorldPanel, bpy.types.Panel):
    """Physically based aerial perspective, sky and sunlight of the scene."""

    bl_label = "Atmosphere"
    bl_idname = "ATMOS_PT_atmosphere"

    def draw_header(self, context):
        self.layout.prop(_settings(context), "enabled", text="")

    def draw(self, context):
        layout = self.layout
        draw_preset_row(layout, context)
        settings = _settings(context)
        layout.prop(settings, "render_mode", expand=True)
        plan = facts.plan_of(context.scene)
        for note in plan.notes:
            if note != NOTE_IN_RENDER_FAST:   # that one is part of the quality status line
                layout.label(text=note, icon="ERROR" if note.startswith("Camera Clip End") else "INFO")
        if not settings.enabled:
            layout.label(text="Off: tick the box to add the atmosphere to the scene", icon="INFO")
        else:
            layout.label(text=plan.viewport, icon="VIEW3D")


class ATMOS_PT_atmosphere_air(_SubPanel, bpy.types.Panel):
    """Air and haze: the scattering coefficients and the simple controls that set them."""

    bl_label = "Air and Haze"
    bl_idname = "ATMOS_PT_atmosphere_air"

    def draw(self, context):
        settings = _settings(context)
        layout = _split(self.layout)
        column = layout.column()
        column.prop(settings, "haze_visibility")
        column.prop(settings, "air_density")
        column.separator()
        column = layout.column()
        column.prop(settings, "rayleigh_scattering_per_km", text="Rayleigh (1/km)")
        column.prop(settings, "mie_scattering_per_km", text="Mie (1/km)")
        column.prop(settings, "mie_absorption_per_km", text="Absorption (1/km)")


class ATMOS_PT_atmosphere_advanced(_SubPanel, bpy.types.Panel):
    """Phase, layer heights, planet and channel wavelengths."""

    bl_label = "Advanced"
    bl_idname = "ATMOS_PT_atmosphere_advanced"
    bl_parent_id = "ATMOS_PT_atmosphere_air"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        settings = _settings(context)
        layout = _split(self.layout)
        column = layout.column()
        column.prop(settings, "mie_g")
        column.separator()
        column.prop(settings, "rayleigh_scale_height")
        column.prop(settings, "mie_scale_height")
        column.separator()
        column.prop(settings, "planet_radius")
        column.prop(settings, "atmosphere_height")
        column.separator()
        column.prop(settings, "wavelengths_nm")


class ATMOS_PT_atmosphere_sun(_SubPanel, bpy.types.Panel):
    """The sun: which lamp, where it is, how bright it is above the air, and what reaches the ground."""

    bl_label = "Sun"
    bl_idname = "ATMOS_PT_atmosphere_sun"

    def draw(self, context):
        settings = _settings(context)
        layout = _split(self.layout)
        column = layout.column()
        column.prop(settings, "sun_object", text="Lamp")
        column.prop(settings, "sun_elevation", text="Elevation")
        column.prop(settings, "sun_azimuth", text="Azimuth")
        column.separator()
        column.prop(settings, "sun_irradiance_top", text="Top Irradiance")
        column.prop(settings, "sun_angular_diameter", text="Angular Diameter")
        column.prop(settings, "sun_limb_darkening")
        column.separator()
        ground = column.column()
        ground.enabled = False  # results, written by Atmos from the atmosphere and the sun
        ground.prop(settings, "sun_colour_display", text="Ground Colour")
        ground.prop(settings, "sun_strength_display", text="Ground Strength (W/m\u00b2)")
        column.separator()
        column.prop(settings, "drive_sun_lamp")
        column.operator("atmos.bake_sun", icon="LIGHT_SUN")


class ATMOS_PT_atmosphere_sky(_SubPanel, bpy.types.Panel):
    """The sky world: on/off, and what is below the horizon."""

    bl_label = "Sky"
    bl_idname = "ATMOS_PT_atmosphere_sky"

    def draw_header(self, context):
        self.layout.prop(_settings(context), "sky_enabled", text="")

    def draw(self, context):
        settings = _settings(context)
        layout = _split(self.layout)
        layout.active = settings.sky_enabled
        column = layout.column()
        column.prop(settings, "sky_ground", text="Ground")
        albedo = column.row()
        albedo.active = settings.sky_ground == "ALBEDO"
        albedo.prop(settings, "ground_albedo")
        if settings.enabled and settings.sky_enabled:
            precise = facts.plan_of(context.scene).sky_level == "precise"
            column.label(text="Sky from the Precise table (this frame's bake)" if precise
                         else "Sky from the virtual dome (Precise quality draws it from its table)")


class ATMOS_PT_atmosphere_aerial(_SubPanel, bpy.types.Panel):
    """Aerial perspective on objects: the distance scale and what Atmos built and skipped."""

    bl_label = "Aerial Perspective"
    bl_idname = "ATMOS_PT_atmosphere_aerial"

    def draw(self, context):
        settings = _settings(context)
        layout = _split(self.layout)
        layout.prop(settings, "distance_scale")
        layout.prop(settings, "quality")
        if settings.quality == "AUTO":
            layout.prop(settings, "auto_tolerance")
        if settings.quality != "FAST":
            layout.prop(settings, "origin_altitude")
        if settings.quality == "PRECISE" or (settings.quality == "AUTO" and settings.auto_level == "precise"):
            layout.prop(settings, "multiple_scattering")
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
        for line in (settings.status_quality, settings.status_built, settings.status_sun, settings.status_materials,
                     settings.status_objects):
            if line:
                status.label(text=line)
        if len(settings.skipped_materials):
            box = layout.box()
            box.label(text=f"Skipped materials ({len(settings.skipped_materials)})", icon="ERROR")
            for item in settings.skipped_materials:
                box.label(text=f"{item.name}: {item.reason}")


class ATMOS_PT_atmosphere_quality(_SubPanel, bpy.types.Panel):
    """How the atmosphere is computed."""

    bl_label = "Quality"
    bl_idname = "ATMOS_PT_atmosphere_quality"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        layout.label(text="Fast (constant density, Hoffman & Preetham 2002)", icon="CHECKMARK")


class ATMOS_PT_atmosphere_look(_SubPanel, bpy.types.Panel):
    """Look development: compare presets and sun elevations side by side."""

    bl_label = "Look Development"
    bl_idname = "ATMOS_PT_atmosphere_look"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        layout.operator("atmos.contact_sheet", icon="IMGDISPLAY")
        row = layout.row(align=True)
        row.operator("atmos.preset_import", text="Import...", icon="IMPORT")
        row.operator("atmos.preset_export", text="Export...", icon="EXPORT")


CLASSES = (
    ATMOS_MT_presets,
    ATMOS_MT_preset_specials,
    ATMOS_PT_atmosphere,
    ATMOS_PT_atmosphere_air,
    ATMOS_PT_atmosphere_advanced,
    ATMOS_PT_atmosphere_sun,
    ATMOS_PT_atmosphere_sky,
    ATMOS_PT_atmosphere_aerial,
    ATMOS_PT_atmosphere_quality,
    ATMOS_PT_atmosphere_look,
)
