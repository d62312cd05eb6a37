# SPDX-License-Identifier: GPL-3.0-or-later
"""The Blender layer of Atmos: properties, operators, panel, node application and handlers.

Importing this package has no side effects; :mod:`.registration` registers everything.
"""
