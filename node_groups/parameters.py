# SPDX-License-Identifier: GPL-3.0-or-later
"""The values the Atmos node groups read at render time: scene custom properties.

The groups read each parameter with an Attribute node of type ``VIEW_LAYER``, which looks the name
up on the view layer, then the scene, then the world (Cycles and Eevee, Blender 3.5+). Changing a
parameter is therefore a property write, never a node-tree rebuild; Eevee does not recompile its
shaders. The properties can be keyframed (``scene.keyframe_insert('["atmos_sun_direction"]')``) and the
render evaluates them per frame, so an animated sun renders on a machine without the add-on.
A parameter that is missing reads as zero: the groups then pass the surface through unchanged
(transmittance 1, in-scattering 0).

Three-float properties are read through the Attribute node's Color/Vector output, floats through Fac.
Units: coefficients 1/m, irradiance W/m^2 (Blender sun strength), the sun direction a unit world-space
vector pointing toward the sun, ``metres_per_unit`` metres per Blender scene unit, planet radius and scale
heights m (the virtual sky dome, shared by the aerial and sky groups), the sun's angular radius rad.
:data:`AERIAL_PARAMETER_NAMES` are what the aerial group reads; the sky group reads every name.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import bpy

from ..physics import atmosphere, precise, sun

#: Rayleigh scattering coefficient beta_R per channel, 1/m.
BETA_RAYLEIGH = "atmos_beta_rayleigh"
#: Mie scattering coefficient beta_M per channel, 1/m.
BETA_MIE = "atmos_beta_mie"
#: Mie absorption coefficient per channel, 1/m (adds to extinction only).
BETA_MIE_ABSORPTION = "atmos_beta_mie_absorption"
#: Henyey-Greenstein anisotropy g per channel (positive: forward, toward the sun).
MIE_G = "atmos_mie_g"
#: Unit vector toward the sun, world space.
SUN_DIRECTION = "atmos_sun_direction"
#: Sun irradiance at the ground E_sun per channel, W/m^2 (Blender sun strength).
SUN_IRRADIANCE = "atmos_sun_irradiance"
#: Metres per scene unit (scene unit scale times the user's distance scale), a float.
METRES_PER_UNIT = "atmos_metres_per_unit"
#: Planet radius R_p, m (the virtual sky dome; the camera is taken on the ground).
PLANET_RADIUS = "atmos_planet_radius"
#: Scale heights (H_R, H_M, 0) of molecules and aerosols, m (the virtual sky dome).
SCALE_HEIGHTS = "atmos_scale_heights"
#: Angular radius of the sun's disk, rad (half the angular diameter).
SUN_ANGULAR_RADIUS = "atmos_sun_angular_radius"
#: Linear limb-darkening coefficient u of the sun's disk, I(mu) / I(1) = 1 - u (1 - mu); 0: a uniform disk.
SUN_LIMB_DARKENING = "atmos_sun_limb_darkening"
#: Albedo of the ground the sky shows below the horizon, per channel.
GROUND_ALBEDO = "atmos_ground_albedo"
#: Precise level, per frame: the table tile's texel origin in the image and the camera altitude, (x0 px, y0 px, h_c m).
PRECISE_TILE = "atmos_precise_tile"
#: Precise level, per frame: the table's largest distance D, its top altitude and the weight of the next key tile
#: (an animated camera or sun), (D m, top m, w).
PRECISE_SCALE = "atmos_precise_scale"
#: Precise level: the table image's size and whether its distance columns start at each row's vertical ray
#: (``physics.precise.Tile.vertical_columns``), (width px, height px, 1 or 0).
PRECISE_ATLAS = "atmos_precise_atlas"

#: The parameters of the aerial-perspective group.
AERIAL_PARAMETER_NAMES = (BETA_RAYLEIGH, BETA_MIE, BETA_MIE_ABSORPTION, MIE_G, SUN_DIRECTION, SUN_IRRADIANCE,
                          METRES_PER_UNIT, PLANET_RADIUS, SCALE_HEIGHTS)
#: Parameters of the retired Balanced level (the origin's altitude and the sun's ground optical depths per
#: species): nothing reads or writes them; :func:`clear_shader_parameters` removes them, with their keys, from files
#: saved with them.
RETIRED_PARAMETER_NAMES = ("atmos_origin_altitude", "atmos_sun_optical_depth_rayleigh", "atmos_sun_optical_depth_mie")
#: The parameters only the Precise level reads (written by the add-on's table bake, keyed with constant
#: interpolation when the camera or the sun moves, never by :func:`keyframe_shader_parameters`).
PRECISE_PARAMETER_NAMES = (PRECISE_TILE, PRECISE_SCALE, PRECISE_ATLAS)
#: The parameters that change with the sun (its direction and what its elevation sets): with the effect on and a
#: sun lamp, drivers on the lamp (:mod:`atmos_addon.blender.apply.sun_drivers`), which the sync never writes over;
#: what :func:`keyframe_shader_parameters` keys by default for a script that animates the groups by hand.
SUN_PARAMETER_NAMES = (SUN_DIRECTION, SUN_IRRADIANCE)
#: Every parameter name, in the order of :func:`write_shader_parameters`' arguments, then the Precise ones.
PARAMETER_NAMES = (*AERIAL_PARAMETER_NAMES, SUN_ANGULAR_RADIUS, SUN_LIMB_DARKENING, GROUND_ALBEDO,
                   *PRECISE_PARAMETER_NAMES)

#: Defaults of the dome and sun parameters: the physics core's default (Earth) ``Atmosphere`` and sun.
#: Callers written before the sky existed get these.
DEFAULT_PLANET_RADIUS_M = atmosphere.DEFAULT_PLANET_RADIUS_M
DEFAULT_RAYLEIGH_SCALE_HEIGHT_M = atmosphere.DEFAULT_RAYLEIGH_SCALE_HEIGHT_M
DEFAULT_MIE_SCALE_HEIGHT_M = atmosphere.DEFAULT_MIE_SCALE_HEIGHT_M
DEFAULT_SUN_ANGULAR_RADIUS_RAD = sun.SUN_ANGULAR_RADIUS_RAD
DEFAULT_SUN_LIMB_DARKENING = sun.SUN_LIMB_DARKENING
DEFAULT_GROUND_ALBEDO = precise.DEFAULT_GROUND_ALBEDO
#: |g| is kept below this so the Henyey-Greenstein phase stays finite in float32.
MAX_ABS_MIE_G = 0.999


def _triple(name: str, value: Sequence[float] | float) -> tuple[float, float, float]:
    """Three finite floats (a number is broadcast to the three channels)."""
    if isinstance(value, (int, float)):
        value = (value, value, value)
    try:
        triple = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"Atmos shader parameter {name}: expected three numbers (R, G, B); got {value!r}") from None
    if len(triple) != 3 or not all(math.isfinite(v) for v in triple):
        raise ValueError(f"Atmos shader parameter {name}: expected three finite numbers (R, G, B); got {value!r}")
    return triple


def _nonnegative(name: str, value: Sequence[float] | float) -> tuple[float, float, float]:
    """Three finite floats >= 0 (coefficients and irradiance)."""
    triple = _triple(name, value)
    if min(triple) < 0.0:
        raise ValueError(f"Atmos shader parameter {name} must be >= 0; got {triple}")
    return triple


def shader_parameter_values(*, beta_rayleigh: Sequence[float], beta_mie: Sequence[float],
                            beta_mie_absorption: Sequence[float], mie_g: Sequence[float] | float,
                            sun_direction: Sequence[float], sun_irradiance: Sequence[float] | float,
                            metres_per_unit: float, planet_radius: float = DEFAULT_PLANET_RADIUS_M,
                            rayleigh_scale_height: float = DEFAULT_RAYLEIGH_SCALE_HEIGHT_M,
                            mie_scale_height: float = DEFAULT_MIE_SCALE_HEIGHT_M,
                            sun_angular_radius: float = DEFAULT_SUN_ANGULAR_RADIUS_RAD,
                            sun_limb_darkening: float = DEFAULT_SUN_LIMB_DARKENING,
                            ground_albedo: Sequence[float] | float = DEFAULT_GROUND_ALBEDO
                            ) -> dict[str, tuple | float]:
    """The aerial-perspective and sky parameters by property name, checked (plain numbers in): what
    :func:`write_shader_parameters` stores and what :class:`~.graph.ArrayBuilder` evaluates the groups with.

    ``sun_direction`` is normalised here; ``mie_g`` is clamped to +-:data:`MAX_ABS_MIE_G`. Lengths are m,
    the sun's angular radius rad (in (0, pi/2)), the limb darkening in [0, 1]. The keyword arguments with
    defaults (Earth, the real sun) were added with the sky; older callers keep working.
    Raises ValueError naming the parameter when a value is not finite, a coefficient is negative, the sun
    direction has zero length, a length is not > 0 or an angle is out of range.
    """
    direction = _triple(SUN_DIRECTION, sun_direction)
    length = math.sqrt(sum(v * v for v in direction))
    if not length > 0.0:
        raise ValueError(f"Atmos shader parameter {SUN_DIRECTION}: the sun direction has zero length")
    metres = float(metres_per_unit)
    if not (math.isfinite(metres) and metres > 0.0):
        raise ValueError(f"Atmos shader parameter {METRES_PER_UNIT} must be a finite number > 0; "
                         f"got {metres_per_unit!r}")
    values = {
        BETA_RAYLEIGH: _nonnegative(BETA_RAYLEIGH, beta_rayleigh),
        BETA_MIE: _nonnegative(BETA_MIE, beta_mie),
        BETA_MIE_ABSORPTION: _nonnegative(BETA_MIE_ABSORPTION, beta_mie_absorption),
        MIE_G: tuple(min(max(g, -MAX_ABS_MIE_G), MAX_ABS_MIE_G) for g in _triple(MIE_G, mie_g)),
        SUN_DIRECTION: tuple(v / length for v in direction),
        SUN_IRRADIANCE: _nonnegative(SUN_IRRADIANCE, sun_irradiance),
        METRES_PER_UNIT: metres,
        PLANET_RADIUS: _positive(PLANET_RADIUS, planet_radius),
        SCALE_HEIGHTS: (_positive(SCALE_HEIGHTS, rayleigh_scale_height), _positive(SCALE_HEIGHTS, mie_scale_height),
                        0.0),
        SUN_ANGULAR_RADIUS: _in_range(SUN_ANGULAR_RADIUS, sun_angular_radius, 0.0, 0.5 * math.pi, open_low=True),
        SUN_LIMB_DARKENING: _in_range(SUN_LIMB_DARKENING, sun_limb_darkening, 0.0, 1.0),
        GROUND_ALBEDO: _nonnegative(GROUND_ALBEDO, ground_albedo),
    }
    return values


def write_shader_parameters(scene: bpy.types.Scene, skip: tuple[str, ...] = (), **values) -> bool:
    """Store :func:`shader_parameter_values` (same keywords) as custom properties of ``scene``; the names in ``skip``
    (driven ones) only where they are missing. Tags the scene when anything was written; True then."""
    wrote = False
    for name, value in shader_parameter_values(**values).items():
        if name in skip and name in scene:
            continue
        wrote = store_if_changed(scene, name, value) or wrote
    if wrote:
        scene.update_tag()
    return wrote


def store_if_changed(scene: bpy.types.Scene, name: str, value) -> bool:
    """Store ``value`` as ``scene``'s custom property ``name`` unless it holds it already; True when written. Only on
    change: a written parameter must be followed by a tag of the scene (which re-evaluates every object), and keyed
    values must not be clobbered needlessly."""
    if name in scene and _as_tuple(scene[name]) == _as_tuple(value):
        return False
    scene[name] = value
    return True


def _positive(name: str, value: float) -> float:
    """A finite float > 0 (lengths)."""
    number = float(value)
    if not (math.isfinite(number) and number > 0.0):
        raise ValueError(f"Atmos shader parameter {name}: expected a finite length > 0 (m); got {value!r}")
    return number


def _in_range(name: str, value: float, low: float, high: float, *, open_low: bool = False) -> float:
    """A finite float in [low, high] (or (low, high] with ``open_low``)."""
    number = float(value)
    if not (math.isfinite(number) and (number > low if open_low else number >= low) and number <= high):
        raise ValueError(f"Atmos shader parameter {name}: expected a number in {'(' if open_low else '['}{low:g}, "
                         f"{high:g}]; got {value!r}")
    return number


def read_shader_parameters(scene: bpy.types.Scene) -> dict[str, tuple[float, ...] | float | None]:
    """The stored parameters by property name (None where one is missing), for panels and tests."""
    return {name: (_as_tuple(scene[name]) if name in scene else None) for name in PARAMETER_NAMES}


def keyframe_shader_parameters(scene: bpy.types.Scene, frame: float | None = None,
                               names: tuple[str, ...] = SUN_PARAMETER_NAMES) -> None:
    """Insert a keyframe on the stored parameters ``names`` (default: those that change with the sun) at ``frame``
    (the current frame by default)."""
    frame = scene.frame_current if frame is None else frame
    for name in names:
        if name in scene and name not in PRECISE_PARAMETER_NAMES:
            scene.keyframe_insert(f'["{name}"]', frame=frame)


def clear_shader_parameters(scene: bpy.types.Scene) -> None:
    """Remove the parameters (and their animation curves) from ``scene``, the retired ones too
    (:data:`RETIRED_PARAMETER_NAMES`); the groups then read zeros."""
    _remove_parameters(scene, PARAMETER_NAMES + RETIRED_PARAMETER_NAMES)


def clear_retired_parameters(scene: bpy.types.Scene) -> bool:
    """Remove :data:`RETIRED_PARAMETER_NAMES` and their keys from ``scene`` (a file saved before they were
    retired); True when there were any."""
    present = [name for name in RETIRED_PARAMETER_NAMES if name in scene]
    if present:
        _remove_parameters(scene, tuple(present))
    return bool(present)


def _remove_parameters(scene: bpy.types.Scene, names: tuple[str, ...]) -> None:
    animation = scene.animation_data
    if animation is not None and animation.action is not None:
        paths = {f'["{name}"]' for name in names}
        for fcurve in [c for c in fcurves_of(animation.action) if c.data_path in paths]:   # read all, then remove
            remove_fcurve(animation.action, fcurve)
    for name in names:
        if name in scene:
            del scene[name]
    scene.update_tag()


def _as_tuple(value) -> tuple[float, ...] | float:
    """An ID property value as a float or a tuple of floats."""
    if isinstance(value, (int, float)):
        return float(value)
    return tuple(float(v) for v in value)


def _curve_lists(action: bpy.types.Action) -> list:
    """The collections that hold ``action``'s F-curves, each once: its channelbags (Blender 4.4+ layered actions), or
    for a legacy action (before 4.4, or one not yet upgraded) its own list. Blender 4.4 and 4.5 also offer a layered
    action's first slot's curves as ``action.fcurves``: listing both gave those curves twice, and removing a curve
    then left its second entry pointing at freed memory."""
    bags = [channelbag.fcurves for layer in getattr(action, "layers", ()) for strip in layer.strips
            for channelbag in getattr(strip, "channelbags", ())]
    legacy = getattr(action, "fcurves", None)
    return bags if any(len(bag) for bag in bags) or legacy is None else [legacy]


def fcurves_of(action: bpy.types.Action) -> list[bpy.types.FCurve]:
    """Every F-curve of ``action``, each once (:func:`_curve_lists`)."""
    return [curve for curves in _curve_lists(action) for curve in curves]


def remove_fcurve(action: bpy.types.Action, fcurve: bpy.types.FCurve) -> None:
    """Remove ``fcurve`` from whichever collection of ``action`` holds it."""
    for curves in _curve_lists(action):
        if any(c == fcurve for c in curves):
            curves.remove(fcurve)
            return
