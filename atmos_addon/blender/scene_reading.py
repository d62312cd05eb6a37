# SPDX-License-Identifier: GPL-3.0-or-later
"""What the rest of the Blender layer reads off a scene: the sun, its direction, the scale, the atmosphere of the
settings, whether something moves over time. Reading only: nothing here writes to the scene but the settings'
status strings (:func:`set_if_changed`).
"""

from __future__ import annotations

import math
from types import ModuleType

import numpy as np
from mathutils import Vector

from .. import node_groups
from ..physics import Atmosphere
from . import motion_path
from .settings_io import FIELD_MAP

#: Used when the scene has no sun lamp: 45 degrees above the horizon, towards +Y (north in Blender's convention).
DEFAULT_SUN_DIRECTION = (0.0, math.sqrt(0.5), math.sqrt(0.5))

#: Per scene: (the settings' values, their Atmosphere), reused while the values are unchanged (a cache only).
_last_atmosphere: dict[str, tuple] = {}


def groups() -> ModuleType:
    """The node groups package, :mod:`atmos_addon.node_groups` (the top-level node_groups/ folder)."""
    return node_groups


def sun_object(scene):
    """The sun lamp that drives the atmosphere: ``scene.atmos.sun_object``, else the first sun lamp in the scene that
    renders, else the first sun lamp (a lamp switched off for renders is an alternative kept in the file: the sky's
    sun would stand where no light comes from)."""
    chosen = scene.atmos.sun_object
    if chosen is not None and chosen.type == "LIGHT" and chosen.data.type == "SUN":
        return chosen
    first = None
    for obj in scene.objects:   # stops at the first that renders: called on every sync, over every object
        if obj.type == "LIGHT" and obj.data.type == "SUN":
            if not obj.hide_render:
                return obj
            if first is None:
                first = obj
    return first


def world_matrix(obj, scene):
    """``obj``'s world matrix at ``scene``'s current frame, without evaluating the scene: composed from its transform
    and its parents' (:func:`.motion_path.world_matrix`) where nothing else moves it (:func:`.motion_path.keys_alone`),
    else the one the depsgraph last evaluated (:func:`needs_evaluation` says when that must be brought up to date)."""
    if _composable(obj, scene):
        return motion_path.world_matrix(obj, scene.frame_current + scene.frame_subframe)
    return obj.matrix_world


def _composable(obj, scene) -> bool:
    """True when ``obj``'s world matrix can be composed from its transform keys at the scene's frame: nothing else
    moves it and the scene's time is not remapped (its frames are then not the keys' frames)."""
    return motion_path.keys_alone(obj) and not motion_path.time_is_remapped(scene)


def needs_evaluation(scene) -> bool:
    """True when the sun lamp's or the camera's world matrix needs the depsgraph: a constraint, a driver, an NLA
    strip, a parent of another kind or remapped time moves it (:func:`world_matrix` reads the evaluated matrix
    then)."""
    return any(obj is not None and not _composable(obj, scene) for obj in (sun_object(scene), scene.camera))


def direction_of(lamp, scene) -> tuple[np.ndarray, str]:
    """Unit direction TO the sun of ``lamp`` (None: the default sun) in world space at ``scene``'s current frame, and
    a sentence saying where it came from. A sun lamp shines along its local -Z axis, so the direction towards the
    sun is its local +Z axis."""
    if lamp is None:
        return np.array(DEFAULT_SUN_DIRECTION), "No sun lamp: using the default sun 45 degrees above the horizon"
    return direction_from_matrix(world_matrix(lamp, scene), lamp.name)


def direction_from_matrix(matrix, name: str) -> tuple[np.ndarray, str]:
    """:func:`direction_of` a sun lamp named ``name`` whose world matrix is ``matrix`` (a lamp's at another frame,
    :mod:`.motion_path`)."""
    axis = matrix.to_3x3() @ Vector((0.0, 0.0, 1.0))
    if axis.length == 0.0:
        return np.array(DEFAULT_SUN_DIRECTION), f"Sun lamp '{name}' has zero scale: using the default sun"
    axis.normalize()
    elevation = math.degrees(math.asin(max(-1.0, min(1.0, axis.z))))
    return np.array(axis), f"Sun: '{name}', {elevation:.1f} degrees above the horizon"


def sun_direction(scene) -> tuple[np.ndarray, str]:
    """The unit direction to the scene's sun (:func:`sun_object`) and where it came from (:func:`direction_of`)."""
    return direction_of(sun_object(scene), scene)


def metres_per_unit(scene) -> float:
    """Metres per Blender unit as the atmosphere sees them (unit scale times the distance scale)."""
    return float(scene.unit_settings.scale_length) * float(scene.atmos.distance_scale)


def atmosphere_with_key(scene) -> tuple[tuple, Atmosphere]:
    """The settings' atmosphere values (each read once, as a hashable key) and their :class:`Atmosphere` (1/km ->
    1/m), reused while the values are unchanged."""
    settings = scene.atmos
    raw = tuple(getattr(settings, prop) for prop, _, _ in FIELD_MAP)
    key = tuple(value if isinstance(value, float) else tuple(value) for value in raw)
    cached = _last_atmosphere.get(scene.name)
    if cached is not None and cached[0] == key:
        return key, cached[1]
    values = {}
    for (_, field, factor), value in zip(FIELD_MAP, key):
        array = np.asarray(value, dtype=float) / factor
        values[field] = array if array.ndim else float(array)
    atmosphere = Atmosphere(**values)
    _last_atmosphere[scene.name] = (key, atmosphere)
    return key, atmosphere


def atmosphere_of(scene) -> Atmosphere:
    """The physics :class:`Atmosphere` of the scene's settings (cached while they are unchanged)."""
    return atmosphere_with_key(scene)[1]


def forget(scene_name: str | None = None) -> None:
    """Drop the cached atmosphere (of every scene when ``scene_name`` is None)."""
    if scene_name is None:
        _last_atmosphere.clear()
    else:
        _last_atmosphere.pop(scene_name, None)


def set_if_changed(settings, name: str, value) -> None:
    """Write a setting (a status string) only when it differs: every write re-tags the depsgraph and redraws."""
    if getattr(settings, name) != value:
        setattr(settings, name, value)


def _animated(idblock) -> bool:
    animation = getattr(idblock, "animation_data", None)
    return animation is not None and (animation.action is not None or len(animation.drivers) > 0
                                      or len(animation.nla_tracks) > 0)


def moves_over_time(obj) -> bool:
    """True if ``obj`` (None: False), or a parent, is animated (action, drivers, NLA) or constrained."""
    while obj is not None:
        if _animated(obj) or len(obj.constraints) > 0:
            return True
        obj = obj.parent
    return False


def motion_objects(obj) -> list:
    """``obj``, its parents and its constraints' targets (with theirs): every object whose animation or transform
    can move it."""
    found, todo, seen = [], [obj], set()
    while todo:
        current = todo.pop()
        if current is None or current.as_pointer() in seen:
            continue
        seen.add(current.as_pointer())
        found.append(current)
        todo.append(current.parent)
        todo.extend(getattr(constraint, "target", None) for constraint in current.constraints)
    return found


#: The scene settings of the Sun Position add-on (bundled with Blender until 4.1, an extension since), an artist's
#: usual way to put the sun where it stands at a place, a date and a time: with its time, date or place keyed it
#: turns its sun object from a frame-change handler, and the lamp itself carries no animation at all.
SUN_POSITION = "sun_pos_properties"


def animation_curves(idblock) -> list:
    """The drivers of ``idblock``, then the F-curves of its action and of its NLA strips' actions (none without
    animation data)."""
    animation = idblock.animation_data
    if animation is None:
        return []
    fcurves_of = groups().parameters.fcurves_of
    actions = [animation.action] + [strip.action for track in animation.nla_tracks for strip in track.strips]
    return list(animation.drivers) + [curve for action in actions if action is not None
                                      for curve in fcurves_of(action)]


def sun_position_curves(scene) -> list:
    """The keys' F-curves (action, NLA strips) and drivers of ``scene`` that animate the Sun Position add-on's
    settings (``sun_pos_properties.time`` and the others)."""
    return [curve for curve in animation_curves(scene) if curve.data_path.startswith(SUN_POSITION + ".")]


def _stored_sun_position(scene):
    """The Sun Position add-on's settings as the file stores them where the add-on is not loaded (an ID property
    group on 4.x; None on 5.x, which keeps them out of Python's reach, or where there are none)."""
    stored = scene.get(SUN_POSITION)
    return stored if hasattr(stored, "to_dict") else None


def sun_position_settings(scene) -> str:
    """The Sun Position add-on's settings of ``scene`` as text (its place, date, time...: where it puts the sun), read
    through the add-on where it is loaded, else from what the file stores where Blender keeps that reachable (4.x);
    empty when neither."""
    settings = getattr(scene, SUN_POSITION, None)
    if settings is None:
        stored = _stored_sun_position(scene)
        return repr(sorted(stored.to_dict().items())) if stored is not None else ""
    values = []
    for prop in settings.bl_rna.properties:
        if prop.identifier == "rna_type" or prop.type == "COLLECTION":
            continue
        value = getattr(settings, prop.identifier)
        if prop.type == "POINTER":
            value = getattr(value, "name", None)
        elif getattr(prop, "is_array", False):
            value = tuple(value)
        values.append((prop.identifier, value))
    return repr(values)


def turned_by_sun_position(scene, obj) -> bool:
    """True when the Sun Position add-on's settings of ``scene`` are animated and the object it turns is ``obj``, a
    parent of it or a target of its constraints: the add-on then turns ``obj`` on every frame. Where the add-on is not
    loaded (a farm, the ``bpy`` module) its settings are read from the file where Blender keeps them reachable (4.x;
    5.x stores an unloaded add-on's settings out of Python's reach: any object may be the one, and nothing turns it
    here, so a path sampled frame by frame stands still)."""
    if obj is None or not sun_position_curves(scene):
        return False
    settings = getattr(scene, SUN_POSITION, None)
    if settings is not None:                       # the add-on loaded
        target = getattr(settings, "sun_object", None)
    else:
        stored = _stored_sun_position(scene)
        if stored is None:
            return True
        target = stored.get("sun_object")
    return target is not None and any(target == moved for moved in motion_objects(obj))


def rendered_view_layers(scene) -> list:
    """The view layers a render of ``scene`` renders: those with *Use for Rendering*, all of them when none has it."""
    return [layer for layer in scene.view_layers if layer.use] or list(scene.view_layers)


def switches_camera(scene) -> bool:
    """True if a timeline marker binds a camera other than the scene's: the render switches to it at the marker's
    frame (a cut), so the camera the tables are measured from changes over time."""
    return any(marker.camera is not None and marker.camera != scene.camera for marker in scene.timeline_markers)


def camera_moves(scene) -> bool:
    """True if the scene's camera can change place over time: it moves (:func:`moves_over_time`) or a marker switches
    to another one (:func:`switches_camera`)."""
    return moves_over_time(scene.camera) or switches_camera(scene)


def is_sun_animated(scene) -> bool:
    """True if the sun lamp's direction can change over time: it, or a parent, is animated or constrained, or the Sun
    Position add-on turns it from its animated settings (:func:`turned_by_sun_position`)."""
    lamp = sun_object(scene)
    return moves_over_time(lamp) or turned_by_sun_position(scene, lamp)


def _held_out_in(layer_collection, found: set) -> None:
    """Add to ``found`` the objects ``layer_collection`` and its children hold out (a held-out collection holds out
    everything in it, children included)."""
    if layer_collection is None or layer_collection.exclude:
        return
    if layer_collection.holdout:
        found.update(layer_collection.collection.all_objects)
        return
    for child in layer_collection.children:
        _held_out_in(child, found)


def held_out(scene) -> tuple[set, set]:
    """(objects held out in every rendered view layer, objects held out in only some of them)."""
    per_layer = []
    for layer in scene.view_layers:
        if layer.use:
            found: set = set()
            _held_out_in(layer.layer_collection, found)
            per_layer.append(found)
    if not per_layer:
        return set(), set()
    everywhere = set.intersection(*per_layer)
    return everywhere, set.union(*per_layer) - everywhere
