# SPDX-License-Identifier: GPL-3.0-or-later
"""The "Atmos Surface AOVs" group: the one group node every managed material carries (the AOV modes).

It holds one node, the "Atmos AOV Outputs" group, fed the material's Opacity and Transparency. Inside that: the
"Atmos Aerial Perspective" group (outputs Transmittance and Inscattering), AOV outputs ``atmos_transmittance``,
its square and cube ``atmos_transmittance2`` and ``atmos_transmittance3``, ``atmos_inscattering`` (colour) and
``atmos_coverage`` (value), each weighted by the surface's opacity alpha = Opacity * (1 - Transparency) * (1 - H)
(H: the object's holdout mark, :data:`~atmos_addon.plan.HOLDOUT_ATTRIBUTE`, 0 where missing); for the
Per Pixel mode, ``atmos_distance`` (alpha times the camera distance in km), ``atmos_view`` (alpha times the unit
view direction) and ``atmos_moments`` (alpha (q, q^2, q^3), q = s / (s + s_0)) instead of those and the aerial
group. The squares and cubes let the compositor tell two surfaces in one pixel apart (``composite.two_point``). The
outputs group holds the outputs of the modes the file's enabled scenes use (its features key, e.g.
"COMPOSITOR,PER_PIXEL"); switching the mode rebuilds it, so the materials are not edited.

Why two groups: a group holding AOV outputs makes every group node of it an output, and Blender then re-checks every
material using the group at each edit of one of them or of the group (with 5000 materials, 1.3 s to add the group
node to them, 2.3 s to rebuild the group for a mode switch). :func:`detached` points the one node at an empty
stand-in while materials or the outputs are edited in bulk, and back with one edit (0.15 s with 5000 materials,
where swapping every material's group with ``user_remap`` took 0.3 s).
"""

from __future__ import annotations

import contextlib

import bpy

from ..plan import (AOV_COVERAGE, AOV_DISTANCE, AOV_INSCATTERING, AOV_MOMENTS, AOV_TRANSMITTANCE, HOLDOUT_ATTRIBUTE,
                    AOV_TRANSMITTANCE_CUBED, AOV_TRANSMITTANCE_SQUARED, AOV_VIEW)
from . import stamps
from .parameters import METRES_PER_UNIT

SURFACE_GROUP = stamps.SURFACE.name
OUTPUTS_GROUP = stamps.SURFACE_OUTPUTS.name
#: The label of the wrapper's one node (it instances :data:`OUTPUTS_GROUP`, or the stand-in while detached).
OUTPUTS_NODE = "AOV Outputs"
#: The Per Pixel mode's distance AOV holds alpha s / this (s in m): km.
DISTANCE_AOV_UNIT_M = 1000.0
#: s_0 of the Per Pixel mode's moments, q = s / (s + s_0), m: q resolves the distances over which the haze changes
#: (a few km to a few hundred) in [0, 1), where Eevee's half-float AOVs keep 11 bits.
MOMENT_DISTANCE_M = 10000.0


def modes_key(evaluations) -> str:
    """The features key of the group: its AOV modes, sorted and comma-separated ("COMPOSITOR,PER_PIXEL")."""
    return ",".join(sorted(evaluations))


def surface_interface(tree) -> None:
    """The group's inputs: Opacity (1) and Transparency (0), each in [0, 1]."""
    tree.interface.clear()
    opacity = tree.interface.new_socket("Opacity", in_out="INPUT", socket_type="NodeSocketFloat")
    opacity.default_value, opacity.min_value, opacity.max_value = 1.0, 0.0, 1.0
    transparency = tree.interface.new_socket("Transparency", in_out="INPUT", socket_type="NodeSocketFloat")
    transparency.default_value, transparency.min_value, transparency.max_value = 0.0, 0.0, 1.0


def _ensure_interface(tree) -> None:
    """Give ``tree`` the Opacity and Transparency inputs when it lacks either (a new group)."""
    if not ("Opacity" in tree.interface.items_tree and "Transparency" in tree.interface.items_tree):
        surface_interface(tree)


def build_outputs_group(tree, aerial_group, evaluations=("COMPOSITOR",)) -> None:
    """Build the outputs group in ``tree`` (its interface when missing): aerial group -> opacity weights -> AOV
    outputs; alpha = Opacity * (1 - Transparency) * (1 - H), H the object's holdout mark.

    Only the outputs of the ``evaluations`` in use ("COMPOSITOR": the aerial group and the transmittance and
    in-scattering AOVs; "PER_PIXEL": the distance and view AOVs) are built: Eevee compiles every AOV output
    of a material, declared or not (a group holding both took Eevee 417 s to compile where one took 2 s).
    """
    _ensure_interface(tree)
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
    # An object a collection holds out writes nothing (its mark, 0 where missing: blender/apply/holdouts.py).
    held_out = nodes.new("ShaderNodeAttribute")
    held_out.attribute_type, held_out.attribute_name = "OBJECT", HOLDOUT_ATTRIBUTE
    held_out.location = (-500, -450)
    shown = nodes.new("ShaderNodeMath")
    shown.operation, shown.location = "SUBTRACT", (-250, -450)
    shown.inputs[0].default_value = 1.0
    links.new(held_out.outputs["Fac"], shown.inputs[1])
    alpha = _math(nodes, links, "MULTIPLY", alpha.outputs[0], shown.outputs[0], (100, -300)).node
    per_sample = ()
    if "COMPOSITOR" in evaluations:
        aerial = nodes.new("ShaderNodeGroup")
        aerial.node_tree = aerial_group
        aerial.location = (-500, 0)
        per_sample = (("Transmittance", AOV_TRANSMITTANCE), ("Inscattering", AOV_INSCATTERING))
    for index, (output, aov_name) in enumerate(per_sample):
        _weighted_aov(nodes, links, aerial.outputs[output], alpha.outputs[0], aov_name, (150, -180.0 * index))
    if per_sample:
        # T^2 and T^3 (alpha-weighted like T): the moments the compositor reads two surfaces' transmittances from.
        square = _vector_math(nodes, links, "MULTIPLY", aerial.outputs["Transmittance"],
                              aerial.outputs["Transmittance"], (-100, 250))
        cube = _vector_math(nodes, links, "MULTIPLY", square, aerial.outputs["Transmittance"], (-100, 400))
        _weighted_aov(nodes, links, square, alpha.outputs[0], AOV_TRANSMITTANCE_SQUARED, (150, 250))
        _weighted_aov(nodes, links, cube, alpha.outputs[0], AOV_TRANSMITTANCE_CUBED, (150, 400))
    coverage = nodes.new("ShaderNodeOutputAOV")
    coverage.aov_name = AOV_COVERAGE
    coverage.location = (400, -400)
    links.new(alpha.outputs[0], coverage.inputs["Value"])
    if "PER_PIXEL" in evaluations:
        _add_per_pixel_outputs(nodes, links, alpha.outputs[0])
    stamps.stamp(tree, stamps.SURFACE_OUTPUTS, modes_key(evaluations))


def _vector_math(nodes, links, operation: str, a, b, location, *, node_type: str = "ShaderNodeVectorMath"):
    """A Vector Math (or ``node_type``) node of ``operation`` on ``a`` and ``b`` (sockets, or a number for b)."""
    node = nodes.new(node_type)
    node.operation = operation
    node.location = location
    links.new(a, node.inputs[0])
    if isinstance(b, bpy.types.NodeSocket):
        links.new(b, node.inputs[1])
    else:
        node.inputs[1].default_value = b
    return node.outputs[0]


def _math(nodes, links, operation: str, a, b, location):
    """A Math node of ``operation`` on ``a`` and ``b``."""
    return _vector_math(nodes, links, operation, a, b, location, node_type="ShaderNodeMath")


def _weighted_aov(nodes, links, colour, alpha, aov_name: str, location) -> None:
    """An AOV output of ``colour`` times the opacity ``alpha``."""
    scale = nodes.new("ShaderNodeVectorMath")
    scale.operation = "SCALE"
    scale.location = location
    links.new(colour, scale.inputs[0])
    links.new(alpha, scale.inputs["Scale"])
    aov = nodes.new("ShaderNodeOutputAOV")
    aov.aov_name = aov_name
    aov.location = (location[0] + 250, location[1])
    links.new(scale.outputs[0], aov.inputs["Color"])


def _add_per_pixel_outputs(nodes, links, alpha) -> None:
    """The Per Pixel mode's AOVs: alpha s / 1000 (s the camera distance in m), alpha v (v the view direction) and
    alpha (q, q^2, q^3) with q = s / (s + s_0)."""
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
    metres_away = _math(nodes, links, "MULTIPLY", camera.outputs["View Distance"], metres.outputs["Fac"], (-250, -1000))
    beyond = _math(nodes, links, "ADD", metres_away, MOMENT_DISTANCE_M, (-50, -1050))
    q = _math(nodes, links, "DIVIDE", metres_away, beyond, (150, -1000))      # q = s / (s + 10 km)
    square = _math(nodes, links, "MULTIPLY", q, q, (250, -1100))
    cube = _math(nodes, links, "MULTIPLY", square, q, (350, -1150))
    powers = nodes.new("ShaderNodeCombineXYZ")
    powers.location = (400, -1000)
    for index, source in enumerate((q, square, cube)):
        links.new(source, powers.inputs[index])
    _weighted_aov(nodes, links, powers.outputs[0], alpha, AOV_MOMENTS, (550, -1000))


def build_surface_group(tree, outputs_group, evaluations=("COMPOSITOR",)) -> None:
    """Build the material group in ``tree`` (its interface when missing): Group Input -> one group node of
    ``outputs_group`` (Opacity and Transparency linked), stamped for ``evaluations``."""
    _ensure_interface(tree)
    tree.nodes.clear()
    group_in = tree.nodes.new("NodeGroupInput")
    group_in.location = (-250, 0)
    node = tree.nodes.new("ShaderNodeGroup")
    node.label = OUTPUTS_NODE
    node.node_tree = outputs_group
    for name in ("Opacity", "Transparency"):
        tree.links.new(group_in.outputs[name], node.inputs[name])
    stamps.stamp(tree, stamps.SURFACE, modes_key(evaluations))


#: Marks the empty group :func:`detached` points the material group at for a while.
STAND_IN_KEY = "atmos_stand_in"


def outputs_node(tree):
    """The material group's node of the outputs group (or of the stand-in); None in a group of an older layout (which
    held the AOV outputs itself)."""
    return next((node for node in tree.nodes if node.bl_idname == "ShaderNodeGroup" and node.node_tree is not None
                 and (stamps.kind_of(node.node_tree) == stamps.SURFACE_OUTPUTS or STAND_IN_KEY in node.node_tree)),
                None)


def _stand_in():
    """An empty group with the material group's interface, used by nothing yet."""
    tree = bpy.data.node_groups.new(OUTPUTS_GROUP + " (stand-in)", "ShaderNodeTree")
    tree[STAND_IN_KEY] = 1
    surface_interface(tree)
    return tree


@contextlib.contextmanager
def detached(tree, outputs_group=None):
    """While inside, the material group ``tree`` instances an empty stand-in instead of its outputs group, so edits of
    the materials that use it, of ``tree`` and of the outputs group do not re-check every user; on leaving, its node
    instances ``outputs_group`` (default: the one it held) with one edit. Yields the stand-in (for a node built
    inside)."""
    node = outputs_node(tree)
    if outputs_group is None:
        outputs_group = None if node is None else node.node_tree
    stand_in = _stand_in()
    if node is not None:
        node.node_tree = stand_in
    try:
        yield stand_in
    finally:
        node = outputs_node(tree)
        if node is not None and outputs_group is not None:
            node.node_tree = outputs_group
        # With no users and nothing used by it (an interface, no nodes), the unlink pass of a plain remove, which
        # visits every data-block of the file (44 ms with 30 000 of them), has nothing to do and is skipped.
        if stand_in.users:
            bpy.data.node_groups.remove(stand_in)
        else:
            bpy.data.node_groups.remove(stand_in, do_unlink=False, do_id_user=False, do_ui_user=False)


def aov_names(tree) -> set:
    """The AOVs a material group writes: those of the AOV outputs in ``tree`` and in the groups it holds."""
    names = {node.aov_name for node in tree.nodes if node.bl_idname == "ShaderNodeOutputAOV"}
    for inner in inner_groups(tree):
        names |= aov_names(inner)
    return names


def _outputs_current(tree, aerial_group, evaluations) -> bool:
    return (stamps.is_current(tree, stamps.SURFACE_OUTPUTS, modes_key(evaluations))
            and ("COMPOSITOR" not in evaluations
                 or any(n.bl_idname == "ShaderNodeGroup" and n.node_tree == aerial_group for n in tree.nodes)))


def ensure_outputs_group(aerial_group, evaluations=("COMPOSITOR",)):
    """Get or create the "Atmos AOV Outputs" group for ``evaluations`` (rebuilt in place when stale; callers detach
    it from a material group in use first, :func:`detached`)."""
    tree = stamps.group(stamps.SURFACE_OUTPUTS, replace_foreign=True)
    _ensure_interface(tree)
    if not _outputs_current(tree, aerial_group, evaluations):
        inner = inner_groups(tree)
        build_outputs_group(tree, aerial_group, evaluations)
        remove_unused(inner)   # the aerial group, when the Compositor mode's outputs left
    return tree


def ensure_surface_group(aerial_group, evaluations=("COMPOSITOR",)):
    """Get or create the "Atmos Surface AOVs" shader group and its outputs group around ``aerial_group`` with the
    outputs of the ``evaluations`` in use. Each is rebuilt in place when stale, while detached (:func:`detached`): the
    materials' group nodes keep pointing at it, and they are re-checked once, not at every edit."""
    tree = stamps.group(stamps.SURFACE, replace_foreign=True)
    _ensure_interface(tree)
    key = modes_key(evaluations)
    outputs = stamps.group(stamps.SURFACE_OUTPUTS, replace_foreign=True)
    node = outputs_node(tree) if tree.get(stamps.VERSION_KEY) == stamps.SURFACE.version else None
    if node is not None and node.node_tree == outputs and _outputs_current(outputs, aerial_group, evaluations):
        if not stamps.is_current(tree, stamps.SURFACE, key):
            stamps.stamp(tree, stamps.SURFACE, key)   # another scene's modes: its outputs group was rebuilt
        return tree
    inner = inner_groups(tree)
    with detached(tree, outputs) as stand_in:
        if node is None:   # new, or of an older layout (the AOV outputs in it): built again
            build_surface_group(tree, stand_in, evaluations)
        ensure_outputs_group(aerial_group, evaluations)
        stamps.stamp(tree, stamps.SURFACE, key)
    remove_unused(inner - {outputs})   # an older layout's aerial group, when no outputs group took it over
    return tree


def inner_groups(tree) -> set:
    """The node groups ``tree`` holds."""
    return {node.node_tree for node in tree.nodes if node.bl_idname == "ShaderNodeGroup" and node.node_tree}


def remove_unused(groups) -> None:
    """Delete the Atmos groups among ``groups`` that nothing uses any more (no orphans left in the file)."""
    for group in groups:
        if group.users == 0 and stamps.kind_of(group) is not None:
            bpy.data.node_groups.remove(group)
