# SPDX-License-Identifier: GPL-3.0-or-later
"""Atmos: physically based aerial perspective, sky and sunlight (Hoffman & Preetham 2002).

Importing this package never imports ``bpy``: ``atmos_addon.physics`` (and the preset and
reference code built on it) work in plain Python with numpy. The Blender layer is imported
only by :func:`register` and by modules that need it.
"""

from __future__ import annotations


def register() -> None:
    """Register the Blender classes, properties and handlers (Blender calls this on enable)."""
    from .blender import registration

    registration.register()


def unregister() -> None:
    """Remove everything :func:`register` added (Blender calls this on disable)."""
    from .blender import registration

    registration.unregister()
