# SPDX-License-Identifier: GPL-3.0-or-later
"""``python -m atmos_addon ARGS``: the Atmos command line with the pip ``bpy`` module."""

import sys

from .cli import main

sys.exit(main())
