# SPDX-License-Identifier: GPL-3.0-or-later
"""Atmos: physically based aerial perspective, sky and sunlight (Hoffman & Preetham 2002).

Importing this package never imports ``bpy``: ``atmos_addon.physics`` (and the preset and
reference code built on it) work in plain Python with numpy. The Blender layer is imported
only by :func:`register` and by modules that need it.
"""

from __future__ import annotations

import importlib
import sys
from pathlib import Path
from types import ModuleType

#: The extension root folder (holds ``blender_manifest.toml``, ``atmos_addon/``, ``sample_scenes/`` in a checkout).
EXTENSION_ROOT = Path(__file__).resolve().parent.parent


def import_sibling(name: str) -> ModuleType:
    """Import a top-level package that sits beside ``atmos_addon`` (the sample scenes of a source checkout).

    Installed as an extension, both live under one parent package (``bl_ext.<repo>.atmos``);
    from a source checkout (tests, ``python -m atmos_addon``) ``atmos_addon`` is top-level and its
    siblings are imported from :data:`EXTENSION_ROOT`.
    """
    parent = __name__.rpartition(".")[0]
    if parent:
        return importlib.import_module(f"{parent}.{name}")
    root = str(EXTENSION_ROOT)
    if root not in sys.path:
        sys.path.insert(0, root)
    return importlib.import_module(name)


def register() -> None:
    """Register the Blender classes, properties and handlers (Blender calls this on enable)."""
    from .blender import registration

    registration.register()


def unregister() -> None:
    """Remove everything :func:`register` added (Blender calls this on disable)."""
    from .blender import registration

    registration.unregister()
