# SPDX-License-Identifier: GPL-3.0-or-later
"""The per-pixel combination of the render with the atmosphere, and the "Atmos Aerial Composite" group (the
Compositor mode's).

A pixel of the render is a filtered sum over its samples. The materials write, per sample and weighted by the
surface's opacity a_i, what the atmosphere does to it (the Compositor mode: F_ex and L_in; the Per Pixel mode: the
distance and direction, from which the compositor evaluates them), the world writes its own coverage, and the render
gives the sky it shows (the Environment pass). So per pixel

    C = sum a_i                  the Atmos surfaces' coverage     S = the sky the pixel shows (Environment)
    T = sum a_i T_i              their transmittance              A = the render's alpha
    L = sum a_i L_i              their in-scattering
    P = Image - S                the surfaces' radiance, sum a_i I_i

and the exact result, sum a_i (I_i T_i + L_i) + S, would need I_i T_i per sample. :func:`combine` forms

    C' = min(C, A),  w = C' / C        a holdout object's hole (alpha 0) stays a hole, its AOVs notwithstanding
    out = S + P w T / C' + w L / max(C', 1) + w K      (S + P, the render itself, where C' = 0)

which is exact for a pixel of one surface, however much sky it shows (the sky passes through untouched: no dark
or light outline along a ridge), and for every pixel of the sky. A surface Atmos does not manage (an object without
a material) writes no AOVs: alone in a pixel it passes through untouched; sharing one with a managed surface it
takes that surface's atmosphere. Where two surfaces n, f share a pixel (coverages
c_n, c_f), P T / C misses the product of their differences,

    K = c_n c_f / C (T_n - T_f) (I_n - I_f),

for which the compositor has the two transmittances (:func:`two_point`: the pixel's samples' values reconstructed
as two, with their shares, from their first three moments) but not the two radiances: :func:`neighbour_slope`
reads I_n - I_f off the 3 x 3 pixels around, each a mix of the same two surfaces in other shares (the slope of
their radiance against their share, by least squares), bounded so that neither radiance it implies is negative.
docs/silhouettes.md measures what is left (pixels that mix three surfaces or more, textures that change within a
pixel). The Compositor mode's group reconstructs the transmittance per colour channel from the per-sample moments
T, sum a_i T_i^2 and sum a_i T_i^3; the Per Pixel group (:mod:`.per_pixel`) reconstructs the distance and
evaluates the atmosphere at both.

Film > Transparent: the render shows no sky (Image is the surfaces alone, premultiplied) while the Environment pass
still holds it, so S is the Environment times 1 - the Film Transparent input (driven from the scene). The add-on
feeds every input when it updates a file saved before they existed (``blender.apply.compositor.link_inputs``);
Blender 4.5 composites with its own Math nodes, 5.0 with the shader's (:class:`.graph.CompositorBuilder` builds
either).
"""

from __future__ import annotations

import bpy

from . import parts, stamps
from .graph import CompositorBuilder, Operand, is_vector

#: The group's interface: (name, in/out, socket type).
INTERFACE = (("Image", "OUTPUT", "NodeSocketColor"), ("Image", "INPUT", "NodeSocketColor"),
             ("Environment", "INPUT", "NodeSocketColor"), ("Film Transparent", "INPUT", "NodeSocketFloat"),
             ("Alpha", "INPUT", "NodeSocketFloat"),
             ("Coverage", "INPUT", "NodeSocketFloat"), ("Transmittance", "INPUT", "NodeSocketColor"),
             ("Transmittance Squared", "INPUT", "NodeSocketColor"),
             ("Transmittance Cubed", "INPUT", "NodeSocketColor"), ("Inscattering", "INPUT", "NodeSocketColor"))
#: The spread of a pixel's values below which they are read as one value, as a share of their mean square: Eevee
#: writes its AOVs as half floats (11 bits: a mean square and a squared mean of one value then differ by up to 1e-3
#: of it, measured), which would otherwise read as two values.
MOMENT_ROUNDING = 2e-3
#: The largest skewness |mu_3| / sigma^3 of the two-point reconstruction (a bound on what rounding can make of it).
MAX_SKEW = 8.0
#: The least spread of the neighbours' shares f (their weighted variance over their weight) a slope is read from.
SPREAD_FLOOR = 0.01
#: Covers below this are no cover (a guard for divisions).
TINY = 1e-12


def _sqrt(g, value: Operand):
    """sqrt per component (a colour) or of a scalar."""
    return g.power_per_channel(value, 0.5, label="sqrt") if is_vector(value) else g.sqrt(value)


def two_point(g, coverage: Operand, first: Operand, second: Operand, third: Operand):
    """(share_lo, share_hi, lo, hi): the two values and their shares (of the coverage) whose coverage-weighted sums
    of x, x^2 and x^3 are ``first``, ``second`` and ``third`` over ``coverage`` = sum a_i: the pixel's samples read
    as two values, exact where it holds two (the Gauss quadrature of two nodes for those moments). Per component
    for colours. With the mean mu, variance v and third central moment k3 of the values, the two lie b below and
    a above the mean with a - b = k3 / v and a b = v, and their shares balance the mean (p_hi a = p_lo b). A variance
    v_raw under t = :data:`MOMENT_ROUNDING` times the mean square reads as one value (share_lo 1, lo = hi = mu); above
    it, v = v_raw - t^2 / v_raw, continuous at t and within t^2 / v_raw of the raw variance, so that two values well
    apart keep their full spread (subtracting t itself would shrink every pixel's two transmittances towards each
    other, and the correction with them)."""
    mean = g.div(first, g.max(coverage, TINY), label="mu")
    square = g.div(second, g.max(coverage, TINY), label="mu_2")
    cube = g.div(third, g.max(coverage, TINY), label="mu_3")
    raw = g.sub(square, g.mul(mean, mean), label="v (raw)")
    rounding = g.mul(square, MOMENT_ROUNDING, label="t")
    variance = g.max(g.sub(raw, g.div(g.mul(rounding, rounding), g.max(raw, TINY))), 0.0, label="v")
    skew = g.sub(cube, g.mul(mean, g.sub(g.mul(square, 3.0), g.mul(g.mul(mean, mean), 2.0))), label="k3")
    spread = _sqrt(g, variance)
    bound = g.mul(spread, MAX_SKEW)
    difference = g.min(g.max(g.div(skew, g.max(variance, TINY)), g.neg(bound)), bound, label="a - b")
    root = _sqrt(g, g.add(g.mul(difference, difference), g.mul(variance, 4.0)))
    above = g.mul(g.add(difference, root), 0.5, label="a")
    below = g.mul(g.sub(root, difference), 0.5, label="b")
    share_hi = g.div(below, root, label="p_hi")        # 0 where root = 0: one value
    return g.sub(1.0, share_hi, label="p_lo"), share_hi, g.sub(mean, below, label="lo"), g.add(mean, above, label="hi")


def neighbour_slope(g, radiance: Operand, coverage: Operand, position: Operand, lo: Operand, hi: Operand,
                    share_lo: Operand, share_hi: Operand):
    """I_hi - I_lo: how the surfaces' radiance I = P / C (``radiance`` / ``coverage``, a colour) of the 3 x 3 pixels
    around changes with their share f = (m - lo) / (hi - lo) of the centre's ``hi`` value, m = x / C their own mean
    value (``position`` / ``coverage``, in the units of ``lo`` and ``hi``; a colour for per-channel values): the
    least-squares slope, each pixel weighted by its coverage (the sky's pixels carry none) and by the Soften weights
    (1 2 1)^T (1 2 1) / 16. Its sums are five weighted averages <.> over the neighbourhood, each one Filter node
    (:meth:`.graph.CompositorBuilder.soften`; all of non-negative values but the radiance, whose average is read
    as 0 where noise on a black surface makes it negative):

        W = <C>,  X = <x>,  Q = <x^2 / C>,  R = <P>,  Y = <x P / C>
        var = Q - X^2 / W    (W times the coverage-weighted variance of m)
        cov = Y - R X / W    (W times the covariance of m and I)
        slope = cov (hi - lo) / var

    damped where the shares hardly differ (var (hi - lo)^-2 under :data:`SPREAD_FLOOR` W), and bounded so that
    neither radiance it implies for the centre, I_lo = I - p_hi slope and I_hi = I + p_lo slope (I the centre's
    mean radiance), is negative."""
    reach = g.div(1.0, g.sub(hi, lo), label="1 / (hi - lo)")   # 0 where hi = lo: no slope
    squares = g.div(g.mul(position, position), coverage, label="x^2 / C")
    if is_vector(position):
        total = g.soften(coverage, label="W")
        first, second = g.soften(position, label="X"), g.soften(squares, label="Q")
    else:
        total, first, second = g.separate(g.soften(g.combine(coverage, position, squares), label="W, X, Q"))
    mean_radiance = g.soften(radiance, label="R")
    cross = g.soften(g.div(g.mul(position, radiance), coverage, label="x P / C"), label="Y")
    total = g.max(total, TINY)
    variance = g.sub(second, g.div(g.mul(first, first), total), label="var")
    covariance = g.sub(cross, g.mul(mean_radiance, g.div(first, total)), label="cov")
    spread = g.max(g.mul(variance, g.mul(reach, reach)), g.mul(total, SPREAD_FLOOR), label="var f")
    slope = g.div(g.mul(covariance, reach), spread, label="I_hi - I_lo")
    centre = g.div(radiance, g.max(coverage, TINY), label="I")
    return g.min(g.max(slope, g.neg(g.div(centre, share_lo))), g.div(centre, share_hi), label="slope, bounded")


def correction(g, coverage: Operand, share_lo: Operand, share_hi: Operand, t_lo: Operand, t_hi: Operand,
               slope: Operand):
    """K = C p_lo p_hi (T_hi - T_lo) (I_hi - I_lo): what P T / C misses where two surfaces share a pixel."""
    shares = g.mul(g.mul(share_lo, share_hi), coverage)
    difference = g.sub(t_hi, t_lo)
    return g.mul(g.mul(difference, slope), shares)


def _slope_correction(g, radiance, coverage, position, share_lo, share_hi, lo, hi, t_lo, t_hi):
    """K (:func:`correction`) with the slope of the radiance (:func:`neighbour_slope`) read off the neighbours."""
    slope = neighbour_slope(g, radiance, coverage, position, lo, hi, share_lo, share_hi)
    return correction(g, coverage, share_lo, share_hi, t_lo, t_hi, slope)


def _two_point_part(name: str, kind: str) -> parts.Part:
    return parts.define(name, 2, (("Coverage", parts.FLOAT), ("First", kind), ("Second", kind), ("Third", kind)),
                        (("Share Lo", kind), ("Share Hi", kind), ("Lo", kind), ("Hi", kind)), two_point,
                        description="A pixel's samples read as two values and their shares, from their first three "
                                    "coverage-weighted moments (Atmos)")


def _correction_part(name: str, kind: str) -> parts.Part:
    return parts.define(name, 2, (("Radiance", parts.VECTOR), ("Coverage", parts.FLOAT), ("Position", kind),
                                  ("Share Lo", kind), ("Share Hi", kind), ("Lo", kind), ("Hi", kind),
                                  ("Transmittance Lo", parts.VECTOR), ("Transmittance Hi", parts.VECTOR)),
                        (("Correction", parts.VECTOR),), _slope_correction,
                        description="What the product of a pixel's averages misses where two surfaces share it, "
                                    "their radiance difference read off the 3 x 3 pixels around (Atmos)")


#: The two-point reconstruction of one value per pixel (the Per Pixel mode's distance) and per colour channel (the
#: Compositor mode's transmittance), and the correction K from it: parts, so that each group stays small.
TWO_POINT = _two_point_part("Atmos Two Point", parts.FLOAT)
TWO_POINT_COLOUR = _two_point_part("Atmos Two Point (Colour)", parts.VECTOR)
CORRECTION = _correction_part("Atmos Two Surface Correction", parts.FLOAT)
CORRECTION_COLOUR = _correction_part("Atmos Two Surface Correction (Colour)", parts.VECTOR)


def shown_sky(g, image: Operand, environment: Operand, film_transparent: Operand):
    """(S, P): the sky the pixel shows (the Environment pass, nothing with Film > Transparent) and the surfaces'
    radiance P = Image - S."""
    sky = g.scale(environment, g.sub(1.0, film_transparent), label="S")
    return sky, g.sub(image, sky, label="P")


def combine(g, *, sky: Operand, surfaces: Operand, alpha: Operand, coverage: Operand, transmittance: Operand,
            inscattering: Operand, correction_term: Operand | None):
    """The composited pixel (module docstring): S + P w T / C' + w L / max(C', 1) + w K, the render where C' = 0."""
    covered = g.min(coverage, alpha, label="C'")
    weight = g.div(covered, coverage, label="w")             # 0 where nothing Atmos manages wrote
    attenuation = g.div(g.scale(transmittance, weight), covered, label="w T / C'")
    factor = g.add(attenuation, g.sub(1.0, g.greater_than(covered, TINY)), label="factor (1 where C' = 0)")
    lit = g.div(g.scale(inscattering, weight), g.max(covered, 1.0), label="w L")
    out = g.add(g.add(sky, g.mul(surfaces, factor)), lit)
    if correction_term is not None:
        out = g.add(out, g.scale(correction_term, weight), label="+ w K")
    return out


def with_alpha(g, colour: Operand, alpha: Operand):
    """``colour`` (premultiplied, as the render's RGB) with the render's ``alpha``: the vector arithmetic above
    drops the alpha, and a transparent film or a holdout's hole keeps its own (Set Alpha, Replace Alpha)."""
    node = g.node("CompositorNodeSetAlpha", label="the render's alpha")
    if "Type" in node.inputs:
        node.inputs["Type"].default_value = "Replace Alpha"
    else:
        node.mode = "REPLACE_ALPHA"
    g.link(colour, node.inputs["Image"])
    g.link(alpha, node.inputs["Alpha"])
    return node.outputs["Image"]


def _ensure_interface(tree) -> None:
    """Give ``tree`` the group's interface (:func:`keep_interface`): a group of an earlier version gains the inputs it
    lacks without losing the links into the others."""
    keep_interface(tree, list(INTERFACE))


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
    """Build the Compositor mode's combining group in ``tree`` (module docstring), in place: its interface is kept."""
    tree.nodes.clear()
    _ensure_interface(tree)
    group_in = tree.nodes.new("NodeGroupInput")
    inputs = group_in.outputs
    g = CompositorBuilder(tree, {})
    coverage, transmittance = inputs["Coverage"], inputs["Transmittance"]
    sky, surfaces = shown_sky(g, inputs["Image"], inputs["Environment"], inputs["Film Transparent"])
    share_lo, share_hi, t_lo, t_hi = g.call(TWO_POINT_COLOUR, coverage, transmittance,
                                            inputs["Transmittance Squared"], inputs["Transmittance Cubed"])
    term = g.call(CORRECTION_COLOUR, surfaces, coverage, transmittance, share_lo, share_hi, t_lo, t_hi, t_lo, t_hi)
    out = combine(g, sky=sky, surfaces=surfaces, alpha=inputs["Alpha"], coverage=coverage,
                  transmittance=transmittance, inscattering=inputs["Inscattering"], correction_term=term)
    output = g.node("NodeGroupOutput", label="Group Output")
    g.link(with_alpha(g, out, inputs["Alpha"]), output.inputs["Image"])
    g.prune()
    g.layout()
    stamps.stamp(tree, stamps.COMPOSITE, "")


def ensure_composite_group():
    """Get or create the "Atmos Aerial Composite" compositor group; rebuilt in place when stale."""
    tree = stamps.group(stamps.COMPOSITE, replace_foreign=True)
    if not stamps.is_current(tree, stamps.COMPOSITE, ""):
        build_composite_group(tree)
    return tree
