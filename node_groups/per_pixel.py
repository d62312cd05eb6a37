# SPDX-License-Identifier: GPL-3.0-or-later
"""The aerial perspective evaluated once per pixel, in the compositor: "Atmos Aerial Composite (Per Pixel)".

The Compositor mode evaluates Hoffman & Preetham's eq. 19 at every camera sample (about 50 shader nodes that
depend on the sample, ~0.35 us per sample in Cycles: docs/quality.md, "Cost"). Per Pixel mode moves that work
out of the render: the materials write AOVs that cost next to nothing per sample,

    atmos_coverage  C = sum a_i                          (opacity alpha a_i, as in the Compositor mode)
    atmos_distance  D = sum a_i s_i / 1000                (s: camera distance, m; km keep Eevee's half floats in range)
    atmos_view      V = sum a_i v_i                      (v: unit view direction from the camera, world space)
    atmos_moments   M = sum a_i (q_i, q_i^2, q_i^3)      (q = s / (s + s_0), s_0 = :data:`MOMENT_DISTANCE_M`)

and this compositor group reads the pixel's samples as two distances (``composite.two_point`` on the moments of q,
which lies in [0, 1) whatever the distance: exact for a pixel of two surfaces, and one distance, the mean
s = 1000 D / C, for a pixel of one), scaled so that their mean is that s, along the direction v = V / |V|, and
evaluates at each

    F_ex, L_in = Fast:     eq. 19 on the layered virtual dome (``terms.scattering_terms``)
                 Precise:  the frame's baked table (``precise.precise_terms``), its texels fetched by Map UV nodes
                           with nearest filtering and blended bilinearly in the graph, as the shader does
    T = C (p_n F_ex,n + p_f F_ex,f),  L = C (p_n L_in,n + p_f L_in,f)

with the very functions that build the shader group, a colour one vector socket as there (:class:`.graph.
CompositorBuilder`), then combines them with the render as the Compositor mode does (:func:`.composite.combine`:
the sky passes untouched, a pixel of one surface gets exactly L0 F_ex + L_in, and the product of two surfaces'
differences is read off the pixels around).

The atmosphere reaches the group as input sockets of the group node (:data:`PARAMETER_SOCKETS`), which the add-on
drives from the scene's custom properties (the ones the shader groups read): a parameter change edits values,
a keyed sun animates them, and a farm machine without the add-on evaluates the drivers (single-property
drivers, no Python). The tree depends only on the features (Mie, absorption, level), stamped like the
shader groups. The Precise table image is the packed one the shader groups sample.
"""

from __future__ import annotations

import bpy

from ..plan import AOV_COVERAGE, AOV_DISTANCE, AOV_MOMENTS, AOV_VIEW, ENVIRONMENT_PASS
from . import parameters, parts, stamps
from .composite import CORRECTION, TWO_POINT, combine, keep_interface, shown_sky, with_alpha
from .dome import cos_theta_to_sun, dome_distances, sun_direction
from .graph import CompositorBuilder
from .precise import precise_terms
from .surface import DISTANCE_AOV_UNIT_M, MOMENT_DISTANCE_M
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
    ("Moments", AOV_MOMENTS, "NodeSocketColor"),
    ("Environment", ENVIRONMENT_PASS, "NodeSocketColor"),
)
#: The input driven from the scene's Film > Transparent (the render then shows no sky: composite.py).
FILM_TRANSPARENT = "Film Transparent"


def _ensure_interface(tree: bpy.types.NodeTree) -> None:
    """Give ``tree`` the wanted inputs and output, keeping every socket it already has of those (so the links into
    the group node and the drivers on it stay): sockets no longer wanted are removed (a group saved with the
    retired Balanced level's camera-z and sun-depth inputs), missing ones added."""
    wanted = ([("Image", "OUTPUT", "NodeSocketColor")]   # Blender lists the outputs first
              + [(name, "INPUT", socket_type) for name, _, socket_type in IMAGE_INPUTS]
              + [(FILM_TRANSPARENT, "INPUT", "NodeSocketFloat")]
              + [(name, "INPUT", "NodeSocketVector" if size == 3 else "NodeSocketFloat")
                 for _, name, size in PARAMETER_SOCKETS]
              + [(name, "INPUT", "NodeSocketVector") for _, name, _ in PRECISE_SOCKETS])
    keep_interface(tree, wanted)


def _terms(g, features: AerialFeatures, s, view):
    """(F_ex, L_in) at distance ``s`` (m) along ``view`` at the level of ``features``."""
    if features.level == "precise":   # the tile's camera altitude is a parameter
        return precise_terms(g, features, s, view)
    r_rayleigh, r_mie = dome_distances(g, g.separate(view, label="v")[2])
    s_rayleigh = g.min(s, r_rayleigh, label="s_R = min(s, R_R)")
    s_mie = g.min(s, r_mie, label="s_M = min(s, R_M)") if features.mie or features.absorption else None
    return scattering_terms(g, features, s_rayleigh, s_mie, cos_theta_to_sun(g, view, sun_direction(g)))


def _terms_part(features: AerialFeatures) -> parts.Part:
    """:func:`_terms` for ``features`` as a part (one per feature set): the group evaluates it at two distances, and
    each copy inline would double the group's size."""
    sockets = PARAMETER_SOCKETS + (PRECISE_SOCKETS if features.level == "precise" else ())

    def build(g, distance, view):
        return _terms(g, features, distance, view)

    return parts.define(f"Atmos Per Pixel Terms ({features.key})", 1,
                        (("Distance (m)", parts.FLOAT), ("View", parts.VECTOR)),
                        (("F_ex", parts.VECTOR), ("L_in", parts.VECTOR)), build,
                        parameters=tuple((name, parts.VECTOR if size == 3 else parts.FLOAT)
                                         for name, _, size in sockets),
                        description="F_ex and L_in at a distance along a view direction (Atmos)")


#: The terms' part for every feature set the group is built for, by the features' key.
TERMS_PARTS = {features.key: _terms_part(features)
               for features in (AerialFeatures(mie=mie, absorption=absorption, level=level, blend=blend)
                                for mie in (True, False) for absorption in (True, False)
                                for level, blend in (("fast", False), ("precise", False), ("precise", True)))}


def build_per_pixel_composite(tree: bpy.types.NodeTree, features: AerialFeatures) -> None:
    """Clear ``tree`` and build the per-pixel graph for ``features`` (see module)."""
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
    mean = g.mul(g.div(group_in.outputs["Distance"], coverage), DISTANCE_AOV_UNIT_M, label="s (m)")
    moments = g.separate(group_in.outputs["Moments"], label="q moments")
    share_lo, share_hi, q_lo, q_hi = g.call(TWO_POINT, coverage, *moments)
    distances = [g.div(g.mul(q, MOMENT_DISTANCE_M), g.max(g.sub(1.0, q), 1e-6)) for q in (q_lo, q_hi)]
    # The two distances scaled so that their mean is the pixel's mean distance (exact for one surface); the mean
    # itself where the moments are 0 (a group node of a file saved before they were written).
    moment_mean = g.add(g.mul(share_lo, distances[0]), g.mul(share_hi, distances[1]), label="mean of the two")
    ratio = g.div(mean, moment_mean, label="s / mean of the two")
    known = g.greater_than(moment_mean, 0.0)
    terms = [g.call(TERMS_PARTS[features.key], g.select(known, g.mul(distance, ratio), mean, label=f"s_{end}"), view)
             for distance, end in zip(distances, ("lo", "hi"))]
    f_ex = g.add(g.scale(terms[0][0], share_lo), g.scale(terms[1][0], share_hi), label="F_ex")
    l_in = g.add(g.scale(terms[0][1], share_lo), g.scale(terms[1][1], share_hi), label="L_in")
    sky, surfaces = shown_sky(g, group_in.outputs["Image"], group_in.outputs["Environment"],
                              group_in.outputs[FILM_TRANSPARENT])
    term = g.call(CORRECTION, surfaces, coverage, moments[0], share_lo, share_hi, q_lo, q_hi, terms[0][0],
                  terms[1][0])
    out = combine(g, sky=sky, surfaces=surfaces, alpha=group_in.outputs["Alpha"], coverage=coverage,
                  transmittance=g.scale(f_ex, coverage, label="T = C F_ex"),
                  inscattering=g.scale(l_in, coverage, label="L = C L_in"), correction_term=term)
    output = g.node("NodeGroupOutput", label="Group Output")
    g.link(with_alpha(g, out, group_in.outputs["Alpha"]), output.inputs["Image"])
    g.prune()
    g.layout()
    stamps.stamp(tree, stamps.PER_PIXEL, features.key)


def ensure_per_pixel_group(features: AerialFeatures) -> bpy.types.NodeTree:
    """Get or create the per-pixel compositor group for ``features``; rebuilt in place when its version or features
    are stale, so group nodes keep their links (the caller re-drives the inputs: a new interface has new sockets,
    and only the Precise level's group reads the table parameters)."""
    tree = stamps.group(stamps.PER_PIXEL)
    if not stamps.is_current(tree, stamps.PER_PIXEL, features.key):
        build_per_pixel_composite(tree, features)
    return tree
