# SPDX-License-Identifier: GPL-3.0-or-later
"""Drive a GUI Blender check written as a generator from Blender's timers (tools/verify_viewport.py, verify_panel.py).

The generator yields the seconds to wait before its next step, so the GUI redraws in between. When it ends or raises,
the traceback goes to ``errors`` and ``finish()`` is called (it writes the results and quits Blender): a hung GUI
Blender helps nobody.
"""

from __future__ import annotations

import traceback
from typing import Callable, Generator

import bpy


def run_steps(steps: Generator, errors: list, finish: Callable[[], None], persistent: bool = False) -> None:
    """Register the timer that runs ``steps``; ``persistent`` keeps it through a file load (read_factory_settings)."""

    def tick():
        try:
            return next(steps)
        except StopIteration:
            pass
        except Exception:  # noqa: BLE001  (record it, then quit)
            errors.append(traceback.format_exc())
        finish()
        return None

    bpy.app.timers.register(tick, first_interval=1.0, persistent=persistent)
