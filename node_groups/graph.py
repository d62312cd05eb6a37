# SPDX-License-Identifier: GPL-3.0-or-later
"""A tiny builder that writes arithmetic as shader nodes, so an equation reads as code.

``g = GraphBuilder(tree)`` then ``g.mul(beta, s)``, ``g.exp(x)``, ``g.per_channel(fn, colour)``...
Each helper adds one node and returns its output socket. Operands are output sockets or plain
numbers (a number becomes the input's default value, not an extra node). Arithmetic on a vector or
colour operand uses Vector Math (exact per component); on scalars it uses Math. Functions without a
Vector Math form in every supported Blender (exp, pow, comparisons) work on scalars; apply them to a
colour with :meth:`GraphBuilder.per_channel`. :meth:`GraphBuilder.layout` places nodes in columns by
their depth in the graph, so the tree reads left to right in the editor.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Union

import bpy
import numpy as np

from . import parts

Socket = bpy.types.NodeSocket
#: An operand: a node output socket, a number, or three numbers (a vector/colour constant).
Operand = Union[Socket, float, int, Sequence[float]]

_VECTOR_SOCKET_TYPES = {"VECTOR", "RGBA"}
#: What a shading point knows without parameters, by name: (node, output) that reads it in a shader.
SHADING_INPUTS = {
    "view_distance": ("ShaderNodeCameraData", "View Distance"),   # scene units from the camera
    "ray_length": ("ShaderNodeLightPath", "Ray Length"),          # scene units along the ray segment just travelled
    "is_camera_ray": ("ShaderNodeLightPath", "Is Camera Ray"),    # 1 for camera rays, else 0
    "incoming": ("ShaderNodeNewGeometry", "Incoming"),            # toward the viewer, world space
    "position": ("ShaderNodeNewGeometry", "Position"),            # the shading point, world space (scene units)
}
_COLUMN_WIDTH = 220.0
_ROW_HEIGHT = 170.0


def is_vector(value: Operand) -> bool:
    """True for a vector/colour socket or a 3-sequence constant (an operand the builders treat per component)."""
    if isinstance(value, bpy.types.NodeSocket):
        return value.type in _VECTOR_SOCKET_TYPES
    return isinstance(value, Sequence) and not isinstance(value, str)


class GraphBuilder:
    """Add arithmetic nodes to ``tree`` (a shader node tree or group) and lay them out in columns."""

    def __init__(self, tree: bpy.types.NodeTree) -> None:
        self.tree = tree
        self._depth: dict[str, int] = {}

    # -- plumbing -----------------------------------------------------------------------------------

    def node(self, bl_idname: str, *, label: str = "", depth: int | None = None, **properties) -> bpy.types.Node:
        """Add a node of type ``bl_idname`` with the given RNA properties; ``depth`` is its layout column."""
        node = self.tree.nodes.new(bl_idname)
        for key, value in properties.items():
            if getattr(node, key) != value:   # a write re-runs the tree's update, even of the value it holds
                setattr(node, key, value)
        if label:
            node.label = label
        self._depth[node.name] = 0 if depth is None else depth
        return node

    def _feed(self, node: bpy.types.Node, socket: bpy.types.NodeSocket, value: Operand) -> None:
        """Link ``value`` into ``socket`` (or set its default) and push ``node`` right of its source."""
        if isinstance(value, bpy.types.NodeSocket):
            self.tree.links.new(value, socket)
            source_depth = self._depth.get(value.node.name, 0)
            self._depth[node.name] = max(self._depth[node.name], source_depth + 1)
        elif is_vector(value):
            value = tuple(float(v) for v in value)
            if tuple(socket.default_value) != value:
                socket.default_value = value
        elif socket.default_value != float(value):
            socket.default_value = float(value)

    def link(self, value: Operand, socket: bpy.types.NodeSocket) -> None:
        """Feed ``value`` (a socket, or a constant for its default) into the input ``socket`` of a node this builder
        made (a group output, a group node's input)."""
        self._feed(socket.node, socket, value)

    def _math(self, operation: str, *operands: Operand, label: str = "") -> Socket:
        """One scalar Math node."""
        node = self.node("ShaderNodeMath", operation=operation, use_clamp=False, label=label)
        for socket, value in zip(node.inputs, operands):
            self._feed(node, socket, value)
        return node.outputs[0]

    def _vector_math(self, operation: str, *operands: Operand, label: str = "") -> Socket:
        """One Vector Math node (inputs 0-2 are vectors); returns its Vector output."""
        node = self.node("ShaderNodeVectorMath", operation=operation, label=label)
        for socket, value in zip(node.inputs, operands):
            self._feed(node, socket, value)
        return node.outputs["Vector"]

    def _arithmetic(self, operation: str, a: Operand, b: Operand, label: str) -> Socket:
        """``a (op) b`` with Math, or Vector Math if either operand is a vector/colour."""
        if is_vector(a) or is_vector(b):
            if operation == "MULTIPLY" and not is_vector(b) and not isinstance(b, bpy.types.NodeSocket):
                return self.scale(a, b, label=label)
            a = a if is_vector(a) or isinstance(a, bpy.types.NodeSocket) else (a, a, a)
            b = b if is_vector(b) or isinstance(b, bpy.types.NodeSocket) else (b, b, b)
            return self._vector_math(operation, a, b, label=label)
        return self._math(operation, a, b, label=label)

    def call(self, part: parts.Part, *operands: Operand, label: str = ""):
        """``part``'s output (a tuple of them with several) for ``operands``, its inputs in order: one node instancing
        the part's group, which is built the first time (:mod:`.parts`)."""
        tree_type = self.tree.bl_idname
        group = parts.ensure(part, tree_type, self.child)
        node = self.node(parts.GROUP_NODES[tree_type], label=label)
        node.node_tree = group
        names = [name for name, _, _ in parts.interface(part, tree_type)[len(part.outputs):]]
        for name, value in zip(names, list(operands) + self._part_parameters(part)):
            self._feed(node, node.inputs[name], value)
        outputs = tuple(node.outputs[name] for name, _ in part.outputs)
        return outputs if len(outputs) > 1 else outputs[0]

    @classmethod
    def child(cls, tree: bpy.types.NodeTree, parameters: Mapping[str, Operand]) -> "GraphBuilder":
        """A builder of this kind for a part's group ``tree`` (a shader part reads its parameters itself)."""
        return cls(tree)

    def _part_parameters(self, part: parts.Part) -> list:
        return []

    # -- arithmetic ---------------------------------------------------------------------------------

    def add(self, a: Operand, b: Operand, *, label: str = "") -> Socket:
        """a + b"""
        return self._arithmetic("ADD", a, b, label)

    def sub(self, a: Operand, b: Operand, *, label: str = "") -> Socket:
        """a - b"""
        return self._arithmetic("SUBTRACT", a, b, label)

    def mul(self, a: Operand, b: Operand, *, label: str = "") -> Socket:
        """a * b (per component for vectors; a scalar socket is broadcast to the three components)."""
        return self._arithmetic("MULTIPLY", a, b, label)

    def div(self, a: Operand, b: Operand, *, label: str = "") -> Socket:
        """a / b (Blender's divide returns 0 where b == 0; callers guard b instead of relying on it)."""
        return self._arithmetic("DIVIDE", a, b, label)

    def max(self, a: Operand, b: Operand, *, label: str = "") -> Socket:
        """max(a, b)"""
        return self._arithmetic("MAXIMUM", a, b, label)

    def min(self, a: Operand, b: Operand, *, label: str = "") -> Socket:
        """min(a, b)"""
        return self._arithmetic("MINIMUM", a, b, label)

    def scale(self, vector: Operand, factor: Operand, *, label: str = "") -> Socket:
        """vector * factor with a scalar factor (Vector Math Scale)."""
        node = self.node("ShaderNodeVectorMath", operation="SCALE", label=label)
        self._feed(node, node.inputs[0], vector)
        self._feed(node, node.inputs["Scale"], factor)
        return node.outputs["Vector"]

    def neg(self, a: Operand, *, label: str = "") -> Socket:
        """-a"""
        if is_vector(a):
            return self.scale(a, -1.0, label=label)
        return self._math("MULTIPLY", a, -1.0, label=label)

    def multiply_add(self, a: Operand, b: Operand, c: Operand, *, label: str = "") -> Socket:
        """a * b + c (per component if any operand is a vector/colour)."""
        if any(is_vector(v) for v in (a, b, c)):
            a, b, c = (v if is_vector(v) or isinstance(v, bpy.types.NodeSocket) else (v, v, v) for v in (a, b, c))
            return self._vector_math("MULTIPLY_ADD", a, b, c, label=label)
        return self._math("MULTIPLY_ADD", a, b, c, label=label)

    def abs(self, a: Operand, *, label: str = "") -> Socket:
        """|a| (per component for vectors)."""
        if is_vector(a):
            return self._vector_math("ABSOLUTE", a, label=label)
        return self._math("ABSOLUTE", a, label=label)

    def floor(self, a: Operand, *, label: str = "") -> Socket:
        """floor(a) (per component for vectors)."""
        if is_vector(a):
            return self._vector_math("FLOOR", a, label=label)
        return self._math("FLOOR", a, label=label)

    def sine(self, a: Operand, *, label: str = "") -> Socket:
        """sin(a), a in rad (scalar)."""
        return self._math("SINE", a, label=label)

    def arcsin(self, a: Operand, *, label: str = "") -> Socket:
        """asin(a) in rad (scalar; a clamped to [-1, 1], as Blender's Math node does)."""
        return self._math("ARCSINE", a, label=label)

    def arctan2(self, y: Operand, x: Operand, *, label: str = "") -> Socket:
        """atan2(y, x) in rad (scalar)."""
        return self._math("ARCTAN2", y, x, label=label)

    def greater_than(self, a: Operand, b: Operand, *, label: str = "") -> Socket:
        """1.0 if a > b else 0.0 (scalar)."""
        return self._math("GREATER_THAN", a, b, label=label)

    def cross(self, a: Operand, b: Operand, *, label: str = "") -> Socket:
        """a x b (vectors)."""
        return self._vector_math("CROSS_PRODUCT", a, b, label=label)

    def length(self, a: Operand, *, label: str = "") -> Socket:
        """|a| (a vector), a scalar."""
        node = self.node("ShaderNodeVectorMath", operation="LENGTH", label=label)
        self._feed(node, node.inputs[0], a)
        return node.outputs["Value"]

    def sign(self, a: Operand, *, label: str = "") -> Socket:
        """sign(a): -1, 0 or 1 (scalar)."""
        return self._math("SIGN", a, label=label)

    def sqrt(self, a: Operand, *, label: str = "") -> Socket:
        """sqrt(a) (scalar, a >= 0)."""
        return self._math("SQRT", a, label=label)

    def exp(self, a: Operand, *, label: str = "") -> Socket:
        """e^a (scalar)."""
        return self._math("EXPONENT", a, label=label)

    def pow(self, a: Operand, b: Operand, *, label: str = "") -> Socket:
        """a^b (scalar, a >= 0)."""
        return self._math("POWER", a, b, label=label)

    def power_per_channel(self, colour: Operand, exponent: Operand, *, label: str = "") -> Socket:
        """colour^exponent per channel with one Gamma node (channels <= 0 pass unchanged; exponent 0 gives 1).

        With a colour base b and a scalar x it gives b^x = exp(x ln b) in every channel at the cost of one node,
        where exp would need a Separate, three Math nodes and a Combine (Vector Math Power computes the same powf).
        """
        node = self.node("ShaderNodeGamma", label=label)
        self._feed(node, node.inputs["Color"], colour)
        self._feed(node, node.inputs["Gamma"], exponent)
        return node.outputs["Color"]

    def less_than(self, a: Operand, b: Operand, *, label: str = "") -> Socket:
        """1.0 if a < b else 0.0 (scalar)."""
        return self._math("LESS_THAN", a, b, label=label)

    def clamp(self, a: Operand, low: float, high: float, *, label: str = "") -> Socket:
        """min(max(a, low), high)."""
        return self.min(self.max(a, low), high, label=label)

    def dot(self, a: Operand, b: Operand, *, label: str = "") -> Socket:
        """a . b (vectors), a scalar."""
        node = self.node("ShaderNodeVectorMath", operation="DOT_PRODUCT", label=label)
        self._feed(node, node.inputs[0], a)
        self._feed(node, node.inputs[1], b)
        return node.outputs["Value"]

    def normalize(self, a: Operand, *, label: str = "") -> Socket:
        """a / |a| (a vector; the zero vector stays zero)."""
        return self._vector_math("NORMALIZE", a, label=label)

    def select(self, condition: Operand, if_true: Operand, if_false: Operand, *, label: str = "") -> Socket:
        """``if_true`` where condition == 1, ``if_false`` where it is 0 (scalars, both branches finite).

        Written as if_true * c + if_false * (1 - c) so a 0/1 condition picks a branch bit-exactly
        (a Mix node's a + t (b - a) form rounds).
        """
        otherwise = self.sub(1.0, condition)
        return self.multiply_add(if_true, condition, self.mul(if_false, otherwise), label=label)

    def mix(self, factor: Operand, a: Operand, b: Operand, *, label: str = "") -> Socket:
        """Linear blend a (factor 0) to b (factor 1) with a Mix node; colours if a or b is a colour."""
        colour = is_vector(a) or is_vector(b)
        node = self.node("ShaderNodeMix", data_type="RGBA" if colour else "FLOAT", label=label)
        self._feed(node, node.inputs[0], factor)
        a_index, b_index, out_index = (6, 7, 2) if colour else (2, 3, 0)
        self._feed(node, node.inputs[a_index], a)
        self._feed(node, node.inputs[b_index], b)
        return node.outputs[out_index]

    # -- constants and channels ---------------------------------------------------------------------

    def separate(self, colour: Operand, *, label: str = "") -> tuple[Socket, Socket, Socket]:
        """The three components of a colour or vector (Separate XYZ: no colour-space conversion)."""
        node = self.node("ShaderNodeSeparateXYZ", label=label)
        self._feed(node, node.inputs[0], colour)
        return node.outputs[0], node.outputs[1], node.outputs[2]

    def combine(self, r: Operand, g: Operand, b: Operand, *, label: str = "") -> Socket:
        """A vector from three scalars (Combine XYZ; links into colour sockets unchanged)."""
        node = self.node("ShaderNodeCombineXYZ", label=label)
        for socket, value in zip(node.inputs, (r, g, b)):
            self._feed(node, socket, value)
        return node.outputs[0]

    def per_channel(self, fn: Callable[..., Socket], *operands: Operand, label: str = "") -> Socket:
        """Apply the scalar function ``fn`` channel by channel: fn(a_r, b_r, ...), fn(a_g, ...), fn(a_b, ...).

        Vector/colour operands are split once with :meth:`separate`; scalars pass to every channel.
        """
        split = [self.separate(op) if is_vector(op) else (op, op, op) for op in operands]
        channels = [fn(*(parts[c] for parts in split)) for c in range(3)]
        return self.combine(*channels, label=label)

    # -- inputs and outputs -------------------------------------------------------------------------

    def soften(self, value: Operand, *, label: str = "") -> Socket:
        """``value`` (a colour, or a scalar) averaged over the 3 x 3 pixels around with the weights (1 2 1)^T (1 2 1)
        / 16: compositor graphs only (a shading point has no neighbours)."""
        raise TypeError("a shader graph has no neighbouring pixels: soften() is for compositor graphs")

    def shading_input(self, name: str, *, label: str = "") -> Socket:
        """What the shading point knows, by name (:data:`SHADING_INPUTS`): a new input node's output each call."""
        bl_idname, output = SHADING_INPUTS[name]
        return self.node(bl_idname, label=label or output).outputs[output]

    def texel(self, image: bpy.types.Image | None, u: Operand, v: Operand, *, label: str = "") -> Socket:
        """The colour of ``image`` at texture coordinates (u, v), unfiltered (Closest; edges extended). Callers
        sample texel centres, (x + 0.5) / width."""
        node = self.node("ShaderNodeTexImage", label=label, interpolation="Closest", extension="EXTEND")
        node.image = image
        self._feed(node, node.inputs["Vector"], self.combine(u, v, 0.0, label=f"uv ({label})"))
        return node.outputs["Color"]

    def texture(self, image: bpy.types.Image | None, u: Operand, v: Operand, *, label: str = "") -> Socket:
        """The colour of ``image`` at texture coordinates (u, v), filtered bilinearly (Linear; edges extended) with
        texel centres at (x + 0.5) / width: one node for four texels. Cycles only (Eevee's Linear lookup picks a
        mipmap from screen-space derivatives, :class:`atmos_addon.node_groups.precise._Bilinear`)."""
        node = self.node("ShaderNodeTexImage", label=label, interpolation="Linear", extension="EXTEND")
        node.image = image
        self._feed(node, node.inputs["Vector"], self.combine(u, v, 0.0, label=f"uv ({label})"))
        return node.outputs["Color"]

    def attribute(self, name: str, *, attribute_type: str = "VIEW_LAYER", output: str = "Color",
                  label: str = "") -> Socket:
        """The ``output`` socket (Color, Vector or Fac) of an Attribute node reading ``name``."""
        node = self.node("ShaderNodeAttribute", attribute_type=attribute_type, attribute_name=name,
                         label=label or name)
        return node.outputs[output]

    # -- layout -------------------------------------------------------------------------------------

    def layout(self, *, origin: tuple[float, float] = (0.0, 0.0)) -> None:
        """Place every node the builder made in a column by its depth (inputs left, outputs right).

        The positions are computed in Python and written with one ``foreach_set``: a ``node.location``
        write per node would trigger one node-tree update each (Blender re-checks the file's trees on
        every edit, so the layout cost grew with the number of materials in the file).
        """
        nodes = self.tree.nodes
        locations = [0.0] * (2 * len(nodes))
        nodes.foreach_get("location", locations)
        rows: dict[int, int] = {}
        for index, name in enumerate(node.name for node in nodes):
            column = self._depth.get(name)
            if column is None:
                continue
            row = rows.get(column, 0)
            rows[column] = row + 1
            locations[2 * index] = origin[0] + column * _COLUMN_WIDTH
            locations[2 * index + 1] = origin[1] - row * _ROW_HEIGHT
        nodes.foreach_set("location", locations)

    def set_depth(self, node: bpy.types.Node, depth: int) -> None:
        """Force a node's layout column (e.g. the group output to the far right)."""
        self._depth[node.name] = depth

    @property
    def max_depth(self) -> int:
        """The deepest column used so far."""
        return max(self._depth.values(), default=0)


#: Math node of a compositor tree: Blender 5.0 shares the shader's, 4.5 has its own.
_COMPOSITOR_GROUP_API = "compositing_node_group" in bpy.types.Scene.bl_rna.properties
COMPOSITOR_MATH = "ShaderNodeMath" if _COMPOSITOR_GROUP_API else "CompositorNodeMath"
COMPOSITOR_SEPARATE_XYZ = "ShaderNodeSeparateXYZ" if _COMPOSITOR_GROUP_API else "CompositorNodeSeparateXYZ"
COMPOSITOR_COMBINE_XYZ = "ShaderNodeCombineXYZ" if _COMPOSITOR_GROUP_API else "CompositorNodeCombineXYZ"


def _floor(a: float, *_) -> float:
    return float(math.floor(a))


#: Math operations on constant operands, computed in Python the way Blender's Math node does (a divide by 0 gives 0).
_FOLDED: dict[str, Callable[..., float]] = {
    "ADD": lambda a, b, *_: a + b,
    "SUBTRACT": lambda a, b, *_: a - b,
    "MULTIPLY": lambda a, b, *_: a * b,
    "DIVIDE": lambda a, b, *_: a / b if b != 0.0 else 0.0,
    "MULTIPLY_ADD": lambda a, b, c: a * b + c,
    "MINIMUM": lambda a, b, *_: min(a, b),
    "MAXIMUM": lambda a, b, *_: max(a, b),
    "ABSOLUTE": lambda a, *_: abs(a),
    "FLOOR": _floor,
    "EXPONENT": lambda a, *_: math.exp(a),
}


class CompositorBuilder(GraphBuilder):
    """The same arithmetic in a compositor tree (the Per Pixel mode's group), node for node the shader groups'.

    A colour or vector is one vector socket and its arithmetic one Vector Math node, as in a shader group, so the
    functions that build the shader groups (``dome_distances``, ``scattering_terms``, ``precise_terms``...) build the
    compositor's from the very equations. What a compositor tree lacks is supplied here: parameters come from a mapping
    (name -> socket, normally the group's inputs) instead of Attribute nodes (:meth:`attribute`); a texel is fetched
    by a Map UV node with nearest filtering (:meth:`texel`); a power per channel is Vector Math Power (4.5's compositor
    has no shader Gamma node; the bases the groups raise are positive, where both compute powf); a blend is
    a + f (b - a) with Vector Math (the numpy backend's form). Arithmetic on constants only is computed here, not built,
    three copies of one scalar are that scalar (a link into a vector input broadcasts it), and a vector is separated
    once however often the equations ask. Every node added or linked re-runs Blender's update of the whole tree, so
    the build costs the square of the node count: 220 nodes at Precise, built in 0.13-0.27 s, where one Math node per
    channel took 396 nodes and 0.91 s; with its parts (:meth:`call`, :mod:`.parts`: their parameters are inputs of
    their groups, see :meth:`child`) 110 nodes of its own, 0.05 s (Blender 5.2.3, the median of 3 builds in a
    fresh file).
    """

    def __init__(self, tree: bpy.types.NodeTree, parameters: dict[str, Operand]) -> None:
        super().__init__(tree)
        self.parameters = parameters
        self._image_node = None
        self._separated: dict[int, tuple] = {}

    @staticmethod
    def _component(value: Operand, index: int) -> float:
        return float(value[index]) if is_vector(value) else float(value)

    def _math(self, operation: str, *operands: Operand, label: str = "") -> Socket | float:
        if operation in _FOLDED and not any(isinstance(value, bpy.types.NodeSocket) for value in operands):
            return _FOLDED[operation](*(float(value) for value in operands))   # constants: no node
        node = self.node(COMPOSITOR_MATH, operation=operation, use_clamp=False, label=label)
        for socket, value in zip(node.inputs, operands):
            self._feed(node, socket, value)
        return node.outputs[0]

    def _vector_math(self, operation: str, *operands: Operand, label: str = "") -> Socket | tuple:
        if operation in _FOLDED and not any(isinstance(value, bpy.types.NodeSocket) for value in operands):
            return tuple(_FOLDED[operation](*(self._component(value, c) for value in operands)) for c in range(3))
        return super()._vector_math(operation, *operands, label=label)

    def scale(self, vector: Operand, factor: Operand, *, label: str = "") -> Socket | tuple:
        if not any(isinstance(value, bpy.types.NodeSocket) for value in (vector, factor)):
            return tuple(self._component(vector, c) * float(factor) for c in range(3))
        return super().scale(vector, factor, label=label)

    def power_per_channel(self, colour: Operand, exponent: Operand, *, label: str = "") -> Socket:
        """colour^exponent per channel: one Vector Math Power (a scalar exponent socket is broadcast by its link)."""
        exponent = exponent if isinstance(exponent, bpy.types.NodeSocket) or is_vector(exponent) else (exponent,) * 3
        return self._vector_math("POWER", colour, exponent, label=label)

    def mix(self, factor: Operand, a: Operand, b: Operand, *, label: str = "") -> Socket:
        """a + factor (b - a), per component if a or b is a colour (the numpy backend's form)."""
        return self.multiply_add(factor, self.sub(b, a), a, label=label)

    def separate(self, colour: Operand, *, label: str = "") -> tuple:
        """The three components: a constant's numbers, a socket's Separate XYZ (one per socket, however often)."""
        if not isinstance(colour, bpy.types.NodeSocket):
            return tuple(self._component(colour, c) for c in range(3))
        key = colour.as_pointer()
        if key not in self._separated:
            node = self.node(COMPOSITOR_SEPARATE_XYZ, label=label)
            self._feed(node, node.inputs[0], colour)
            self._separated[key] = tuple(node.outputs[:3])
        return self._separated[key]

    def combine(self, r: Operand, g: Operand, b: Operand, *, label: str = "") -> Socket | tuple:
        """A vector from three scalars: numbers stay numbers; one scalar socket three times is that socket (its link
        into a vector input gives the three components); else Combine XYZ."""
        parts = (r, g, b)
        if not any(isinstance(value, bpy.types.NodeSocket) for value in parts):
            return tuple(float(value) for value in parts)
        if isinstance(r, bpy.types.NodeSocket) and not is_vector(r) and r == g and r == b:
            return r
        node = self.node(COMPOSITOR_COMBINE_XYZ, label=label)
        for socket, value in zip(node.inputs, parts):
            self._feed(node, socket, value)
        return node.outputs[0]

    def prune(self) -> int:
        """Remove the nodes this builder made whose outputs feed nothing (a component no equation reads), repeatedly;
        returns how many were removed."""
        removed = 0
        while True:
            dead = [node for node in self.tree.nodes if node.name in self._depth and node.outputs
                    and node.bl_idname != "NodeGroupOutput" and not any(out.is_linked for out in node.outputs)]
            if not dead:
                return removed
            for node in dead:
                del self._depth[node.name]
                self.tree.nodes.remove(node)
            removed += len(dead)

    @classmethod
    def child(cls, tree: bpy.types.NodeTree, parameters: Mapping[str, Operand]) -> "CompositorBuilder":
        """A compositor builder for a part's group ``tree``, its parameters the group's inputs."""
        return cls(tree, dict(parameters))

    def _part_parameters(self, part: parts.Part) -> list:
        return [self.parameters[name] for name, _ in part.parameters]

    def shading_input(self, name: str, *, label: str = ""):
        raise TypeError(f"a compositor graph has no shading point ({name!r}): its inputs are the group's")

    def texture(self, image, u: Operand, v: Operand, *, label: str = ""):
        raise TypeError("the compositor graphs sample their table unfiltered (texel)")

    def texel(self, image: bpy.types.Image | None, u: Operand, v: Operand, *, label: str = "") -> Socket:
        """``image`` at per-pixel coordinates (u, v), unfiltered: an Image node (one per builder) sampled by a Map UV
        node with nearest-texel filtering (4.5: ``filter_type``; 5.0: the Interpolation input); its colour. The UV's
        third component is 1 (Map UV reads it as the sample's alpha where the UV is a colour)."""
        if self._image_node is None:
            self._image_node = self.node("CompositorNodeImage", label="table image")
            self._image_node.image = image
        uv = self.node(COMPOSITOR_COMBINE_XYZ, label=f"uv ({label})")
        for socket, value in zip(uv.inputs, (u, v, 1.0)):
            self._feed(uv, socket, value)
        node = self.node("CompositorNodeMapUV", label=label)
        if "Interpolation" in node.inputs:
            node.inputs["Interpolation"].default_value = "Nearest"
            node.inputs["Extension X"].default_value = node.inputs["Extension Y"].default_value = "Extend"
        else:
            node.filter_type = "NEAREST"
        self._feed(node, node.inputs["Image"], self._image_node.outputs["Image"])
        self._feed(node, node.inputs["UV"], uv.outputs[0])
        return node.outputs["Image"]

    def soften(self, value: Operand, *, label: str = "") -> Socket | float | tuple:
        """``value`` averaged over the 3 x 3 pixels around (weights (1 2 1)^T (1 2 1) / 16, edges extended): one
        Filter node of the Soften type. The node's result is clamped at 0 (measured on 4.5, 5.2 and 5.3), so the
        values averaged must not be negative. A constant is its own average; a scalar goes through as a colour's
        first channel and comes back so."""
        if not isinstance(value, bpy.types.NodeSocket):
            return value
        scalar = not is_vector(value)
        node = self.node("CompositorNodeFilter", label=label)
        if "Type" in node.inputs:   # 5.0: the filter type is a menu input
            node.inputs["Type"].default_value = "Soften"
        else:
            node.filter_type = "SOFTEN"
        self._feed(node, node.inputs["Image"], self.combine(value, 0.0, 0.0) if scalar else value)
        return self.separate(node.outputs["Image"])[0] if scalar else node.outputs["Image"]

    def attribute(self, name: str, *, attribute_type: str = "VIEW_LAYER", output: str = "Color",
                  label: str = ""):
        """The parameter ``name`` from the mapping given to the builder (a KeyError names a missing one)."""
        return self.parameters[name]


# -- the numpy backend ----------------------------------------------------------------------------------


def _safe_divide(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.divide(a, b, out=np.zeros(np.broadcast_shapes(a.shape, b.shape), np.float32), where=b != 0.0)


def _safe_power(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Blender's Math Power: a^b, 0 where a < 0 and b is not a whole number."""
    whole = np.floor(b) == b
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        result = np.power(a, b)
    return np.where((a >= 0.0) | whole, result, np.float32(0.0))


#: The shading inputs that are vectors (the others are scalars).
_VECTOR_INPUTS = {"incoming", "position"}
#: Math operations as Blender's SVM computes them, in float32 (divide by 0 and sqrt of a negative give 0).
_ARRAY_MATH: dict[str, Callable[..., np.ndarray]] = {
    "ADD": np.add,
    "SUBTRACT": np.subtract,
    "MULTIPLY": np.multiply,
    "DIVIDE": _safe_divide,
    "MULTIPLY_ADD": lambda a, b, c: a * b + c,
    "MINIMUM": np.minimum,
    "MAXIMUM": np.maximum,
    "ABSOLUTE": np.abs,
    "SIGN": np.sign,
    "FLOOR": np.floor,
    "SQRT": lambda a: np.sqrt(np.maximum(a, np.float32(0.0))),
    "EXPONENT": np.exp,
    "POWER": _safe_power,
    "SINE": np.sin,
    "ARCSINE": lambda a: np.arcsin(np.clip(a, np.float32(-1.0), np.float32(1.0))),
    "ARCTAN2": np.arctan2,
    "LESS_THAN": lambda a, b: (a < b).astype(np.float32),
    "GREATER_THAN": lambda a, b: (a > b).astype(np.float32),
}


class ArrayBuilder(GraphBuilder):
    """The same equations evaluated in numpy: the functions that build the node groups (``scattering_terms``,
    ``dome_distances``, ``precise_terms``...) run on this builder and return arrays instead of sockets, so what a
    group computes is a Python value the tests compare with the physics core and with Blender's renders: one
    source for each equation, evaluated two ways.

    Every operation is the float32 arithmetic of Blender's node (:data:`_ARRAY_MATH`: a divide by 0 gives 0, the
    Gamma node leaves channels <= 0 unchanged); a scalar is an array, a vector or colour three arrays, its arithmetic
    per component. ``parameters`` are the group's parameters by property name (what
    :func:`~.parameters.shader_parameter_values` writes; a missing one reads 0, as Blender's Attribute node does),
    ``inputs`` the shading point's values by :data:`SHADING_INPUTS` name (arrays, (N,) or (N, 3)), ``images`` the
    pixels of the images the graph samples by name ((height, width, 4) arrays, row 0 at the bottom).
    """

    def __init__(self, parameters: Mapping[str, float | Sequence[float]], inputs: Mapping[str, np.ndarray],
                 images: Mapping[str, np.ndarray] | None = None) -> None:
        GraphBuilder.__init__(self, None)
        self.parameters = {name: self._value(value, np.ndim(value) == 1 and len(value) == 3)
                           for name, value in parameters.items()}
        self.inputs = {name: self._value(value, name in _VECTOR_INPUTS) for name, value in inputs.items()}
        self.images = dict(images or {})

    # -- a colour or vector is three arrays, its arithmetic per component ------------------------------

    @staticmethod
    def _channels(value: Operand) -> tuple:
        return tuple(value) if is_vector(value) else (value, value, value)

    def _vector_math(self, operation: str, *operands: Operand, label: str = "") -> tuple:
        return self._per_component(operation, *operands, label=label)

    def _per_component(self, operation: str, *operands: Operand, label: str = "") -> tuple:
        split = [self._channels(value) for value in operands]
        return tuple(self._math(operation, *(parts[c] for parts in split)) for c in range(3))

    def _arithmetic(self, operation: str, a: Operand, b: Operand, label: str):
        if is_vector(a) or is_vector(b):
            return self._per_component(operation, a, b)
        return self._math(operation, a, b)

    def scale(self, vector: Operand, factor: Operand, *, label: str = ""):
        return self._per_component("MULTIPLY", vector, factor)

    def neg(self, a: Operand, *, label: str = ""):
        return self._arithmetic("MULTIPLY", a, -1.0, label)

    def multiply_add(self, a: Operand, b: Operand, c: Operand, *, label: str = ""):
        if any(is_vector(v) for v in (a, b, c)):
            return self._per_component("MULTIPLY_ADD", a, b, c)
        return self._math("MULTIPLY_ADD", a, b, c)

    def abs(self, a: Operand, *, label: str = ""):
        return self._per_component("ABSOLUTE", a) if is_vector(a) else self._math("ABSOLUTE", a)

    def dot(self, a: Operand, b: Operand, *, label: str = ""):
        a, b = self._channels(a), self._channels(b)
        partial = self._math("MULTIPLY", a[0], b[0])
        partial = self._math("MULTIPLY_ADD", a[1], b[1], partial)
        return self._math("MULTIPLY_ADD", a[2], b[2], partial)

    def length(self, a: Operand, *, label: str = ""):
        return self._math("SQRT", self.dot(a, a))

    def cross(self, a: Operand, b: Operand, *, label: str = "") -> tuple:
        (ax, ay, az), (bx, by, bz) = self._channels(a), self._channels(b)
        return (self.sub(self.mul(ay, bz), self.mul(az, by)), self.sub(self.mul(az, bx), self.mul(ax, bz)),
                self.sub(self.mul(ax, by), self.mul(ay, bx)))

    def normalize(self, a: Operand, *, label: str = "") -> tuple:
        """a / |a| (the zero vector stays zero: Blender's divide gives 0 where the length is 0)."""
        return self._per_component("DIVIDE", a, self.length(a))

    def mix(self, factor: Operand, a: Operand, b: Operand, *, label: str = ""):
        """a + factor (b - a), per component if a or b is a colour."""
        return self.multiply_add(factor, self.sub(b, a), a)

    def separate(self, colour: Operand, *, label: str = "") -> tuple:
        return self._channels(colour)

    def combine(self, r: Operand, g: Operand, b: Operand, *, label: str = "") -> tuple:
        return (r, g, b)

    def per_channel(self, fn: Callable[..., Socket], *operands: Operand, label: str = "") -> tuple:
        split = [self._channels(op) for op in operands]
        return tuple(fn(*(parts[c] for parts in split)) for c in range(3))

    # -- values ---------------------------------------------------------------------------------------

    @staticmethod
    def _value(value, vector: bool) -> np.ndarray | tuple:
        array = np.asarray(value, dtype=np.float32)
        if vector:
            if array.shape[-1:] != (3,):
                raise ValueError(f"expected vectors of three components (..., 3); got shape {array.shape}")
            return tuple(array[..., c] for c in range(3))
        return array

    @staticmethod
    def array(value) -> np.ndarray:
        """A result as one float32 array: a vector or colour (N, 3) (components stacked), a scalar (N,)."""
        if is_vector(value):
            parts = np.broadcast_arrays(*(np.asarray(v, dtype=np.float32) for v in value))
            return np.stack(parts, axis=-1)
        return np.asarray(value, dtype=np.float32)

    def call(self, part: parts.Part, *operands: Operand, label: str = ""):
        """``part``'s equations evaluated in place on the arrays (a part is a node group only in Blender)."""
        return part.build(self, *operands)

    def node(self, bl_idname: str, *, label: str = "", depth: int | None = None, **properties):
        raise TypeError(f"the numpy builder evaluates equations and builds no node ({bl_idname}, {label!r})")

    def _math(self, operation: str, *operands: Operand, label: str = "") -> np.ndarray:
        arrays = [np.asarray(value, dtype=np.float32) for value in operands]
        return np.asarray(_ARRAY_MATH[operation](*arrays), dtype=np.float32)

    def power_per_channel(self, colour: Operand, exponent: Operand, *, label: str = "") -> tuple:
        """The Gamma node: c^exponent where c > 0, c unchanged elsewhere, 1 for an exponent of 0."""
        x = np.asarray(exponent, dtype=np.float32)

        def gamma(c):
            c = np.asarray(c, dtype=np.float32)
            with np.errstate(divide="ignore", over="ignore"):
                raised = np.where(c > 0.0, np.power(np.maximum(c, np.float32(1e-38)), x), c)
            return np.where(x == 0.0, np.float32(1.0), raised).astype(np.float32)

        return tuple(gamma(c) for c in self._channels(colour))

    def soften(self, value: Operand, *, label: str = ""):
        """``value`` averaged over the 3 x 3 pixels around each pixel of (height, width) arrays with the weights
        (1 2 1)^T (1 2 1) / 16, edges extended and the result clamped at 0, as the compositor's Filter node (Soften)
        computes it; a constant is its own average."""
        if is_vector(value):
            return tuple(self.soften(part) for part in value)
        array = np.asarray(value, dtype=np.float32)
        if array.ndim < 2:
            return array
        padded = np.pad(array, ((1, 1), (1, 1)), mode="edge")
        height, width = array.shape[:2]
        total = np.zeros_like(array)
        for dy, wy in ((0, 1.0), (1, 2.0), (2, 1.0)):
            for dx, wx in ((0, 1.0), (1, 2.0), (2, 1.0)):
                total += np.float32(wy * wx / 16.0) * padded[dy:dy + height, dx:dx + width]
        return np.maximum(total, np.float32(0.0))

    def shading_input(self, name: str, *, label: str = ""):
        if name not in SHADING_INPUTS:
            raise KeyError(f"unknown shading input {name!r}; known: {', '.join(SHADING_INPUTS)}")
        return self.inputs[name]

    def attribute(self, name: str, *, attribute_type: str = "VIEW_LAYER", output: str = "Color", label: str = ""):
        value = self.parameters.get(name, np.float32(0.0))
        if output == "Fac":
            return (value[0] + value[1] + value[2]) / np.float32(3.0) if is_vector(value) else value
        return value if is_vector(value) else (value, value, value)

    def texel(self, image, u: Operand, v: Operand, *, label: str = "") -> tuple:
        """The image's texel at (u, v), unfiltered with extended edges (Closest), as Cycles samples it; black where
        the graph has no image."""
        pixels = None if image is None else self.images.get(getattr(image, "name", image))
        if pixels is None:
            zero = np.zeros(np.broadcast_shapes(np.shape(u), np.shape(v)), np.float32)
            return (zero, zero, zero)
        height, width = pixels.shape[:2]
        column = np.clip(np.floor(np.asarray(u, np.float32) * width), 0, width - 1).astype(np.int64)
        row = np.clip(np.floor(np.asarray(v, np.float32) * height), 0, height - 1).astype(np.int64)
        texel = pixels[row, column]
        return tuple(np.asarray(texel[..., c], dtype=np.float32) for c in range(3))

    def texture(self, image, u: Operand, v: Operand, *, label: str = "") -> tuple:
        """The image at (u, v) filtered bilinearly with extended edges (Linear), as Cycles samples it: the four
        texels around x = u W - 1/2, y = v H - 1/2 weighted by the fractions; black where the graph has no image."""
        pixels = None if image is None else self.images.get(getattr(image, "name", image))
        if pixels is None:
            zero = np.zeros(np.broadcast_shapes(np.shape(u), np.shape(v)), np.float32)
            return (zero, zero, zero)
        height, width = pixels.shape[:2]
        x = np.asarray(u, np.float32) * np.float32(width) - np.float32(0.5)
        y = np.asarray(v, np.float32) * np.float32(height) - np.float32(0.5)
        x0, y0 = np.floor(x), np.floor(y)
        fx, fy = (x - x0)[..., None], (y - y0)[..., None]
        c0, c1 = (np.clip(x0 + k, 0, width - 1).astype(np.int64) for k in (0, 1))
        r0, r1 = (np.clip(y0 + k, 0, height - 1).astype(np.int64) for k in (0, 1))
        rgb = pixels[..., :3].astype(np.float32)
        low = rgb[r0, c0] * (np.float32(1) - fx) + rgb[r0, c1] * fx
        high = rgb[r1, c0] * (np.float32(1) - fx) + rgb[r1, c1] * fx
        texel = low * (np.float32(1) - fy) + high * fy
        return tuple(np.asarray(texel[..., c], dtype=np.float32) for c in range(3))

    def layout(self, *, origin: tuple[float, float] = (0.0, 0.0)) -> None:
        raise TypeError("the numpy builder has no nodes to lay out")
