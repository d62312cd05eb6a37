# SPDX-License-Identifier: GPL-3.0-or-later
"""Editing a user's node tree the Atmos way: every node Atmos adds carries the tag :data:`TAG` and sits beside the
user's nodes; what it changes outside its nodes is remembered on them and restored when they go (:func:`remove_tagged`).
Shared by the appliers that add nodes to materials and worlds (:mod:`.materials`, :mod:`.in_render`, :mod:`.world`).
"""

from __future__ import annotations

#: The custom property on every node Atmos adds (its value names the node's role).
TAG = "atmos_tag"
#: Custom properties on tagged nodes: what to restore when they are removed (:func:`remove_tagged`). The user's
#: Cycles-target output that was active before a tagged one took over, and the material's Cycles emission sampling
#: before In-Render mode changed it.
REACTIVATE_KEY = "atmos_reactivate"
EMISSION_SAMPLING_KEY = "atmos_emission_sampling"


def output_nodes(tree, kind: str = "ShaderNodeOutputMaterial", skip_tags=None) -> list:
    """The output nodes of type ``kind``, without Atmos' own: every tagged one, or those tagged ``skip_tags``."""
    if skip_tags is None:
        return [node for node in tree.nodes if node.bl_idname == kind and not node.get(TAG)]
    return [node for node in tree.nodes if node.bl_idname == kind and node.get(TAG) not in skip_tags]


def active_of(outputs):
    """The output the surface's opacity is read from: the active "All" one, else the first active one."""
    best = None
    for node in outputs:
        if node.is_active_output:
            if node.target == "ALL":
                return node
            best = best or node
    return best


def cycles_of(outputs):
    """The output Cycles renders: an active one with target Cycles, any Cycles one, else the active "All" one, else
    any "All" one."""
    best, best_rank = None, 4
    for node in outputs:
        target = node.target
        if target not in ("CYCLES", "ALL"):
            continue
        rank = (0 if target == "CYCLES" else 2) + (0 if node.is_active_output else 1)
        if rank < best_rank:
            best, best_rank = node, rank
    return best


def surface_link(output):
    """The link into ``output``'s Surface, or None (one ``links`` lookup, the slow part of reading a socket)."""
    if output is None:
        return None
    surface = output.inputs["Surface"]
    return surface.links[0] if surface.is_linked else None


def cycles_output(tree, kind: str = "ShaderNodeOutputMaterial", skip_tags=None):
    """The output node (of type ``kind``: material or world) Cycles renders: an active one with target Cycles, any
    Cycles one, else the active "All" one, else any "All" one (Atmos' own outputs left out: every tagged one, or
    those tagged ``skip_tags``)."""
    return cycles_of(output_nodes(tree, kind, skip_tags))


def copy_input(tree, source_output, target_output, name: str) -> None:
    """Give ``target_output``'s input ``name`` the link (or the value) of ``source_output``'s."""
    source, target = source_output.inputs.get(name), target_output.inputs.get(name)
    if source is None or target is None:
        return
    if source.is_linked:
        tree.links.new(source.links[0].from_socket, target)
    elif hasattr(source, "default_value") and hasattr(target, "default_value"):
        target.default_value = source.default_value


def take_over_cycles_output(tree, ours, user_output) -> None:
    """Make the tagged Cycles-target output ``ours`` the one Cycles renders. Blender prefers an output of the engine's
    own target to an "All" one, so this matters only where the user has a Cycles-target output too: ours is made
    active and theirs remembered (:data:`REACTIVATE_KEY`), to be made active again by :func:`remove_tagged`."""
    if user_output is None or user_output.target != "CYCLES":
        return
    active = next((n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial" and n.is_active_output
                   and n != ours), None)
    if active is not None:
        ours[REACTIVATE_KEY] = active.name
    ours.is_active_output = True


def free_spot(nodes) -> tuple[float, float]:
    """Where a new node goes: 200 units right of the rightmost of ``nodes``, level with the highest ((0, 0) if none).

    Read with ``foreach_get``: no Python object per node (a third of the Python time of a 5.0 enable went to
    reading each node's location and width one by one).
    """
    count = len(nodes)
    if not count:
        return 0.0, 0.0
    locations, widths = [0.0] * (2 * count), [0.0] * count
    nodes.foreach_get("location", locations)
    nodes.foreach_get("width", widths)
    return max(map(float.__add__, locations[0::2], widths)) + 200.0, max(locations[1::2])


def place_last(nodes, x: float, y: float) -> None:
    """Move the last node of ``nodes`` to (x, y) without an RNA update.

    Every node property write runs a node-tree update (19-27 us in a file of 5000 materials, Blender 4.5-5.3,
    ``tools/bench_node_edits.py``); ``foreach_set`` writes the raw locations (the other nodes get back the values
    just read) and skips that update.
    """
    locations = [0.0] * (2 * len(nodes))
    nodes.foreach_get("location", locations)
    locations[-2:] = (x, y)
    nodes.foreach_set("location", locations)


def remove_tagged(material, tagged) -> None:
    """Delete the tagged nodes ``tagged`` of ``material``, restoring what they remember: the material's Cycles
    emission sampling and the user output that was active before one of them took over (:data:`REACTIVATE_KEY`)."""
    if not tagged:
        return
    reactivate = None
    for node in tagged:
        sampling = node.get(EMISSION_SAMPLING_KEY)
        if sampling is not None and getattr(material, "cycles", None) is not None:
            material.cycles.emission_sampling = sampling
        reactivate = node.get(REACTIVATE_KEY) or reactivate
    nodes = material.node_tree.nodes
    for node in tagged:
        nodes.remove(node)
    if reactivate and nodes.get(reactivate) is not None:
        nodes[reactivate].is_active_output = True
