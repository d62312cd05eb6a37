# SPDX-License-Identifier: GPL-3.0-or-later
"""The "Atmos Surface AOVs" group: the one group node every managed material carries (the AOV modes).

Inside: the "Atmos Aerial Perspective" group (outputs Transmittance and Inscattering), AOV outputs
``atmos_transmittance`` and ``atmos_inscattering`` (colour) and ``atmos_coverage`` (value), each weighted by the
surface's opacity alpha = Opacity * (1 - Transparency); for the Per Pixel mode, ``atmos_distance`` (alpha times the
camera distance in km) and ``atmos_view`` (alpha times the unit view direction) instead of the first two and the
aerial group. The group holds the outputs of the modes the file's enabled scenes use (its features key, e.g.
"COMPOSITOR,PER_PIXEL"); switching the mode rebuilds it in place, so the materials are not edited.
"""

from __future__ import annotations

import bpy

from ..plan import AOV_COVERAGE, AOV_DISTANCE, AOV_INSCATTERING, AOV_TRANSMITTANCE, AOV_VIEW
from . import stamps
from .parameters import METRES_PER_UNIT

SURFACE_GROUP = stamps.SURFACE.name
#: The Per Pixel mode's distance AOV holds alpha s / this (s in m): km.
DISTANCE_AOV_UNIT_M = 1000.0


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


def build_surface_group(tree, aerial_group, evaluations=("COMPOSITOR",)) -> None:
    """Build the material group in ``tree`` (its interface when missing): aerial group -> opacity weights -> AOV
    outputs; alpha = Opacity * (1 - Transparency).

    Only the outputs of the ``evaluations`` in use ("COMPOSITOR": the aerial group and the transmittance and
    in-scattering AOVs; "PER_PIXEL": the distance and view AOVs) are built: Eevee compiles every AOV output
    of a material, declared or not (a group holding both took Eevee 417 s to compile where one took 2 s).
    """
    if not ("Opacity" in tree.interface.items_tree and "Transparency" in tree.interface.items_tree):
        surface_interface(tree)
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
    stamps.stamp(tree, stamps.SURFACE, modes_key(evaluations))


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
    return (stamps.is_current(tree, stamps.SURFACE, modes_key(evaluations))
            and ("COMPOSITOR" not in evaluations
                 or any(n.bl_idname == "ShaderNodeGroup" and n.node_tree == aerial_group for n in tree.nodes)))


def ensure_surface_group(aerial_group, evaluations=("COMPOSITOR",)):
    """Get or create the "Atmos Surface AOVs" shader group around ``aerial_group`` with the outputs of the
    ``evaluations`` in use (rebuilt in place when stale: the materials' group nodes keep pointing at it)."""
    tree = stamps.group(stamps.SURFACE, replace_foreign=True)
    if not ("Opacity" in tree.interface.items_tree and "Transparency" in tree.interface.items_tree):
        surface_interface(tree)
    if not _is_populated(tree, aerial_group, evaluations):
        inner = inner_groups(tree)
        build_surface_group(tree, aerial_group, evaluations)
        remove_unused(inner)   # the aerial group, when the Compositor mode's outputs left
    return tree


def inner_groups(tree) -> set:
    """The node groups ``tree`` holds."""
    return {node.node_tree for node in tree.nodes if node.bl_idname == "ShaderNodeGroup" and node.node_tree}


def remove_unused(groups) -> None:
    """Delete the Atmos groups among ``groups`` that nothing uses any more (no orphans left in the file)."""
    for group in groups:
        if group.users == 0 and stamps.kind_of(group) is not None:
            bpy.data.node_groups.remove(group)
