# SPDX-License-Identifier: GPL-3.0-or-later
"""The "Atmos Sky" world node group: the virtual-dome sky, the sun's disk and the ground, as nodes.

Per view direction v (-(Geometry > Incoming) in the world shader: the camera ray's direction), per channel,
for a camera on the ground (Hoffman & Preetham 2002, GDC slides "Virtual sky dome"; the numpy reference
is ``atmos_addon.physics.sky.sky_radiance`` with ``dome=dome_distance_approx``):

    R_R, R_M = dome distances of :mod:`.dome` (elevation clamped at the horizon)
    a        = min(R_R, R_M),  t_R = R_R - a,  t_M = R_M - a      the layered dome: both species, then the longer
    tau(x_R, x_M) = beta_R x_R + (beta_M + beta_M,abs) x_M
    L(x_R, x_M)   = (beta_R Phi_R(mu) x_R + beta_M Phi_HG(mu, g) x_M) phi1(tau(x_R, x_M))            mu = v . l
    L_sky    = E_sun [L(a, a) + exp(-tau(a, a)) L(t_R, t_M)]
    F_ex     = exp(-tau(a, a)) exp(-tau(t_R, t_M))
    L_ground = albedo E_sun max(l_z, 0) / pi F_ex                 below the horizon (v_z < 0), ground "ALBEDO"
    L_disk   = E_sun / Omega  (1 - u (1 - mu_e)) / (1 - u / 3)     inside the disk, above the horizon,
               Omega = 4 pi sin^2(r / 2),  mu_e = sqrt(1 - (sin t / sin r)^2),  sin t = |v x l|

The scattering is the aerial group's own ``scattering_terms`` with b_i = R_i (s -> infinity), so a black
surface beyond both domes composites to exactly this sky and a nearer one to less.

At the Precise level (``SkyFeatures.level == "precise"``) the scattering comes instead from the frame's Precise
table (:mod:`.precise`, the aerial group's own ``precise_terms``) at the length of the whole ray, to the top of
the atmosphere or to the spherical ground where the ray meets it (:func:`sky_path_length`; the numpy reference is
``physics.precise.sky_from_tile``): single scattering through the curved exponential atmosphere with the sun
seen from every point (and the multiple-scattering term when baked), about 1 % from the brute-force sky on
average where the dome sky is 7-77 % off. The ground is then lit where the ray meets it, and a far surface's
Precise in-scattering tends to this sky as its distance reaches the path's (the same table cells).
E_sun is the sun's irradiance at the ground (the aerial group's parameter): the sky, the haze in front of
surfaces and the sun lamp share it. The disk (angular radius r, linear limb darkening u, 0 for a uniform
disk; its mean over the disk is 1 - u/3 for a small disk) integrates to E_sun; it is shown to camera rays
only, because the sun lamp (angle = the disk's diameter, strength and colour from the same E_sun) already
lights diffuse and glossy surfaces: the disk on other rays would count the sun twice. Every term uses the
scene-property parameters of :mod:`.parameters`; the tree depends only on :class:`SkyFeatures`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import bpy
import numpy as np

from . import parameters, parts, stamps
from .terms import AerialFeatures, scattering_terms
from .dome import cos_theta_to_sun, dome_distances, sun_direction, view_direction
from .graph import ArrayBuilder, GraphBuilder, Socket
from .precise import ALTITUDES, distance_to_top, precise_terms, tile_camera

#: Name of the world node group in ``bpy.data.node_groups``.
SKY_GROUP_NAME = stamps.SKY.name
#: Bump when the tree a given feature set builds changes; stale trees are rebuilt in place.
OUTPUT_RADIANCE = "Radiance"
GROUND_MODES = ("ALBEDO", "BLACK")
#: Where the scattering comes from: the virtual dome ("fast", every level but Precise) or the Precise level's table.
SKY_LEVELS = ("fast", "precise")


@dataclass(frozen=True)
class SkyFeatures:
    """Which optional terms the sky contains: Mie scattering, Mie absorption, the lit ground below the horizon.

    ``ground`` is "ALBEDO" (a Lambertian ground lit by the sun, seen through the horizon's haze) or "BLACK"
    (only the horizon's haze below the horizon: ``sky_radiance`` with albedo 0).
    """

    mie: bool = True
    absorption: bool = True
    ground: str = "ALBEDO"
    level: str = "fast"
    #: The Precise sky blends two key tiles (:class:`~.terms.AerialFeatures`' ``blend``).
    blend: bool = False

    def __post_init__(self) -> None:
        if self.ground not in GROUND_MODES:
            raise ValueError(f"SkyFeatures.ground must be one of {GROUND_MODES}; got {self.ground!r}")
        if self.level not in SKY_LEVELS:
            raise ValueError(f"SkyFeatures.level must be one of {SKY_LEVELS}; got {self.level!r}")
        if self.blend and self.level != "precise":
            raise ValueError(f"SkyFeatures.blend needs the precise level; got {self.level!r}")

    @classmethod
    def from_key(cls, key: str) -> "SkyFeatures":
        """The features a :attr:`key` names (a stamped group's, to rebuild it as it was)."""
        tokens = set(str(key).split("+"))
        return cls(mie="mie" in tokens, absorption="abs" in tokens, ground="ALBEDO" if "ground" in tokens else "BLACK",
                   level="precise" if "precise" in tokens else "fast", blend="precise" in tokens and "blend" in tokens)

    @property
    def aerial(self) -> AerialFeatures:
        """The scattering terms, as the aerial group names them."""
        return AerialFeatures(mie=self.mie, absorption=self.absorption, level=self.level, blend=self.blend)

    @property
    def key(self) -> str:
        """A stable short name stamped on the tree, e.g. "rayleigh+mie+abs+ground", "rayleigh+mie+precise+ground"."""
        terms = AerialFeatures(mie=self.mie, absorption=self.absorption).key
        return (terms + ("+precise" if self.level == "precise" else "") + ("+blend" if self.blend else "")
                + ("+ground" if self.ground == "ALBEDO" else ""))

    @property
    def dome(self) -> "SkyFeatures":
        """The same terms on the virtual dome (what the lighting table of :mod:`.sky_lighting` factorises)."""
        return dataclasses.replace(self, level="fast", blend=False)


# -- the quantities ------------------------------------------------------------------------------------


def sun_disk(g: GraphBuilder, view: Socket, view_z: Socket, sun: Socket, mu: Socket) -> Socket:
    """L_disk per channel (:func:`sun_disk_graph`), one instance of its part."""
    return g.call(SUN_DISK, view, view_z, sun, mu, label="L_disk")


def sun_disk_graph(g: GraphBuilder, view: Socket, view_z: Socket, sun: Socket, mu: Socket) -> Socket:
    """L_disk per channel: E_sun / Omega times the limb darkening, inside the disk, above the horizon, camera rays.

    The offset from the disk centre uses sin t = |v x l| (1 - mu^2 loses all precision for t ~ 0.005 rad in
    float32). Inside: sin t < sin r and mu > 0.
    """
    radius = g.attribute(parameters.SUN_ANGULAR_RADIUS, output="Fac", label="r")
    sin_r = g.sine(radius, label="sin r")
    sin_t = g.length(g.cross(view, sun, label="v x l"), label="sin t")
    inside = g.mul(g.less_than(sin_t, sin_r), g.greater_than(mu, 0.0), label="in disk")
    above = g.greater_than(view_z, 0.0, label="above horizon")
    camera = g.shading_input("is_camera_ray", label="Light Path")
    mask = g.mul(g.mul(inside, above), camera, label="disk mask")
    sin_half = g.sine(g.mul(radius, 0.5), label="sin(r/2)")
    solid_angle = g.mul(g.mul(sin_half, sin_half), 4.0 * math.pi, label="Omega")
    rho = g.div(sin_t, g.max(sin_r, 1.0e-9), label="sin t / sin r")
    mu_e = g.sqrt(g.max(g.sub(1.0, g.mul(rho, rho)), 0.0), label="mu_e")
    u = g.attribute(parameters.SUN_LIMB_DARKENING, output="Fac", label="u")
    darkening = g.multiply_add(u, g.sub(mu_e, 1.0), 1.0, label="1 - u (1 - mu_e)")
    mean = g.multiply_add(u, -1.0 / 3.0, 1.0, label="1 - u/3")
    profile = g.div(g.mul(darkening, mask), g.mul(mean, g.max(solid_angle, 1.0e-30)), label="disk / Omega")
    return g.scale(g.attribute(parameters.SUN_IRRADIANCE), profile, label="L_disk")


SUN_DISK = parts.define(
    "Atmos Sun Disk", 1, (("v", parts.VECTOR), ("v_z", parts.FLOAT), ("l", parts.VECTOR), ("mu", parts.FLOAT)),
    (("L_disk", parts.VECTOR),), sun_disk_graph,
    description="The sun's disk: E_sun / Omega with limb darkening, inside the disk, above the horizon, camera rays")


def ground(g: GraphBuilder, below: Socket, sun_z: Socket, f_ex: Socket) -> Socket:
    """L_ground exp(-tau) where ``below`` is 1 (the ray meets the ground): albedo E_sun max(l_z, 0) / pi seen
    through the haze in front of it."""
    lit = g.mul(g.max(sun_z, 0.0), 1.0 / math.pi, label="max(l_z, 0) / pi")
    radiance = g.scale(g.mul(g.attribute(parameters.GROUND_ALBEDO), g.attribute(parameters.SUN_IRRADIANCE)), lit,
                       label="L_ground")
    return g.scale(g.mul(radiance, f_ex), below, label="L_ground F_ex")


def sky_path_length(g: GraphBuilder, view_z: Socket) -> tuple[Socket, Socket, Socket]:
    """(length m, 1 where the ray meets the ground, the distance to the top m) (:func:`sky_path_length_graph`), one
    instance of its part."""
    return g.call(SKY_PATH_LENGTH, view_z, label="path length")


def sky_path_length_graph(g: GraphBuilder, view_z: Socket) -> tuple[Socket, Socket, Socket]:
    """(length m, 1 where the ray meets the ground, the distance to the top m) from the Precise tile's camera
    along a ray with zenith cosine ``view_z``: to the ground, else to the top of the atmosphere;
    ``physics.precise.sky_path_length`` node for node (its docstring has the cancellation-free forms)."""
    h_c, top, radius = tile_camera(g)
    r_c_c = g.mul(g.add(radius, h_c, label="r_c"), view_z, label="r_c c")
    ground_term = g.mul(h_c, g.add(g.mul(radius, 2.0, label="2 R"), h_c), label="G = h_c (2 R + h_c)")
    ground_disc = g.sub(g.mul(r_c_c, r_c_c), ground_term, label="(r_c c)^2 - G")
    hits = g.mul(g.less_than(view_z, 0.0), g.sub(1.0, g.less_than(ground_disc, 0.0)), label="meets the ground")
    to_ground = g.div(ground_term, g.max(g.sub(g.sqrt(g.max(ground_disc, 0.0)), r_c_c), 1.0), label="to the ground")
    to_top = distance_to_top(g, view_z, h_c, top, radius)
    return g.max(g.select(hits, to_ground, to_top), 0.0, label="path length"), hits, to_top


SKY_PATH_LENGTH = parts.define(
    "Atmos Sky Path Length", 1, (("v_z", parts.FLOAT),),
    (("Length", parts.FLOAT), ("Meets the Ground", parts.FLOAT), ("To the Top", parts.FLOAT)), sky_path_length_graph,
    description="From the Precise tile's camera along the view: to the ground, else to the top of the atmosphere (m)")


# -- the group ---------------------------------------------------------------------------------------


def ensure_radiance_output(tree: bpy.types.ShaderNodeTree, description: str) -> None:
    """Add the Radiance output if missing (an existing socket, and the links to it, are kept)."""
    present = {item.name for item in tree.interface.items_tree
               if item.item_type == "SOCKET" and item.in_out == "OUTPUT"}
    if OUTPUT_RADIANCE not in present:
        socket = tree.interface.new_socket(OUTPUT_RADIANCE, in_out="OUTPUT", socket_type="NodeSocketColor")
        socket.description = description


@dataclass(frozen=True)
class SkyRay:
    """The per-ray inputs every sky graph starts from: v, its z component, l and mu = v . l."""

    view: Socket
    view_z: Socket
    sun: Socket
    mu: Socket


def start_radiance_graph(tree: bpy.types.ShaderNodeTree, description: str) -> tuple[GraphBuilder, SkyRay]:
    """Clear ``tree``'s nodes (interface kept, the Radiance output described by ``description``) and start a sky
    graph: the builder and the ray's inputs. :func:`finish_radiance_group` ends it."""
    tree.nodes.clear()
    ensure_radiance_output(tree, description)
    g = GraphBuilder(tree)
    return g, sky_ray(g)


def sky_ray(g: GraphBuilder) -> SkyRay:
    """The ray's inputs on any builder: v from the shading point, l from the parameters, mu = v . l."""
    view = view_direction(g)
    _, _, view_z = g.separate(view, label="v")
    sun = sun_direction(g)
    return SkyRay(view, view_z, sun, cos_theta_to_sun(g, view, sun))


def build_sky(tree: bpy.types.ShaderNodeTree, features: SkyFeatures) -> None:
    """Clear ``tree``'s nodes and build the sky graph for ``features`` (interface kept)."""
    g, ray = start_radiance_graph(
        tree, "Sky radiance along the view ray (sky, sun disk, ground): feed a Background shader")
    finish_radiance_group(g, sky_radiance(g, features, ray), stamps.SKY, features)


def evaluate(features: SkyFeatures, parameter_values, *, view_direction, is_camera_ray=1.0, images=None):
    """What the group computes, in numpy float32: the radiance (N, 3) along the unit ``view_direction`` (N, 3)
    (``is_camera_ray`` 0 hides the sun's disk, as for the rays that light the scene); ``parameter_values`` are
    :func:`~.parameters.shader_parameter_values`, ``images`` the Precise table's pixels by image name."""
    direction = np.asarray(view_direction, dtype=np.float64)
    camera = np.broadcast_to(np.asarray(is_camera_ray, dtype=np.float32), direction.shape[:-1])
    g = ArrayBuilder(parameter_values, {"incoming": -direction, "is_camera_ray": camera}, images)
    radiance = sky_radiance(g, features, sky_ray(g))
    return np.broadcast_to(g.array(radiance), direction.shape)


def sky_radiance(g: GraphBuilder, features: SkyFeatures, ray: SkyRay) -> Socket:
    """The sky's radiance along ``ray`` for ``features`` on any builder: the dome or Precise sky, the sun's disk
    and, with ``ground="ALBEDO"``, the lit ground below the horizon."""
    view, view_z, sun, mu = ray.view, ray.view_z, ray.sun, ray.mu
    if features.level == "precise":
        length, below, to_top = sky_path_length(g, view_z)
        top_row = g.mul(g.sub(1.0, below), float(ALTITUDES - 1), label="row: the top, or 0 on the ground")
        f_ex, radiance = precise_terms(g, features.aerial, length, view, to_top, whole_row=top_row)
    else:
        r_rayleigh, r_mie = dome_distances(g, view_z)
        haze = features.mie or features.absorption  # as the aerial group: one species, one slab, without haze
        f_ex, radiance = scattering_terms(g, features.aerial, r_rayleigh, r_mie if haze else None, mu)
        below = None
    radiance = g.add(radiance, sun_disk(g, view, view_z, sun, mu), label="sky + disk")
    if features.ground == "ALBEDO":
        _, _, sun_z = g.separate(sun, label="l")
        below = below if below is not None else g.less_than(view_z, 0.0, label="below horizon")
        radiance = g.add(radiance, ground(g, below, sun_z, f_ex), label="sky + disk + ground")
    return radiance


def finish_radiance_group(g: GraphBuilder, radiance: Socket, kind: stamps.GroupKind, features: SkyFeatures) -> None:
    """Link ``radiance`` to the Radiance output, lay the tree out and stamp it as ``kind``'s for ``features``."""
    output = g.node("NodeGroupOutput", label="Group Output")
    g.tree.links.new(radiance, output.inputs[OUTPUT_RADIANCE])
    g.set_depth(output, g.max_depth + 1)
    g.layout()
    stamps.stamp(g.tree, kind, features.key)


def is_current(tree: bpy.types.NodeTree, features: SkyFeatures) -> bool:
    """True if ``tree`` was built by this version for ``features``."""
    return stamps.is_current(tree, stamps.SKY, features.key)


def ensure_sky_group(features: SkyFeatures = SkyFeatures()) -> bpy.types.ShaderNodeTree:
    """Get or create the "Atmos Sky" group, rebuilt in place only if stale (worlds keep their links)."""
    tree = stamps.group(stamps.SKY)
    if not is_current(tree, features):
        build_sky(tree, features)
    return tree


#: Nodes in the sky group per feature key for this version (:data:`.stamps.SKY`; group output included).
SKY_NODE_COUNTS = {"rayleigh": 75, "rayleigh+ground": 86, "rayleigh+abs": 100, "rayleigh+abs+ground": 111,
                   "rayleigh+mie": 126, "rayleigh+mie+ground": 137, "rayleigh+mie+abs": 128,
                   "rayleigh+mie+abs+ground": 139,
                   "rayleigh+precise": 201, "rayleigh+precise+ground": 211, "rayleigh+abs+precise": 201,
                   "rayleigh+abs+precise+ground": 211, "rayleigh+mie+precise": 248,
                   "rayleigh+mie+precise+ground": 258, "rayleigh+mie+abs+precise": 248,
                   "rayleigh+mie+abs+precise+ground": 258,
                   **{f"{terms}+precise+blend{ground}": count
                      for terms, counts in (("rayleigh", (230, 240)), ("rayleigh+abs", (230, 240)),
                                            ("rayleigh+mie", (293, 303)), ("rayleigh+mie+abs", (293, 303)))
                      for ground, count in zip(("", "+ground"), counts)}}
