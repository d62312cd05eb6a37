# SPDX-License-Identifier: GPL-3.0-or-later
"""Atmos extension entry point: Blender loads this package; the add-on lives in ``atmos_addon``."""

from .atmos_addon import register, unregister

__all__ = ["register", "unregister"]
