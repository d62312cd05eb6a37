# SPDX-License-Identifier: GPL-3.0-or-later
"""The compositor half of aerial perspective: AOV and pass declarations and one inserted group node.

Per pixel the materials leave AOV sums over the surfaces that wrote (see :mod:`.materials`; alpha a_i, 1 for
opaque surfaces, averaged over the pixel's samples): the coverage ``C = sum a_i``, and in the Compositor mode
``T = sum a_i T_i``, its square and cube, ``L = sum a_i L_i``, and the render the sky it shows (the Environment
pass, switched on in every view layer). The group (``node_groups.composite``) combines them: the sky passes untouched, a
pixel of one surface gets exactly L0 F_ex + L_in (Hoffman & Preetham eq. 16), a holdout's hole stays a hole, and a
pixel of two surfaces is corrected for the product of their differences. Its Film Transparent input is driven from
the scene's Film > Transparent (the render then shows no sky).

Per Pixel evaluation (``render_mode`` "PER_PIXEL") inserts ``node_groups.per_pixel``'s group instead: the
materials write the coverage, distance, its moments and the view direction, and the compositor evaluates T and L
from them once per pixel before the same combination. Its parameter inputs are driven from the scene's properties.

The node tree is inserted non-destructively: the links that left Render Layers.Image are moved to
leave our group's output; removing the group puts them back. What must be restored (the previous
``use_nodes`` / ``compositing_node_group`` / ``use_compositing`` and which nodes and AOVs we created)
is stored in the scene (custom property ``atmos_compositor``) so it survives save and reload.
Blender 4.5 composites through ``scene.node_tree`` (Composite node); 5.0 through the node group
in ``scene.compositing_node_group`` (its Group Output).
"""

from __future__ import annotations

import warnings

import bpy

from ... import node_groups
from ...plan import (AOV_COVERAGE, AOV_DISTANCE, AOV_INSCATTERING, AOV_MODES, AOV_MOMENTS, AOV_TRANSMITTANCE,
                     AOV_TRANSMITTANCE_CUBED, AOV_TRANSMITTANCE_SQUARED, AOV_VIEW, AOVS, ENVIRONMENT_PASS, Plan)
from .. import drivers
from ..facts import aerial_features
from ..scene_reading import rendered_view_layers
from ..tree_edits import TAG

GROUP_NAME = node_groups.stamps.COMPOSITE.name
STATE_KEY = "atmos_compositor"
COMPOSITE_NODE = "Atmos Aerial Composite"
CREATED_TREE_NAME = "Atmos Compositor"
#: How the compositor applies the effect: "COMPOSITOR" (per-sample AOVs combined) or "PER_PIXEL" (evaluated here);
#: the view layer AOVs of each are the plan's (:data:`atmos_addon.plan.AOVS`). Per Pixel's colour AOV comes first:
#: Eevee in Blender 5.2 writes 0 into the first AOV of a view layer when that one is a Value AOV (measured in a GUI
#: Blender 5.2.2, viewport and final render, ``tools/verify_viewport.py``, and with the bpy 5.2.3 wheel, where
#: ``test_per_pixel_mode_composites_the_physics[EEVEE]`` fails with that order; not in 4.5, 5.0 or 5.3.0).
EVALUATIONS = AOV_MODES

#: Blender 5.0 replaced scene.node_tree / use_nodes by scene.compositing_node_group.
GROUP_API = "compositing_node_group" in bpy.types.Scene.bl_rna.properties
#: Blender 5.3 composites through a stack of effects (scene.compositor_effects); compositing_node_group, deprecated
#: there, is the active effect's group, and setting it on a scene without effects creates one.
EFFECT_STACK = "compositor_effects" in bpy.types.Scene.bl_rna.properties


def _silently(function, *args):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        return function(*args)


# -- view layer AOVs ---------------------------------------------------------------------------


def declare_aovs(scene, state: dict, aovs=AOVS["COMPOSITOR"]) -> None:
    """Add the Atmos ``aovs`` to every view layer that lacks them; remember which we added."""
    added = list(state.get("added_aovs", []))
    for layer in scene.view_layers:
        existing = {aov.name for aov in layer.aovs}
        for name, kind in aovs:
            if name not in existing:
                aov = layer.aovs.add()
                aov.name = name
                aov.type = kind
                added.append(f"{layer.name}\t{name}")
    state["added_aovs"] = added


def aovs_out_of_order(scene, state: dict, aovs) -> bool:
    """True when a view layer lacks one of ``aovs`` or holds a colour AOV after a Value AOV that Atmos added (a file
    saved by an Atmos that declared fewer or other AOVs): Eevee writes 0 into a Value AOV that a colour AOV follows
    (measured in Blender 5.2.3: with the view layer's AOVs colour, value, value, colour, the first value reads 0; with
    every colour AOV first, each reads what was written)."""
    added = set(state.get("added_aovs", []))
    for layer in scene.view_layers:
        names = {aov.name for aov in layer.aovs}
        if any(name not in names for name, _ in aovs):
            return True
        ours_seen = False
        for aov in layer.aovs:
            if aov.type != "VALUE" and ours_seen:
                return True
            ours_seen = ours_seen or (aov.type == "VALUE" and f"{layer.name}\t{aov.name}" in added)
    return False


def remove_aovs(scene, state: dict) -> None:
    for entry in state.get("added_aovs", []):
        layer_name, _, name = entry.partition("\t")
        layer = scene.view_layers.get(layer_name)
        if layer is None:
            continue
        aov = layer.aovs.get(name)
        if aov is not None:
            layer.aovs.remove(aov)


# -- the scene's compositor tree ---------------------------------------------------------------


def _tag(node, name: str):
    node.name = name
    node[TAG] = 1
    return node


def _scene_tree(scene, state: dict):
    """The scene's compositor tree, created (and recorded for removal) when there is none."""
    if GROUP_API:
        tree = current_tree(scene)
        state.setdefault("had_group", tree is not None)
        if tree is None:
            if EFFECT_STACK:
                state.setdefault("effects_before", [effect.name for effect in scene.compositor_effects])
            tree = bpy.data.node_groups.new(CREATED_TREE_NAME, "CompositorNodeTree")
            tree[TAG] = 1
            _silently(setattr, scene, "compositing_node_group", tree)
        return tree
    state.setdefault("use_nodes", bool(_silently(getattr, scene, "use_nodes")))
    had_tree = scene.node_tree is not None
    before = set(scene.node_tree.nodes.keys()) if had_tree else set()
    scene.use_nodes = True
    tree = scene.node_tree
    # Setting use_nodes on a scene without a tree creates default nodes: they are ours to remove.
    for node in tree.nodes:
        if node.name not in before:
            node[TAG] = 1
    return tree


def _output_input(tree, state: dict):
    """The socket whose input is the final composite: created (tagged) when missing."""
    if GROUP_API:
        output = next((n for n in tree.nodes if n.bl_idname == "NodeGroupOutput" and n.is_active_output), None)
        if output is None:
            output = next((n for n in tree.nodes if n.bl_idname == "NodeGroupOutput"), None)
        if not any(item.item_type == "SOCKET" and item.in_out == "OUTPUT" for item in tree.interface.items_tree):
            tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
            state["added_output_socket"] = True
        if output is None:
            output = _tag(tree.nodes.new("NodeGroupOutput"), "Atmos Group Output")
            output.location = (600, 0)
        return output.inputs[0]
    output = next((n for n in tree.nodes if n.bl_idname == "CompositorNodeComposite"), None)
    if output is None:
        output = _tag(tree.nodes.new("CompositorNodeComposite"), "Atmos Composite")
        output.location = (600, 0)
    return output.inputs["Image"]


def shown_view_layer(scene):
    """The view layer whose image ``scene``'s render shows when no compositor picks one: with *Render Single Layer*,
    the window's view layer (the context's, where the context shows ``scene``), else the first that renders (the
    first of all when none does). A Render Layers node is made for this one: a new node reads the first view layer,
    and a scene whose first layer is switched off (an artist's "Beauty" layer beside the default one) would render
    black."""
    context_layer = getattr(bpy.context, "view_layer", None)
    if scene.render.use_single_layer and getattr(bpy.context, "scene", None) == scene and context_layer is not None:
        return context_layer
    return rendered_view_layers(scene)[0]


#: The Render Layers output that bounds the coverage (:mod:`atmos_addon.node_groups.composite`).
ALPHA = "Alpha"
#: The Environment pass's Render Layers output in Blender 4.5 (5.0 names it :data:`~atmos_addon.plan.ENVIRONMENT_PASS`).
ENVIRONMENT_4_5 = "Env"
#: The group nodes' input driven from the scene's Film > Transparent.
FILM_TRANSPARENT = "Film Transparent"


def sources(evaluation: str) -> tuple[tuple[str, str], ...]:
    """(Render Layers output, group input) of every input the ``evaluation``'s group node reads from the render."""
    shared = ((ALPHA, "Alpha"), (ENVIRONMENT_PASS, "Environment"))
    if evaluation == "PER_PIXEL":
        return ((AOV_COVERAGE, "Coverage"), (AOV_DISTANCE, "Distance"), (AOV_VIEW, "View"),
                (AOV_MOMENTS, "Moments")) + shared
    return ((AOV_TRANSMITTANCE, "Transmittance"), (AOV_INSCATTERING, "Inscattering"), (AOV_COVERAGE, "Coverage"),
            (AOV_TRANSMITTANCE_SQUARED, "Transmittance Squared"),
            (AOV_TRANSMITTANCE_CUBED, "Transmittance Cubed")) + shared


def layer_output(layer_node, name: str):
    """The Render Layers node's output ``name`` (the Environment pass under either of its names), or None."""
    output = layer_node.outputs.get(name)
    if output is None and name == ENVIRONMENT_PASS:
        output = layer_node.outputs.get(ENVIRONMENT_4_5)
    return output


def link_inputs(scene) -> None:
    """Feed each Atmos group node's unfed inputs from the Render Layers node that feeds its Image (a node installed
    by an Atmos whose group lacked them: the alpha, the sky's pass, the moments), and drive its Film
    Transparent input."""
    tree = current_tree(scene)
    if tree is None:
        return
    for node in _installed_nodes(scene):
        image = node.inputs.get("Image")
        if image is None or not image.is_linked:
            continue
        layer_node = image.links[0].from_node
        if layer_node.bl_idname != "CompositorNodeRLayers":
            continue
        for output_name, input_name in sources(installed_evaluation(scene) or "COMPOSITOR"):
            target, source = node.inputs.get(input_name), layer_output(layer_node, output_name)
            if target is not None and source is not None and not target.is_linked:
                tree.links.new(source, target)
        _drive_film(node, scene)


def _drive_film(node, scene) -> None:
    """Drive the group node's Film Transparent input from ``scene.render.film_transparent`` (a single-property
    driver: a farm machine evaluates it without the add-on)."""
    socket = node.inputs.get(FILM_TRANSPARENT)
    if socket is None:
        return
    animation = node.id_data.animation_data
    path = socket.path_from_id("default_value")
    if animation is not None and any(curve.data_path == path for curve in animation.drivers):
        return
    driver = drivers.fresh(socket, "default_value").driver
    drivers.add_variable(driver, "SCENE", scene, "render.film_transparent")


# -- the Environment pass ----------------------------------------------------------------


def upgrade_passes(scene, evaluation: str) -> None:
    """Give an installed ``evaluation`` the AOVs (in the order Eevee reads them: :func:`aovs_out_of_order`), the
    Environment pass and the links its group reads now, where a file saved by an Atmos that read fewer lacks them;
    the compositor tree's routing stays as the file has it. Cheap where nothing is missing (every update calls it)."""
    state = scene[STATE_KEY].to_dict()
    changed = False
    if aovs_out_of_order(scene, state, AOVS[evaluation]):
        remove_aovs(scene, state)
        state["added_aovs"] = []
        declare_aovs(scene, state, AOVS[evaluation])
        changed = True
    changed = declare_environment(scene, state) or changed
    if changed:
        scene[STATE_KEY] = state
    link_inputs(scene)


def declare_environment(scene, state: dict) -> bool:
    """Switch the Environment pass on in every view layer (the sky each pixel shows); remember where we did. True
    when it switched one on."""
    switched = list(state.get("environment_passes", []))
    before = len(switched)
    for layer in scene.view_layers:
        if not layer.use_pass_environment:
            layer.use_pass_environment = True
            switched.append(layer.name)
    state["environment_passes"] = switched
    return len(switched) > before


def follow_shown_view_layer(scene) -> None:
    """Point the Render Layers node Atmos made at :func:`shown_view_layer` when the scene's layers changed since (a
    refresh, an enable); the user's own Render Layers nodes are theirs."""
    tree = current_tree(scene)
    if tree is None:
        return
    name = shown_view_layer(scene).name
    for node in tree.nodes:
        if node.get(TAG) and node.bl_idname == "CompositorNodeRLayers" and node.layer != name:
            node.layer = name


def _render_layer_nodes(tree, scene) -> list:
    return [
        node for node in tree.nodes
        if node.bl_idname == "CompositorNodeRLayers" and not node.mute and node.scene in (None, scene)
    ]


def installed_evaluation(scene) -> str | None:
    """The evaluation (one of :data:`EVALUATIONS`) installed in ``scene``'s compositor, None when not installed."""
    if STATE_KEY not in scene or not _installed_nodes(scene):
        return None
    return str(scene[STATE_KEY].get("evaluation", "COMPOSITOR"))


def ensure_per_pixel_group(features):
    """The per-pixel compositor group for the aerial ``features``, around the combining group.

    When the group is rebuilt for another level or with a new interface (an older version), its group nodes'
    inputs are driven again in every scene that shows it: no input is left at its default, and the Precise
    table's inputs are driven only at that level (the scene has those properties only then).
    """
    per_pixel = node_groups.per_pixel
    old = node_groups.stamps.local(bpy.data.node_groups, per_pixel.GROUP_NAME)
    before = None if old is None else (len(old.interface.items_tree), old.get(per_pixel.FEATURES_KEY))
    tree = per_pixel.ensure_per_pixel_group(features)
    if before is not None and (len(tree.interface.items_tree), tree.get(per_pixel.FEATURES_KEY)) != before:
        for scene in bpy.data.scenes:
            for node in _installed_nodes(scene):
                if node.node_tree == tree:
                    _drive_parameters(node, scene)
    return tree


def ensure_group(plan: Plan):
    """The compositor group of ``plan``'s mode, rebuilt in place when stale: the per-pixel group
    (:func:`ensure_per_pixel_group`) in the Per Pixel mode, the combining group in the Compositor mode; None in
    In-Render mode."""
    if plan.mode == "PER_PIXEL":
        return ensure_per_pixel_group(aerial_features(plan))
    if plan.mode == "COMPOSITOR":
        return node_groups.composite.ensure_composite_group()
    return None


def _drive_parameters(node, scene) -> None:
    """Drive the per-pixel group node's parameter inputs from ``scene``'s Atmos custom properties; at the Precise
    level also the table's inputs (else their drivers are removed).

    Single-property drivers (type Average of one variable): Blender evaluates them without Python, so a farm
    machine without the add-on, or a file opened with scripts disabled, renders the keyed parameters. Existing
    drivers are reset in place (a rebuilt group keeps its sockets' drivers); drivers on inputs the group no
    longer has at those indices (a file saved with the retired Balanced level's camera and sun-depth inputs) are
    removed.
    """
    per_pixel = node_groups.per_pixel
    key = str(node.node_tree.get(per_pixel.FEATURES_KEY, ""))
    precise = node_groups.AerialFeatures.from_key(key).level == "precise"   # "...+precise" or "...+precise+blend"
    sockets = per_pixel.PARAMETER_SOCKETS + (per_pixel.PRECISE_SOCKETS if precise else ())
    targets = [(node.inputs[socket_name], index if size > 1 else None,
                f'["{name}"][{index}]' if size > 1 else f'["{name}"]')
               for name, socket_name, size in sockets for index in range(size)]
    driven = {(socket.path_from_id("default_value"), index if index is not None else 0)
              for socket, index, _ in targets}
    animation = node.id_data.animation_data
    prefix = f'nodes["{node.name}"].inputs['
    for curve in list(animation.drivers) if animation is not None else ():
        if curve.data_path.startswith(prefix) and (curve.data_path, curve.array_index) not in driven:
            animation.drivers.remove(curve)
    for socket, index, data_path in targets:
        driver = drivers.fresh(socket, "default_value", index).driver
        drivers.add_variable(driver, "SCENE", scene, data_path)
        driver.is_valid = True   # an earlier failure (a property written later) would skip it for good
    node.id_data.update_tag()


def revalidate_drivers(scene) -> None:
    """Clear the "invalid" flag of the per-pixel group nodes' drivers in ``scene``. A driver whose target did not
    exist when it was last evaluated is flagged and skipped from then on, in this session and in the saved file:
    the Precise tile parameters, written by the table bake after the group node was driven (the bake calls this
    once they exist), and the camera's z in a scene that had no camera (the depsgraph handler calls this when
    the camera changes)."""
    tree = current_tree(scene)
    animation = None if tree is None else tree.animation_data
    if animation is None:
        return
    prefixes = tuple(f'nodes["{node.name}"].inputs[' for node in _installed_nodes(scene))
    changed = False
    for curve in animation.drivers:
        if prefixes and curve.data_path.startswith(prefixes) and not curve.driver.is_valid:
            curve.driver.is_valid = True
            changed = True
    if changed:
        tree.update_tag()


def _remove_drivers(node) -> None:
    """Remove the drivers :func:`_drive_parameters` put on ``node`` (and nothing else of the tree's animation)."""
    animation = node.id_data.animation_data
    if animation is None:
        return
    prefix = f'nodes["{node.name}"].inputs['
    for curve in [c for c in animation.drivers if c.data_path.startswith(prefix)]:
        animation.drivers.remove(curve)


def install(scene, plan: Plan) -> list[str]:
    """Declare the AOVs of ``plan``'s evaluation and insert its group after every Render Layers node of the scene:
    the combining group (the Compositor mode), or the per-pixel group for the plan's aerial features (the Per Pixel
    mode; its parameters driven from the scene). Installing one evaluation over the other replaces it; messages.
    """
    evaluation = plan.compositor
    if evaluation not in EVALUATIONS:
        raise ValueError(f"the plan's mode {plan.mode!r} installs no compositor group (one of {EVALUATIONS} does)")
    features = aerial_features(plan)
    messages: list[str] = []
    installed = installed_evaluation(scene)
    if installed == evaluation:
        if evaluation == "PER_PIXEL":
            ensure_per_pixel_group(features)
        else:
            node_groups.composite.ensure_composite_group()   # rebuilt in place when stale (a file of an earlier release)
        follow_shown_view_layer(scene)
        upgrade_passes(scene, evaluation)
        return messages  # already installed: idempotent
    if installed is not None:
        remove(scene)
    state = scene[STATE_KEY].to_dict() if STATE_KEY in scene else {}
    state.setdefault("use_compositing", bool(scene.render.use_compositing))
    state.setdefault("viewer_images", _viewer_images())
    state["evaluation"] = evaluation
    per_pixel = evaluation == "PER_PIXEL"
    declare_aovs(scene, state, AOVS[evaluation])
    declare_environment(scene, state)
    group = ensure_per_pixel_group(features) if per_pixel else node_groups.composite.ensure_composite_group()
    tree = _scene_tree(scene, state)
    state.setdefault("created_animation_data", tree.animation_data is None)
    final_input = _output_input(tree, state)
    layers = _render_layer_nodes(tree, scene)
    if not layers:
        layer_node = _tag(tree.nodes.new("CompositorNodeRLayers"), "Atmos Render Layers")
        layer_node.scene = scene
        layer_node.layer = shown_view_layer(scene).name
        layer_node.location = (-400, 0)
        layers = [layer_node]
    for index, layer_node in enumerate(layers):
        image = layer_node.outputs["Image"]
        targets = [link.to_socket for link in image.links]
        if not targets and index == 0 and not final_input.is_linked:
            targets = [final_input]
        combine = _tag(tree.nodes.new("CompositorNodeGroup"), f"{COMPOSITE_NODE} {index}" if index else COMPOSITE_NODE)
        combine.node_tree = group
        combine.label = "Atmos: aerial perspective"
        combine.location = (layer_node.location.x + 300, layer_node.location.y + 250)
        for link in list(image.links):
            tree.links.remove(link)
        tree.links.new(image, combine.inputs["Image"])
        missing = []
        if per_pixel:
            combine.label = "Atmos: aerial perspective (per pixel)"
            _drive_parameters(combine, scene)
        _drive_film(combine, scene)
        for output_name, socket_name in sources(evaluation):
            source = layer_output(layer_node, output_name)
            if source is None:
                missing.append(output_name)
            else:
                tree.links.new(source, combine.inputs[socket_name])
        if missing:
            messages.append(
                f"Render Layers node '{layer_node.name}' has no output {', '.join(missing)}: "
                "switch the render engine to Cycles or Eevee and press Refresh"
            )
        for target in targets:
            tree.links.new(combine.outputs["Image"], target)
    scene.render.use_compositing = True
    scene[STATE_KEY] = state
    if installed == "PER_PIXEL" and not per_pixel:   # left for the Compositor mode: its group, unless in use
        node_groups.registry.remove_unused((node_groups.stamps.PER_PIXEL,))
    return messages


def _viewer_images() -> list[str]:
    """Names of Blender's compositor images ("Viewer Node"; 4.5 creates one when a compositor tree is set up)."""
    return [image.name for image in bpy.data.images if image.type == "COMPOSITING"]


def _remove_viewer_images_created_since(names_before) -> None:
    for image in [bpy.data.images[name] for name in _viewer_images()]:
        if image.name not in names_before:  # Blender recreates it whenever a compositor needs one
            bpy.data.images.remove(image)


def _installed_nodes(scene) -> list:
    tree = current_tree(scene)
    if tree is None:
        return []
    return [node for node in tree.nodes if node.get(TAG) and node.name.startswith(COMPOSITE_NODE)]


def current_tree(scene):
    """The scene's compositing node tree (Blender 5's node group, 4.5's scene tree), or None."""
    if GROUP_API:
        return _silently(getattr, scene, "compositing_node_group")
    return scene.node_tree


def remove(scene) -> None:
    """Undo :func:`install`: relink, remove our nodes, AOVs and tree, restore the scene's switches (the groups
    left unused go with :func:`atmos_addon.node_groups.registry.remove_unused`)."""
    state = scene[STATE_KEY].to_dict() if STATE_KEY in scene else {}
    tree = current_tree(scene)
    if tree is not None:
        for node in [n for n in tree.nodes if n.get(TAG) and n.name.startswith(COMPOSITE_NODE)]:
            _remove_drivers(node)
            image_in = node.inputs["Image"]
            source = image_in.links[0].from_socket if image_in.is_linked else None
            targets = [link.to_socket for link in node.outputs["Image"].links]
            tree.nodes.remove(node)
            if source is not None and not source.node.get(TAG):
                for target in targets:
                    if not target.node.get(TAG):
                        tree.links.new(source, target)
        for node in [n for n in tree.nodes if n.get(TAG)]:
            tree.nodes.remove(node)
        animation = tree.animation_data
        if animation is not None and state.get("created_animation_data") and not animation.drivers \
                and animation.action is None:
            tree.animation_data_clear()
        if GROUP_API:
            if state.get("added_output_socket"):
                for item in list(tree.interface.items_tree):
                    if item.item_type == "SOCKET" and item.in_out == "OUTPUT":
                        tree.interface.remove(item)
                        break
            if tree.get(TAG) and not state.get("had_group", True):
                _silently(setattr, scene, "compositing_node_group", None)
                if not len(tree.nodes) and tree.users == 0:
                    bpy.data.node_groups.remove(tree)
                if EFFECT_STACK and "effects_before" in state:   # the effect that setting the group created
                    for effect in [e for e in scene.compositor_effects if e.name not in state["effects_before"]
                                   and e.node_group is None]:
                        scene.compositor_effects.remove(effect)
    if not GROUP_API and "use_nodes" in state:
        scene.use_nodes = bool(state["use_nodes"])
    remove_aovs(scene, state)
    for name in state.get("environment_passes", []):
        layer = scene.view_layers.get(name)
        if layer is not None:
            layer.use_pass_environment = False
    if "viewer_images" in state:
        _remove_viewer_images_created_since(state["viewer_images"])
    if "use_compositing" in state:
        scene.render.use_compositing = bool(state["use_compositing"])
    if STATE_KEY in scene:
        del scene[STATE_KEY]
