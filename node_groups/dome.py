# SPDX-License-Identifier: GPL-3.0-or-later
"""The virtual sky dome as nodes: one builder shared by the sky and the aerial-perspective groups.

Hoffman & Preetham (GDC 2002 slides, "Virtual sky dome") replace the real atmosphere in each view
direction by a homogeneous one that ends at the distance R_i holding the same matter. For a camera on
the ground (altitude 0) with the closed-form Chapman function of ``atmos_addon.physics.sky.chapman_approx``:

    R_i = H_i c_i / (p c_i mu + sqrt(((1 - p) c_i mu)^2 + 1)),   c_i = sqrt(pi x_i / 2),  x_i = R_p / H_i

per species i (molecules R, aerosols M), with mu = max(v_z, 0) the sine of the view elevation clamped
at the horizon (rays below it take the horizontal dome) and p = :data:`CHAPMAN_APPROX_P`. Both species
run as the x and y components of one vector (Vector Math is exact per component), so the sky group and
the aerial group evaluate the very same nodes in the same order: their dome distances agree bit for bit
in Cycles, and a surface beyond the dome composites to exactly the sky behind it.

The parameters read are :data:`~.parameters.PLANET_RADIUS` (m) and :data:`~.parameters.SCALE_HEIGHTS`
((H_R, H_M, 0), m). Missing parameters read 0 and give R = 0: no atmosphere (the documented pass-through).
"""

from __future__ import annotations

import math

from ..physics.sky import CHAPMAN_APPROX_P
from . import parameters
from .graph import GraphBuilder, Socket



def view_direction(g: GraphBuilder) -> Socket:
    """v: the unit direction from the camera along the ray, -(Geometry > Incoming), world space.

    Incoming points back toward the viewer in both engines, for surfaces and for the world background
    (the sky tests check the world's sign against the physics core).
    """
    return g.normalize(g.neg(g.shading_input("incoming", label="Geometry")), label="v")


def sun_direction(g: GraphBuilder) -> Socket:
    """l: the unit direction to the sun (normalised here too: keyed directions interpolate off the sphere)."""
    return g.normalize(g.attribute(parameters.SUN_DIRECTION, output="Vector"), label="l")


def cos_theta_to_sun(g: GraphBuilder, view: Socket, sun_direction: Socket) -> Socket:
    """mu = v . l clamped to [-1, 1]."""
    return g.clamp(g.dot(view, sun_direction), -1.0, 1.0, label="mu")


def dome_distances(g: GraphBuilder, view_z: Socket) -> tuple[Socket, Socket]:
    """(R_R, R_M): dome distances of molecules and aerosols in m for a view ray with z component ``view_z``."""
    heights = g.attribute(parameters.SCALE_HEIGHTS, output="Vector", label="(H_R, H_M, 0)")
    planet = g.attribute(parameters.PLANET_RADIUS, output="Fac", label="R_p")
    x = g.div(planet, heights, label="x = R_p / H")  # Blender's Vector Math divide gives 0 for the unused 0 height
    c_squared = g.scale(x, 0.5 * math.pi, label="c^2 = pi x / 2")
    c = _sqrt_xy(g, c_squared, label="c")
    mu = g.max(view_z, 0.0, label="mu_z = max(v_z, 0)")
    c_mu = g.scale(c, mu, label="c mu")
    tail = g.scale(c_mu, 1.0 - CHAPMAN_APPROX_P, label="(1 - p) c mu")
    root = _sqrt_xy(g, g.multiply_add(tail, tail, (1.0, 1.0, 1.0), label="tail^2 + 1"), label="sqrt(tail^2 + 1)")
    denominator = g.multiply_add(c_mu, (CHAPMAN_APPROX_P,) * 3, root, label="p c mu + sqrt")
    chapman = g.div(c, denominator, label="Ch")
    domes = g.mul(chapman, heights, label="R = H Ch")
    r_rayleigh, r_mie, _ = g.separate(domes, label="R_R, R_M")
    return r_rayleigh, r_mie


def _sqrt_xy(g: GraphBuilder, vector: Socket, *, label: str) -> Socket:
    """(sqrt(x), sqrt(y), z^0.5) of a vector with x, y >= 0, one Gamma node (the z component is unused)."""
    return g.power_per_channel(vector, 0.5, label=label)
