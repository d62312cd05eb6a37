# SPDX-License-Identifier: GPL-3.0-or-later
"""Parts: pieces of an equation built once as their own node group and instanced wherever the equations use them.

Blender re-runs the whole update of a node tree after every node, link or value a script adds: about 2 us for each
node already in the tree (a Math node added to a tree of 400 nodes costs 1.1 ms, to one of 50 about 0.1 ms; Blender
5.2.3), so building a tree costs the square of its size, and the Precise sky (244 nodes) and Per Pixel groups (220)
took most of an enable. A part (the bilinear table sample, the distance to the top of the atmosphere, phi1, the
sun's disk...) is a small group of its own, built once however many times it is used, and a one-node instance in the
group that uses it, so every tree stays small. What renders is the same: Cycles and Eevee inline groups, and the
numpy builder (:class:`.graph.ArrayBuilder`) evaluates a part's equations in place, so the parity tests read the same
arithmetic.

A :class:`Part` names its group, its version, its inputs and outputs and the function that builds it on any builder
(``build(g, *inputs)``, returning its output or a tuple of them). Parts are stamped like every managed group (kind
:data:`.stamps.PART` or :data:`.stamps.COMPOSITOR_PART`, the part's name and version as the features key), rebuilt in
place when stale, removed once nothing uses them (:func:`.registry.remove_unused`), fingerprinted against hand edits
(:mod:`atmos_addon.blender.group_integrity`). In a compositor tree, where parameters are the top group's inputs and
not Attribute nodes, the parameters a part reads (:attr:`Part.parameters`) become inputs of its group too.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import Any

import bpy

from . import stamps

#: A part's socket kinds and the interface socket type each becomes.
FLOAT, VECTOR = "FLOAT", "VECTOR"
_SOCKET_TYPES = {FLOAT: "NodeSocketFloat", VECTOR: "NodeSocketVector"}
#: Group node type by tree type.
GROUP_NODES = {"ShaderNodeTree": "ShaderNodeGroup", "CompositorNodeTree": "CompositorNodeGroup"}
_KINDS = {"ShaderNodeTree": stamps.PART, "CompositorNodeTree": stamps.COMPOSITOR_PART}
_GROUP_NODE_TYPES = frozenset(GROUP_NODES.values())
#: A part's tree type by its kind's stamp.
_PART_TREE_TYPES = {kind.name: kind.tree_type for kind in stamps.PART_KINDS}


def kind_for(tree_type: str) -> stamps.GroupKind:
    """The stamp kind of a part's group in trees of ``tree_type``."""
    return _KINDS[tree_type]


def _name_of(key: str) -> str:
    """The part's name in a features key (:attr:`Part.key`)."""
    return key.split("|")[0]


@dataclass(frozen=True)
class Part:
    """A piece of an equation built as its own node group: ``build(g, *inputs)`` on any builder returns its output
    (or a tuple of them, in :attr:`outputs` order); :attr:`parameters` are the scene parameters it reads (name,
    kind), which a compositor copy takes as inputs after :attr:`inputs`."""

    name: str
    version: int
    inputs: tuple[tuple[str, str], ...]
    outputs: tuple[tuple[str, str], ...]
    build: Callable[..., Any]
    parameters: tuple[tuple[str, str], ...] = ()
    description: str = ""

    @property
    def key(self) -> str:
        """The features key stamped on its group: name and version."""
        return f"{self.name}|{self.version}"


#: Every part by name (filled as the modules that define them are imported: :func:`define`).
PARTS: dict[str, Part] = {}


def define(name: str, version: int, inputs, outputs, build: Callable[..., Any], *, parameters=(),
           description: str = "") -> Part:
    """Make and register a part. Names are unique: a second part of a name from another module is an error; from
    the same module (the module reloaded, as Blender's Reload Scripts does) it replaces the first."""
    if name in PARTS and PARTS[name].build.__module__ != build.__module__:
        raise ValueError(f"part {name!r} is defined twice ({PARTS[name].build.__module__}, {build.__module__})")
    part = Part(name, version, tuple(inputs), tuple(outputs), build, tuple(parameters), description)
    PARTS[name] = part
    return part


def group_name(part: Part, tree_type: str) -> str:
    """The data-block name of ``part``'s group for a tree of ``tree_type``."""
    return part.name if tree_type == "ShaderNodeTree" else f"{part.name} (Compositor)"


def interface(part: Part, tree_type: str) -> list[tuple[str, str, str]]:
    """(name, in/out, socket type) of ``part``'s group in a tree of ``tree_type``, outputs first as Blender lists."""
    inputs = part.inputs + (part.parameters if tree_type == "CompositorNodeTree" else ())
    return ([(name, "OUTPUT", _SOCKET_TYPES[kind]) for name, kind in part.outputs]
            + [(name, "INPUT", _SOCKET_TYPES[kind]) for name, kind in inputs])


def _ensure_interface(tree: bpy.types.NodeTree, wanted: list[tuple[str, str, str]]) -> None:
    items = [item for item in tree.interface.items_tree if item.item_type == "SOCKET"]
    if [(item.name, item.in_out, item.socket_type) for item in items] == wanted:
        return
    tree.interface.clear()
    for name, in_out, socket_type in wanted:
        tree.interface.new_socket(name, in_out=in_out, socket_type=socket_type)


def build(tree: bpy.types.NodeTree, part: Part, make_builder: Callable[..., Any]) -> None:
    """Clear ``tree`` and build ``part`` in it with the builder ``make_builder(tree, parameters)`` makes
    (``parameters``: the group's parameter inputs by name, for a compositor builder); then stamp it."""
    tree.nodes.clear()
    if hasattr(tree, "description"):
        tree.description = part.description
    _ensure_interface(tree, interface(part, tree.bl_idname))
    group_in = tree.nodes.new("NodeGroupInput")
    parameters = ({name: group_in.outputs[name] for name, _ in part.parameters}
                  if tree.bl_idname == "CompositorNodeTree" else {})
    g = make_builder(tree, parameters)
    outputs = part.build(g, *(group_in.outputs[name] for name, _ in part.inputs))
    outputs = outputs if isinstance(outputs, tuple) and len(part.outputs) > 1 else (outputs,)
    group_out = g.node("NodeGroupOutput", label="Group Output")
    for (name, _), value in zip(part.outputs, outputs):
        g._feed(group_out, group_out.inputs[name], value)
    g.set_depth(group_out, g.max_depth + 1)
    prune = getattr(g, "prune", None)
    if prune is not None:
        prune()
    g.layout()
    group_in.location = (-220.0, 0.0)
    stamps.stamp(tree, kind_for(tree.bl_idname), part.key)


def ensure(part: Part, tree_type: str, make_builder: Callable[..., Any]) -> bpy.types.NodeTree:
    """``part``'s group for trees of ``tree_type``, built (:func:`build`) when missing or stale. A data-block of its
    name that is not this part's is renamed "... (not Atmos)" and left to its users."""
    kind = kind_for(tree_type)
    name = group_name(part, tree_type)
    tree = stamps.local(bpy.data.node_groups, name)
    if tree is not None and (tree.bl_idname != tree_type or stamps.kind_of(tree) != kind
                             or _name_of(str(tree.get(stamps.FEATURES_KEY, ""))) != part.name):
        tree.name = name + " (not Atmos)"
        tree = None
    if tree is None:
        tree = bpy.data.node_groups.new(name, tree_type)
    if not stamps.is_current(tree, kind, part.key):
        build(tree, part, make_builder)
    return tree


def part_of(key: str) -> Part | None:
    """The current part a group stamped with features ``key`` was built from (by name), or None (retired)."""
    return PARTS.get(_name_of(key))


def is_part(tree: bpy.types.NodeTree | None) -> bool:
    """True for a part's group: its kind stamp names a part's kind of its tree type (parts came after the kind stamp,
    so every part carries one; read directly, not through :func:`.stamps.kind_of`, which also recognises groups of
    releases before the stamp: this runs for every group node of a walk, :func:`used_parts`)."""
    return tree is not None and _PART_TREE_TYPES.get(tree.get(stamps.KIND_KEY)) == tree.bl_idname


def instanced_part(node: bpy.types.Node) -> bpy.types.NodeTree | None:
    """The part's group ``node`` instances, or None (not a group node, or a group that is not a part)."""
    if node.bl_idname not in _GROUP_NODE_TYPES:
        return None
    inner = node.node_tree
    return inner if is_part(inner) else None


def inline_count(tree: bpy.types.NodeTree) -> int:
    """The nodes ``tree`` evaluates, its parts' counted as if inlined: a part's instance counts its group's nodes
    but its Group Input and Output."""
    return len(inline_nodes(tree))


def used_parts(tree: bpy.types.NodeTree, found: set | None = None) -> set:
    """The parts' groups ``tree`` instances, directly or through other parts, added to ``found`` (a new set when
    None) and returned: each part is walked once however many groups or parts instance it."""
    found = set() if found is None else found
    for node in tree.nodes:
        inner = instanced_part(node)
        if inner is not None and inner not in found:
            found.add(inner)
            used_parts(inner, found)
    return found


def nodes_with_parts(trees: Iterable[bpy.types.NodeTree]) -> Iterator[tuple[bpy.types.NodeTree, bpy.types.Node, str]]:
    """(tree, node, its ``bl_idname``) for every node of ``trees`` and of the parts they instance, directly or through
    other parts, each part's nodes once: one pass that reads each node's type once (a scan of the table's image nodes
    on every bake, :mod:`atmos_addon.blender.apply.precise_tables`)."""
    seen: set = set()
    todo = list(trees)
    while todo:
        tree = todo.pop(0)
        for node in tree.nodes:
            idname = node.bl_idname
            if idname in _GROUP_NODE_TYPES:
                inner = node.node_tree
                if inner is not None and inner not in seen and is_part(inner):
                    seen.add(inner)
                    todo.append(inner)
            yield tree, node, idname


def inline_nodes(tree: bpy.types.NodeTree) -> list:
    """The nodes ``tree`` evaluates as if its parts were inlined: its own but its parts' instances, and for each
    instance its part's nodes (recursively) but their Group Input and Output; :func:`inline_count` is its length."""
    found = []
    for node in tree.nodes:
        inner = instanced_part(node)
        if inner is not None:
            found += [n for n in inline_nodes(inner) if n.bl_idname not in ("NodeGroupInput", "NodeGroupOutput")]
        else:
            found.append(node)
    return found
