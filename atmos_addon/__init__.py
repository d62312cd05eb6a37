# SPDX-License-Identifier: GPL-3.0-or-later
"""Atmos: physically based aerial perspective, sky and sunlight (Hoffman & Preetham 2002).

Importing this package never imports ``bpy``: ``atmos_addon.physics`` (and the preset code
built on it) work in plain Python with numpy. The Blender layer is imported
only by :func:`register` and by modules that need it.
"""

from __future__ import annotations

import os

# The node groups and the sample scenes are top-level folders of the extension (``node_groups/``,
# ``sample_scenes/``, beside this package, as the design card lays it out) imported as subpackages of this one:
# ``atmos_addon.node_groups``, ``atmos_addon.sample_scenes``. Searching the extension root after this package's own
# folder makes that so both in a source checkout (``atmos_addon`` top-level) and installed (``bl_ext.<repo>.atmos``),
# and keeps their relative imports (``from ..physics import sun``) pointing into this package.
__path__.append(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def register() -> None:
    """Register the Blender classes, properties and handlers (Blender calls this on enable)."""
    from .blender import registration

    registration.register()


def unregister() -> None:
    """Remove everything :func:`register` added (Blender calls this on disable)."""
    from .blender import registration

    registration.unregister()
