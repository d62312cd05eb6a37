# SPDX-License-Identifier: GPL-3.0-or-later
"""Register the Blender layer: one classes tuple in order, unregistered in reverse, plus the handlers."""

from __future__ import annotations

import bpy

from . import handlers, properties, sun_bake
from .apply import precise_tables
from .ui import cli_command, contact_sheet, operators, preset_ops
from .ui import panel as ui_panel

CLASSES = (*properties.CLASSES, *operators.CLASSES, *preset_ops.CLASSES, *contact_sheet.CLASSES, *sun_bake.CLASSES,
           *ui_panel.CLASSES)


def register() -> None:
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    handlers.add_handlers()
    cli_command.register()


def unregister() -> None:
    cli_command.unregister()
    handlers.remove_handlers()
    precise_tables.cancel_pending()
    sun_bake.cancel_pending()
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
