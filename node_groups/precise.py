# SPDX-License-Identifier: GPL-3.0-or-later
"""The Precise quality level as nodes: the frame's baked table, sampled per shading point.

The numpy reference is ``atmos_addon.physics.precise`` (``bake_tile`` builds the table, ``evaluate`` samples it
exactly as this graph does; its docstring derives the quantities). Per shading point, with s the camera
distance (m), v the unit view direction, l the unit direction to the sun:

    r_c    = R + h_c,  rise = (2 r_c v_z + s) s,  h_p = h_c + rise / (sqrt(r_c^2 + rise) + r_c)   target altitude
    row    = (clamp(h_p / top, 0, 1))^(1/3) (N_h - 1)
    a      = atan2(|v_x l_y - v_y l_x|, v_x l_x + v_y l_y) (N_a - 1) / pi,  a0 = min(floor(a), N_a - 2)
    u      = row / (N_h - 1),  d_min = |top u^3 - h_c| v,  p = v (1 - u) + 2     v = 1, or 0 for a camera whose
    col    = min(((max(s - d_min, 0) / max(D - d_min, 1))^(1/p), 1) (N_d - 1)     altitude moves (its key tiles)
    tau    = s * image(x0 + 0.5 + col, y0 + 0.5 + row)                         the extinction block
    A_i    = lerp(image(x_i + a0 N_d + ...), image(x_i + (a0 + 1) N_d + ...), a - a0)   A_R and A_M blocks
    F_ex   = exp(-tau),  L_in = [Phi_R(nu) A_R + Phi_HG(nu, g) A_M] tau phi1(tau),  nu = v . l

Within an azimuth slice the blend is bilinear in (row, col), from the four texels around the point fetched
unfiltered (texel centres at +0.5), the same arithmetic in both engines. :func:`sky_view` reads the tile's sky-view
block (the Precise sky by view direction) with Cycles' filtered lookup, for the world's non-camera rays.
Per-frame values are scene parameters (:mod:`.parameters`): the tile's texel origin and the camera altitude
(``atmos_precise_tile`` = (x0, y0, h_c)), the frame's largest distance and the table's top
(``atmos_precise_scale`` = (D, top, w)) and the image size with v (``atmos_precise_atlas`` = (W, H, v)). When the
camera or the sun moves over time the image holds key tiles along the path (``physics.precise.key_tiles``) and the
graph is built to blend each texel of the frame's key tile with the next key's, one tile height up, by the weight w
(:class:`KeyBlend`); the add-on keys the parameters per frame (constant interpolation), so a farm renders every
frame from the packed image without Python.
"""

from __future__ import annotations

import math

import bpy

from ..physics.aerial_perspective import SMALL_OPTICAL_DEPTH
from ..physics.precise import DEFAULT_SHAPE
from . import parameters, parts, stamps
from .dome import cos_theta_to_sun, sun_direction
from .graph import GraphBuilder, Socket
from .terms import phase_henyey_greenstein, phase_rayleigh

#: Name of the image the add-on bakes the tables into (packed into the .blend).
IMAGE_NAME = "Atmos Precise Table"
#: Table shape the graph samples: the one the core bakes.
ALTITUDES, AZIMUTHS, DISTANCES = DEFAULT_SHAPE.altitudes, DEFAULT_SHAPE.azimuths, DEFAULT_SHAPE.distances



def branch_large(g: GraphBuilder, x: Socket, threshold: float) -> Socket:
    """Per component, 1 where x >= ``threshold`` and 0 below (x >= 0): min(floor(x / threshold), 1)."""
    return g.min(g.floor(g.scale(x, 1.0 / threshold)), (1.0, 1.0, 1.0), label=f"x >= {threshold:g}")

def table_image() -> bpy.types.Image | None:
    """The baked table image, or None before the first bake (the graph then samples nothing: black)."""
    return stamps.local(bpy.data.images, IMAGE_NAME)   # never a library's


def _texel(g: GraphBuilder, u: Socket, v: Socket, label: str) -> Socket:
    """The table's texel at texture coordinates (u, v) (a texel centre), unfiltered: its colour."""
    return g.texel(table_image(), u, v, label=label)


def _lerp(g: GraphBuilder, low: Socket, high: Socket, fraction: Socket, label: str) -> Socket:
    """low + fraction (high - low), per component (``fraction`` a scalar)."""
    return g.multiply_add(g.combine(fraction, fraction, fraction), g.sub(high, low), low, label=label)


def phi1_exact(g: GraphBuilder, x: Socket, exp_minus_x: Socket) -> Socket:
    """phi1(x) per component (:func:`phi1_graph`), one instance of its part."""
    return g.call(PHI1, x, exp_minus_x, label="phi1(tau)")


def phi1_graph(g: GraphBuilder, x: Socket, exp_minus_x: Socket) -> Socket:
    """phi1(x) = (1 - exp(-x)) / x per component, the series 1 - x/2 + x^2/6 below 1e-3 (x >= 0), picked exactly:
    m quotient + (1 - m) series with m 0 or 1 and the series taken at min(x, 1e-3). (A blend
    series + m (quotient - series) cancels once x^2/6 dwarfs the quotient: optical depths of thousands, which the
    Precise table's far columns reach.)"""
    small = g.min(x, (SMALL_OPTICAL_DEPTH,) * 3)
    series = g.multiply_add(small, g.multiply_add(small, (1.0 / 6.0,) * 3, (-0.5,) * 3), (1.0, 1.0, 1.0),
                            label="1 - x/2 + x^2/6")
    quotient = g.div(g.sub((1.0, 1.0, 1.0), exp_minus_x), g.max(x, (SMALL_OPTICAL_DEPTH,) * 3),
                     label="(1 - e^-x) / x")
    large = branch_large(g, x, SMALL_OPTICAL_DEPTH)
    return g.multiply_add(large, quotient, g.mul(g.sub((1.0, 1.0, 1.0), large), series), label="phi1(tau)")


PHI1 = parts.define("Atmos phi1", 1, (("x", parts.VECTOR), ("exp(-x)", parts.VECTOR)), (("phi1", parts.VECTOR),),
                    phi1_graph, description="phi1(x) = (1 - exp(-x)) / x per channel, its series below 1e-3")


class _Bilinear:
    """Bilinear samples of the image at (x + col, row) for integer x offsets: the four texels around it fetched
    unfiltered and blended here. (A filtered texture lookup would do the same in Cycles, but Eevee filters with
    mipmaps chosen from screen-space derivatives, which the slice jumps of the atlas coordinates make huge.)
    The fractions are shared by every block: their offsets are whole texels. With ``whole_row`` the row is a whole
    number (the sky's rays end on the top row or the ground's): one row, two texels per sample. With ``blend``
    (:func:`key_blend`) every texel is its key tile's blended with the next key tile's, one tile height up. Each
    sample is one instance of a table-sample part (:data:`TABLE_SAMPLES`, :func:`table_sample`)."""

    def __init__(self, g: GraphBuilder, x0: Socket, y0: Socket, column: Socket, row: Socket, width: Socket,
                 height: Socket, whole_row: bool = False, blend: "KeyBlend | None" = None) -> None:
        self.g = g
        column_floor = g.floor(column, label="floor(col)")
        row_floor = row if whole_row else g.floor(row, label="floor(row)")
        self.f_column = g.sub(column, column_floor, label="col fraction")
        self.f_row = None if whole_row else g.sub(row, row_floor, label="row fraction")
        self.x = g.add(g.add(x0, 0.5), column_floor, label="x0 + floor(col) + 0.5")
        self.width = width
        v_low = g.div(g.add(g.add(y0, 0.5), row_floor), height, label="v (row)")
        self.v = (v_low,) if whole_row else (v_low, g.add(v_low, g.div(1.0, height), label="v (row + 1)"))
        self.step_u = g.div(1.0, width, label="1 / W")
        self.blend = blend
        self.v_next = None if blend is None else tuple(g.add(v, blend.step_v, label="v (next key)") for v in self.v)
        self.part = TABLE_SAMPLES[len(self.v), blend is not None]

    def sample(self, offset: Socket | float, label: str) -> Socket:
        operands = [self.x, offset, self.width, self.step_u, self.f_column, *self.v]
        if self.f_row is not None:
            operands.append(self.f_row)
        if self.blend is not None:
            operands += [self.blend.weights, *self.v_next]
        return self.g.call(self.part, *operands, label=label)


def table_sample(g: GraphBuilder, x: Socket, offset: Socket, width: Socket, step_u: Socket, f_column: Socket,
                 *rest: Socket, rows: int, blend: bool) -> Socket:
    """One bilinear sample of the table (:class:`_Bilinear`): the texels at u = (x + offset) / W and u + 1 / W on
    ``rows`` rows (texture v given; with two, the row fraction follows), blended by the column (and row) fraction;
    with ``blend`` each texel is mixed with the next key tile's (weights and its rows' v follow)."""
    v, rest = rest[:rows], rest[rows:]
    f_row, rest = (rest[0], rest[1:]) if rows == 2 else (None, rest)
    weights, v_next = (rest[0], rest[1:]) if blend else (None, ())

    def texel(u: Socket, index: int) -> Socket:
        first = _texel(g, u, v[index], "texel")
        if not blend:
            return first
        second = _texel(g, u, v_next[index], "texel, next key")
        return g.multiply_add(weights, g.sub(second, first), first, label="texel, blended")

    u_low = g.div(g.add(x, offset), width, label="u")
    u_high = g.add(u_low, step_u)
    lines = [_lerp(g, texel(u_low, i), texel(u_high, i), f_column, "row") for i in range(rows)]
    return lines[0] if f_row is None else _lerp(g, lines[0], lines[1], f_row, "sample")


def _table_sample_part(rows: int, blend: bool) -> parts.Part:
    inputs = ([("x", parts.FLOAT), ("offset", parts.FLOAT), ("W", parts.FLOAT), ("1 / W", parts.FLOAT),
               ("column fraction", parts.FLOAT)] + [(f"v (row {i})", parts.FLOAT) for i in range(rows)]
              + ([("row fraction", parts.FLOAT)] if rows == 2 else [])
              + ([("key weights", parts.VECTOR)] + [(f"v (row {i}, next key)", parts.FLOAT) for i in range(rows)]
                 if blend else []))
    name = "Atmos Table Sample" + (" (Row)" if rows == 1 else "") + (" (Key Blend)" if blend else "")
    return parts.define(name, 1, inputs, (("Sample", parts.VECTOR),),
                        lambda g, *sockets: table_sample(g, *sockets, rows=rows, blend=blend),
                        description="The Precise table sampled bilinearly from its texels (unfiltered fetches)")


#: The table-sample parts by (rows, key blend).
TABLE_SAMPLES = {(rows, blend): _table_sample_part(rows, blend) for rows in (1, 2) for blend in (False, True)}


class KeyBlend:
    """The blend of a frame's two key tiles (an animated camera or sun, ``physics.precise.key_tiles``): the frame's
    key tile at the tile origin, the next one a tile height (N_h texels) up, weight w = the z of
    ``atmos_precise_scale``; a texel is first + w (next - first) (``physics.precise.blend_tiles``)."""

    def __init__(self, g: GraphBuilder, height: Socket) -> None:
        self.g = g
        _, _, weight = g.separate(g.attribute(parameters.PRECISE_SCALE, output="Vector"), label="scale w")
        self.weights = g.combine(weight, weight, weight)
        self.step_v = g.div(float(ALTITUDES), height, label="N_h / H (next key)")

    def mix(self, first: Socket, second: Socket, label: str) -> Socket:
        return self.g.multiply_add(self.weights, self.g.sub(second, first), first, label=f"{label}, blended")


def distance_to_top(g: GraphBuilder, view_z: Socket, h_c: Socket, top: Socket, radius: Socket) -> Socket:
    """Distance in m from the tile's camera to the top of the atmosphere (:func:`distance_to_top_graph`), one
    instance of its part."""
    return g.call(DISTANCE_TO_TOP, view_z, h_c, top, radius, label="to the top")


def distance_to_top_graph(g: GraphBuilder, view_z: Socket, h_c: Socket, top: Socket, radius: Socket) -> Socket:
    """Distance in m from the tile's camera (altitude h_c) to the top of the atmosphere along a ray with zenith
    cosine ``view_z``: ``physics.precise.distance_to_top`` node for node (its docstring has the forms)."""
    r_c_c = g.mul(g.add(radius, h_c, label="r_c"), view_z, label="r_c c")
    top_term = g.mul(g.sub(top, h_c), g.add(g.add(g.mul(radius, 2.0, label="2 R"), top), h_c),
                     label="K = (top - h_c)(2 R + top + h_c)")
    root = g.sqrt(g.max(g.multiply_add(r_c_c, r_c_c, top_term), 0.0), label="sqrt(K + (r_c c)^2)")
    up = g.div(top_term, g.max(g.add(root, r_c_c), 1.0), label="to the top (c >= 0)")
    down = g.sub(root, r_c_c, label="to the top (c < 0)")
    return g.max(g.select(g.less_than(view_z, 0.0, label="c < 0"), down, up), 0.0, label="to the top")


DISTANCE_TO_TOP = parts.define(
    "Atmos Distance to Top", 1, (("v_z", parts.FLOAT), ("h_c", parts.FLOAT), ("top", parts.FLOAT), ("R", parts.FLOAT)),
    (("Distance", parts.FLOAT),), distance_to_top_graph,
    description="Distance in m from the camera (altitude h_c) to the top of the atmosphere along the view")


def azimuth_from_sun(g: GraphBuilder, vx: Socket, vy: Socket, sx: Socket, sy: Socket) -> Socket:
    """The view's azimuth from the sun's, rad in 0..pi (the table is mirror-symmetric about the sun's azimuth):
    atan2(|v x l|_z, (v . l)_xy)."""
    cross = g.abs(g.sub(g.mul(vx, sy), g.mul(vy, sx)), label="|v x l|_z")
    dot = g.multiply_add(vx, sx, g.mul(vy, sy), label="(v . l)_xy")
    return g.arctan2(cross, dot, label="azimuth from the sun")


class _ViewLookup:
    """What both sky views read per ray: the view's zenith cosine v_z, the column of its azimuth from the sun, the
    tile's texel origin, the atlas size and sin(dip) = sqrt(h_c (2 R + h_c)) / (R + h_c) (the horizon's zenith
    cosine is -sin(dip)); and their filtered lookups, blended with the next key tile's with ``blend``."""

    def __init__(self, g: GraphBuilder, view: Socket, sun: Socket, blend: bool, label: str) -> None:
        self.g = g
        vx, vy, self.vz = g.separate(view, label="v")
        sx, sy, _ = g.separate(sun, label="l")
        self.x0, self.y0, h_c = g.separate(g.attribute(parameters.PRECISE_TILE, output="Vector"),
                                           label="tile (x0, y0, h_c)")
        self.width, self.height, _ = g.separate(g.attribute(parameters.PRECISE_ATLAS, output="Vector"),
                                                label="atlas (W, H)")
        radius = g.attribute(parameters.PLANET_RADIUS, output="Fac")
        ground_term = g.mul(h_c, g.multiply_add(radius, 2.0, h_c), label="h_c (2 R + h_c)")
        self.sin_dip = g.div(g.sqrt(ground_term), g.add(radius, h_c), label="sin(dip) = -z_h")
        self.column = g.mul(azimuth_from_sun(g, vx, vy, sx, sy), (DEFAULT_SHAPE.sky_azimuths - 1) / math.pi,
                            label=f"{label} column")
        self.mixer = KeyBlend(g, self.height) if blend else None

    def lookup(self, x: Socket, v: Socket, label: str) -> Socket:
        """The filtered texel at column x (texel units, centres at +0.5) and texture coordinate v."""
        g = self.g
        u = g.div(x, self.width, label=f"u ({label})")
        first = g.texture(table_image(), u, v, label=label)
        if self.mixer is None:
            return first
        return self.mixer.mix(first, g.texture(table_image(), u, g.add(v, self.mixer.step_v),
                                               label=f"{label}, next key"), label)


def sky_view(g: GraphBuilder, view: Socket, sun: Socket, blend: bool = False) -> tuple[Socket, Socket]:
    """(radiance, ground transmittance) of the frame's sky view (``physics.precise.sky_view``, sampled as
    ``physics.precise.lighting_from_tile``): one filtered lookup each in the tile's sky-view block,

        z_h = -sqrt(h_c (2 R + h_c)) / (R + h_c)                                   the horizon's zenith cosine
        row = K + (N - 1 - K) sqrt((v_z - z_h) / (1 - z_h))        above the horizon (the sky's rows)
              (K - 1) - (K - 1) sqrt((z_h - v_z) / (1 + z_h))      below it (the ground's K rows)
        column = azimuth from the sun (N_s - 1) / pi
        radiance = image(x0 + offset + 0.5 + column, y0 + 0.5 + row),   transmittance: the block's last column

    (Cycles' Linear lookup; the coordinates stay within one side's texel centres, so neither the other side of the
    horizon nor a neighbouring block bleeds in). With ``blend`` each lookup is blended with the next key tile's
    (:class:`KeyBlend`; the rows follow the frame's camera altitude)."""
    ray = _ViewLookup(g, view, sun, blend, "sky view")
    horizon = ray.sin_dip
    above = g.add(ray.vz, horizon, label="v_z - z_h")
    k, n = DEFAULT_SHAPE.sky_ground_rows, ALTITUDES
    sky_row = g.multiply_add(g.sqrt(g.div(g.max(above, 0.0), g.add(horizon, 1.0))), float(n - 1 - k), float(k),
                             label="sky row")
    ground_row = g.multiply_add(g.sqrt(g.div(g.max(g.neg(above), 0.0), g.sub(1.0, horizon))), float(1 - k),
                                float(k - 1), label="ground row")
    row = g.select(g.less_than(above, 0.0, label="below the horizon"), ground_row, sky_row, label="sky view row")
    v = g.div(g.add(g.add(ray.y0, 0.5), row), ray.height, label="v (sky view)")
    start = g.add(ray.x0, DEFAULT_SHAPE.sky_view_offset + 0.5, label="sky view x0")
    return (ray.lookup(g.add(start, ray.column), v, "sky view"),
            ray.lookup(g.add(start, float(DEFAULT_SHAPE.sky_azimuths)), v, "ground transmittance"))


def camera_sky_view(g: GraphBuilder, view: Socket, sun: Socket, mu: Socket,
                    blend: bool = False) -> tuple[Socket, Socket]:
    """(radiance, elevation above the horizon in rad) of the frame's camera sky view
    (``physics.precise.camera_sky_view``, sampled as ``physics.precise.camera_sky_from_tile``): two filtered lookups
    in the tile's last blocks,

        e_h = asin(-sqrt(h_c (2 R + h_c)) / (R + h_c))                        the horizon's elevation
        row = (N - 1) sqrt(max(asin(v_z) - e_h, 0) / (pi/2 - e_h)),   column = azimuth from the sun (N_s - 1) / pi
        radiance = image(x0 + Rayleigh offset + 0.5 + column, ...) + Phi_HG(mu, g) image(x0 + Mie offset + ...)

    (Cycles' Linear lookup; row 0 at and below the horizon, where the world shows the table's own sky). With
    ``blend`` each lookup is blended with the next key tile's (:class:`KeyBlend`)."""
    ray = _ViewLookup(g, view, sun, blend, "camera sky")
    horizon = g.arcsin(ray.sin_dip, label="-e_h")   # minus the horizon's elevation
    above = g.add(g.arcsin(ray.vz, label="e"), horizon, label="e - e_h")
    row = g.mul(g.sqrt(g.div(g.max(above, 0.0), g.add(horizon, 0.5 * math.pi))), float(ALTITUDES - 1),
                label="camera sky row")
    v = g.div(g.add(g.add(ray.y0, 0.5), row), ray.height, label="v (camera sky)")
    start = g.add(g.add(ray.x0, ray.column), DEFAULT_SHAPE.camera_sky_offset + 0.5, label="camera sky x")
    rayleigh = ray.lookup(start, v, "camera sky, Rayleigh")
    mie = ray.lookup(g.add(start, float(DEFAULT_SHAPE.sky_azimuths)), v, "camera sky, Mie")
    phase = phase_henyey_greenstein(g, mu, g.attribute(parameters.MIE_G))
    return g.multiply_add(mie, phase, rayleigh, label="camera sky"), above


def tile_camera(g: GraphBuilder) -> tuple[Socket, Socket, Socket]:
    """(h_c, top, R) in m: the tile's camera altitude, the table's top and the planet radius (parameters)."""
    _, _, h_c = g.separate(g.attribute(parameters.PRECISE_TILE, output="Vector"), label="tile h_c")
    _, top, _ = g.separate(g.attribute(parameters.PRECISE_SCALE, output="Vector"), label="scale top")
    return h_c, top, g.attribute(parameters.PLANET_RADIUS, output="Fac")


def table_column_graph(g: GraphBuilder, s: Socket, row: Socket, h_c: Socket, top: Socket, d_max: Socket,
                       vertical: Socket) -> Socket:
    """The distance column of a point s m along the view in table row ``row`` (module docstring;
    ``physics.precise.table_coordinates``): the row's columns start at its vertical ray, d_min = |h_row - h_c| with
    h_row = top (row / (N_h - 1))^3, where ``vertical`` is 1 (0: at the camera), spaced by the row's power p."""
    u = g.div(row, float(ALTITUDES - 1), label="u = row / (N_h - 1)")
    h_row = g.mul(g.mul(g.mul(u, u), u), top, label="h_row = top u^3")
    d_min = g.mul(g.abs(g.sub(h_row, h_c)), vertical, label="d_min = |h_row - h_c|")
    span = g.max(g.sub(d_max, d_min), 1.0, label="D - d_min")
    power = g.multiply_add(vertical, g.sub(1.0, u), 2.0, label="p = 2 + vertical (1 - u)")
    return g.mul(g.min(g.pow(g.div(g.max(g.sub(s, d_min), 0.0), span), g.div(1.0, power)), 1.0),
                 float(DISTANCES - 1), label="col")


TABLE_COLUMN = parts.define(
    "Atmos Table Column", 1,
    (("s", parts.FLOAT), ("row", parts.FLOAT), ("h_c", parts.FLOAT), ("top", parts.FLOAT), ("D", parts.FLOAT),
     ("vertical", parts.FLOAT)),
    (("col", parts.FLOAT),), table_column_graph,
    description="The Precise table's distance column of a point s m along the view in a row")


class PreciseLookup:
    """The frame's table read at one point s m along ``view`` (module docstring): its row and column, the
    bilinear texel blend there (:class:`_Bilinear`), and the transmittance F_ex = exp(-tau) with 1 - F_ex (s taken
    at most to the top of the atmosphere, :func:`distance_to_top`, or ``to_top`` where the caller has it: a surface
    out in space shows the sky behind it). ``whole_row``: the table row where the caller knows it is a whole number
    (the sky: the top row, or row 0 where the ray meets the ground), which skips the target altitude and half the
    texel fetches. ``features.blend``: every texel blends the frame's two key tiles (:class:`KeyBlend`)."""

    def __init__(self, g: GraphBuilder, features, s: Socket, view: Socket, to_top: Socket | None = None,
                 whole_row: Socket | None = None):
        self.g, self.features, self.view = g, features, view
        self.vx, self.vy, vz = g.separate(view, label="v")
        x0, y0, h_c = g.separate(g.attribute(parameters.PRECISE_TILE, output="Vector"), label="tile (x0, y0, h_c)")
        d_max, top, _ = g.separate(g.attribute(parameters.PRECISE_SCALE, output="Vector"), label="scale (D, top)")
        width, height, vertical = g.separate(g.attribute(parameters.PRECISE_ATLAS, output="Vector"),
                                             label="atlas (W, H, vertical columns)")
        radius = g.attribute(parameters.PLANET_RADIUS, output="Fac")
        to_top = to_top if to_top is not None else distance_to_top(g, vz, h_c, top, radius)
        s = g.min(g.max(s, 0.0), to_top, label="s, at most to the top")
        if whole_row is None:
            r_c = g.add(radius, h_c, label="r_c")
            rise = g.mul(g.multiply_add(g.mul(r_c, 2.0), vz, s), s, label="rise = (2 r_c v_z + s) s")
            r_p = g.sqrt(g.max(g.multiply_add(r_c, r_c, rise), 0.0), label="r_p")
            h_p = g.add(h_c, g.div(rise, g.add(r_p, r_c)), label="h_p")
            fraction = g.min(g.max(g.div(h_p, top), 0.0), 1.0, label="h_p / top")
            row = g.mul(g.pow(fraction, 1.0 / 3.0), float(ALTITUDES - 1), label="row")
        else:
            row = whole_row
        column = g.call(TABLE_COLUMN, s, row, h_c, top, d_max, vertical, label="col")
        self.bilinear = _Bilinear(g, x0, y0, column, row, width, height, whole_row=whole_row is not None,
                                  blend=KeyBlend(g, height) if features.blend else None)
        tau = g.scale(self.bilinear.sample(0.0, "tau / s"), s, label="tau")
        self.f_ex = g.per_channel(g.exp, g.neg(tau), label="F_ex")
        self.one_minus_t = g.mul(tau, phi1_exact(g, tau, self.f_ex), label="1 - exp(-tau)")

    def light(self) -> Socket:
        """Phi_R A_R + Phi_HG A_M at the point: the in-scattered light per unit of 1 - F_ex (module docstring), its
        two azimuth slices blended."""
        g, view, vx, vy = self.g, self.view, self.vx, self.vy
        sun = sun_direction(g)
        sx, sy, _ = g.separate(sun, label="l")
        azimuth = g.mul(azimuth_from_sun(g, vx, vy, sx, sy), (AZIMUTHS - 1) / math.pi, label="a")
        a0 = g.min(g.floor(azimuth), float(AZIMUTHS - 2), label="a0")
        fa = g.sub(azimuth, a0, label="a - a0")
        slice_offset = g.mul(a0, float(DISTANCES), label="a0 N_d")

        def block(offset: int, name: str) -> Socket:
            low = self.bilinear.sample(g.add(slice_offset, float(offset)), f"{name} (a0)")
            high = self.bilinear.sample(g.add(slice_offset, float(offset + DISTANCES)), f"{name} (a0 + 1)")
            return _lerp(g, low, high, fa, name)

        nu = cos_theta_to_sun(g, view, sun)
        light = g.scale(block(DISTANCES, "A_R"), phase_rayleigh(g, nu), label="Phi_R A_R")
        if self.features.mie:
            mie = g.mul(block(DISTANCES * (1 + AZIMUTHS), "A_M"),
                        phase_henyey_greenstein(g, nu, g.attribute(parameters.MIE_G)), label="Phi_HG A_M")
            light = g.add(light, mie, label="Phi_R A_R + Phi_HG A_M")
        return light


def precise_terms(g: GraphBuilder, features, s: Socket, view: Socket, to_top: Socket | None = None,
                  whole_row: Socket | None = None) -> tuple[Socket, Socket]:
    """(F_ex, L_in) sampled from the frame's table (:class:`PreciseLookup`): L_in = (Phi_R A_R + Phi_HG A_M)
    (1 - F_ex)."""
    lookup = PreciseLookup(g, features, s, view, to_top, whole_row)
    return lookup.f_ex, g.mul(lookup.light(), lookup.one_minus_t, label="L_in")
