# SPDX-License-Identifier: GPL-3.0-or-later
"""Shared pytest set-up: the repo root on sys.path so ``atmos_addon`` and ``node_groups`` import."""

import os
import sys
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
if str(REPO_ROOT) not in sys.path:
    sys.path.insert(0, str(REPO_ROOT))

_exit_status: int | None = None


def pytest_sessionfinish(session, exitstatus) -> None:
    global _exit_status
    _exit_status = int(exitstatus)


def pytest_unconfigure(config) -> None:
    """End the process with pytest's status before Blender 4.2's bpy module tears down.

    The 4.2 LTS module crashes (SIGSEGV, exit code 139) while Python shuts down when a property with
    Python get/set/poll callbacks was registered, a file was loaded, and the property was unregistered
    (a Blender bug fixed in 4.3; a one-property script reproduces it). By then pytest has printed its
    summary, so nothing is lost; later versions exit normally.
    """
    bpy = sys.modules.get("bpy")
    if bpy is not None and _exit_status is not None and tuple(bpy.app.version[:2]) < (4, 3):
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(_exit_status)
