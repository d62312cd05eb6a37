# SPDX-License-Identifier: GPL-3.0-or-later
"""The Atmos sky in the scene's world, inserted non-destructively and removed exactly.

The user's world data-block is kept (its Eevee probe resolution, sun-extraction and Cycles sampling settings,
its other nodes): seven tagged nodes are added to its tree (ten at the Precise level). The analytic "Atmos Sky" group
(:mod:`atmos_addon.node_groups.sky`) feeds a Background shader of strength 1, and that Background feeds the active World
Output's Surface: what Eevee renders, and what Cycles' camera rays see. For Cycles a second, Cycles-target
World Output is added: a Mix Shader on Light Path > Is Camera Ray gives camera rays that same Background and
every other ray (light samples of the world, rays escaping after a bounce) the same sky from the world's own
"Atmos Sky Lighting" group (:mod:`atmos_addon.node_groups.sky_lighting`: a per-atmosphere table, or at the Precise level
the frame's sky view in the baked table image; a fraction of the cost);
Cycles skips the branch it does not pick. At the Precise level the camera rays' branch is itself a Mix Shader
(:func:`_route_camera_rays`): the "Atmos Sky View" group's two lookups above the horizon, the camera's Background
within a band at the horizon and below it. The link that fed Surface before is remembered (node name and socket
identifier) and put back when the sky is removed; nothing else in the tree is touched, so the tree comes back
exactly. :func:`sync_sky_lighting` writes the table when the atmosphere changes. A scene without a world gets a new
world "Atmos Sky World", removed again (with the scene's world slot emptied) on removal.

Cycles importance-samples the world only when its sampling method is not "None"; an Atmos sky with sampling
off would light the scene with noise, so "None" is switched to "Automatic" and restored on removal. Other
settings are left alone. What must be restored is stored in the scene (custom property ``atmos_sky``), so
it survives save and reload.
"""

from __future__ import annotations

import warnings

import bpy

from ...node_groups import registry, stamps
from ...plan import Plan
from ..facts import sky_features
from ..scene_reading import groups
from ..tree_edits import REACTIVATE_KEY, TAG

STATE_KEY = "atmos_sky"
#: Scene property: the world the sky's copy was made from (an ID reference, :func:`install_sky`).
ORIGINAL_WORLD_KEY = "atmos_sky_original_world"
CREATED_WORLD_NAME = "Atmos Sky World"
SKY_NODE_TAG = "sky"
BACKGROUND_TAG = "sky background"
LIGHTING_TAG = "sky lighting"
LIGHTING_BACKGROUND_TAG = "sky lighting background"
RAY_SWITCH_TAG = "sky ray switch"
MIX_TAG = "sky mix"
CYCLES_OUTPUT_TAG = "sky cycles output"
SKY_VIEW_TAG = "sky view"
SKY_VIEW_BACKGROUND_TAG = "sky view background"
BAND_TAG = "sky horizon band"
#: The nodes of the Precise level's camera sky view (:func:`_route_camera_rays`).
SKY_VIEW_TAGS = (SKY_VIEW_TAG, SKY_VIEW_BACKGROUND_TAG, BAND_TAG)
#: Every tag of the nodes :func:`install_sky` and :func:`_route_camera_rays` add.
TAGS = (SKY_NODE_TAG, BACKGROUND_TAG, LIGHTING_TAG, LIGHTING_BACKGROUND_TAG, RAY_SWITCH_TAG, MIX_TAG,
        CYCLES_OUTPUT_TAG) + SKY_VIEW_TAGS
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
    return [n for n in world.node_tree.nodes if n.get(TAG) in TAGS]


def _tagged(world: bpy.types.World, tag: str, bl_idname: str | None = None) -> bpy.types.Node | None:
    return next((n for n in tagged_nodes(world) if n.get(TAG) == tag
                 and (bl_idname is None or n.bl_idname == bl_idname)), None)


def camera_background(node: bpy.types.Node) -> bpy.types.Node:
    """The Background that camera rays see through ``node`` (a World Output's Surface source): the Atmos sky's
    camera Background (the table's sky, at the Precise level past the horizon band) when ``node`` is its ray switch,
    else ``node`` itself."""
    while node.get(TAG) in (MIX_TAG, BAND_TAG) and node.inputs[2].is_linked:
        node = node.inputs[2].links[0].from_node
    return node


def _add_lighting_branch(tree: bpy.types.NodeTree, features, background: bpy.types.Node) -> None:
    """The lighting group and its Background, the ray switch and Mix Shader, and a Cycles World Output for them.

    Only Cycles gets the switch: Eevee renders the world once into its light probes (no per-sample cost to
    save) and its shader compiler (Mesa's llvmpipe, measured) did not finish a world with the switched Mix
    Shader in 10 minutes, where the camera sky alone compiles in 2 s. Blender prefers an output of the engine's
    own target to an "All" one, so the added Cycles output takes over in Cycles only; where the user already
    has a Cycles-target output, ours is made the active one and theirs re-activated on removal.
    """
    x, y = background.location
    lighting = tree.nodes.new("ShaderNodeGroup")
    lighting.node_tree = groups().sky_lighting.new_sky_lighting_group(features)
    lighting.label = "Atmos Sky Lighting"
    lighting_background = tree.nodes.new("ShaderNodeBackground")
    lighting_background.label = "Atmos Lighting"
    lighting_background.inputs["Strength"].default_value = 1.0
    switch = tree.nodes.new("ShaderNodeLightPath")
    switch.label = "Atmos"   # the Surface slot shows "Atmos | Is Camera Ray" (121 px; 127 px was cut in GUI 5.2.2)
    mix = tree.nodes.new("ShaderNodeMixShader")
    mix.label = "Atmos Sky + Light"  # the World tab's Surface slot shows it (GUI 5.2.2: cut at 22 characters)
    output = tree.nodes.new("ShaderNodeOutputWorld")
    output.label = "Atmos Output"
    output.target = "CYCLES"
    for node, tag, location in ((lighting, LIGHTING_TAG, (x - 240.0, y - 200.0)),
                                (lighting_background, LIGHTING_BACKGROUND_TAG, (x, y - 200.0)),
                                (switch, RAY_SWITCH_TAG, (x, y + 260.0)), (mix, MIX_TAG, (x + 200.0, y - 100.0)),
                                (output, CYCLES_OUTPUT_TAG, (x + 400.0, y - 100.0))):
        node[TAG] = tag
        node.location = location
    tree.links.new(lighting.outputs[0], lighting_background.inputs["Color"])
    tree.links.new(switch.outputs["Is Camera Ray"], mix.inputs["Fac"])
    tree.links.new(lighting_background.outputs["Background"], mix.inputs[1])
    tree.links.new(background.outputs["Background"], mix.inputs[2])
    tree.links.new(mix.outputs["Shader"], output.inputs["Surface"])
    others = [n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputWorld" and n != output and n.target == "CYCLES"]
    if others:
        active = next((n for n in others if n.is_active_output), None)
        if active is not None:
            output[REACTIVATE_KEY] = active.name
        output.is_active_output = True


def sky_group(plan: Plan) -> bpy.types.ShaderNodeTree:
    """The "Atmos Sky" group for ``plan`` (rebuilt in place when stale)."""
    return groups().sky.ensure_sky_group(sky_features(plan))


def install(scene: bpy.types.Scene, plan: Plan) -> str:
    """Show the sky of ``plan`` in ``scene``'s world (:func:`install_sky` of :func:`sky_group`); a sentence for the
    report."""
    return install_sky(scene, sky_group(plan), sky_features(plan))


def update(scene: bpy.types.Scene, plan: Plan) -> None:
    """Rebuild in place what of the installed sky is stale for ``plan`` (cheap when current): the sky group, the
    lighting group and the rays' routes (:func:`update_sky_lighting`)."""
    sky_group(plan)
    update_sky_lighting(scene, sky_features(plan))


def install_sky(scene: bpy.types.Scene, group: bpy.types.ShaderNodeTree, features=None) -> str:
    """Show the sky ``group`` in ``scene``'s world (idempotent: an installed sky only gets ``group`` set).

    ``features`` (the sky's :class:`~atmos_addon.node_groups.sky.SkyFeatures`, default: all terms) shape the lighting group.
    A sky installed by an Atmos without the lighting branch gets it. Returns a sentence for the report.
    """
    features = features if features is not None else groups().sky.SkyFeatures()
    world = scene.world
    if world is not None and tagged_nodes(world):
        for node in tagged_nodes(world):
            if node.get(TAG) == SKY_NODE_TAG and node.node_tree != group:
                node.node_tree = group
        background = _tagged(world, BACKGROUND_TAG, "ShaderNodeBackground")
        if _tagged(world, MIX_TAG) is None and background is not None:
            _add_lighting_branch(world.node_tree, features, background)
        return f"Sky: in world '{world.name}'"
    state: dict = {}
    keeping = sharing_scenes(scene, world)
    original = None
    if world is None:
        world = bpy.data.worlds.new(CREATED_WORLD_NAME)
        scene.world = world
        state["created_world"] = world.name
    else:
        linked = world.library is not None or not getattr(world, "is_editable", True)
        if keeping or linked:   # the sky goes into a copy: the other scenes keep theirs, a library's is not ours
            original = world
            world = original.copy()
            world.name = f"{original.name} (Atmos)"
            scene.world = world
            scene[ORIGINAL_WORLD_KEY] = original   # an ID reference: a linked world no scene uses is kept on save
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
    registry.remove_unused((stamps.SKY_LIGHTING,))   # that of a world deleted since: the new one takes its name
    _add_lighting_branch(tree, features, background)
    scene[STATE_KEY] = state
    if original is not None and not keeping:
        return (f"Sky: in world '{world.name}', a copy of '{original.name}', which is linked from a library "
                "(not editable)")
    if original is not None:
        names = ", ".join(f"'{other.name}'" for other in keeping)
        return (f"Sky: in world '{world.name}', a copy of '{original.name}', which scene(s) {names} keep "
                "(they share it and have no Atmos sky)")
    return f"Sky: in world '{world.name}'" + (" (created)" if "created_world" in state else "")


def sharing_scenes(scene: bpy.types.Scene, world: bpy.types.World | None) -> list:
    """The other scenes that render with ``world`` and have no Atmos sky in it: the sky would reach them without the
    parameters it reads (their world would render black), so :func:`install_sky` puts it in a copy of ``world`` for
    ``scene``."""
    if world is None:
        return []
    return [other for other in bpy.data.scenes if other != scene and other.world == world and STATE_KEY not in other]


def remove(scene: bpy.types.Scene) -> None:
    """Remove what :func:`install_sky` added and restore the world as it was (no-op if nothing is installed)."""
    state = scene.get(STATE_KEY)
    if state is None:
        return
    state = state.to_dict() if hasattr(state, "to_dict") else dict(state)
    world = bpy.data.worlds.get((state.get("world", ""), None))
    created = state.get("created_world")
    original = scene.get(ORIGINAL_WORLD_KEY)
    if world is not None and original is not None:   # the scene's own copy: the scene gets the original back
        if scene.world == world:
            scene.world = original
        if world.users == 0:
            bpy.data.worlds.remove(world)
            world = None
    if world is not None and created == world.name:
        if scene.world == world:
            scene.world = None
        if world.users == 0:
            bpy.data.worlds.remove(world)
    elif world is not None and world.node_tree is not None:
        tree = world.node_tree
        reactivate = next((n.get(REACTIVATE_KEY) for n in tagged_nodes(world) if n.get(REACTIVATE_KEY)), None)
        for node in tagged_nodes(world):
            tree.nodes.remove(node)
        if reactivate and tree.nodes.get(reactivate) is not None:
            tree.nodes[reactivate].is_active_output = True
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
    if ORIGINAL_WORLD_KEY in scene:
        del scene[ORIGINAL_WORLD_KEY]
    registry.remove_unused((stamps.SKY, stamps.SKY_LIGHTING, stamps.SKY_VIEW))


def _table_key(atmosphere) -> str:
    """The atmosphere values the lighting table depends on, as text (stored on the lighting group)."""
    values = [*atmosphere.rayleigh_scattering, *atmosphere.mie_scattering, *atmosphere.mie_absorption,
              atmosphere.planet_radius, atmosphere.rayleigh_scale_height, atmosphere.mie_scale_height]
    return " ".join(f"{float(v):.9g}" for v in values)


def _route_other_rays(world: bpy.types.World) -> None:
    """Cycles' non-camera rays see the lighting group's Background: the curves' dome sky, or at the Precise level
    the frame's sky view (:func:`atmos_addon.node_groups.sky_lighting.precise_lighting_radiance`). Files saved before the
    Precise sky view routed those rays to the camera's Precise sky; they are relinked here. Relinks only when the
    route changes."""
    mix = _tagged(world, MIX_TAG, "ShaderNodeMixShader")
    source = _tagged(world, LIGHTING_BACKGROUND_TAG, "ShaderNodeBackground")
    if mix is None or source is None:
        return
    socket = mix.inputs[1]
    if not (socket.is_linked and socket.links[0].from_node == source):
        world.node_tree.links.new(source.outputs["Background"], socket)


def _remove_sky_view_nodes(world: bpy.types.World) -> bool:
    """Remove the camera sky view's nodes from ``world``; True if there were any."""
    leaving = [n for n in tagged_nodes(world) if n.get(TAG) in SKY_VIEW_TAGS]
    for node in leaving:
        world.node_tree.nodes.remove(node)
    return bool(leaving)


def _route_camera_rays(world: bpy.types.World, features) -> None:
    """Cycles' camera rays at the Precise level: above the horizon band the "Atmos Sky View" group's two lookups
    (:mod:`atmos_addon.node_groups.sky_view`), within it and below the horizon the camera's Background (the "Atmos Sky"
    group), mixed by a Mix Shader on the group's Exact weight, whose other branch Cycles skips where the weight is 0
    or 1. At the Fast level the camera's Background directly; the view's nodes and its group are removed. (A table
    baked by an older Atmos lacks the camera sky view: ``precise_tables.follow`` bakes it again.) Edits only when the
    route changes."""
    mix = _tagged(world, MIX_TAG, "ShaderNodeMixShader")
    background = _tagged(world, BACKGROUND_TAG, "ShaderNodeBackground")
    if mix is None or background is None:
        return
    tree = world.node_tree
    band = _tagged(world, BAND_TAG, "ShaderNodeMixShader")
    if features.level != "precise":
        if not (mix.inputs[2].is_linked and mix.inputs[2].links[0].from_node == background):
            tree.links.new(background.outputs["Background"], mix.inputs[2])
        if _remove_sky_view_nodes(world):
            registry.remove_unused((stamps.SKY_VIEW,))
        return
    group = groups().sky_view.ensure_sky_view_group(features)
    view = _tagged(world, SKY_VIEW_TAG, "ShaderNodeGroup")
    view_background = _tagged(world, SKY_VIEW_BACKGROUND_TAG, "ShaderNodeBackground")
    if band is None or view is None or view_background is None:
        _remove_sky_view_nodes(world)   # a partial set (a hand edit): made again whole
        x, y = mix.location
        view = tree.nodes.new("ShaderNodeGroup")
        view.label = "Atmos Sky View"
        view_background = tree.nodes.new("ShaderNodeBackground")
        view_background.label = "Atmos Sky View"
        view_background.inputs["Strength"].default_value = 1.0
        band = tree.nodes.new("ShaderNodeMixShader")
        band.label = "Atmos Horizon Band"
        for node, tag, location in ((view, SKY_VIEW_TAG, (x - 440.0, y + 120.0)),
                                    (view_background, SKY_VIEW_BACKGROUND_TAG, (x - 200.0, y + 120.0)),
                                    (band, BAND_TAG, (x, y + 120.0))):
            node[TAG] = tag
            node.location = location
        view.node_tree = group
        sky_view = groups().sky_view
        tree.links.new(view.outputs[groups().OUTPUT_RADIANCE], view_background.inputs["Color"])
        tree.links.new(view.outputs[sky_view.OUTPUT_EXACT], band.inputs["Fac"])
        tree.links.new(view_background.outputs["Background"], band.inputs[1])
    elif view.node_tree != group:
        view.node_tree = group
    if not (band.inputs[2].is_linked and band.inputs[2].links[0].from_node == background):
        tree.links.new(background.outputs["Background"], band.inputs[2])
    if not (mix.inputs[2].is_linked and mix.inputs[2].links[0].from_node == band):
        tree.links.new(band.outputs["Shader"], mix.inputs[2])


def _lighting_tree(scene: bpy.types.Scene):
    node = _tagged(scene.world, LIGHTING_TAG) if scene.world is not None else None
    return None if node is None else node.node_tree


def update_sky_lighting(scene: bpy.types.Scene, features) -> None:
    """Rebuild the world's lighting group if stale for ``features`` (the dome's table is then written again by
    :func:`write_sky_lighting_table`; the Precise one reads the frame's sky view from the baked table image), route
    the other rays to it (:func:`_route_other_rays`) and the camera rays through the Precise level's sky view
    (:func:`_route_camera_rays`). Cheap when current."""
    tree = _lighting_tree(scene)
    if tree is None:
        return
    _route_other_rays(scene.world)
    _route_camera_rays(scene.world, features)
    module = groups().sky_lighting
    if module.ensure_current(tree, features) and module.TABLE_KEY in tree:
        del tree[module.TABLE_KEY]


def write_sky_lighting_table(scene: bpy.types.Scene, atmosphere) -> None:
    """Write the lighting group's table when the atmosphere changed (values only; one key comparison when not)."""
    from ...physics.sky_table import sky_lighting_table

    tree = _lighting_tree(scene)
    module = groups().sky_lighting
    if tree is None or module.TABLE_NODES[0] not in tree.nodes:   # none, or the Precise sky view's group
        return
    key = _table_key(atmosphere)
    if tree.get(module.TABLE_KEY) == key:
        return
    table = sky_lighting_table(atmosphere)
    module.write_sky_table(tree, table.coordinate,
                           (table.scattering_rayleigh, table.scattering_mie, table.transmittance), key)
