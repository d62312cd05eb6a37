# SPDX-License-Identifier: GPL-3.0-or-later
"""Every node group Atmos manages, with how to build it again: the one table that integrity checks, resets and
clean-ups loop over.

:mod:`.stamps` names the kinds and their versions; here each kind gets the function that rebuilds a group of that
kind in place from the features key stamped on it (what it was built for), so a reset gives back exactly the
group the scene uses, whichever kind it is: the aerial perspective (camera and ray-segment), the sky and its
per-world lighting table, the compositor's combining and Per Pixel groups, the material group and its outputs, the
In-Render surface and sky.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterable

import bpy

from . import aerial_perspective, composite, in_render, parts, per_pixel, sky, sky_lighting, sky_view, stamps, surface
from .graph import CompositorBuilder, GraphBuilder
from .sky import SkyFeatures
from .terms import AerialFeatures


def _modes(key: str, tree: bpy.types.NodeTree) -> tuple[str, ...]:
    key = key or str(tree.get("atmos_evaluations", ""))   # a release before the kind stamp kept the modes there
    return tuple(mode for mode in key.split(",") if mode) or ("COMPOSITOR",)


def _rebuild_outputs(tree: bpy.types.NodeTree, key: str) -> None:
    """The outputs group, detached from the material group meanwhile (its materials re-checked once)."""
    modes = _modes(key, tree)
    aerial = next((group for group in surface.inner_groups(tree) if stamps.kind_of(group) == stamps.AERIAL), None)
    if aerial is None and "COMPOSITOR" in modes:
        aerial = aerial_perspective.ensure_aerial_perspective_group()
    wrapper = stamps.local(bpy.data.node_groups, surface.SURFACE_GROUP)
    with surface.detached(wrapper, tree) if stamps.kind_of(wrapper) == stamps.SURFACE else contextlib.nullcontext():
        surface.build_outputs_group(tree, aerial, modes)


def _rebuild_surface(tree: bpy.types.NodeTree, key: str) -> None:
    """The material group around the file's outputs group (built for the stamped modes when it is missing)."""
    modes = _modes(key, tree)
    outputs = stamps.local(bpy.data.node_groups, surface.OUTPUTS_GROUP)
    if stamps.kind_of(outputs) != stamps.SURFACE_OUTPUTS:
        aerial = aerial_perspective.ensure_aerial_perspective_group() if "COMPOSITOR" in modes else None
        outputs = surface.ensure_outputs_group(aerial, modes)
    with surface.detached(tree, outputs) as stand_in:
        surface.build_surface_group(tree, stand_in, modes)


def _rebuild_sky_lighting(tree: bpy.types.NodeTree, key: str) -> None:
    sky_lighting.build_sky_lighting(tree, SkyFeatures.from_key(key))
    if sky_lighting.TABLE_KEY in tree:
        del tree[sky_lighting.TABLE_KEY]   # the table is written again by the next sync


def _rebuild_part(tree: bpy.types.NodeTree, key: str) -> None:
    """A part's group, built again from the current part of its name (a retired part is left for the clean-up)."""
    part = parts.part_of(key)
    if part is not None:
        builder = CompositorBuilder if tree.bl_idname == "CompositorNodeTree" else GraphBuilder
        parts.build(tree, part, builder.child)


#: kind -> rebuild(tree, its stamped features key).
REBUILD: dict[stamps.GroupKind, Callable[[bpy.types.NodeTree, str], None]] = {
    stamps.PART: _rebuild_part,
    stamps.COMPOSITOR_PART: _rebuild_part,
    stamps.AERIAL: lambda tree, key: aerial_perspective.build_aerial_perspective(tree, AerialFeatures.from_key(key)),
    stamps.AERIAL_SEGMENT: lambda tree, key: aerial_perspective.build_aerial_perspective(
        tree, AerialFeatures.from_key(key), distance="RAY"),
    stamps.SKY: lambda tree, key: sky.build_sky(tree, SkyFeatures.from_key(key)),
    stamps.SKY_LIGHTING: _rebuild_sky_lighting,
    stamps.SKY_VIEW: lambda tree, key: sky_view.build_sky_view(tree, SkyFeatures.from_key(key)),
    stamps.COMPOSITE: lambda tree, key: composite.build_composite_group(tree),
    stamps.PER_PIXEL: lambda tree, key: per_pixel.build_per_pixel_composite(tree, AerialFeatures.from_key(key)),
    stamps.SURFACE_OUTPUTS: _rebuild_outputs,
    stamps.SURFACE: _rebuild_surface,
    stamps.IN_RENDER_SURFACE: lambda tree, key: in_render.build_surface_group(
        tree, aerial_perspective.ensure_aerial_perspective_group(AerialFeatures.from_key(key), distance="RAY")),
    stamps.IN_RENDER_SKY: lambda tree, key: in_render.build_sky_group(tree, AerialFeatures.from_key(key)),
}
assert set(REBUILD) == set(stamps.KINDS), "every kind needs its rebuild"


def managed_trees() -> list[tuple[stamps.GroupKind, bpy.types.NodeTree]]:
    """Every local node group of the file that Atmos built, with its kind, in :data:`.stamps.KINDS` order."""
    found = [(stamps.kind_of(tree), tree) for tree in bpy.data.node_groups if tree.library is None]
    order = {kind: index for index, kind in enumerate(stamps.KINDS)}
    return sorted(((kind, tree) for kind, tree in found if kind is not None), key=lambda item: order[item[0]])


def rebuild(tree: bpy.types.NodeTree) -> None:
    """Rebuild a managed group in place for the features stamped on it (its identity and links kept)."""
    kind = stamps.kind_of(tree)
    if kind is None:
        raise ValueError(f"node group {tree.name!r} is not one Atmos built")
    REBUILD[kind](tree, str(tree.get(stamps.FEATURES_KEY, "")))


def remove_unused(kinds: Iterable[stamps.GroupKind] | None = None) -> list[str]:
    """Delete every managed group (of ``kinds``, all when None) that nothing uses, so a file the effect left holds
    no Atmos orphans; the names deleted. Groups that use others go first, so those become unused in turn; parts
    (:mod:`.parts`) that nothing uses any more go too, whatever ``kinds``. A group with a fake user, or used by the
    artist's own material, stays."""
    wanted = set(stamps.KINDS if kinds is None else kinds) | set(stamps.PART_KINDS)
    removed = []
    while True:
        unused = [tree for kind, tree in reversed(managed_trees()) if kind in wanted and tree.users == 0]
        if not unused:
            return removed
        for tree in unused:
            if tree.users == 0:   # a part used by a group removed just before is counted on the next pass
                removed.append(tree.name)
                # Nothing uses it, so the unlink pass of a plain remove (which visits every data-block of the
                # file: 20-40 ms each with 30 000 of them) has nothing to do; the users of what it uses are
                # still decremented.
                bpy.data.node_groups.remove(tree, do_unlink=False)
