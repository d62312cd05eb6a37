# SPDX-License-Identifier: GPL-3.0-or-later
"""The "Atmos Aerial Composite" compositor group: the per-pixel combination of the Compositor mode's AOVs.

Per pixel the materials leave three AOV sums: ``T = sum a_i T_i``, ``L = sum a_i L_i`` and the coverage
``C = sum a_i`` over the surfaces that wrote (alpha a_i, 1 for opaque surfaces, averaged over the pixel's samples).
The render's alpha A bounds the coverage: a holdout object (a collection set to Holdout in the view layer) is a hole
of alpha 0 whose material still writes its AOVs (until December 2026 its hole got the haze, RGB with alpha 0):

    C' = min(C, A),  w = C' / C  (0 where C = 0),  k = max(C', 1)
    out = Image * (w T + max(1 - C', 0)) / k + w L / k

With every pixel's alpha 1 (an opaque film) and no holdout, C' = C: the composite as before. The Alpha input is 1
where nothing feeds it (a group node of a file saved before it).

(:mod:`atmos_addon.blender.apply.compositor` says what each case gives). Blender 5.0 composites with the shader
nodes (Math, Mix); 4.5 has compositor nodes of its own (Math, MixRGB).
"""

from __future__ import annotations

import bpy

from . import stamps

#: Blender 5.0 replaced scene.node_tree / use_nodes by scene.compositing_node_group, and compositor trees take the
#: shader's Math and Mix nodes.
GROUP_API = "compositing_node_group" in bpy.types.Scene.bl_rna.properties


def _mix(nodes, blend: str, location):
    if GROUP_API:
        node = nodes.new("ShaderNodeMix")
        node.data_type = "RGBA"
        node.blend_type = blend
        node.clamp_result = False
        inputs = {socket.identifier: socket for socket in node.inputs}
        inputs["Factor_Float"].default_value = 1.0
        out = next(socket for socket in node.outputs if socket.identifier == "Result_Color")
        a, b = inputs["A_Color"], inputs["B_Color"]
    else:
        node = nodes.new("CompositorNodeMixRGB")
        node.blend_type = blend
        node.use_clamp = False
        node.inputs[0].default_value = 1.0
        a, b, out = node.inputs[1], node.inputs[2], node.outputs[0]
    node.location = location
    return a, b, out


def _math(nodes, operation: str, location, *, clamp: bool = False):
    node = nodes.new("ShaderNodeMath" if GROUP_API else "CompositorNodeMath")
    node.operation = operation
    node.use_clamp = clamp
    node.location = location
    return node


#: The group's interface: (name, in/out, socket type).
INTERFACE = (("Image", "INPUT", "NodeSocketColor"), ("Transmittance", "INPUT", "NodeSocketColor"),
             ("Inscattering", "INPUT", "NodeSocketColor"), ("Coverage", "INPUT", "NodeSocketFloat"),
             ("Alpha", "INPUT", "NodeSocketFloat"), ("Image", "OUTPUT", "NodeSocketColor"))
#: Coverage below which a pixel counts as uncovered when its weight w = C' / C is formed (a divide by 0 guard).
_TINY_COVERAGE = 1e-20


def _ensure_interface(tree) -> None:
    """Give ``tree`` the group's interface (:func:`keep_interface`): a group of an earlier version gains the Alpha of
    version 2 without losing the links into its other inputs."""
    keep_interface(tree, list(INTERFACE), ordered=False)


def keep_interface(tree, wanted: list[tuple[str, str, str]], *, ordered: bool = True) -> None:
    """Give ``tree`` the ``wanted`` sockets ((name, in/out, socket type); Blender lists the outputs first), keeping
    every socket it already has of those, so the links into its group nodes and the drivers on them survive a
    rebuild: sockets no longer wanted (or second copies) are removed, missing ones added; an added "Alpha" input
    starts at 1 in the interface and in the group nodes already in the file (:func:`open_alpha_inputs`).
    ``ordered``: the order counts when comparing (else only the set of sockets)."""
    items = [item for item in tree.interface.items_tree if item.item_type == "SOCKET"]
    present = [(item.name, item.in_out, item.socket_type) for item in items]
    if (present == wanted) if ordered else (sorted(present) == sorted(wanted)):
        return
    kept = set()
    for item, key in zip(items, present):
        if key in wanted and key not in kept:
            kept.add(key)
        else:
            tree.interface.remove(item)   # no longer wanted, or a second copy
    for name, in_out, socket_type in wanted:
        if (name, in_out, socket_type) not in kept:
            item = tree.interface.new_socket(name, in_out=in_out, socket_type=socket_type)
            if name == "Alpha":
                item.default_value = 1.0   # unlinked: an opaque film, the composite as before the input existed
                open_alpha_inputs(tree)


def open_alpha_inputs(tree) -> None:
    """Set the unlinked Alpha input of every group node that instances ``tree`` to 1 (an opaque film): a socket added
    to a group's interface reaches the group nodes already in the file with the value it had when it was added, 0,
    which would read every pixel as a hole. The compositor trees are the file's compositor node groups (Blender 5) and
    the scenes' own trees (4.5)."""
    trees = [group for group in bpy.data.node_groups if group.bl_idname == "CompositorNodeTree"]
    trees += [scene.node_tree for scene in bpy.data.scenes if getattr(scene, "node_tree", None) is not None]
    for owner in trees:
        for node in owner.nodes:
            if node.bl_idname == "CompositorNodeGroup" and node.node_tree == tree:
                socket = node.inputs.get("Alpha")
                if socket is not None and not socket.is_linked:
                    socket.default_value = 1.0


def build_composite_group(tree) -> None:
    """Build the combining group in ``tree`` (module docstring), in place: its interface is kept."""
    tree.nodes.clear()
    _ensure_interface(tree)
    nodes, links = tree.nodes, tree.links
    group_in = nodes.new("NodeGroupInput")
    group_in.location = (-600, 0)
    group_out = nodes.new("NodeGroupOutput")
    group_out.location = (800, 0)

    covered = _math(nodes, "MINIMUM", (-850, -300))        # C' = min(C, A)
    links.new(group_in.outputs["Coverage"], covered.inputs[0])
    links.new(group_in.outputs["Alpha"], covered.inputs[1])
    guard = _math(nodes, "MAXIMUM", (-850, -500))
    links.new(group_in.outputs["Coverage"], guard.inputs[0])
    guard.inputs[1].default_value = _TINY_COVERAGE
    weight = _math(nodes, "DIVIDE", (-600, -400))          # w = C' / C
    links.new(covered.outputs[0], weight.inputs[0])
    links.new(guard.outputs[0], weight.inputs[1])
    a, b, transmittance = _mix(nodes, "MULTIPLY", (-350, 300))
    links.new(group_in.outputs["Transmittance"], a)
    links.new(weight.outputs[0], b)
    a, b, inscattering_in = _mix(nodes, "MULTIPLY", (-350, -500))
    links.new(group_in.outputs["Inscattering"], a)
    links.new(weight.outputs[0], b)

    k = _math(nodes, "MAXIMUM", (-350, -300))
    links.new(covered.outputs[0], k.inputs[0])
    k.inputs[1].default_value = 1.0
    uncovered = _math(nodes, "SUBTRACT", (-350, -120), clamp=True)
    uncovered.inputs[0].default_value = 1.0
    links.new(covered.outputs[0], uncovered.inputs[1])

    a, b, factor_sum = _mix(nodes, "ADD", (-100, 100))
    links.new(transmittance, a)
    links.new(uncovered.outputs[0], b)
    a, b, factor = _mix(nodes, "DIVIDE", (100, 100))
    links.new(factor_sum, a)
    links.new(k.outputs[0], b)
    a, b, attenuated = _mix(nodes, "MULTIPLY", (300, 200))
    links.new(group_in.outputs["Image"], a)
    links.new(factor, b)
    a, b, inscattering = _mix(nodes, "DIVIDE", (300, -150))
    links.new(inscattering_in, a)
    links.new(k.outputs[0], b)
    a, b, result = _mix(nodes, "ADD", (550, 0))
    links.new(attenuated, a)
    links.new(inscattering, b)
    links.new(result, group_out.inputs["Image"])
    stamps.stamp(tree, stamps.COMPOSITE, "")


def ensure_composite_group():
    """Get or create the "Atmos Aerial Composite" compositor group; rebuilt in place when stale."""
    tree = stamps.group(stamps.COMPOSITE, replace_foreign=True)
    if not stamps.is_current(tree, stamps.COMPOSITE, ""):
        build_composite_group(tree)
    return tree
