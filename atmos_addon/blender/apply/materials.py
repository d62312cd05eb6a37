# SPDX-License-Identifier: GPL-3.0-or-later
"""Injection of the aerial perspective AOVs into the materials of a scene, and their removal.

Each managed material gets one node beside the user's nodes: a group node (label "Atmos Surface
AOVs", custom property ``atmos_tag``) instancing the shared group "Atmos Surface AOVs"
(:mod:`atmos_addon.node_groups.surface`: through its outputs group, the aerial perspective and the AOV outputs, each
weighted by the surface's opacity alpha = Opacity * (1 - Transparency)).

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
edits materials while the shared group is detached from its outputs (:func:`atmos_addon.node_groups.surface.detached`):
one edit re-attaches them at the end. The node keeps
Blender's default name ("Group"): renaming a node fixes animation paths across the whole file and
would be the slowest step; it is found by its tag. Removal deletes exactly the tagged nodes (and
with them their links), so the user's node set and links come back unchanged.
"""

from __future__ import annotations

import contextlib
import warnings
from dataclasses import dataclass, field

import bpy

from ... import node_groups
from ...node_groups import stamps, surface
from ...plan import AOVS, Plan
from ..facts import aerial_features
from ..scene_reading import rendered_view_layers
from ..tree_edits import (TAG, active_of, copy_input, cycles_of, cycles_output, free_spot, output_nodes, place_last,
                          remove_tagged, surface_link, take_over_cycles_output)

#: The one group node each managed material gets instances this group (built by :mod:`atmos_addon.node_groups.surface`).
SURFACE_GROUP = surface.SURFACE_GROUP
ensure_surface_group = surface.ensure_surface_group
NODE_LABEL = "Atmos Surface AOVs"
#: Above this many materials per pass, the surface group is detached from its outputs while materials are edited.
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
    """The distinct materials the scene renders with (first-seen order) and its objects that render without one.

    Found in three places: the material slots of the scene's objects (hidden ones too: they may render); the Material
    Override of each view layer, which every object of that layer renders with; and, where the file instances
    geometry (:func:`instances_geometry`) or the scene has a background set, the materials of the view layers'
    evaluated dependency graphs: a Geometry Nodes *Set Material*, the objects of a collection instanced from outside
    the scene, a particle system's objects, the set scene's objects.
    A view layer not evaluated yet (:meth:`bpy.types.ViewLayer.update`) has no graph to read; the enable evaluates
    the first before it injects. An object counts as without material when no slot holds one, its evaluated geometry
    has none and not every rendered view layer overrides its materials."""
    seen: dict[int, object] = {}
    bare: list = []
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
            bare.append(obj)
    layers = rendered_view_layers(scene)
    overrides = [layer.material_override for layer in layers]
    for material in overrides:
        if material is not None:
            seen.setdefault(material.as_pointer(), material)
    if layers and all(material is not None for material in overrides):
        bare = []
    if instances_geometry() or scene.background_set is not None:   # a set scene's objects render too
        for layer in layers:
            layer.update()   # what the instances render is only in the evaluated graph: a script's new objects too
        graphs = [layer.depsgraph for layer in layers]
        for depsgraph in graphs:
            for material in evaluated_materials(depsgraph):
                seen.setdefault(material.as_pointer(), material)
        bare = [obj for obj in bare if not any(_evaluated_material_count(obj, depsgraph) for depsgraph in graphs)]
    return list(seen.values()), [obj.name for obj in bare]


def instances_geometry() -> bool:
    """True when the file holds something through which an object can render materials no slot of a scene's object
    lists: a Geometry Nodes tree in use, a collection instanced by an object, or particles that render objects. A
    few reads of the file's node groups, collections and particle settings (none of the 20 000 objects)."""
    return (any(tree.users for tree in bpy.data.node_groups if tree.bl_idname == "GeometryNodeTree")
            or any(collection.users_dupli_group for collection in bpy.data.collections)
            or any(particles.users and particles.render_type in {"OBJECT", "COLLECTION"}
                   for particles in bpy.data.particles))


def evaluated_materials(depsgraph) -> list:
    """The original surface materials among ``depsgraph``'s evaluated data-blocks (grease pencil's left out): what its
    objects, their Geometry Nodes and their instances render with. 11-12 ms with 20 000 objects and 5000 materials
    (5.2.3), where listing the slots takes 50 ms."""
    found = []
    for block in depsgraph.ids:
        if block.id_type == "MATERIAL":
            material = block.original
            if not material.is_grease_pencil:
                found.append(material)
    return found


def _evaluated_material_count(obj, depsgraph) -> int:
    """How many materials ``obj``'s evaluated geometry in ``depsgraph`` holds (where the graph does not hold the object
    Blender hands back the original, whose slots the caller found empty)."""
    return sum(1 for slot in obj.evaluated_get(depsgraph).material_slots if slot.material is not None)


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
        if material.library is None:
            return "a library override (not editable): make it local to include it"
        return (f"linked from {material.library.filepath} (not editable): make it local, or turn Atmos on in that "
                "file (its materials then carry the Atmos nodes)")
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


def edited_materials(depsgraph) -> list:
    """The original materials that carry the AOV group among ``depsgraph``'s updates.

    Read before the handler changes any data: the updates point at the depsgraph's evaluated copies, and rebuilding
    a node group or an image in the same handler (a sun bake, key tiles that start to blend) can free them, so
    reading ``update.id`` afterwards reads freed memory (Blender 5.2.3 crashed there in CI)."""
    if not depsgraph.id_type_updated("MATERIAL"):
        return []
    found = []
    for update in depsgraph.updates:
        material = getattr(update.id, "original", None)
        if not isinstance(material, bpy.types.Material) or material.node_tree is None or material.library:
            continue
        if any(node.get(TAG) == 1 and node.bl_idname == "ShaderNodeGroup" for node in material.node_tree.nodes):
            found.append(material)
    return found


def follow_edits(edited) -> None:
    """After edits: keep the ``edited`` materials (:func:`edited_materials`) opaque where their surface now folds
    away, and drop the opaque-keeping nodes where it no longer does (:func:`keep_opaque`; In-Render materials have
    their own Cycles output and are left alone)."""
    for material in edited:
        keep_opaque(material)


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


def library_aovs(material) -> set[str] | None:
    """The AOVs written by the Atmos nodes a linked material carries (Atmos was on in its library file when it was
    saved), None when it carries none. Such a material needs no edit: its surface group writes the view layer's Atmos
    AOVs by name, like a local one (the Per Pixel mode's distance, view and coverage do not depend on the file)."""
    names: set[str] = set()
    found = False
    for node in atmos_nodes(material):
        if node.bl_idname == "ShaderNodeGroup" and node.node_tree is not None:
            found = True
            names |= surface.aov_names(node.node_tree)
    return names if found else None


def strip(material) -> bool:
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
    needed = {name for mode in evaluations for name, _ in AOVS.get(mode, ())}
    for material in materials:
        reason = skip_reason(material)
        if reason is not None and material.library is not None:
            written = library_aovs(material)
            if written is not None and needed <= written:
                report.managed.append(material.name)   # the Atmos nodes its library file gave it write what we read
                continue
            if written is not None:
                reason = (f"linked from {material.library.filepath} with Atmos nodes of another mode (no "
                          f"{', '.join(sorted(needed - written))}): switch that file to this scene's mode")
        if reason is not None:
            report.skipped.append((material.name, reason))
            continue
        report.managed.append(material.name)
        tagged = atmos_nodes(material)
        if not (only_new and any(node.bl_idname == "ShaderNodeGroup" for node in tagged)):
            todo.append((material, tagged))
    if not todo and stamps.local(bpy.data.node_groups, SURFACE_GROUP) is None:
        return report  # nothing to inject: no group with zero users left in the file
    surface_group = surface.ensure_surface_group(aerial_group, evaluations)
    with surface.detached(surface_group) if len(todo) > BULK_THRESHOLD else contextlib.nullcontext():
        for material, tagged in todo:
            inject(material, surface_group, tagged)
            report.injected.append(material.name)
    return report


def remove_all(materials) -> list[str]:
    """Strip the Atmos nodes from ``materials``; the names of those that had them (with many materials the shared group
    detached meanwhile: :func:`.surface.detached`)."""
    surface_group = stamps.local(bpy.data.node_groups, SURFACE_GROUP)
    bulk = surface_group is not None and len(materials) > BULK_THRESHOLD and surface_group.users
    stripped = []
    with surface.detached(surface_group) if bulk else contextlib.nullcontext():
        for material in materials:
            if material.library is None and material.node_tree is not None and strip(material):
                stripped.append(material.name)
    return stripped


# -- the plan's interface (the orchestrator's) ----------------------------------------------------------------


def aerial_group(plan: Plan):
    """The aerial perspective group the shared surface group wraps for ``plan``: built for the Compositor mode. In the
    Per Pixel mode the compositor group evaluates the atmosphere and the materials need no shader group: the file's
    aerial group, built only when another enabled scene's Compositor mode uses it (None otherwise), so none is built
    for nothing."""
    aerial = node_groups.aerial_perspective
    features = aerial_features(plan)
    if plan.mode == "COMPOSITOR":
        return aerial.ensure_aerial_perspective_group(features)
    group = stamps.local(bpy.data.node_groups, aerial.GROUP_NAME)
    if group is None and "COMPOSITOR" in plan.surface_modes:
        group = aerial.ensure_aerial_perspective_group(features)
    return group


def install(scene, plan: Plan, *, only_new: bool = False) -> MaterialReport:
    """Give every material ``scene`` renders with the surface group of ``plan`` (the Compositor and Per Pixel modes:
    its AOVs, :func:`inject_scene`); ``only_new``: leave the materials that carry it already."""
    return inject_scene(scene, aerial_group(plan), only_new=only_new, evaluations=plan.surface_modes)


def update_groups(plan: Plan) -> None:
    """Rebuild in place the groups the materials carry where they are stale for ``plan`` (cheap when current): the
    aerial group and, once the materials have it, the shared surface group."""
    group = aerial_group(plan)
    if stamps.local(bpy.data.node_groups, SURFACE_GROUP) is not None:
        ensure_surface_group(group, plan.surface_modes)


def remove(scene) -> list[str]:
    """Strip the Atmos nodes (of either mode) from the file's materials but those another scene with the effect on
    renders with; the names of the stripped materials."""
    keep: set[int] = set()
    for other in bpy.data.scenes:
        if other != scene and getattr(other, "atmos", None) is not None and other.atmos.enabled:
            keep.update(material.as_pointer() for material in scene_materials(other)[0])
    return remove_all([material for material in bpy.data.materials if material.as_pointer() not in keep])
