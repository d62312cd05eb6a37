# SPDX-License-Identifier: GPL-3.0-or-later
"""The aerial perspective evaluated once per pixel, in the compositor: "Atmos Aerial Composite (Per Pixel)".

The Compositor mode evaluates Hoffman & Preetham's eq. 19 at every camera sample (about 50 shader nodes that
depend on the sample, ~0.35 us per sample in Cycles: docs/quality.md, "Cost"). Per Pixel mode moves that work
out of the render: the materials write three AOVs that cost next to nothing per sample,

    atmos_coverage  C = sum a_i                  (opacity alpha a_i, as in the Compositor mode)
    atmos_distance  D = sum a_i s_i / 1000        (s: camera distance, m; km keep Eevee's half floats in range)
    atmos_view      V = sum a_i v_i              (v: unit view direction from the camera, world space)

and this compositor group evaluates, per pixel, the mean distance s = 1000 D / C and direction v = V / |V|,

    F_ex, L_in = Fast:     eq. 19 on the layered virtual dome (``terms.scattering_terms``)
                 Precise:  the frame's baked table (``precise.precise_terms``), its texels fetched by Map UV nodes
                           with nearest filtering and blended bilinearly in the graph, as the shader does
    T = C F_ex,  L = C L_in  ->  the "Atmos Aerial Composite" group: out = Image (T + max(1 - C, 0)) / k + L / k
                                  (C bounded by the render's alpha there: :mod:`.composite`)

with the very functions that build the shader group, a colour one vector socket as there (:class:`.graph.
CompositorBuilder`): a fully covered pixel gets exactly L0 F_ex + L_in, a sky pixel (C = 0) passes untouched.
Only edges differ from the per-sample mode: a pixel mixing two distances gets F_ex of the mean distance, not
the mean of F_ex (Jensen's gap, first order in the mix like the per-sample mode's own edge error;
docs/silhouettes.md measures both).

The atmosphere reaches the group as input sockets of the group node (:data:`PARAMETER_SOCKETS`), which the add-on
drives from the scene's custom properties (the ones the shader groups read): a parameter change edits values,
a keyed sun animates them, and a farm machine without the add-on evaluates the drivers (single-property
drivers, no Python). The tree depends only on the features (Mie, absorption, level), stamped like the
shader groups. The Precise table image is the packed one the shader groups sample.
"""

from __future__ import annotations

import bpy

from ..plan import AOV_COVERAGE, AOV_DISTANCE, AOV_VIEW
from . import parameters, stamps
from .composite import keep_interface
from .dome import cos_theta_to_sun, dome_distances, sun_direction
from .graph import CompositorBuilder
from .precise import precise_terms
from .surface import DISTANCE_AOV_UNIT_M
from .terms import AerialFeatures, scattering_terms

GROUP_NAME = stamps.PER_PIXEL.name
#: The stamp the group carries its feature key in (stale groups are rebuilt in place: the interface, and the drivers
#: on it, stay).
FEATURES_KEY = stamps.FEATURES_KEY

#: Levels the group evaluates.
LEVELS = ("fast", "precise")

#: (scene custom property, group input socket, components) for every parameter the Fast graph reads.
PARAMETER_SOCKETS = (
    (parameters.BETA_RAYLEIGH, "Rayleigh Scattering (1/m)", 3),
    (parameters.BETA_MIE, "Mie Scattering (1/m)", 3),
    (parameters.BETA_MIE_ABSORPTION, "Mie Absorption (1/m)", 3),
    (parameters.MIE_G, "Mie Anisotropy g", 3),
    (parameters.SUN_DIRECTION, "Sun Direction", 3),
    (parameters.SUN_IRRADIANCE, "Sun Irradiance (W/m^2)", 3),
    (parameters.PLANET_RADIUS, "Planet Radius (m)", 1),
    (parameters.SCALE_HEIGHTS, "Scale Heights (m)", 3),
    (parameters.METRES_PER_UNIT, "Metres per Unit", 1),
)
#: The Precise level's per-frame table parameters (driven only where the group is built at that level: the
#: scene has them only then).
PRECISE_SOCKETS = (
    (parameters.PRECISE_TILE, "Precise Tile (x0, y0, h_c)", 3),
    (parameters.PRECISE_SCALE, "Precise Scale (D, top)", 3),
    (parameters.PRECISE_ATLAS, "Precise Atlas Size", 3),
)
#: Inputs fed from the Render Layers node: (socket, AOV or pass name, socket type).
IMAGE_INPUTS = (
    ("Image", "Image", "NodeSocketColor"),
    ("Coverage", AOV_COVERAGE, "NodeSocketFloat"),
    ("Distance", AOV_DISTANCE, "NodeSocketFloat"),
    ("View", AOV_VIEW, "NodeSocketVector"),
    ("Alpha", "Alpha", "NodeSocketFloat"),   # the render's alpha bounds the coverage (composite.py: holdouts)
)


def _ensure_interface(tree: bpy.types.NodeTree) -> None:
    """Give ``tree`` the wanted inputs and output, keeping every socket it already has of those (so the links into
    the group node and the drivers on it stay): sockets no longer wanted are removed (a group saved with the
    retired Balanced level's camera-z and sun-depth inputs), missing ones added."""
    wanted = ([("Image", "OUTPUT", "NodeSocketColor")]   # Blender lists the outputs first
              + [(name, "INPUT", socket_type) for name, _, socket_type in IMAGE_INPUTS]
              + [(name, "INPUT", "NodeSocketVector" if size == 3 else "NodeSocketFloat")
                 for _, name, size in PARAMETER_SOCKETS]
              + [(name, "INPUT", "NodeSocketVector") for _, name, _ in PRECISE_SOCKETS])
    keep_interface(tree, wanted)


def build_per_pixel_composite(tree: bpy.types.NodeTree, features: AerialFeatures,
                              composite_group: bpy.types.NodeTree) -> None:
    """Clear ``tree`` and build the per-pixel graph for ``features``; ``composite_group`` combines (see module)."""
    if features.level not in LEVELS:
        raise ValueError(f"the per-pixel composite evaluates the levels {LEVELS}; got {features.level!r}")
    tree.nodes.clear()
    _ensure_interface(tree)
    group_in = tree.nodes.new("NodeGroupInput")
    inputs = {name: group_in.outputs[socket_name]
              for name, socket_name, _ in PARAMETER_SOCKETS + (PRECISE_SOCKETS if features.level == "precise" else ())}
    g = CompositorBuilder(tree, inputs)
    coverage = group_in.outputs["Coverage"]
    view = g.normalize(group_in.outputs["View"], label="v")
    # Blender's divide gives 0 where nothing wrote (C = 0): s = 0, F_ex = 1, L_in = 0, and T = L = 0 below.
    s = g.mul(g.div(group_in.outputs["Distance"], coverage), DISTANCE_AOV_UNIT_M, label="s (m)")
    if features.level == "precise":   # the tile's camera altitude is a parameter
        f_ex, l_in = precise_terms(g, features, s, view)
    else:
        r_rayleigh, r_mie = dome_distances(g, g.separate(view, label="v")[2])
        s_rayleigh = g.min(s, r_rayleigh, label="s_R = min(s, R_R)")
        s_mie = g.min(s, r_mie, label="s_M = min(s, R_M)") if features.mie or features.absorption else None
        f_ex, l_in = scattering_terms(g, features, s_rayleigh, s_mie, cos_theta_to_sun(g, view, sun_direction(g)))
    combine = g.node("CompositorNodeGroup", label="Atmos: combine")
    combine.node_tree = composite_group
    g._feed(combine, combine.inputs["Transmittance"], g.scale(f_ex, coverage, label="T = C F_ex"))
    g._feed(combine, combine.inputs["Inscattering"], g.scale(l_in, coverage, label="L = C L_in"))
    g._feed(combine, combine.inputs["Coverage"], coverage)
    g._feed(combine, combine.inputs["Alpha"], group_in.outputs["Alpha"])
    g._feed(combine, combine.inputs["Image"], group_in.outputs["Image"])
    output = g.node("NodeGroupOutput", label="Group Output")
    g._feed(output, output.inputs["Image"], combine.outputs["Image"])
    g.prune()
    g.layout()
    stamps.stamp(tree, stamps.PER_PIXEL, features.key)


def ensure_per_pixel_group(features: AerialFeatures, composite_group: bpy.types.NodeTree) -> bpy.types.NodeTree:
    """Get or create the per-pixel compositor group for ``features``; rebuilt in place when its version or features
    are stale, so group nodes keep their links (the caller re-drives the inputs: a new interface has new sockets,
    and only the Precise level's group reads the table parameters)."""
    tree = stamps.group(stamps.PER_PIXEL)
    if not stamps.is_current(tree, stamps.PER_PIXEL, features.key):
        build_per_pixel_composite(tree, features, composite_group)
    return tree
