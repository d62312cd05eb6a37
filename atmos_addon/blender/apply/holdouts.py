# SPDX-License-Identifier: GPL-3.0-or-later
"""Objects held out by a collection (Collection > Holdout) write no AOVs: a mark the AOV outputs group reads.

Cycles and Eevee shade a held-out object like any other (its samples then become the hole, alpha 0), so its
material's AOV outputs still add its coverage, distance and transmittance to the pixel. Where its hole meets a
hazed surface behind it, the compositor would read the edge pixels as a mix of the two (5.5 % mean, 59 % max error
in Cycles, docs/silhouettes.md). Atmos sets the object custom property :data:`~atmos_addon.plan.HOLDOUT_ATTRIBUTE`
to 1 on every object that a collection holds out in every view layer that renders; the AOV outputs group weighs
its outputs by one minus it (an Object Attribute node: 0 where the property is missing), so the edge pixels are
composited from the visible surface's samples alone. The marks are saved with the file: a farm without the add-on
renders the same.

An object held out in some rendered view layers and not in others keeps no mark (one property cannot say both):
the plan notes it (``plan.NOTE_HOLDOUT``). :func:`remove` deletes every mark, so a disabled scene keeps nothing.
"""

from __future__ import annotations

from ...plan import HOLDOUT_ATTRIBUTE
from ..scene_reading import held_out

#: Scenes that hold marks (by name): :func:`follow` rescans a scene's objects only when it has a held-out
#: collection or marks to take back, so a scene without holdouts pays one walk of its view layers' collections.
_MARKED: set[str] = set()


def install(scene, plan=None) -> None:
    """Mark the objects held out in every rendered view layer of ``scene``, and take the mark off every other one
    (``plan`` unused: the marks follow the view layers alone)."""
    marked, _ = held_out(scene)
    for obj in scene.objects:
        want = obj in marked
        if want != (HOLDOUT_ATTRIBUTE in obj):
            if want:
                obj[HOLDOUT_ATTRIBUTE] = 1.0
            else:
                del obj[HOLDOUT_ATTRIBUTE]
            obj.update_tag()   # a custom property written from Python tags nothing: the viewport re-reads it
    if marked:
        _MARKED.add(scene.name)
    else:
        _MARKED.discard(scene.name)


def follow(scene) -> None:
    """After an edit: the marks again where the scene holds something out or holds marks (a collection's Holdout
    switched, objects linked into a held-out collection or out of it)."""
    marked, _ = held_out(scene)
    if marked or scene.name in _MARKED:
        install(scene)


def remove(scene) -> None:
    """Take every mark off the objects of ``scene``."""
    for obj in scene.objects:
        if HOLDOUT_ATTRIBUTE in obj:
            del obj[HOLDOUT_ATTRIBUTE]
    _MARKED.discard(scene.name)


def forget() -> None:
    """Drop what is known of marked scenes (a file loaded or an undo step: :func:`install` scans again)."""
    _MARKED.clear()

