# SPDX-License-Identifier: GPL-3.0-or-later
"""The one version scheme of the node groups Atmos builds.

Every group carries three custom properties: its kind (:data:`KIND_KEY`, the kind's name), the version of the
builder that made it (:data:`VERSION_KEY`) and the key of the features it was built for (:data:`FEATURES_KEY`, e.g.
"rayleigh+mie+abs+precise"). A group whose stamp differs from what is asked for is rebuilt in place: the
data-block keeps its identity and interface, so the group nodes in materials, worlds and compositors keep their
links. Bump a kind's version here when its builder's output changes; :mod:`.registry` lists how each kind is built.
"""

from __future__ import annotations

from dataclasses import dataclass

import bpy

KIND_KEY = "atmos_group"
VERSION_KEY = "atmos_version"
FEATURES_KEY = "atmos_features"


@dataclass(frozen=True)
class GroupKind:
    """A node group Atmos manages: its data-block name, tree type and builder version."""

    name: str
    tree_type: str
    version: int
    #: One group per world (named ``name``, ``name.001``...) instead of one per file.
    per_world: bool = False


#: Each kind's version is bumped whenever its builder's output changes (CHANGELOG.md says what changed).
AERIAL = GroupKind("Atmos Aerial Perspective", "ShaderNodeTree", 7)
AERIAL_SEGMENT = GroupKind("Atmos Aerial Perspective (Ray Segment)", "ShaderNodeTree", 6)
SKY = GroupKind("Atmos Sky", "ShaderNodeTree", 5)
SKY_LIGHTING = GroupKind("Atmos Sky Lighting", "ShaderNodeTree", 1, per_world=True)
#: The Precise sky for Cycles' camera rays above the horizon (:mod:`.sky_view`).
SKY_VIEW = GroupKind("Atmos Sky View", "ShaderNodeTree", 2)
#: The materials' group (one node of the outputs group) and its outputs (:mod:`.surface`).
SURFACE = GroupKind("Atmos Surface AOVs", "ShaderNodeTree", 4)
SURFACE_OUTPUTS = GroupKind("Atmos AOV Outputs", "ShaderNodeTree", 3)
COMPOSITE = GroupKind("Atmos Aerial Composite", "CompositorNodeTree", 4)
PER_PIXEL = GroupKind("Atmos Aerial Composite (Per Pixel)", "CompositorNodeTree", 10)
IN_RENDER_SURFACE = GroupKind("Atmos In-Render Surface", "ShaderNodeTree", 3)
IN_RENDER_SKY = GroupKind("Atmos In-Render Sky", "ShaderNodeTree", 3)
#: A part: a piece of an equation built once as its own group and instanced by the groups above (:mod:`.parts`;
#: its features key is the part's name and version), in shader and in compositor trees.
PART = GroupKind("Atmos Part", "ShaderNodeTree", 1)
COMPOSITOR_PART = GroupKind("Atmos Compositor Part", "CompositorNodeTree", 1)
PART_KINDS = (PART, COMPOSITOR_PART)
#: Not a node group: the tree of each haze dome's material (In-Render mode), its features key the species.
DOME_VOLUME = GroupKind("Atmos Dome", "ShaderNodeTree", 3)
#: Every kind, in build order (a group that instances another comes after it).
KINDS = (PART, COMPOSITOR_PART, AERIAL, AERIAL_SEGMENT, SKY, SKY_LIGHTING, SKY_VIEW, SURFACE_OUTPUTS, SURFACE,
         COMPOSITE, PER_PIXEL, IN_RENDER_SURFACE, IN_RENDER_SKY)
#: The key stamped by releases before the kind key on the per-world lighting groups (their names are numbered).
_LEGACY_SKY_LIGHTING_KEY = "atmos_sky_lighting"


def stamp(tree: bpy.types.NodeTree, kind: GroupKind, features_key: str) -> None:
    """Record that ``tree`` is ``kind``'s group built by the current builder for ``features_key``."""
    tree[KIND_KEY] = kind.name
    tree[VERSION_KEY] = kind.version
    tree[FEATURES_KEY] = features_key


def is_current(tree: bpy.types.NodeTree, kind: GroupKind, features_key: str) -> bool:
    """True when ``tree`` is ``kind``'s group as the current builder makes it for ``features_key``."""
    return (tree.get(KIND_KEY) == kind.name and tree.get(VERSION_KEY) == kind.version
            and tree.get(FEATURES_KEY) == features_key)


def kind_of(tree: bpy.types.NodeTree | None) -> GroupKind | None:
    """The kind of a group Atmos built (also one built by a release before the kind key), or None."""
    if tree is None:
        return None
    name = tree.get(KIND_KEY)
    if name is None:
        if tree.get(_LEGACY_SKY_LIGHTING_KEY):
            return SKY_LIGHTING
        name = tree.name
    return next((kind for kind in KINDS if kind.name == name and tree.bl_idname == kind.tree_type), None)


def local(collection, name: str):
    """The file's own data-block ``name`` in ``collection`` (``bpy.data.node_groups``, ``bpy.data.images``), not a
    linked one of that name; None when the file has none. A plain ``get(name)`` returns a linked data-block when the
    file has no local one of the name: an asset linked from a file saved with Atmos on brings that file's groups (and
    at the Precise level its table image), which Atmos must neither edit nor point this file's materials at."""
    return collection.get((name, None))


def group(kind: GroupKind, *, replace_foreign: bool = False) -> bpy.types.NodeTree:
    """``kind``'s data-block (a per-file kind), created when missing. A data-block of that name that is not of the
    kind's tree type is renamed "... (not Atmos)" and replaced when ``replace_foreign``, else an error the user must
    resolve (its users would otherwise silently change)."""
    tree = local(bpy.data.node_groups, kind.name)
    if tree is not None and tree.bl_idname != kind.tree_type:
        if not replace_foreign:
            raise TypeError(f'Node group "{kind.name}" exists but is a {tree.bl_idname}, not a {kind.tree_type}; '
                            f"rename or delete it, then apply Atmos again")
        tree.name = kind.name + " (not Atmos)"
        tree = None
    if tree is None:
        tree = bpy.data.node_groups.new(kind.name, kind.tree_type)
    return tree
