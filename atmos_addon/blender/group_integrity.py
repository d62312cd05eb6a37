# SPDX-License-Identifier: GPL-3.0-or-later
"""Notice hand edits inside the node groups Atmos manages, and put the groups back.

Atmos owns every group its registry lists (:mod:`atmos_addon.node_groups.registry`: the aerial perspective, the sky and
its lighting table, the compositor's groups, the material group, the In-Render groups). A user who opens one (Tab)
and changes a value or a link changes the effect in every material or render, usually by accident. Each group carries
a fingerprint of what the builder made (``tree["atmos_fingerprint"]``:
a hash of the nodes' types, names and settings, the links and the unlinked inputs' values, and the
interface; node locations, labels and selection are left out, so tidying the layout is no edit),
stamped right after the builder ran and keyed on the group's version and feature stamps and the
Blender version. :func:`edited_groups` compares each group with its stamp; the Aerial Perspective
panel calls it on every draw, so the comparison is cached and recomputed only after a depsgraph update
that touched a node tree (sync's handlers call :func:`on_depsgraph_update` and :func:`invalidate`).
:func:`reset_groups` rebuilds the edited (or all) groups in place: the group
data-blocks keep their identity and interface, so materials and worlds keep their group nodes and links.

A group with no stamp for the current build (built by an older Atmos, or by another Blender version,
whose node settings may read back differently) is stamped as it is: an edit made before that is not
reported, and Reset still rebuilds it.
"""

from __future__ import annotations

import contextlib
import hashlib

import bpy

from ..node_groups import registry, stamps

FINGERPRINT_KEY = "atmos_fingerprint"
STAMP_KEY = "atmos_fingerprint_of"

AERIAL = stamps.AERIAL.name
SKY = stamps.SKY.name
SURFACE = stamps.SURFACE.name
SURFACE_OUTPUTS = stamps.SURFACE_OUTPUTS.name
PER_PIXEL = stamps.PER_PIXEL.name

#: Node properties every node has (layout, selection, bookkeeping): not part of the fingerprint.
_BASE_PROPERTIES: frozenset[str] | None = None
_node_properties: dict[str, tuple[str, ...]] = {}

#: Settings whose choices depend on the image (a compositor Image node's render layer and view of a multilayer
#: file): reading them on a plain image warns, and the image pointer already names what the node reads.
_DYNAMIC_ENUMS = frozenset({"layer", "view"})

#: name -> edited? for the managed groups present, or None when it must be recomputed.
_cache: dict[str, bool] | None = None


def _base_properties() -> frozenset[str]:
    global _BASE_PROPERTIES
    if _BASE_PROPERTIES is None:
        _BASE_PROPERTIES = frozenset(p.identifier for p in bpy.types.Node.bl_rna.properties) | {"rna_type"}
    return _BASE_PROPERTIES


def _settings_of(node) -> tuple[str, ...]:
    """The identifiers of ``node``'s own settings (operation, clamp, attribute name, ...), cached per type."""
    names = _node_properties.get(node.bl_idname)
    if names is None:
        base = _base_properties()
        names = tuple(sorted(
            p.identifier for p in node.bl_rna.properties
            if p.identifier not in base and p.identifier not in _DYNAMIC_ENUMS and not p.is_readonly
            and p.type in {"BOOLEAN", "INT", "FLOAT", "STRING", "ENUM", "POINTER"}
        ))
        _node_properties[node.bl_idname] = names
    return names


def _value(value) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, (bool, int, str)):
        return repr(value)
    if isinstance(value, bpy.types.ID):
        return "ID:" + value.name
    if value is None:
        return "None"
    try:
        return "(" + ",".join(_value(v) for v in value) + ")"
    except TypeError:
        return type(value).__name__


def fingerprint(tree) -> str:
    """A hash of what the group computes: nodes (type, name, settings, mute), unlinked input values, links,
    interface."""
    parts: list[str] = []
    for item in tree.interface.items_tree:
        if item.item_type == "SOCKET":
            parts.append(f"I|{item.in_out}|{item.name}|{item.socket_type}")
    for node in sorted(tree.nodes, key=lambda n: n.name):
        parts.append(f"N|{node.name}|{node.bl_idname}|{node.mute}")
        for name in _settings_of(node):
            parts.append(f"P|{name}|{_value(getattr(node, name, None))}")
        for index, socket in enumerate(node.inputs):
            if not socket.is_linked and hasattr(socket, "default_value"):
                parts.append(f"V|{index}|{_value(socket.default_value)}")
    for link in tree.links:
        parts.append(f"L|{link.from_node.name}|{link.from_socket.identifier}|{link.to_node.name}|"
                     f"{link.to_socket.identifier}|{link.is_muted}")
    return hashlib.sha1("\n".join(parts).encode()).hexdigest()


def _build_key(tree) -> str:
    """What the stamp belongs to: the group's kind, version and features stamps and the Blender version (a group
    rebuilt for another feature set, or the material group rebuilt for the modes of another scene, is stamped
    again, not reported as edited)."""
    return (f"{tree.get(stamps.KIND_KEY)}|{tree.get(stamps.VERSION_KEY)}|{tree.get(stamps.FEATURES_KEY)}|"
            f"{bpy.app.version_string}")


def _managed_trees():
    return [tree for _, tree in registry.managed_trees()]


def stamp(tree) -> None:
    """Record ``tree`` as the builder made it."""
    tree[FINGERPRINT_KEY] = fingerprint(tree)
    tree[STAMP_KEY] = _build_key(tree)
    invalidate()


@contextlib.contextmanager
def owned_change(tree):
    """A change Atmos itself makes to a built group (the Precise table's image pointed at by its texture nodes):
    a group that matched its stamp before is stamped again after, so the change is not reported as an edit; a
    group the user had edited stays reported."""
    clean = tree.get(FINGERPRINT_KEY) is not None and tree.get(FINGERPRINT_KEY) == fingerprint(tree)
    yield tree
    if clean:
        stamp(tree)


def stamp_new() -> None:
    """Stamp the managed groups that have no stamp for their current build (just built or rebuilt). Cheap when none."""
    for tree in _managed_trees():
        if tree.get(STAMP_KEY) != _build_key(tree) or FINGERPRINT_KEY not in tree:
            stamp(tree)


def invalidate() -> None:
    """Forget the cached comparison (it is recomputed on the next :func:`edited_groups`)."""
    global _cache
    _cache = None


def edited_groups(*, force: bool = False) -> list[str]:
    """Names of the managed groups whose nodes differ from what Atmos built (cached; see the module docstring)."""
    global _cache
    if _cache is None or force:
        result = {}
        for tree in _managed_trees():
            stored = tree.get(FINGERPRINT_KEY)
            result[tree.name] = (stored is not None and tree.get(STAMP_KEY) == _build_key(tree)
                                 and fingerprint(tree) != stored)
        _cache = result
    return [tree.name for tree in _managed_trees() if _cache.get(tree.name)]


def warning(name: str) -> str:
    """The panel's line for an edited group."""
    return f"'{name}' was edited by hand: the effect may be wrong"


def reset_groups(names=None) -> list[str]:
    """Rebuild the managed groups (all present ones, or ``names``) in place, each for the features it was built for
    (:func:`atmos_addon.node_groups.registry.rebuild`); their names. Each tree keeps its identity and its interface
    sockets, so the group nodes in materials and worlds keep their links; only the nodes inside are rebuilt (the
    caller writes the values again: a lighting group's table is refilled by the next sync)."""
    done = []
    for tree in _managed_trees():
        if names is not None and tree.name not in names:
            continue
        registry.rebuild(tree)
        stamp(tree)
        done.append(tree.name)
    invalidate()
    return done


def on_depsgraph_update(_scene, depsgraph) -> None:
    """Drop the cached comparison when a node tree changed (called by :func:`.handlers.on_depsgraph_update`)."""
    if _cache is not None and depsgraph.id_type_updated("NODETREE"):
        invalidate()
