# SPDX-License-Identifier: GPL-3.0-or-later
"""``blender --command atmos ARGS``: the same CLI as ``python -m atmos_addon`` inside a real Blender.

Blender (4.2 and later) lets an extension register a command-line command (``bpy.utils.register_cli_command``);
its handler receives the arguments after the command name and returns the exit code.
"""

from __future__ import annotations

import bpy

COMMAND = "atmos"
_handle = None


def _run(argv: list[str]) -> int:
    from ...cli import main

    return main(argv)


def register() -> None:
    global _handle
    if _handle is None and hasattr(bpy.utils, "register_cli_command"):
        _handle = bpy.utils.register_cli_command(COMMAND, _run)


def unregister() -> None:
    global _handle
    if _handle is not None:
        bpy.utils.unregister_cli_command(_handle)
        _handle = None
