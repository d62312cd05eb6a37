# SPDX-License-Identifier: GPL-3.0-or-later
"""The minimal "Atmosphere" panel in World properties: switch, parameters, sun, refresh and status."""

from __future__ import annotations

import bpy


class ATMOS_PT_atmosphere(bpy.types.Panel):
    """Aerial perspective settings of the scene."""

    bl_label = "Atmosphere"
    bl_idname = "ATMOS_PT_atmosphere"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "world"

    def draw_header(self, context):
        self.layout.prop(context.scene.atmos, "enabled", text="")

    def draw(self, context):
        settings = context.scene.atmos
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False

        column = layout.column()
        column.prop(settings, "sun_object")
        column.prop(settings, "distance_scale")
        column.separator()
        column.prop(settings, "rayleigh_scattering_per_km", text="Rayleigh (1/km)")
        column.prop(settings, "rayleigh_scale_height")
        column.prop(settings, "mie_scattering_per_km", text="Mie (1/km)")
        column.prop(settings, "mie_absorption_per_km", text="Absorption (1/km)")
        column.prop(settings, "mie_g")
        column.prop(settings, "mie_scale_height")

        layout.operator("atmos.refresh", icon="FILE_REFRESH")
        if not settings.enabled:
            return
        status = layout.column(align=True)
        for line in (settings.status_built, settings.status_sun, settings.status_materials, settings.status_objects):
            if line:
                status.label(text=line)
        for item in settings.skipped_materials:
            status.label(text=f"{item.name}: {item.reason}", icon="ERROR")


CLASSES = (ATMOS_PT_atmosphere,)
