# SPDX-License-Identifier: GPL-3.0-or-later
"""Operators: enable, disable and refresh aerial perspective on the active scene (thin wrappers over
:mod:`.orchestrator`)."""

from __future__ import annotations

import bpy

from .. import group_integrity, orchestrator


def _report(operator, report: orchestrator.Report) -> None:
    for name, reason in report.skipped:
        operator.report({"WARNING"}, f"Atmos: material '{name}' skipped: {reason}")
    operator.report({"INFO"}, f"Atmos: {len(report.managed)} material(s) with aerial perspective")


class ATMOS_OT_enable(bpy.types.Operator):
    """Apply aerial perspective to every object of the scene (materials, render passes, compositor)"""

    bl_idname = "atmos.enable"
    bl_label = "Enable Aerial Perspective"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        try:
            report = orchestrator.enable_effect(context.scene)
        except (RuntimeError, ValueError, TypeError) as error:
            self.report({"ERROR"}, f"Atmos could not enable aerial perspective: {error}")
            return {"CANCELLED"}
        _report(self, report)
        return {"FINISHED"}


class ATMOS_OT_disable(bpy.types.Operator):
    """Remove aerial perspective: the materials and compositor return to how they were"""

    bl_idname = "atmos.disable"
    bl_label = "Disable Aerial Perspective"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        try:
            stripped = orchestrator.disable_effect(context.scene)
        except (RuntimeError, ValueError, TypeError) as error:
            self.report({"ERROR"}, f"Atmos could not remove aerial perspective: {error}")
            return {"CANCELLED"}
        self.report({"INFO"}, f"Atmos: removed from {len(stripped)} material(s)")
        return {"FINISHED"}


class ATMOS_OT_refresh(bpy.types.Operator):
    """Include materials and objects added since aerial perspective was enabled, and re-read the sun"""

    bl_idname = "atmos.refresh"
    bl_label = "Refresh"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        try:
            report = orchestrator.refresh_effect(context.scene)
        except (RuntimeError, ValueError, TypeError) as error:
            self.report({"ERROR"}, f"Atmos could not refresh aerial perspective: {error}")
            return {"CANCELLED"}
        _report(self, report)
        return {"FINISHED"}


class ATMOS_OT_reset_groups(bpy.types.Operator):
    """Rebuild the Atmos node groups as Atmos makes them, undoing edits made inside them (materials keep their links)"""

    bl_idname = "atmos.reset_groups"
    bl_label = "Reset Atmos Node Groups"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        try:
            rebuilt = group_integrity.reset_groups()
            for scene in bpy.data.scenes:   # the values a rebuilt group reads (a lighting group's table)
                if getattr(scene, "atmos", None) is not None and scene.atmos.enabled:
                    orchestrator.update(scene)
        except (RuntimeError, ValueError, TypeError) as error:
            self.report({"ERROR"}, f"Atmos could not reset its node groups: {error}")
            return {"CANCELLED"}
        self.report({"INFO"}, f"Atmos: rebuilt {', '.join(rebuilt) or 'no node group (none present)'}")
        return {"FINISHED"}


CLASSES = (ATMOS_OT_enable, ATMOS_OT_disable, ATMOS_OT_refresh, ATMOS_OT_reset_groups)
