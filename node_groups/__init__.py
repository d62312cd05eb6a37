# SPDX-License-Identifier: GPL-3.0-or-later
"""Atmos shader node groups: built from code, parameterised by scene custom properties.

The Blender layer (:mod:`atmos_addon.blender`) imports this package and hands it plain numbers and feature
sets; nothing here imports the Blender layer or the plan. Constants shared with the physics core (the
Chapman shape, the table shape) are imported from it: one source. Modules: :mod:`.graph` (a builder that writes
arithmetic as nodes), :mod:`.parameters` (the property names and their writer), :mod:`.aerial_perspective` (the
"Atmos Aerial Perspective" group, Hoffman & Preetham 2002 eq. 19), :mod:`.dome` (the virtual sky dome both
groups share), :mod:`.sky` (the "Atmos Sky" world group), :mod:`.sky_lighting` (the same sky from a table, for
the rays that light the scene), :mod:`.sky_view` (the Precise sky for Cycles' camera rays above the horizon),
:mod:`.parts` (pieces of those equations built once as groups of their own and instanced where used, so that every
tree stays small: Blender's build cost grows with the square of a tree's size).
"""

from .aerial_perspective import (GROUP_NAME, OUTPUT_INSCATTERING, OUTPUT_TRANSMITTANCE, build_aerial_perspective,
                                 describe_features, ensure_aerial_perspective_group, is_current, node_count)
from .terms import AerialFeatures
from . import in_render  # noqa: F401  (atmos_addon.node_groups.in_render: Cycles In-Render mode)
from .graph import GraphBuilder
from .parameters import (AERIAL_PARAMETER_NAMES, PARAMETER_NAMES, clear_shader_parameters,
                         keyframe_shader_parameters, read_shader_parameters, write_shader_parameters)
from .sky import OUTPUT_RADIANCE, SKY_GROUP_NAME, SKY_NODE_COUNTS, SkyFeatures, build_sky, ensure_sky_group
from . import sky_lighting  # noqa: F401  (atmos_addon.node_groups.sky_lighting: the world's table sky for non-camera rays)
from . import sky_view  # noqa: F401  (atmos_addon.node_groups.sky_view: the Precise sky for camera rays, two lookups)
from . import per_pixel  # noqa: F401  (atmos_addon.node_groups.per_pixel: the Fast level evaluated per pixel in the compositor)
from . import composite, parts, registry, stamps, surface  # noqa: F401  (compositor, material groups, parts, registry)

__all__ = [
    "AERIAL_PARAMETER_NAMES",
    "OUTPUT_RADIANCE",
    "SKY_GROUP_NAME",
    "SKY_NODE_COUNTS",
    "SkyFeatures",
    "build_sky",
    "ensure_sky_group",
    "GROUP_NAME",
    "OUTPUT_INSCATTERING",
    "OUTPUT_TRANSMITTANCE",
    "PARAMETER_NAMES",
    "AerialFeatures",
    "GraphBuilder",
    "build_aerial_perspective",
    "clear_shader_parameters",
    "describe_features",
    "ensure_aerial_perspective_group",
    "is_current",
    "keyframe_shader_parameters",
    "node_count",
    "read_shader_parameters",
    "write_shader_parameters",
]
