# SPDX-License-Identifier: GPL-3.0-or-later
"""Per-scene work run once a short while after the last request: a slider drag asks on every step, the work
(a re-bake) runs once when it stops."""

from __future__ import annotations

from typing import Callable

import bpy


class Debounced:
    """``work(scene)`` for each scene requested, ``delay_s`` after the last :meth:`request` (a ``bpy.app.timers``
    timer, restarted by every request); scenes deleted meanwhile are skipped."""

    def __init__(self, work: Callable[[bpy.types.Scene], object], delay_s: float = 0.3) -> None:
        self.work = work
        self.delay_s = delay_s
        self._pending: set[str] = set()
        self._timer = self._run   # one bound method object: the timers API compares by identity

    def request(self, scene: bpy.types.Scene) -> None:
        self._pending.add(scene.name)
        if bpy.app.timers.is_registered(self._timer):
            bpy.app.timers.unregister(self._timer)
        bpy.app.timers.register(self._timer, first_interval=self.delay_s)

    def discard(self, scene: bpy.types.Scene) -> None:
        """Drop ``scene`` from the queue (the timer runs on for the others)."""
        self._pending.discard(scene.name)

    def _run(self):
        for name in sorted(self._pending):
            scene = bpy.data.scenes.get(name)
            if scene is not None:
                self.work(scene)
        self._pending.clear()
        return None

    def flush(self) -> None:
        """Run the queued work now instead of at the timer (before a save: the file gets what the scenes ask for)."""
        if bpy.app.timers.is_registered(self._timer):
            bpy.app.timers.unregister(self._timer)
        if self._pending:
            self._run()

    def cancel(self) -> None:
        """Drop the queued scenes and the timer (unregister)."""
        self._pending.clear()
        if bpy.app.timers.is_registered(self._timer):
            bpy.app.timers.unregister(self._timer)
