# SPDX-License-Identifier: GPL-3.0-or-later
"""Register the Blender layer: one classes tuple in order, unregistered in reverse, plus the handlers."""

from __future__ import annotations

import atexit

import bpy

from . import handlers, properties, sun_bake
from .apply import precise_tables
from .ui import cli_command, contact_sheet, match_plate, operators, preset_ops
from .ui import panel as ui_panel

CLASSES = (*properties.CLASSES, *operators.CLASSES, *preset_ops.CLASSES, *contact_sheet.CLASSES,
           *match_plate.CLASSES, *ui_panel.CLASSES)


def register() -> None:
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    handlers.add_handlers()
    cli_command.register()
    # The pip bpy module frees the CLI command after Python has shut down, so a process that exits with the add-on
    # registered crashes (exit code -11) or hangs: unregister while Python runs. Blender's own binary must not do
    # this: it frees the RNA types first, so the same callback fails ("missing bl_rna attribute") and segfaults.
    if getattr(bpy.app, "module", False):
        atexit.register(unregister)


def unregister() -> None:
    atexit.unregister(unregister)
    cli_command.unregister()
    handlers.remove_handlers()
    precise_tables.cancel_pending()
    sun_bake.cancel_pending()
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
