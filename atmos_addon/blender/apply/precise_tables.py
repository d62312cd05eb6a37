# SPDX-License-Identifier: GPL-3.0-or-later
"""The Precise level's baked tables: the tiles of the scene's camera altitudes and sun elevations in one float image
packed into the .blend.

A tile (``physics.precise.bake_tile``) depends on the atmosphere, the camera's altitude and the sun's elevation.
:func:`bake` integrates one tile when neither moves over the frame range (a camera that pans at one altitude
included), else the key tiles of their path (``physics.precise.key_tiles``: a key every step of the sun's elevation
or the camera's altitude, 47 for a sun setting from 60 to -4 deg, however many frames), and writes them into the
"Atmos Precise Table" image: tiles stacked upward in path order (at most :data:`TILES_PER_COLUMN`: GPU textures stop
at 16384 texels). The frame's tile origin, camera altitude, largest distance and blend weight are scene parameters;
when they change over the range they are keyed per frame with constant interpolation, so the render (a farm's
included) picks each frame's two key tiles and blends them without Python (``node_groups.precise.KeyBlend``; the plan
builds the blend where the table holds more than one key tile: :data:`.facts.KEY_TILES`). The image is packed, so
the file carries it. A bake is skipped while its inputs are unchanged (a key stored on the image).
"""

from __future__ import annotations

import concurrent.futures
import hashlib
import math
import threading
import time
import traceback
from dataclasses import dataclass

import bpy
import numpy as np

from ...node_groups import stamps
from ...physics.precise import (DEFAULT_SHAPE, Tile, bake_tile, bank_key, bank_tile, bank_units_around, banked,
                                key_tiles, shared_max_distance, tables_ready, tile_from_bank)
from ...plan import Plan
from .. import facts, group_integrity, motion_path, scene_reading
from ..debounce import Debounced
from . import compositor

#: Largest texture side GPUs accept (OpenGL's usual GL_MAX_TEXTURE_SIZE), px.
MAX_TEXTURE_SIZE = 16384
#: Tiles stacked in one column of the image.
TILES_PER_COLUMN = MAX_TEXTURE_SIZE // DEFAULT_SHAPE.altitudes
_KEY = "atmos_bake_key"
_TILES = "atmos_tiles"
#: The table layout's version, bumped whenever the same inputs bake a different table (CHANGELOG.md lists each), so
#: that a file saved with an older layout re-bakes on opening (:func:`follow`), its key tiles included.
_LAYOUT = 8
#: Image property: the :data:`_LAYOUT` its tiles were written with.
_LAYOUT_KEY = "atmos_layout"


def _camera_altitude_m(scene, metres_per_unit: float) -> float:
    """The scene camera's altitude above sea level at the current frame, m (origin altitude + z; 0 without one)."""
    camera = scene.camera
    z = float(scene_reading.world_matrix(camera, scene).translation.z) if camera is not None else 0.0
    return float(scene.atmos.origin_altitude) + z * metres_per_unit


def frame_inputs(scene) -> list[tuple[int, float, float]]:
    """(frame, camera altitude m, sun elevation rad) per tile: the current frame only, or every frame of the range
    when the camera or the sun moves over time (the current frame is restored): read off their keys where nothing
    else moves them (:mod:`..motion_path`, checked against the scene at three frames), else sampled frame by frame."""
    metres = scene_reading.metres_per_unit(scene)

    def now(frame: int) -> tuple[int, float, float]:
        direction, _ = scene_reading.sun_direction(scene)
        return _rounded(frame, _camera_altitude_m(scene, metres), direction)

    if not moves(scene):
        return [now(scene.frame_current)]
    current = scene.frame_current
    try:
        keyed = _keyed_inputs(scene, metres)
        frames = range(scene.frame_start, scene.frame_end + 1)
        if keyed is not None and len(frames):
            for frame in sorted({frames[0], frames[len(frames) // 2], frames[-1]}):
                scene.frame_set(frame)
                _, altitude, elevation = now(frame)
                _, keyed_altitude, keyed_elevation = keyed[frame - frames[0]]
                # one unit of the rounding apart at most (float32 sums in another order), more is another path
                if (abs(altitude - keyed_altitude) > 2e-3 + 2e-6 * abs(altitude)
                        or abs(elevation - keyed_elevation) > 2e-7):
                    keyed = None
                    break
        if keyed is not None:
            return keyed
        inputs = []
        for frame in frames:
            scene.frame_set(frame)
            inputs.append(now(frame))
        return inputs
    finally:
        scene.frame_set(current)


def _rounded(frame: int, altitude_m: float, direction) -> tuple[int, float, float]:
    """One frame's inputs, rounded as the bake key records them, so that the table is a function of its key: a lamp
    matrix that differs in its last float32 bit (the same rotation evaluated again after an undo) bakes the same
    pixels."""
    elevation = math.asin(float(np.clip(direction[2], -1.0, 1.0)))
    return frame, round(altitude_m, 3), round(elevation, 7)


def _keyed_inputs(scene, metres_per_unit: float) -> list | None:
    """Every frame's inputs composed from the camera's and the sun lamp's keys (:func:`..motion_path.world_matrix`),
    or None where something else may move them: a constraint, driver, NLA strip or other parenting on their chains
    (:func:`..motion_path.keys_alone`), a cut between cameras, the Sun Position add-on, remapped time."""
    sun, camera = scene_reading.sun_object(scene), scene.camera
    if (scene_reading.switches_camera(scene) or scene_reading.turned_by_sun_position(scene, sun)
            or motion_path.time_is_remapped(scene)
            or not all(motion_path.keys_alone(obj) for obj in (sun, camera) if obj is not None)):
        return None
    origin = float(scene.atmos.origin_altitude)
    inputs = []
    for frame in range(scene.frame_start, scene.frame_end + 1):
        z = motion_path.world_matrix(camera, frame).translation.z if camera is not None else 0.0
        if sun is None:
            direction, _ = scene_reading.direction_of(None, scene)
        else:
            direction, _ = scene_reading.direction_from_matrix(motion_path.world_matrix(sun, frame), sun.name)
        inputs.append(_rounded(frame, origin + float(z) * metres_per_unit, direction))
    return inputs


def motion_key(scene) -> tuple:
    """What :func:`frame_inputs` reads that can change between two bakes of one enable (a sun lamp it creates, a
    lamp or camera it picks): the sun lamp and camera (which, and where at the current frame), the frames, the cuts
    between cameras, the scale and the origin's altitude, and whether anything moves over time. Cheap: no frame is
    evaluated. Not a digest of the animation itself, which nothing between the two bakes edits (:class:`Sampled`)."""
    sun, camera = scene_reading.sun_object(scene), scene.camera
    return (tuple((obj.as_pointer(), tuple(v for row in scene_reading.world_matrix(obj, scene) for v in row))
                  if obj is not None else None for obj in (sun, camera)),
            scene.frame_start, scene.frame_end, scene.frame_current,
            tuple((marker.frame, marker.camera.as_pointer() if marker.camera is not None else 0)
                  for marker in scene.timeline_markers),
            scene_reading.metres_per_unit(scene), float(scene.atmos.origin_altitude), moves(scene))


@dataclass(frozen=True)
class Sampled:
    """A scene's frames sampled once (:func:`sample`): :func:`frame_inputs` and the :func:`motion_key` they were read
    under. Enable bakes twice (before the materials, so the groups link the image as they are built, and at its end,
    after it may have made a sun lamp); an animated scene's frames were sampled for each, and where they are not read
    off the keys (:mod:`..motion_path`) that is one depsgraph evaluation a frame (57 ms a frame in a scene of 20000
    objects: 17-23 s for 250 frames, twice); the second bake reuses them where the key is unchanged. Held for one
    enable only: an edit of the animation between two calls is not in the key."""

    key: tuple
    inputs: list


def sample(scene) -> Sampled:
    """The scene's frames sampled now (:class:`Sampled`)."""
    return Sampled(motion_key(scene), frame_inputs(scene))


def _bake_key(atmosphere, albedo, multiple: bool, inputs) -> str:
    text = repr((_LAYOUT, DEFAULT_SHAPE, sorted(atmosphere.to_dict().items()), tuple(round(a, 6) for a in albedo),
                 multiple,
                 [(f, round(h, 3), round(e, 7)) for f, h, e in inputs]))
    return hashlib.sha1(text.encode()).hexdigest()


def tile_origin(index: int, shape=DEFAULT_SHAPE) -> tuple[int, int]:
    """Texel origin (x0, y0) of tile ``index`` in the image."""
    return (index // TILES_PER_COLUMN) * shape.width, (index % TILES_PER_COLUMN) * shape.altitudes


def _ensure_image(width: int, height: int) -> bpy.types.Image:
    """The table image at this size (a new float, non-colour image when missing; resized in place, so the groups'
    image nodes keep pointing at it: re-pointing them re-evaluates every material that uses the groups)."""
    name = scene_reading.groups().precise.IMAGE_NAME
    image = stamps.local(bpy.data.images, name)
    if image is not None and tuple(image.size) != (width, height):
        image.scale(width, height)
    if image is None:
        image = bpy.data.images.new(name, width=width, height=height, alpha=False, float_buffer=True, is_data=True)
        image.colorspace_settings.name = "Non-Color"
    image.use_half_precision = False   # Eevee would otherwise upload 16-bit floats
    return image


def write_tiles(tiles: list[Tile]) -> bpy.types.Image:
    """Write ``tiles`` into the table image (tile i at :func:`tile_origin`), pack it and point the aerial
    group's image nodes at it."""
    shape = tiles[0].shape
    columns = (len(tiles) - 1) // TILES_PER_COLUMN + 1
    rows = min(len(tiles), TILES_PER_COLUMN)
    width, height = columns * shape.width, rows * shape.altitudes
    pixels = np.zeros((height, width, 4), dtype=np.float32)
    pixels[..., 3] = 1.0
    for index, tile in enumerate(tiles):
        x0, y0 = tile_origin(index, shape)
        pixels[y0:y0 + shape.altitudes, x0:x0 + shape.width, :3] = tile.pixels()
    image = _ensure_image(width, height)
    image.pixels.foreach_set(pixels.ravel())
    image.update()
    image.pack()
    _link_image(image)
    return image


def _link_image(image: bpy.types.Image) -> None:
    """Point the image nodes of the aerial group, of the Precise sky and its camera sky view, of the worlds' lighting
    groups (the Precise sky view), of the Per Pixel compositor group and of the parts they use (the table samples;
    those built) at ``image``."""
    groups = scene_reading.groups()
    named = [stamps.local(bpy.data.node_groups, name) for name in (groups.aerial_perspective.GROUP_NAME,
                                                        groups.sky.SKY_GROUP_NAME, groups.stamps.SKY_VIEW.name,
                                                        groups.per_pixel.GROUP_NAME)]
    lighting = [tree for tree in bpy.data.node_groups if groups.sky_lighting.is_sky_lighting_group(tree)]
    stale: dict = {}
    for tree, node, idname in groups.parts.nodes_with_parts(group for group in named + lighting if group is not None):
        if idname in ("ShaderNodeTexImage", "CompositorNodeImage") and node.image != image:
            stale.setdefault(tree, []).append(node)
    for tree, nodes in stale.items():
        with group_integrity.owned_change(tree):   # the table is ours to point at: no hand edit
            for node in nodes:
                node.image = image


def _write_parameters(scene, origin: tuple[int, int], camera_altitude_m: float, tile: Tile, top_m: float,
                      size: tuple[int, int], weight: float = 0.0) -> bool:
    """Write the Precise parameters where they changed; True when any did (a written scene must be tagged for the
    groups to read the values, and a tagged scene re-evaluates every object: a still scene's re-bake under a moved
    sun writes the same values and only the image's pixels change)."""
    parameters = scene_reading.groups().parameters
    wrote = False
    for name, value in _parameter_values(origin, camera_altitude_m, tile, top_m, size, weight).items():
        wrote = parameters.store_if_changed(scene, name, value) or wrote
    return wrote


def _parameter_values(origin: tuple[int, int], camera_altitude_m: float, tile: Tile, top_m: float,
                      size: tuple[int, int], weight: float = 0.0) -> dict:
    """The Precise parameters' values (name: 3 floats) for a frame whose tile has texel ``origin``."""
    parameters = scene_reading.groups().parameters
    return {parameters.PRECISE_TILE: (float(origin[0]), float(origin[1]), max(float(camera_altitude_m), 0.0)),
            parameters.PRECISE_SCALE: (float(tile.max_distance_m), float(top_m), float(weight)),
            parameters.PRECISE_ATLAS: (float(size[0]), float(size[1]), float(tile.vertical_columns))}


def _key_parameters(scene, frames: list[tuple[int, dict]]) -> None:
    """Key the Precise parameters on every frame of ``frames`` ((frame, :func:`_parameter_values`), in frame order),
    CONSTANT between keys. The first frame's keys are inserted as a user would (Blender makes the F-curves in the
    scene's action and slot); the others are written into those curves at once (``keyframe_points.add`` and
    ``foreach_set``): 2.3 ms a ``keyframe_insert`` in a scene of 20000 objects, 1.7 s for 250 frames' three
    parameters."""
    parameters = scene_reading.groups().parameters
    first_frame, first = frames[0]
    for name, value in first.items():
        scene[name] = value
        scene.keyframe_insert(f'["{name}"]', frame=first_frame)
    curves = {(curve.data_path, curve.array_index): curve
              for curve in parameters.fcurves_of(scene.animation_data.action)}
    constant = bpy.types.Keyframe.bl_rna.properties["interpolation"].enum_items["CONSTANT"].value
    for name in first:
        for index in range(3):
            points = curves[(f'["{name}"]', index)].keyframe_points
            coordinates = np.array([(frame, values[name][index]) for frame, values in frames], np.float32).ravel()
            points.add(len(frames) - len(points))
            for attribute in ("co", "handle_left", "handle_right"):
                points.foreach_set(attribute, coordinates)
            points.foreach_set("interpolation", np.full(len(frames), constant, np.int32))
            curves[(f'["{name}"]', index)].update()


def _clear_keys(scene) -> bool:
    """Remove the per-frame keys of the Precise parameters; True when there were any."""
    animation = scene.animation_data
    if animation is None or animation.action is None:
        return False
    parameters = scene_reading.groups().parameters
    paths = {f'["{name}"]' for name in parameters.PRECISE_PARAMETER_NAMES}
    curves = [c for c in parameters.fcurves_of(animation.action) if c.data_path in paths]
    for fcurve in curves:
        parameters.remove_fcurve(animation.action, fcurve)
    return bool(curves)


@dataclass(frozen=True)
class _Request:
    """What :func:`bake` integrates for a scene now: its inputs' ``key`` and the key tiles' arguments."""

    key: str
    inputs: list
    path: object                 #: ``physics.precise.key_tiles``' path: the keys, each frame's segment and weight
    atmosphere: object
    albedo: tuple
    multiple: bool
    shared_distance_m: float | None

    @property
    def options(self) -> dict:
        """The table's options as ``physics.precise``'s tile functions take them."""
        return {"multiple_scattering": self.multiple, "ground_albedo": self.albedo}


def _request(scene, sampled: Sampled | None = None) -> _Request:
    """What a bake of ``scene`` integrates now; its frames read from ``sampled`` where it was sampled under the
    scene's current :func:`motion_key`, else sampled anew."""
    settings = scene.atmos
    atmosphere = scene_reading.atmosphere_of(scene)
    albedo = tuple(float(a) for a in settings.ground_albedo)
    multiple = bool(settings.multiple_scattering)
    inputs = (sampled.inputs if sampled is not None and sampled.key == motion_key(scene) else frame_inputs(scene))
    altitudes = [altitude for _, altitude, _ in inputs]
    path = key_tiles(altitudes, [elevation for _, _, elevation in inputs], max_keys=TILES_PER_COLUMN)
    shared = shared_max_distance(altitudes, atmosphere) if len(path.keys) > 1 else None
    return _Request(_bake_key(atmosphere, albedo, multiple, inputs), inputs, path, atmosphere, albedo, multiple,
                    shared)


def _integrate(request: _Request) -> list[Tile]:
    """The request's key tiles (``physics.precise.bake_tile``: numpy alone, so it runs on a worker thread too; its
    cache keeps the last tiles, so a bake after the worker's reads them back)."""
    return _tiles(request, preview=False)


def _integrate_preview(request: _Request) -> list[Tile]:
    """The request's key tiles from the preview tables (``physics.precise.PREVIEW_RESOLUTION``): the interface's
    first look after an atmosphere edit, before the full tables are built (:func:`bake_on_worker`)."""
    return _tiles(request, preview=True)


def _tiles(request: _Request, *, preview: bool) -> list[Tile]:
    return [bake_tile(request.atmosphere, altitude, elevation, max_distance_m=request.shared_distance_m,
                      preview=preview, vertical_columns=request.path.vertical_columns, **request.options)
            for altitude, elevation in request.path.keys]


def _current_image(request: _Request, scene) -> bpy.types.Image | None:
    """The table image when it holds what ``request`` asks for (and the scene its parameters), else None."""
    image = stamps.local(bpy.data.images, scene_reading.groups().precise.IMAGE_NAME)
    current = (image is not None and image.get(_KEY) == request.key
               and scene_reading.groups().parameters.PRECISE_TILE in scene)
    return image if current else None


def bake(scene, *, force: bool = False, sampled: Sampled | None = None) -> int:
    """Bake the scene's tables if their inputs changed (or ``force``); returns the number of tiles baked (0: the
    image was current). Writes and, when they change over the frame range, keys the Precise parameters, and records
    the number of key tiles (:data:`.facts.KEY_TILES`, which the plan's blend follows). In the interface a still
    scene's bank is then filled around its sun (:func:`show_banked`; its keys are baked on the worker thread).
    ``sampled``: the scene's frames as an enable sampled them for its first bake (:class:`Sampled`)."""
    request = _request(scene, sampled)
    image = None if force else _current_image(request, scene)
    if image is not None:
        _link_image(image)
        _revalidate_drivers(scene)
        baked = 0
    else:
        baked = _write(scene, request, _integrate(request), request.key)
    if interactive() and _bakes_still(scene):
        _fill_bank(request, BANK_SPAN)
    return baked


def _write(scene, request: _Request, tiles: list[Tile], key: str) -> int:
    """Write ``tiles`` (the request's, or its preview's) into the image under ``key``, and the scene's parameters;
    returns the number of tiles."""
    inputs, path, atmosphere = request.inputs, request.path, request.atmosphere
    image = write_tiles(tiles)
    image[_KEY] = key
    image[_LAYOUT_KEY] = _LAYOUT
    image[_TILES] = len(tiles)
    scene[facts.KEY_TILES] = len(tiles)
    size = tuple(image.size)
    had_keys = _clear_keys(scene)
    top = atmosphere.atmosphere_height
    keyed = len({(altitude, elevation) for _, altitude, elevation in inputs}) > 1   # else one tile, constant values
    wrote = had_keys or keyed
    if keyed:
        _key_parameters(scene, [(frame, _parameter_values(tile_origin(segment), altitude, tiles[segment], top, size,
                                                          weight))
                                for (frame, altitude, _), segment, weight in zip(inputs, path.segments,
                                                                                 path.weights)])
        scene.frame_set(scene.frame_current)   # re-evaluate the keyed values at the current frame
    else:
        (_, altitude, _), segment, weight = inputs[0], path.segments[0], path.weights[0]
        wrote = _write_parameters(scene, tile_origin(segment), altitude, tiles[segment], top, size, weight) or wrote
    _revalidate_drivers(scene)
    if wrote:
        scene.update_tag()
    return len(tiles)


def _revalidate_drivers(scene) -> None:
    """The Per Pixel group node's drivers read the parameters just written (:func:`.compositor.revalidate_drivers`)."""
    compositor.revalidate_drivers(scene)


def remove(scene) -> None:
    """Remove the Precise parameters' keys (the parameters are cleared with the others), the scene's pending bakes
    (:func:`drop_pending`) and, when no scene uses the Precise level any more, the table image."""
    drop_pending(scene)
    _clear_keys(scene)
    if facts.KEY_TILES in scene:
        del scene[facts.KEY_TILES]
    image = stamps.local(bpy.data.images, scene_reading.groups().precise.IMAGE_NAME)
    still_used = any(getattr(other, "atmos", None) is not None and other.atmos.enabled and other is not scene
                     and other.get(scene_reading.groups().parameters.PRECISE_TILE) is not None
                     for other in bpy.data.scenes)
    if image is not None and not still_used:
        bpy.data.images.remove(image)


def free_buffers() -> None:
    """Drop the table image's pixel buffer (and GPU texture) so the next read decodes the packed data. An undo step
    restores the packed data and the bake key but not the buffer Blender keeps in memory."""
    image = stamps.local(bpy.data.images, scene_reading.groups().precise.IMAGE_NAME)
    if image is not None and image.packed_file is not None:
        image.buffers_free()


def describe() -> str:
    """One line for reports: how many tiles the table image holds."""
    image = stamps.local(bpy.data.images, scene_reading.groups().precise.IMAGE_NAME)
    if image is None:
        return "Precise: no table baked yet"
    tiles = int(image.get(_TILES, 1))
    keys = " (key tiles along the camera's and sun's path, two blended per frame)" if tiles > 1 else ""
    return (f"Precise: baked {tiles} table tile{'s' if tiles != 1 else ''} into the image \"{image.name}\" "
            f"({image.size[0]}x{image.size[1]}, packed){keys}")


def moves(scene) -> bool:
    """True when the camera or the sun moves over time (key tiles along their path, when altitude or elevation
    changes), a marker's switch to another camera included."""
    return scene_reading.camera_moves(scene) or scene_reading.is_sun_animated(scene)


def install(scene, plan: Plan, *, force: bool = False, sampled: Sampled | None = None) -> int:
    """Bake the tables ``plan`` lists (:func:`bake`; none where it is not at the Precise level); the number of tiles
    baked."""
    return bake(scene, force=force, sampled=sampled) if plan.tables else 0


def follow(scene) -> None:
    """After a parameter, sun or camera change of a scene whose plan bakes the tables (the caller's check): re-bake a
    still scene's one tile (at once in the background, else 0.3 s after the last change, so a slider drag bakes
    once, on a worker thread: :func:`bake_on_worker`). An animated scene's key tiles are re-baked by Enable, Refresh
    and quality changes (:func:`bake`), and in the background when an edit makes the sun's recorded animation stale
    (:func:`.sun_bake.follow`); in the UI not on every edit (0.4-0.5 s a key tile), except once for a file whose
    image has an older tile layout (:func:`layout_stale`). In the UI a sun move among the banked key tiles shows at
    once (:func:`show_banked`)."""
    if moves(scene):
        if layout_stale():
            bake(scene)   # a file saved by an Atmos that laid its tiles out otherwise: its key tiles, once
        return
    if not interactive():
        bake(scene)
        return
    show_banked(scene)
    _later.request(scene)


def interactive() -> bool:
    """True in the interface: a change is baked later on the worker thread (a script in the background bakes at once,
    :func:`follow`)."""
    return not bpy.app.background


def layout_stale() -> bool:
    """True when the file's table image was written with another tile layout than this version's (an older
    Atmos's): its groups would read the wrong columns until it is baked again."""
    image = stamps.local(bpy.data.images, scene_reading.groups().precise.IMAGE_NAME)
    return image is not None and image.get(_LAYOUT_KEY) != _LAYOUT


def bake_on_worker(scene) -> None:
    """The debounced re-bake of a still scene in the UI: its tile is integrated on a worker thread (0.4-0.5 s, and
    the atmosphere's tables after an edit of it), so the interface never waits for it; :func:`write_finished` writes
    the image on the main thread when it is ready. After an atmosphere edit with multiple scattering (its full tables
    not built yet: ``physics.precise.tables_ready``), the worker first bakes the tile from the preview tables
    (a fifth of the full tables' build), which is written as soon as it is done (its key marked
    :data:`PREVIEW_MARK`, so nothing takes it for the scene's table), then the full one, written over it."""
    if not _bakes_still(scene):
        return
    request = _request(scene)
    if _current_image(request, scene) is not None:
        return
    job = _jobs.get(scene.name)
    if job is not None:
        if job[0].key == request.key:
            return                 # already on its way
        job[1].cancel()            # not started yet: dropped (a started one finishes; its tile is then unused)
        preview = _previews.pop(scene.name, None)
        if preview is not None:
            preview[1].cancel()
    _cancel_bank()                 # the scene's own tile first: the bank's keys not started wait for the next fill
    if request.multiple and not tables_ready(request.atmosphere, request.albedo):
        _previews[scene.name] = (request, _executor().submit(_integrate_preview, request))
    _jobs[scene.name] = (request, _executor().submit(_integrate, request))
    if not bpy.app.timers.is_registered(write_finished):
        bpy.app.timers.register(write_finished, first_interval=APPLY_POLL_S)


#: Seconds between the main thread's checks for a finished worker bake.
APPLY_POLL_S = 0.05
#: Appended to the image's bake key while it holds a preview (:func:`bake_on_worker`).
PREVIEW_MARK = ":preview"
#: Scene name -> (request, future) of the worker bakes under way.
_jobs: dict[str, tuple[_Request, concurrent.futures.Future]] = {}
#: Scene name -> (request, future) of their previews (the worker runs them first).
_previews: dict[str, tuple[_Request, concurrent.futures.Future]] = {}
_worker: list[concurrent.futures.ThreadPoolExecutor] = []


def _executor() -> concurrent.futures.ThreadPoolExecutor:
    """One worker thread (its bake runs ``physics.precise.parallel.WORKERS`` threads of its own), made when first
    needed."""
    if not _worker:
        _worker.append(concurrent.futures.ThreadPoolExecutor(max_workers=1, thread_name_prefix="atmos-bake"))
    return _worker[0]


def write_finished():
    """Timer: write the tables of the worker bakes that finished (the tiles come from ``bake_tile``'s cache, so
    :func:`bake` only writes the image and the parameters). A scene whose inputs changed meanwhile (another edit,
    another file with a scene of that name) is baked again on the worker instead; one deleted or no longer still is
    dropped. A worker's error is raised again by baking at once, on the main thread, and printed with its
    traceback; the other scenes' bakes go on. Nothing is written while a render runs (it may be reading the image):
    the next check after it does."""
    if bpy.app.is_job_running("RENDER"):
        return APPLY_POLL_S
    for name, request, future, scene in _take_finished(_previews):
        job = _jobs.get(name)
        try:
            if (future.cancelled() or future.exception() is not None or scene is None or job is None
                    or job[0].key != request.key or job[1].done() or _request(scene).key != request.key):
                continue           # the full bake is done (or the preview's scene changed): nothing to show first
            _write(scene, request, future.result(), request.key + PREVIEW_MARK)
        except Exception:          # as below: the timer must go on
            traceback.print_exc()
    for _, request, future, scene in _take_finished(_jobs):
        if future.cancelled() or scene is None:
            continue
        try:
            if future.exception() is not None or _request(scene).key == request.key:
                bake(scene)
                _fill_bank(request, BANK_SPAN)   # the keys around the sun for the next move (also where a script
                                                 # drives this path in the background)
            else:
                bake_on_worker(scene)
        except Exception:   # a timer that raises is unregistered: the other scenes' bakes would never be written
            traceback.print_exc()
    return APPLY_POLL_S if _jobs or _previews else None


def _bakes_still(scene) -> bool:
    """True when the scene has the effect on and its table is one tile (nothing moves): what the worker bakes. That
    its plan bakes the tables is the callers': an action whose plan leaves the Precise level drops the scene's
    pending bakes (:func:`remove`, :func:`drop_pending`), so those that run later (the debounce, the worker's
    timer) are of a scene whose last plan baked them."""
    return bool(scene.atmos.enabled) and not moves(scene)


def _take_finished(jobs: dict[str, tuple[_Request, concurrent.futures.Future]]) -> list[tuple]:
    """Take the finished entries out of ``jobs``: (scene name, request, future, scene), the scene None where it is
    gone or no longer baked on the worker (:func:`_bakes_still`), so there is nothing to write for it."""
    finished = []
    for name, (request, future) in list(jobs.items()):
        if future.done():
            del jobs[name]
            scene = bpy.data.scenes.get(name)
            finished.append((name, request, future, scene if scene is not None and _bakes_still(scene) else None))
    return finished


def wait_for_worker(timeout_s: float = 60.0, *, write: bool = True) -> bool:
    """Block until the worker bakes under way are done and (``write``) written, at most ``timeout_s`` (scripts that
    drive the UI path, tests, the bench); True when none is left to wait for."""
    deadline = time.monotonic() + timeout_s
    if not write:
        concurrent.futures.wait([future for _, future in _jobs.values()], timeout=timeout_s)
        return all(future.done() for _, future in _jobs.values())
    while _jobs and time.monotonic() < deadline:
        concurrent.futures.wait([future for _, future in _jobs.values()], timeout=max(deadline - time.monotonic(), 0))
        if write_finished() is not None and all(future.done() for _, future in _jobs.values()):
            time.sleep(APPLY_POLL_S)   # a render holds the writes back
    if not _jobs:
        _previews.clear()          # what is left of them was skipped: their full bakes are written
        if bpy.app.timers.is_registered(write_finished):
            bpy.app.timers.unregister(write_finished)
    return not _jobs


def wait_for_first_look(timeout_s: float = 60.0, *, write: bool = True) -> None:
    """Block until the first bake of each scene the worker bakes is done (its preview, or with none its bake) and
    (``write``) written, at most ``timeout_s`` (the bench's first-look row, tests)."""
    firsts = {name: future for name, (_, future) in _jobs.items()}
    firsts.update({name: future for name, (_, future) in _previews.items()})
    concurrent.futures.wait(list(firsts.values()), timeout=timeout_s)
    if write:
        write_finished()


def pending() -> list[str]:
    """The names of the scenes whose worker bake is not written yet."""
    return sorted(_jobs)


#: An interactive re-bake, 0.3 s after the last change.
_later = Debounced(bake_on_worker)


# -- The UI's sun move: the bank of key tiles around a still scene's sun ---------------------------------------------

#: Keys of the sun's grid (``physics.precise.bank_units_around``) the worker bakes around a still scene's sun once its
#: tile is written in the UI (the two around it, then outward: +-2 deg by day, +-1 deg below 3 deg), 0.3-0.4 s each.
BANK_SPAN = 6
#: The bank's key (``physics.precise.bank_key``) -> the worker's future baking it and the event that stops it.
_bank_jobs: dict[tuple, tuple[concurrent.futures.Future, threading.Event]] = {}


def show_banked(scene) -> bool:
    """The UI's first look at a still scene's sun move: where the bank holds the two key tiles of the sun's grid around
    the new elevation (``physics.precise.tile_from_bank``), their blend is written at once (a few ms), its key marked
    :data:`PREVIEW_MARK`; the debounced bake writes the exact tile over it (:func:`bake_on_worker`; a save waits for
    it). Where the bank holds keys of this camera altitude and atmosphere but not those two (a drag past them), the
    worker bakes those two next. Nothing for an atmosphere not built yet (its own preview comes first) or a camera
    altitude the bank has no key of (a camera drag: the exact tile, then the bank around it). True when written."""
    if not _bakes_still(scene):
        return False
    request = _request(scene)
    image = stamps.local(bpy.data.images, scene_reading.groups().precise.IMAGE_NAME)
    if image is not None and image.get(_KEY) in (request.key, request.key + PREVIEW_MARK):
        return False
    if request.multiple and not tables_ready(request.atmosphere, request.albedo):
        return False
    altitude, elevation = request.path.keys[0]
    tile = tile_from_bank(request.atmosphere, altitude, elevation, **request.options)
    if tile is None:
        if banked(request.atmosphere, altitude, **request.options):
            _fill_bank(request, 2)
        return False
    _write(scene, request, [tile], request.key + PREVIEW_MARK)
    return True


def fill_bank(scene, count: int = BANK_SPAN) -> None:
    """Have the worker bake the ``count`` keys of the sun's grid nearest the sun of a still scene whose plan bakes the
    tables (what the UI does after each of its bakes; scripts that drive the UI's path, tests and the bench call it
    after a synchronous one)."""
    if _bakes_still(scene):
        _fill_bank(_request(scene), count)


def _fill_bank(request: _Request, count: int) -> None:
    """Submit the keys around ``request``'s sun that the bank lacks (the jobs of an earlier fill for other keys are
    dropped where not started); a worker error is printed (the exact bake reports its own)."""
    altitude, elevation = request.path.keys[0]
    wanted = {unit: bank_key(request.atmosphere, altitude, unit, **request.options)
              for unit in bank_units_around(elevation, count)}
    _cancel_bank(keep=set(wanted.values()))
    for unit, key in wanted.items():
        if key in _bank_jobs or banked(request.atmosphere, altitude, unit, **request.options):
            continue
        stop = threading.Event()
        future = _executor().submit(bank_tile, request.atmosphere, altitude, unit, stop=stop, **request.options)
        future.add_done_callback(_report_bank_error)
        _bank_jobs[key] = future, stop


def _report_bank_error(future: concurrent.futures.Future) -> None:
    if not future.cancelled() and future.exception() is not None:
        traceback.print_exception(future.exception())


def _cancel_bank(keep: set = frozenset()) -> None:
    """Drop the bank's jobs (but those of the keys in ``keep``): one not started is cancelled, a running one stopped
    at its next block of rows (``physics.precise.integrate_tile``'s ``stop``: 20-40 ms, so the scene's own bake
    waits no longer); forget the finished ones."""
    for key, (future, stop) in list(_bank_jobs.items()):
        if key not in keep and not future.cancel():
            stop.set()
        if future.done() or key not in keep:
            del _bank_jobs[key]


def wait_for_bank(timeout_s: float = 60.0) -> bool:
    """Block until the bank's jobs are done, at most ``timeout_s`` (tests, the bench); True when none is left."""
    concurrent.futures.wait([future for future, _ in _bank_jobs.values()], timeout=timeout_s)
    for key, (future, _) in list(_bank_jobs.items()):
        if future.done():
            del _bank_jobs[key]
    return not _bank_jobs


def finish_pending() -> None:
    """Bake now what the UI has queued (the debounced re-bake) and write what the worker is baking (before a save: a
    farm renders the file's table, so it must be the scene's)."""
    _later.flush()
    wait_for_worker()


def drop_pending(scene) -> None:
    """Drop ``scene``'s queued re-bake and its worker bakes (a running one finishes unwritten): its plan no longer
    bakes the tables. Cheap (a few dictionary look-ups)."""
    _later.discard(scene)
    for jobs in (_jobs, _previews):
        job = jobs.pop(scene.name, None)
        if job is not None:
            job[1].cancel()


def cancel_pending() -> None:
    """Drop queued re-bakes, the worker's and their timers (unregister)."""
    _later.cancel()
    for _, future in list(_jobs.values()) + list(_previews.values()):
        future.cancel()
    _jobs.clear()
    _previews.clear()
    _cancel_bank()
    _bank_jobs.clear()
    if bpy.app.timers.is_registered(write_finished):
        bpy.app.timers.unregister(write_finished)
    if _worker:
        _worker.pop().shutdown(wait=False, cancel_futures=True)
