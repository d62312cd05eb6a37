# SPDX-License-Identifier: GPL-3.0-or-later
"""Injection of the aerial perspective AOVs into the materials of a scene, and their removal.

Each managed material gets one node beside the user's nodes: a group node (label "Atmos Surface
AOVs", custom property ``atmos_tag``) instancing the shared group "Atmos Surface AOVs", which holds

- the "Atmos Aerial Perspective" group (outputs Transmittance and Inscattering),
- AOV Outputs ``atmos_transmittance`` and ``atmos_inscattering`` (colour) and ``atmos_coverage``
  (value), each weighted by the surface's opacity alpha = Opacity * (1 - Transparency);
- for the Per Pixel mode, AOV Outputs ``atmos_distance`` (alpha times the camera distance in km) and
  ``atmos_view`` (alpha times the unit view direction) instead of the first two and the aerial group. The group
  holds the outputs of the modes the file's enabled scenes use (both when scenes differ); switching the mode
  rebuilds it in place, so the materials are not edited.

Where the surface has an alpha path (Principled BSDF Alpha, or a Mix Shader with a Transparent BSDF
on one side) that socket is linked to the group's Opacity (or Transparency) input. Weighting by
opacity keeps a cut-out (a leaf card) from writing the atmosphere of its own distance where it is
transparent: Cycles writes AOVs at every surface a camera ray passes until one with alpha >= the
view layer's alpha threshold (0.5), adding them up, so a fully transparent texel writes 0 and the
surface behind writes its own values; Eevee's dithered transparency discards those samples.
The compositor (:mod:`.compositor`) reads the coverage to leave sky pixels untouched and to
normalise pixels where more than one surface wrote.

One node per material (not six) because every node edit in a material whose tree holds AOV outputs
makes Blender re-check all materials (cost grows with the file); for the same reason a large pass
edits materials against an empty stand-in group and swaps the real group in with one remap. The node keeps
Blender's default name ("Group"): renaming a node fixes animation paths across the whole file and
would be the slowest step; it is found by its tag. Removal deletes exactly the tagged nodes (and
with them their links), so the user's node set and links come back unchanged.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import bpy

from ...plan import AOV_COVERAGE, AOV_DISTANCE, AOV_INSCATTERING, AOV_TRANSMITTANCE, AOV_VIEW
from ..tree_edits import (TAG, active_of, copy_input, cycles_of, cycles_output, free_spot, output_nodes, place_last,
                          remove_tagged, surface_link, take_over_cycles_output)

PREFIX = "Atmos "
#: The AOV names (:data:`atmos_addon.plan.AOVS`); the Per Pixel mode's distance AOV holds alpha s / 1000 (s in m).
DISTANCE_AOV_UNIT_M = 1000.0
#: The scene custom property holding metres per scene unit (``atmos_addon.nodes.parameters.METRES_PER_UNIT``).
METRES_PER_UNIT = "atmos_metres_per_unit"

#: The one group node each managed material gets, and the group it instances.
SURFACE_GROUP = "Atmos Surface AOVs"
SURFACE_GROUP_VERSION = 2  # 2: the Per Pixel mode's distance and view outputs
VERSION_KEY = "atmos_version"
#: The evaluations whose outputs the surface group holds, e.g. "COMPOSITOR" or "COMPOSITOR,PER_PIXEL".
EVALUATIONS_KEY = "atmos_evaluations"
NODE_LABEL = "Atmos Surface AOVs"
#: Above this many materials per pass, the surface group is emptied while materials are edited (see inject_scene).
BULK_THRESHOLD = 16

#: Tags of the three nodes that keep a surface opaque in Cycles when Cycles folds its shader away (:func:`keep_opaque`).
OPAQUE_BLACK_TAG, OPAQUE_ADD_TAG, OPAQUE_OUTPUT_TAG = "opaque black", "opaque add", "opaque output"
OPAQUE_TAGS = (OPAQUE_BLACK_TAG, OPAQUE_ADD_TAG, OPAQUE_OUTPUT_TAG)

#: Object types that render surfaces with materials.
GEOMETRY_TYPES = frozenset({"MESH", "CURVE", "SURFACE", "META", "FONT", "CURVES", "POINTCLOUD", "VOLUME"})


@dataclass
class MaterialReport:
    """What an injection pass did: managed materials, skipped ones and why, objects without materials."""

    managed: list[str] = field(default_factory=list)
    injected: list[str] = field(default_factory=list)
    skipped: list[tuple[str, str]] = field(default_factory=list)
    objects_without_material: list[str] = field(default_factory=list)


#: Blender 5.0 materials always use their nodes (``Material.use_nodes`` reads True, deprecated, gone in 6.0).
_ALWAYS_NODES = bpy.app.version >= (5, 0, 0)


def _uses_nodes(material) -> bool:
    if _ALWAYS_NODES:
        return material.node_tree is not None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        return bool(material.use_nodes) and material.node_tree is not None


def _is_editable(material) -> bool:
    if material.library is not None:
        return False
    return bool(getattr(material, "is_editable", True))


def scene_materials(scene) -> tuple[list, list[str]]:
    """The distinct materials used by the scene's objects (first-seen order) and the objects without one."""
    seen: dict[int, object] = {}
    bare: list[str] = []
    for obj in scene.objects:
        if obj.type not in GEOMETRY_TYPES:
            continue
        found = False
        for slot in obj.material_slots:
            material = slot.material
            if material is None:
                continue
            found = True
            key = material.as_pointer()
            if key not in seen:
                seen[key] = material
        if not found:
            bare.append(obj.name)
    return list(seen.values()), bare


def atmos_nodes(material) -> list:
    """The Atmos-tagged nodes of a material."""
    tree = material.node_tree
    return [] if tree is None else [node for node in tree.nodes if node.get(TAG)]


def is_injected(material) -> bool:
    """True when the material carries the Atmos surface group node."""
    return any(node.bl_idname == "ShaderNodeGroup" for node in atmos_nodes(material))


def skip_reason(material) -> str | None:
    """Why the material cannot be managed, or None."""
    if not _is_editable(material):
        where = material.library.filepath if material.library is not None else "a library override"
        return f"linked from {where} (not editable): make it local to include it"
    if not _uses_nodes(material):
        return "does not use nodes: enable 'Use Nodes' to include it"
    return None


#: Shaders through which Atmos sees what lies behind: a Transparent BSDF shows the surface behind, a Holdout cuts a
#: hole in the render (alpha 0) that a compositor fills with a plate, which has its own atmosphere: Atmos leaves
#: the hole as it is (coverage 0), in both engines.
SEE_THROUGH_SHADERS = frozenset({"ShaderNodeBsdfTransparent", "ShaderNodeHoldout"})


def opacity(tree, link=False, shader=None):
    """The surface's opacity as ``(socket, None, invert)``, ``(None, constant, False)``, or ``(None, None, False)``
    when opaque.

    Found for a Principled BSDF (its Alpha input), a Holdout (opacity 0), or a Mix Shader with a Transparent BSDF
    or a Holdout on one side (its factor, or one minus it) feeding the active Material Output. ``link``: the link
    into that output's Surface when the caller has it (None: unlinked), ``shader`` its source node.
    """
    if link is False:
        link = surface_link(active_of(output_nodes(tree)))
    if link is None:
        return None, None, False
    shader = link.from_node if shader is None else shader
    if shader.bl_idname == "ShaderNodeHoldout":
        return None, 0.0, False
    if shader.bl_idname == "ShaderNodeBsdfPrincipled":
        alpha = shader.inputs["Alpha"]
        if alpha.is_linked:
            return alpha.links[0].from_socket, None, False
        return (None, float(alpha.default_value), False) if alpha.default_value < 1.0 else (None, None, False)
    if shader.bl_idname == "ShaderNodeMixShader":
        factor = shader.inputs[0]
        for index, invert in ((1, False), (2, True)):
            sock = shader.inputs[index]
            if sock.is_linked and sock.links[0].from_node.bl_idname in SEE_THROUGH_SHADERS:
                # Mix = (1 - f) * A + f * B: opacity is f when A is transparent, 1 - f when B is.
                if factor.is_linked:
                    return factor.links[0].from_socket, None, invert
                value = float(factor.default_value)
                return None, (1.0 - value if invert else value), False
    return None, None, False


# -- the output Cycles renders, and surfaces Cycles folds away ------------------------------------------------


def _is_zero(socket) -> bool:
    """True when ``socket`` holds a constant exactly 0 (all three channels of a colour), unlinked or fed by a Value or
    RGB node: what Cycles' constant folding sees as zero."""
    if socket.is_linked:
        node = socket.links[0].from_node
        if node.bl_idname not in ("ShaderNodeValue", "ShaderNodeRGB") or node.mute:
            return False
        value = node.outputs[0].default_value
    else:
        value = socket.default_value
    values = tuple(value)[:3] if hasattr(value, "__len__") else (value,)
    return all(float(v) == 0.0 for v in values)


def _folds_away(socket, depth: int = 0) -> bool:
    """True when the shader linked into ``socket`` (a shader input) is nothing after Cycles' constant folding
    (:func:`_link_folds_away`; no link is nothing)."""
    return not socket.is_linked or _link_folds_away(socket.links[0], depth)


#: Shader nodes that can fold away; any other source of a surface is a shader (the fast exit of the check).
_FOLDABLE = frozenset({"NodeReroute", "ShaderNodeEmission", "ShaderNodeBackground", "ShaderNodeAddShader",
                       "ShaderNodeMixShader", "ShaderNodeGroup"})


def _link_folds_away(link, depth: int = 0, node=None) -> bool:
    """True when the shader ``link`` carries is nothing after Cycles' constant folding: an Emission or Background
    of colour 0 or strength 0, an Add Shader of two such, a Mix Shader whose constant factor picks one or whose
    both sides are such, a group whose output is such (a muted link is no link). Anything else (a BSDF of any
    colour, a texture, a muted node) counts as a shader: Atmos only acts where it is sure. ``node``: the link's
    source node when the caller has it."""
    if depth > 32:
        return False
    node = link.from_node if node is None else node
    if node.bl_idname not in _FOLDABLE and not link.is_muted:
        return False
    if link.is_muted or not link.is_valid:
        return True
    node = link.from_node
    if node.mute:
        return False
    kind = node.bl_idname
    if kind == "NodeReroute":
        return _folds_away(node.inputs[0], depth + 1)
    if kind in ("ShaderNodeEmission", "ShaderNodeBackground"):
        return _is_zero(node.inputs["Color"]) or _is_zero(node.inputs["Strength"])
    if kind == "ShaderNodeAddShader":
        return _folds_away(node.inputs[0], depth + 1) and _folds_away(node.inputs[1], depth + 1)
    if kind == "ShaderNodeMixShader":
        factor = node.inputs[0]
        if not factor.is_linked and factor.default_value <= 0.0:
            return _folds_away(node.inputs[1], depth + 1)
        if not factor.is_linked and factor.default_value >= 1.0:
            return _folds_away(node.inputs[2], depth + 1)
        return _folds_away(node.inputs[1], depth + 1) and _folds_away(node.inputs[2], depth + 1)
    if kind == "ShaderNodeGroup" and node.node_tree is not None:
        output = next((n for n in node.node_tree.nodes if n.bl_idname == "NodeGroupOutput" and n.is_active_output),
                      None)
        inner = None if output is None else next(
            (i for i in output.inputs if i.identifier == link.from_socket.identifier), None)
        return inner is not None and _folds_away(inner, depth + 1)
    return False


def surface_folds_away(tree, output=False, link=False, shader=None) -> bool:
    """True when the surface Cycles renders is nothing after constant folding and no volume is linked.

    Measured (bpy 4.5.15, 5.2.3, 5.3.0): Cycles renders such a material, which without Atmos is opaque black, as if
    it were transparent once the material also holds AOV outputs fed by shading data (Atmos' distance, view and
    haze AOVs are): camera rays pass on to the world behind it (its AOVs still written) and it casts no shadow. A
    black emissive target then composites as the sky behind it hazed, not as its haze. A volume-only material (no
    surface, a volume linked) is transparent by design and left alone. ``output``, ``link``: the output Cycles
    renders, the link into its Surface and that link's source node, when the caller has them.
    """
    output = cycles_output(tree) if output is False else output
    if output is None:
        return False
    link = surface_link(output) if link is False else link
    if link is not None and not _link_folds_away(link, node=shader):
        return False
    volume = output.inputs.get("Volume")
    return not (volume is not None and volume.is_linked)


def _opaque_nodes(material) -> list:
    return [node for node in atmos_nodes(material) if node.get(TAG) in OPAQUE_TAGS]


def keep_opaque(material, present: list | None = None, output=False, link=False, shader=None) -> bool:
    """Keep ``material`` opaque in Cycles while its surface folds away (:func:`surface_folds_away`); idempotent.

    Three tagged nodes beside the user's, none of the user's links or values touched: a black Diffuse BSDF (a
    closure Cycles keeps, which reflects nothing: the surface stays what it was without Atmos, opaque black and
    casting shadows), an Add Shader of the user's surface shader and that black one (so an edit of the user's
    shader's values still shows), and a Cycles-target Material Output carrying it with the user's Displacement and
    Thickness. Eevee ignores a Cycles-target output. They are rebuilt when the user relinks the surface and removed
    when it stops folding (the depsgraph handler calls this for edited materials). Returns True when anything
    changed. ``present``: the material's opaque-keeping nodes when the caller knows them (none after a re-inject);
    ``output``, ``link``, ``shader``: the output Cycles renders, the link into its Surface and that link's source
    node, when the caller has them.
    """
    tree = material.node_tree
    present = _opaque_nodes(material) if present is None else present
    user_output = cycles_output(tree) if output is False else output
    link = surface_link(user_output) if link is False else link
    needed = surface_folds_away(tree, user_output, link, shader)
    source = link.from_socket if needed and link is not None else None
    if present and needed:
        adds = [node for node in present if node.get(TAG) == OPAQUE_ADD_TAG]
        current = adds[0].inputs[0].links[0].from_socket if adds and adds[0].inputs[0].is_linked else None
        if len(present) == len(OPAQUE_TAGS) and current == source:
            return False
    if not present and not needed:
        return False
    remove_tagged(material, present)
    if not needed:
        return True
    x, y = free_spot(tree.nodes)
    black = tree.nodes.new("ShaderNodeBsdfDiffuse")
    place_last(tree.nodes, x, y - 300.0)
    black.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    add = tree.nodes.new("ShaderNodeAddShader")
    place_last(tree.nodes, x + 200.0, y - 300.0)
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    place_last(tree.nodes, x + 400.0, y - 300.0)
    output.target = "CYCLES"
    for node, tag, label in ((black, OPAQUE_BLACK_TAG, "Atmos: opaque black (Cycles)"),
                             (add, OPAQUE_ADD_TAG, "Atmos: keeps the surface (Cycles)"),
                             (output, OPAQUE_OUTPUT_TAG, "Atmos Output (Cycles): keeps the surface opaque")):
        node[TAG] = tag
        node.label = label
    if source is not None:
        tree.links.new(source, add.inputs[0])
    tree.links.new(black.outputs[0], add.inputs[1])
    tree.links.new(add.outputs[0], output.inputs["Surface"])
    if user_output is not None:
        for name in ("Displacement", "Thickness"):
            copy_input(tree, user_output, output, name)
    take_over_cycles_output(tree, output, user_output)
    return True


def follow_edits(depsgraph) -> None:
    """After edits: keep the edited materials that carry the AOV group opaque where their surface now folds away,
    and drop the opaque-keeping nodes where it no longer does (:func:`keep_opaque`; In-Render materials have their
    own Cycles output and are left alone)."""
    for update in depsgraph.updates:
        material = getattr(update.id, "original", None)
        if not isinstance(material, bpy.types.Material) or material.node_tree is None or material.library:
            continue
        if any(node.get(TAG) == 1 and node.bl_idname == "ShaderNodeGroup" for node in material.node_tree.nodes):
            keep_opaque(material)


def _surface_group_interface(tree) -> None:
    tree.interface.clear()
    opacity = tree.interface.new_socket("Opacity", in_out="INPUT", socket_type="NodeSocketFloat")
    opacity.default_value, opacity.min_value, opacity.max_value = 1.0, 0.0, 1.0
    transparency = tree.interface.new_socket("Transparency", in_out="INPUT", socket_type="NodeSocketFloat")
    transparency.default_value, transparency.min_value, transparency.max_value = 0.0, 0.0, 1.0


def build_surface_group(tree, aerial_group, evaluations=("COMPOSITOR",)) -> None:
    """Build the material group in ``tree`` (its interface when missing): aerial group -> opacity weights -> AOV
    outputs; alpha = Opacity * (1 - Transparency).

    Only the outputs of the ``evaluations`` in use ("COMPOSITOR": the aerial group and the transmittance and
    in-scattering AOVs; "PER_PIXEL": the distance and view AOVs) are built: Eevee compiles every AOV output
    of a material, declared or not (a group holding both took Eevee 417 s to compile where one took 2 s).
    """
    if not ("Opacity" in tree.interface.items_tree and "Transparency" in tree.interface.items_tree):
        _surface_group_interface(tree)
    nodes, links = tree.nodes, tree.links
    nodes.clear()
    group_in = nodes.new("NodeGroupInput")
    group_in.location = (-500, -250)
    one_minus = nodes.new("ShaderNodeMath")
    one_minus.operation = "SUBTRACT"
    one_minus.inputs[0].default_value = 1.0
    one_minus.location = (-250, -300)
    links.new(group_in.outputs["Transparency"], one_minus.inputs[1])
    alpha = nodes.new("ShaderNodeMath")
    alpha.operation = "MULTIPLY"
    alpha.use_clamp = True
    alpha.location = (-50, -250)
    links.new(group_in.outputs["Opacity"], alpha.inputs[0])
    links.new(one_minus.outputs[0], alpha.inputs[1])
    per_sample = ()
    if "COMPOSITOR" in evaluations:
        aerial = nodes.new("ShaderNodeGroup")
        aerial.node_tree = aerial_group
        aerial.location = (-500, 0)
        per_sample = (("Transmittance", AOV_TRANSMITTANCE), ("Inscattering", AOV_INSCATTERING))
    for index, (output, aov_name) in enumerate(per_sample):
        scale = nodes.new("ShaderNodeVectorMath")
        scale.operation = "SCALE"
        scale.location = (150, -180.0 * index)
        links.new(aerial.outputs[output], scale.inputs[0])
        links.new(alpha.outputs[0], scale.inputs["Scale"])
        aov = nodes.new("ShaderNodeOutputAOV")
        aov.aov_name = aov_name
        aov.location = (400, -180.0 * index)
        links.new(scale.outputs[0], aov.inputs["Color"])
    coverage = nodes.new("ShaderNodeOutputAOV")
    coverage.aov_name = AOV_COVERAGE
    coverage.location = (400, -400)
    links.new(alpha.outputs[0], coverage.inputs["Value"])
    if "PER_PIXEL" in evaluations:
        _add_per_pixel_outputs(nodes, links, alpha.outputs[0])
    tree[VERSION_KEY] = SURFACE_GROUP_VERSION
    tree[EVALUATIONS_KEY] = ",".join(sorted(evaluations))


def _add_per_pixel_outputs(nodes, links, alpha) -> None:
    """The Per Pixel mode's AOVs: alpha s / 1000 (s the camera distance in m) and alpha v (v the view direction)."""
    camera = nodes.new("ShaderNodeCameraData")
    camera.location = (-500, -550)
    metres = nodes.new("ShaderNodeAttribute")
    metres.attribute_type = "VIEW_LAYER"
    metres.attribute_name = METRES_PER_UNIT
    metres.location = (-500, -700)
    unit = nodes.new("ShaderNodeMath")
    unit.operation = "MULTIPLY"
    unit.inputs[1].default_value = 1.0 / DISTANCE_AOV_UNIT_M
    unit.location = (-250, -650)
    links.new(metres.outputs["Fac"], unit.inputs[0])
    weight = nodes.new("ShaderNodeMath")
    weight.operation = "MULTIPLY"
    weight.location = (-50, -600)
    links.new(alpha, weight.inputs[0])
    links.new(unit.outputs[0], weight.inputs[1])
    distance = nodes.new("ShaderNodeMath")
    distance.operation = "MULTIPLY"
    distance.location = (150, -560)
    links.new(camera.outputs["View Distance"], distance.inputs[0])
    links.new(weight.outputs[0], distance.inputs[1])
    distance_aov = nodes.new("ShaderNodeOutputAOV")
    distance_aov.aov_name = AOV_DISTANCE
    distance_aov.location = (400, -560)
    links.new(distance.outputs[0], distance_aov.inputs["Value"])
    geometry = nodes.new("ShaderNodeNewGeometry")
    geometry.location = (-500, -850)
    toward = nodes.new("ShaderNodeMath")
    toward.operation = "MULTIPLY"
    toward.inputs[1].default_value = -1.0
    toward.location = (-50, -800)
    links.new(alpha, toward.inputs[0])
    view = nodes.new("ShaderNodeVectorMath")
    view.operation = "SCALE"
    view.location = (150, -760)
    links.new(geometry.outputs["Incoming"], view.inputs[0])
    links.new(toward.outputs[0], view.inputs["Scale"])
    view_aov = nodes.new("ShaderNodeOutputAOV")
    view_aov.aov_name = AOV_VIEW
    view_aov.location = (400, -760)
    links.new(view.outputs[0], view_aov.inputs["Color"])


def _is_populated(tree, aerial_group, evaluations) -> bool:
    return (
        tree.get(VERSION_KEY) == SURFACE_GROUP_VERSION
        and tree.get(EVALUATIONS_KEY) == ",".join(sorted(evaluations))
        and ("COMPOSITOR" not in evaluations
             or any(n.bl_idname == "ShaderNodeGroup" and n.node_tree == aerial_group for n in tree.nodes))
    )


def ensure_surface_group(aerial_group, evaluations=("COMPOSITOR",)):
    """Get or create the "Atmos Surface AOVs" shader group around ``aerial_group`` with the outputs of the
    ``evaluations`` in use (rebuilt in place when stale: the materials' group nodes keep pointing at it)."""
    tree = bpy.data.node_groups.get(SURFACE_GROUP)
    if tree is not None and tree.bl_idname != "ShaderNodeTree":
        tree.name = SURFACE_GROUP + " (not Atmos)"
        tree = None
    if tree is None:
        tree = bpy.data.node_groups.new(SURFACE_GROUP, "ShaderNodeTree")
    if not ("Opacity" in tree.interface.items_tree and "Transparency" in tree.interface.items_tree):
        _surface_group_interface(tree)
    if not _is_populated(tree, aerial_group, evaluations):
        inner = _inner_groups(tree)
        build_surface_group(tree, aerial_group, evaluations)
        _remove_unused(inner)   # the aerial group, when the Compositor mode's outputs left
    return tree


def _inner_groups(tree) -> set:
    return {node.node_tree for node in tree.nodes if node.bl_idname == "ShaderNodeGroup" and node.node_tree}


def _remove_unused(groups) -> None:
    """Delete the Atmos groups among ``groups`` that nothing uses any more (no orphans left in the file)."""
    for group in groups:
        if group.users == 0 and group.name.startswith(PREFIX):
            bpy.data.node_groups.remove(group)


def _stand_in():
    """An empty group with the surface group's interface, used by nothing yet.

    Every node edit in a material (or group) that holds AOV outputs makes Blender re-check all the
    materials in the file, so bulk edits point the materials at this empty stand-in and swap the
    real group in (or out) with one ``user_remap``.
    """
    tree = bpy.data.node_groups.new(SURFACE_GROUP + " (stand-in)", "ShaderNodeTree")
    _surface_group_interface(tree)
    return tree


def _remove_stand_in(tree) -> None:
    """Delete the stand-in once the remap has moved its users away.

    With no users and nothing used by it (an interface, no nodes), the unlink pass of a plain remove,
    which visits every data-block of the file (44 ms with 30 000 of them), has nothing to do and is skipped.
    """
    if tree.users:
        bpy.data.node_groups.remove(tree)
    else:
        bpy.data.node_groups.remove(tree, do_unlink=False, do_id_user=False, do_ui_user=False)


def inject(material, surface_group, tagged=None) -> None:
    """Add the Atmos surface group node to one node-based, editable material (idempotent).

    The node sits to the right of the user's nodes; where the surface has an alpha path its opacity
    (or transparency) socket is also linked to the group -- a new link from a user output, never a
    change to the user's links or values. ``tagged``: the material's Atmos nodes, when the caller has
    just listed them (they are replaced).
    """
    tree = material.node_tree
    remove_tagged(material, atmos_nodes(material) if tagged is None else tagged)
    outputs = output_nodes(tree)
    active, cycles = active_of(outputs), cycles_of(outputs)
    active_link = surface_link(active)
    shader = None if active_link is None else active_link.from_node
    opacity_socket, opacity_value, invert = opacity(tree, active_link, shader)
    x, y = free_spot(tree.nodes)
    node = tree.nodes.new("ShaderNodeGroup")
    place_last(tree.nodes, x, y)
    node.label = NODE_LABEL
    node[TAG] = 1
    node.node_tree = surface_group
    target = node.inputs["Transparency" if invert else "Opacity"]
    if opacity_socket is not None:
        tree.links.new(opacity_socket, target)
    elif opacity_value is not None:
        target.default_value = opacity_value
    if cycles == active:
        keep_opaque(material, present=[], output=cycles, link=active_link, shader=shader)
    else:
        keep_opaque(material, present=[], output=cycles)


def remove(material) -> bool:
    """Delete exactly the Atmos-tagged nodes of ``material`` (and with them their links); True if any.

    Settings the tagged nodes changed outside the tree (Cycles emission sampling, which output is active) are
    restored from what those nodes remember (:func:`_remove_nodes`).
    """
    tagged = atmos_nodes(material)
    remove_tagged(material, tagged)
    return bool(tagged)


def inject_scene(scene, aerial_group, *, only_new: bool = False, evaluations=("COMPOSITOR",)) -> MaterialReport:
    """Inject every material used by the scene's objects, each once; report the skipped ones and why.

    ``evaluations``: the compositor evaluations the file's enabled scenes use (see :func:`ensure_surface_group`).
    """
    report = MaterialReport()
    materials, report.objects_without_material = scene_materials(scene)
    todo = []
    for material in materials:
        reason = skip_reason(material)
        if reason is not None:
            report.skipped.append((material.name, reason))
            continue
        report.managed.append(material.name)
        tagged = atmos_nodes(material)
        if not (only_new and any(node.bl_idname == "ShaderNodeGroup" for node in tagged)):
            todo.append((material, tagged))
    if not todo and bpy.data.node_groups.get(SURFACE_GROUP) is None:
        return report  # nothing to inject: no group with zero users left in the file
    surface_group = ensure_surface_group(aerial_group, evaluations)
    target = _stand_in() if len(todo) > BULK_THRESHOLD else surface_group
    for material, tagged in todo:
        inject(material, target, tagged)
        report.injected.append(material.name)
    if target is not surface_group:
        target.user_remap(surface_group)
        _remove_stand_in(target)
    return report


def remove_all(materials) -> list[str]:
    """Strip the Atmos nodes from ``materials``; the names of those that had them.

    With many materials the shared group is swapped for an empty stand-in first (see :func:`_stand_in`).
    """
    surface_group = bpy.data.node_groups.get(SURFACE_GROUP)
    stand_in = None
    if surface_group is not None and len(materials) > BULK_THRESHOLD and surface_group.users:
        stand_in = _stand_in()
        surface_group.user_remap(stand_in)
    stripped = []
    for material in materials:
        if material.library is None and material.node_tree is not None and remove(material):
            stripped.append(material.name)
    if stand_in is not None:
        if stand_in.users:  # materials outside this pass keep the real group
            stand_in.user_remap(surface_group)
        _remove_stand_in(stand_in)
    return stripped


def remove_surface_group() -> None:
    """Delete the surface group once no material uses it, and the aerial group inside it once nothing else does.

    Enabling creates both groups, so disabling the last scene removes both: after the effect was on and
    off again the file holds no Atmos data-block with zero users (orphans that would stay in the session
    and in Orphan Data until the file is saved and reopened). A group with a fake user or another user
    (a user's own material, the sky) stays.
    """
    tree = bpy.data.node_groups.get(SURFACE_GROUP)
    if tree is None or tree.users != 0:
        return
    inner = _inner_groups(tree)
    bpy.data.node_groups.remove(tree)
    _remove_unused(inner)
