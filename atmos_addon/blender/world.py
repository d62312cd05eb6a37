# SPDX-License-Identifier: GPL-3.0-or-later
"""The Atmos sky in the scene's world, inserted non-destructively and removed exactly.

The user's world data-block is kept (its Eevee probe resolution, sun-extraction and Cycles sampling settings,
its other nodes): two nodes are added to its tree, the "Atmos Sky" group (:mod:`node_groups.sky`) and a
Background shader of strength 1, and the Background feeds the active World Output's Surface. The link that
fed Surface before is remembered (node name and socket identifier) and put back when the sky is removed;
nothing else in the tree is touched, so the tree comes back exactly. A scene without a world gets a new world
"Atmos Sky World", removed again (with the scene's world slot emptied) on removal.

Cycles importance-samples the world only when its sampling method is not "None"; an Atmos sky with sampling
off would light the scene with noise, so "None" is switched to "Automatic" and restored on removal. Other
settings are left alone. What must be restored is stored in the scene (custom property ``atmos_sky``), so
it survives save and reload.
"""

from __future__ import annotations

import warnings

import bpy

from .materials import TAG

STATE_KEY = "atmos_sky"
CREATED_WORLD_NAME = "Atmos Sky World"
SKY_NODE_TAG = "sky"
BACKGROUND_TAG = "sky background"
#: Cycles world importance map width (pixels) while the Atmos sky is in the world (height is half).
SKY_IMPORTANCE_MAP_RESOLUTION = 256


def _set_use_nodes(world: bpy.types.World) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        if not world.use_nodes:
            world.use_nodes = True


def _output_node(tree: bpy.types.NodeTree) -> bpy.types.Node | None:
    outputs = [n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputWorld"]
    active = [n for n in outputs if n.is_active_output]
    return (active or outputs or [None])[0]


def tagged_nodes(world: bpy.types.World | None) -> list[bpy.types.Node]:
    """The nodes the sky added to ``world``'s tree."""
    if world is None or world.node_tree is None:
        return []
    return [n for n in world.node_tree.nodes if n.get(TAG) in (SKY_NODE_TAG, BACKGROUND_TAG)]


def install_sky(scene: bpy.types.Scene, group: bpy.types.ShaderNodeTree) -> str:
    """Show the sky ``group`` in ``scene``'s world (idempotent: an installed sky only gets ``group`` set).

    Returns a sentence for the report.
    """
    world = scene.world
    if world is not None and tagged_nodes(world):
        for node in tagged_nodes(world):
            if node.get(TAG) == SKY_NODE_TAG and node.node_tree != group:
                node.node_tree = group
        return f"Sky: in world '{world.name}'"
    state: dict = {}
    if world is None:
        world = bpy.data.worlds.new(CREATED_WORLD_NAME)
        scene.world = world
        state["created_world"] = world.name
    else:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            state["use_nodes"] = bool(world.use_nodes)
    _set_use_nodes(world)
    tree = world.node_tree
    output = _output_node(tree)
    if output is None:
        output = tree.nodes.new("ShaderNodeOutputWorld")
        output[TAG] = BACKGROUND_TAG  # ours: removed with the sky
    surface = output.inputs["Surface"]
    if surface.is_linked:
        link = surface.links[0]
        state["previous"] = [link.from_node.name, link.from_socket.identifier]
    state["output"] = output.name
    state["world"] = world.name
    cycles = getattr(world, "cycles", None)
    if cycles is not None and cycles.sampling_method in {"NONE", "AUTOMATIC"}:
        # The sky is smooth (the sun disk is for camera rays only, the sun lamp carries the sunlight), so a
        # coarse importance map serves Cycles' world sampling; the automatic 1024 x 512 map costs ~20 s of
        # sky evaluations before every CPU render on 2 cores. A user's manual choice is left alone.
        state["sampling_method"] = cycles.sampling_method
        state["sample_map_resolution"] = cycles.sample_map_resolution
        cycles.sampling_method = "MANUAL"
        cycles.sample_map_resolution = SKY_IMPORTANCE_MAP_RESOLUTION
    sky = tree.nodes.new("ShaderNodeGroup")
    sky.node_tree = group
    sky[TAG] = SKY_NODE_TAG
    sky.label = "Atmos Sky"
    background = tree.nodes.new("ShaderNodeBackground")
    background[TAG] = BACKGROUND_TAG
    background.label = "Atmos Sky Background"
    background.inputs["Strength"].default_value = 1.0
    x, y = output.location
    sky.location = (x - 440.0, y - 320.0)
    background.location = (x - 200.0, y - 320.0)
    tree.links.new(sky.outputs[0], background.inputs["Color"])
    tree.links.new(background.outputs["Background"], surface)
    scene[STATE_KEY] = state
    return f"Sky: in world '{world.name}'" + (" (created)" if "created_world" in state else "")


def uninstall_sky(scene: bpy.types.Scene) -> None:
    """Remove what :func:`install_sky` added and restore the world as it was (no-op if nothing is installed)."""
    state = scene.get(STATE_KEY)
    if state is None:
        return
    state = state.to_dict() if hasattr(state, "to_dict") else dict(state)
    world = bpy.data.worlds.get(state.get("world", ""))
    created = state.get("created_world")
    if world is not None and created == world.name:
        if scene.world == world:
            scene.world = None
        if world.users == 0:
            bpy.data.worlds.remove(world)
    elif world is not None and world.node_tree is not None:
        tree = world.node_tree
        for node in tagged_nodes(world):
            tree.nodes.remove(node)
        output = tree.nodes.get(state.get("output", ""))
        previous = state.get("previous")
        if output is not None and previous:
            source = tree.nodes.get(previous[0])
            socket = next((s for s in source.outputs if s.identifier == previous[1]), None) if source else None
            if socket is not None:
                tree.links.new(socket, output.inputs["Surface"])
        if "sampling_method" in state:
            world.cycles.sampling_method = state["sampling_method"]
            world.cycles.sample_map_resolution = state["sample_map_resolution"]
        if "use_nodes" in state and not state["use_nodes"]:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", DeprecationWarning)
                world.use_nodes = False
    del scene[STATE_KEY]
    remove_unused_sky_group()


def remove_unused_sky_group() -> None:
    """Delete the "Atmos Sky" node group once no world uses it (disabling leaves no orphan data behind)."""
    from .sync import node_groups

    group = bpy.data.node_groups.get(node_groups().sky.SKY_GROUP_NAME)
    if group is not None and group.users == 0:
        bpy.data.node_groups.remove(group)
