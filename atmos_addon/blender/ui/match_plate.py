# SPDX-License-Identifier: GPL-3.0-or-later
"""Match Plate: fit the atmosphere to a photograph and keep the result as a user preset (World > Atmosphere > Look
Development > Match Plate, and ``atmos match`` on the command line).

The fit itself is numpy (:mod:`atmos_addon.physics.match`); this module reads the plate, its masks and its depth pass
with Blender's image loading (OpenEXR, PNG, JPEG and the rest Blender reads), turns a fit into a preset and writes the
side-by-side comparison. Reading an image adds a data-block for the time of the read and removes it: a refused plate
leaves the file as it was. The preset goes to the user library (:func:`.preset_ops.user_directory`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import bpy
import numpy as np
from bpy.props import BoolProperty, EnumProperty, FloatProperty, StringProperty
from mathutils import Vector

from ... import presets
from ...physics import match
from ...presets import Preset, PresetError
from . import preset_ops

#: Image data-block that keeps the operator's comparison (plate | Atmos | difference).
COMPARISON_IMAGE = "Atmos Match Comparison"
#: Colour spaces a plate may be given in: auto takes float files (EXR, HDR) as scene-linear and 8/16-bit ones (PNG,
#: JPEG, TIFF) as sRGB-encoded.
COLORSPACES = ("auto", "srgb", "linear")
#: File formats whose values do not clip at 1 (scene-linear float data).
HIGH_RANGE_FORMATS = frozenset(("OPEN_EXR", "OPEN_EXR_MULTILAYER", "HDR"))
#: A depth pass value at or beyond this is the background (Blender writes 1e10 where no surface is), m.
DEPTH_BACKGROUND_M = 1.0e9
#: Number of surface mask slots in the operator.
SURFACE_SLOTS = 3


@dataclass
class PlateImage:
    """An image read for the fit: linear RGB (H, W, 3), row 0 at the top, and the clip level (None: float data)."""

    pixels: np.ndarray
    clip_level: float | None
    is_float: bool


def read_image(path: str | Path, colorspace: str = "auto", data: bool = False) -> PlateImage:
    """Read ``path`` with Blender's image loading as linear RGB. ``auto``: a float buffer (EXR, HDR, and the 16-bit
    PNG or TIFF Blender decodes itself) in Blender's scene-linear space, an 8-bit one as sRGB-encoded values decoded
    here (IEC 61966-2-1); ``srgb``: the stored values decoded; ``linear`` or ``data`` (a depth pass): the stored
    values as they are. Integer files (PNG, JPEG, TIFF...) clip at 1. Raises :class:`~.match.MatchError`."""
    path = Path(path)
    if colorspace not in COLORSPACES:
        raise match.MatchError(f"colour space '{colorspace}' is not one of {', '.join(COLORSPACES)}")
    if not path.is_file():
        raise match.MatchError(f"image '{path}' does not exist")
    try:
        image = bpy.data.images.load(str(path.resolve()), check_existing=False)
    except RuntimeError as error:
        first_line = str(error).strip().splitlines()[0] if str(error).strip() else "unknown reason"
        raise match.MatchError(f"cannot read '{path.name}' as an image: {first_line}") from None
    try:
        is_float = bool(image.is_float)
        high_range = image.file_format in HIGH_RANGE_FORMATS
        raw = data or colorspace != "auto" or not is_float
        if raw:
            image.colorspace_settings.name = "Non-Color"  # the stored values, decoded below when they are sRGB
        width, height = image.size
        channels = image.channels
        if width == 0 or height == 0:
            raise match.MatchError(f"'{path.name}' holds no pixels (is it an image Blender reads?)")
        values = np.empty(width * height * channels, dtype=np.float32)
        image.pixels.foreach_get(values)
    finally:
        bpy.data.images.remove(image)
    values = values.reshape(height, width, channels)[::-1].astype(np.float64)
    rgb = values[..., :3] if channels >= 3 else np.repeat(values[..., :1], 3, axis=2)
    if not data and (colorspace == "srgb" or (colorspace == "auto" and not is_float)):
        rgb = match.srgb_to_linear(np.clip(rgb, 0.0, 1.0))
    return PlateImage(np.ascontiguousarray(rgb), None if high_range else 1.0, is_float)


def read_mask(path: str | Path, shape: tuple[int, int]) -> np.ndarray:
    """A mask image as booleans (H, W): white (the mean of R, G, B times alpha above 0.5) marks the region."""
    path = Path(path)
    if not path.is_file():
        raise match.MatchError(f"mask '{path}' does not exist")
    image = bpy.data.images.load(str(path.resolve()), check_existing=False)
    try:
        if not image.is_float:
            image.colorspace_settings.name = "Non-Color"
        width, height = image.size
        channels = image.channels
        data = np.empty(width * height * channels, dtype=np.float32)
        image.pixels.foreach_get(data)
    finally:
        bpy.data.images.remove(image)
    if (height, width) != tuple(shape):
        raise match.MatchError(f"mask '{path.name}' is {width}x{height} px but the plate {shape[1]}x{shape[0]}")
    data = data.reshape(height, width, channels)[::-1]
    value = data[..., :3].mean(axis=2) if channels >= 3 else data[..., 0]
    if channels == 4:
        value = value * data[..., 3]
    return value > 0.5


def read_depth(path: str | Path, camera: match.PlateCamera, planar: bool = True) -> np.ndarray:
    """A depth pass (its first channel, metres) as the distance along each pixel's ray, (H, W); NaN where it holds no
    surface (not finite, at most 0, or Blender's background 1e10). ``planar``: the values are depths along the camera
    axis (Blender's Z pass), turned into ranges."""
    image = read_image(path, "linear", data=True)
    depth = image.pixels[..., 0].copy()
    if depth.shape != (camera.height, camera.width):
        raise match.MatchError(f"depth pass '{Path(path).name}' is {depth.shape[1]}x{depth.shape[0]} px but the plate "
                               f"{camera.width}x{camera.height}")
    depth[~np.isfinite(depth) | (depth <= 0.0) | (depth >= DEPTH_BACKGROUND_M)] = np.nan
    if planar:
        rows, cols = np.indices(depth.shape)
        depth = depth * camera.range_per_depth(rows, cols)
    return depth


#: Most rays the scene-geometry distances cast; a larger plate casts one ray per block of pixels.
MAX_GEOMETRY_RAYS = 40_000


def scene_distances(scene, camera: match.PlateCamera, skip: np.ndarray | None = None) -> np.ndarray:
    """Distances (m) along the plate's pixel rays from the scene camera to the scene's own geometry, (H, W); NaN where
    a ray meets nothing or ``skip`` is set. One ray per block of pixels when the plate has more than
    :data:`MAX_GEOMETRY_RAYS` (the block takes its ray's distance); metres from Blender units as the atmosphere reads
    them (:func:`~atmos_addon.blender.scene_reading.metres_per_unit`)."""
    from .. import scene_reading

    if scene.camera is None:
        raise match.MatchError("the scene has no camera to see its geometry through")
    step = max(1, math.ceil(math.sqrt(camera.width * camera.height / MAX_GEOMETRY_RAYS)))
    rows, cols = np.meshgrid(np.arange(0, camera.height, step), np.arange(0, camera.width, step), indexing="ij")
    centre_rows = np.minimum(rows + (step - 1) / 2.0, camera.height - 1)
    centre_cols = np.minimum(cols + (step - 1) / 2.0, camera.width - 1)
    directions = camera.directions(centre_rows.ravel(), centre_cols.ravel())
    depsgraph = bpy.context.evaluated_depsgraph_get()
    origin = scene.camera.matrix_world.translation.copy()
    metres = scene_reading.metres_per_unit(scene)
    coarse = np.full(directions.shape[0], np.nan)
    for index, direction in enumerate(directions):
        hit, location, *_ = scene.ray_cast(depsgraph, origin, Vector(direction))
        if hit:
            coarse[index] = (location - origin).length * metres
    coarse = coarse.reshape(rows.shape)
    distance = np.repeat(np.repeat(coarse, step, axis=0), step, axis=1)[:camera.height, :camera.width]
    if skip is not None:
        distance = np.where(skip, np.nan, distance)
    return np.where(distance > 0.0, distance, np.nan)


@dataclass
class SurfaceInput:
    """A surface region: a mask file and its distance (m), a depth pass (``depth_path``, ``mask_path`` optional) or
    the scene's own geometry seen through its camera (``scene_geometry``, ``mask_path`` optional)."""

    name: str
    mask_path: str | None
    distance_m: float | None = None
    depth_path: str | None = None
    depth_planar: bool = True
    surface: str = "ground"
    scene_geometry: bool = False


@dataclass
class MatchInputs:
    """Everything a match reads: the plate and its colour space, the camera, the sky mask and the surfaces."""

    plate_path: str
    fov_deg: float
    sky_mask_path: str
    surfaces: list[SurfaceInput] = field(default_factory=list)
    colorspace: str = "auto"
    pitch_deg: float | None = None
    horizon_fraction: float | None = None
    heading_deg: float = 0.0
    altitude_m: float = 0.0


def build_plate(inputs: MatchInputs, camera_from: Callable[[int, int], tuple[float, float, float]] | None = None,
                scene=None) -> match.Plate:
    """Read the plate, masks and depth passes into a :class:`~.match.Plate`; refuses bad input with MatchError.
    ``camera_from(width, height)`` gives (field of view, pitch, heading) in degrees instead of ``inputs``' own;
    ``scene`` is the scene whose geometry a ``scene_geometry`` surface measures."""
    if not inputs.sky_mask_path:
        raise match.MatchError("no sky marked: give a sky mask (white where the plate shows sky)")
    image = read_image(inputs.plate_path, inputs.colorspace)
    height, width = image.pixels.shape[:2]
    if camera_from is not None:
        inputs.fov_deg, inputs.pitch_deg, inputs.heading_deg = camera_from(width, height)
    if inputs.pitch_deg is not None and inputs.horizon_fraction is not None:
        raise match.MatchError("give the camera pitch or the horizon line, not both")
    pitch = inputs.pitch_deg if inputs.pitch_deg is not None else (
        match.pitch_from_horizon(inputs.horizon_fraction, width, height, inputs.fov_deg)
        if inputs.horizon_fraction is not None else 0.0)
    camera = match.PlateCamera(width, height, inputs.fov_deg, pitch, inputs.heading_deg, inputs.altitude_m)
    sky = read_mask(inputs.sky_mask_path, (height, width))
    regions = [match.Region("sky", sky)]
    for surface in inputs.surfaces:
        if surface.scene_geometry:
            if scene is None:
                raise match.MatchError("distances from the scene's geometry need a scene")
            distance = scene_distances(scene, camera, skip=sky)
            mask = (read_mask(surface.mask_path, (height, width)) if surface.mask_path else np.isfinite(distance))
            regions.append(match.Region(surface.name, mask & np.isfinite(distance), distance, surface.surface))
        elif surface.depth_path:
            distance = read_depth(surface.depth_path, camera, surface.depth_planar)
            mask = (read_mask(surface.mask_path, (height, width)) if surface.mask_path else
                    np.isfinite(distance) & ~sky)
            regions.append(match.Region(surface.name, mask, distance, surface.surface))
        else:
            if surface.distance_m is None:
                raise match.MatchError(f"surface '{surface.name}' needs a distance in metres or a depth pass")
            regions.append(match.Region(surface.name, read_mask(surface.mask_path, (height, width)),
                                        float(surface.distance_m), surface.surface))
    return match.Plate(image.pixels, camera, tuple(regions), image.clip_level)


def start_atmospheres(start: str, scene=None) -> dict:
    """The start atmospheres for a ``start`` choice: 'auto' (every built-in preset; the fit keeps the best), 'scene'
    (the scene's own settings), a library preset's name or a preset file."""
    from .. import settings_io

    if start == "auto":
        return {name: presets.load(name).atmosphere for name in presets.BUILTIN_NAMES}
    if start == "scene":
        if scene is None:
            raise match.MatchError("start 'scene' needs a scene")
        return {"scene": settings_io.atmosphere_from_settings(scene.atmos)}
    preset = presets.load(start, preset_ops.user_directory()) if presets.schema.is_valid_name(start) else (
        presets.validate_file(start))
    return {preset.name: preset.atmosphere}


def run(plate: match.Plate, starts: dict, knowns: match.Knowns,
        progress: Callable[[float, str], None] | None = None) -> tuple[str, match.Fit]:
    """Fit ``plate`` from each start (:func:`~.match.fit_best_start`); returns the start's name and the fit."""
    return match.fit_best_start(plate, starts, knowns, progress=progress)


def preset_from_fit(result: match.Fit, name: str, plate_path: str, start_name: str) -> Preset:
    """The fitted look as a preset (checked like a file): its atmosphere and sun, a description with the visibility
    and the sun, and a source line naming the plate."""
    look = result.look
    description = (f"Matched to {Path(plate_path).name}: visibility {look.visibility_m / 1000.0:.3g} km, sun "
                   f"{look.sun_elevation_deg:.1f} deg up")
    sources = [f"Fitted by Atmos Match Plate to {Path(plate_path).name} from the '{start_name}' preset (Fast level "
               f"model); worst region {100.0 * result.worst_colour_error:.2f} % off"]
    return presets.preset_from_atmosphere(name, look.atmosphere, round(look.sun_elevation_deg, 4),
                                          round(look.sun_azimuth_deg, 4), description=description, sources=sources)


def comparison_pixels(plate: match.Plate, result: match.Fit) -> np.ndarray:
    """The side-by-side image (plate | Atmos | difference), display sRGB, RGBA (h, w, 4), row 0 at the top."""
    rendered = match.render_plate(plate, result.look, result.surface_radiance)
    rgb = match.comparison_image(plate, rendered)
    return np.concatenate([rgb, np.ones(rgb.shape[:2] + (1,))], axis=2)


def store_comparison(pixels: np.ndarray, path: str | Path | None = None, keep: bool = True):
    """Put the comparison into the ``Atmos Match Comparison`` image (made or resized), save it as PNG when ``path``
    is given; ``keep`` False removes the data-block afterwards (the command line). Returns the image or None."""
    height, width = pixels.shape[:2]
    image = bpy.data.images.get(COMPARISON_IMAGE) if keep else None
    if image is not None and tuple(image.size) != (width, height):
        image.scale(width, height)
    if image is None:
        image = bpy.data.images.new(COMPARISON_IMAGE, width, height, alpha=True, float_buffer=False)
    image.colorspace_settings.name = "Non-Color"  # the values are display sRGB already
    image.pixels.foreach_set(np.ascontiguousarray(pixels[::-1], dtype=np.float32).ravel())
    if path is not None:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        image.filepath_raw = str(path)
        image.file_format = "PNG"
        image.save()
    if not keep:
        bpy.data.images.remove(image)
        return None
    return image


# ---------------------------------------------------------------------------------------------- the scene camera

def camera_view(scene, width: int, height: int) -> tuple[float, float, float]:
    """(horizontal field of view, pitch, heading) in degrees of the scene camera for a plate of ``width`` x ``height``
    px (the sensor fit as Blender applies it; heading clockwise from +Y). Raises MatchError without a perspective
    camera."""
    camera = scene.camera
    if camera is None or camera.type != "CAMERA":
        raise match.MatchError("the scene has no camera: add one, or turn off 'From Scene Camera' and give the field "
                               "of view")
    data = camera.data
    if data.type != "PERSP":
        raise match.MatchError(f"camera '{camera.name}' is {data.type.lower()}: the match needs a perspective camera")
    fit = data.sensor_fit
    vertical = fit == "VERTICAL" or (fit == "AUTO" and height > width)
    sensor = data.sensor_height if fit == "VERTICAL" else data.sensor_width
    half = sensor / (2.0 * data.lens)
    fov = 2.0 * math.atan(half * width / height) if vertical else 2.0 * math.atan(half)
    forward = camera.matrix_world.to_3x3() @ Vector((0.0, 0.0, -1.0))
    forward.normalize()
    pitch = math.degrees(math.asin(max(-1.0, min(1.0, forward.z))))
    heading = math.degrees(math.atan2(forward.x, forward.y))
    return math.degrees(fov), pitch, heading


# ---------------------------------------------------------------------------------------------- the operator

#: The operator's start choices: the best built-in, the scene's settings, or one built-in preset.
START_ITEMS = (("AUTO", "Best Built-in", "Fit from every built-in preset and keep the best"),
               ("SCENE", "Scene Settings", "Fit from the scene's current atmosphere"),
               *((name.upper(), name.title(), f"Fit from the '{name}' preset") for name in presets.BUILTIN_NAMES))


class ATMOS_OT_match_plate(bpy.types.Operator):
    """Fit the atmosphere to a photograph of the location (sky and surfaces at known distances) and save it as a user
    preset"""

    bl_idname = "atmos.match_plate"
    bl_label = "Match Plate"
    bl_options = {"REGISTER", "UNDO"}

    filepath: StringProperty(name="Plate", description="The photograph: EXR (scene-linear), PNG or JPEG",
                             subtype="FILE_PATH")
    colorspace: EnumProperty(name="Colour Space", items=(
        ("AUTO", "Auto", "EXR and HDR are scene-linear, PNG and JPEG sRGB"),
        ("SRGB", "sRGB", "The values carry the sRGB transfer"),
        ("LINEAR", "Linear", "The values are linear light")), default="AUTO")
    sky_mask: StringProperty(name="Sky Mask", description="Image, white where the plate shows sky (not the sun)",
                             subtype="FILE_PATH")
    surface_mask_1: StringProperty(name="Surface 1", description="Image, white on a surface at the distance below",
                                   subtype="FILE_PATH")
    distance_1: FloatProperty(name="Distance 1 (m)", description="Distance of surface 1 from the camera, metres",
                              default=2000.0, min=0.0)
    surface_mask_2: StringProperty(name="Surface 2", description="Image, white on the same kind of surface further "
                                   "away", subtype="FILE_PATH")
    distance_2: FloatProperty(name="Distance 2 (m)", default=10000.0, min=0.0)
    surface_mask_3: StringProperty(name="Surface 3", subtype="FILE_PATH")
    distance_3: FloatProperty(name="Distance 3 (m)", default=20000.0, min=0.0)
    depth_pass: StringProperty(name="Depth Pass", description="EXR whose first channel is each pixel's depth in "
                               "metres (Blender's Z pass); its surfaces are fitted too", subtype="FILE_PATH")
    use_scene_geometry: BoolProperty(name="Scene Geometry", description="Distances from the scene's own objects seen "
                                     "through the scene camera (the plate's location modelled in the scene)",
                                     default=False)
    geometry_mask: StringProperty(name="Geometry Mask", description="Image, white where the scene's geometry matches "
                                  "the plate (empty: wherever a ray meets it outside the sky)", subtype="FILE_PATH")
    use_scene_camera: BoolProperty(name="From Scene Camera", description="Field of view, pitch and heading from the "
                                   "scene camera", default=True)
    fov_deg: FloatProperty(name="Field of View", description="Horizontal field of view, degrees", default=50.0,
                           min=1.0, max=170.0)
    pitch_deg: FloatProperty(name="Pitch", description="Camera pitch above the horizon, degrees", default=0.0,
                             min=-89.0, max=89.0)
    sun_known: BoolProperty(name="Sun Known", description="Keep the scene's sun direction instead of fitting it",
                            default=False)
    exposure_known: BoolProperty(name="Exposure Known", description="The plate's exposure is the scene's Film "
                                 "exposure (else it is fitted)", default=False)
    start: EnumProperty(name="Start From", items=START_ITEMS, default="AUTO")
    preset_name: StringProperty(name="Preset Name", description="User preset the result is saved as",
                                default="Matched Plate")
    overwrite: BoolProperty(name="Overwrite", description="Replace a user preset of that name", default=False)
    apply: BoolProperty(name="Apply", description="Apply the matched preset (atmosphere and sun) to the scene",
                        default=True)
    set_exposure: BoolProperty(name="Set Film Exposure", description="Set the scene's Film exposure to the plate's "
                               "fitted exposure", default=False)

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self, width=420)

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        for name in ("filepath", "colorspace", "sky_mask"):
            layout.prop(self, name)
        for slot in range(1, SURFACE_SLOTS + 1):
            row = layout.row(align=True)
            row.prop(self, f"surface_mask_{slot}")
            row.prop(self, f"distance_{slot}", text="")
        layout.prop(self, "depth_pass")
        layout.prop(self, "use_scene_geometry")
        if self.use_scene_geometry:
            layout.prop(self, "geometry_mask")
        layout.prop(self, "use_scene_camera")
        if not self.use_scene_camera:
            layout.prop(self, "fov_deg")
            layout.prop(self, "pitch_deg")
        for name in ("sun_known", "exposure_known", "start", "preset_name", "overwrite", "apply", "set_exposure"):
            layout.prop(self, name)

    def _inputs(self, context) -> tuple[MatchInputs, match.Knowns]:
        scene = context.scene
        plate_path = bpy.path.abspath(self.filepath)
        if not self.filepath:
            raise match.MatchError("no plate: pick the photograph to match")
        surfaces = []
        for slot in range(1, SURFACE_SLOTS + 1):
            mask = getattr(self, f"surface_mask_{slot}")
            if mask:
                surfaces.append(SurfaceInput(f"surface {slot}", bpy.path.abspath(mask),
                                             getattr(self, f"distance_{slot}")))
        if self.depth_pass:
            surfaces.append(SurfaceInput("depth pass", None, depth_path=bpy.path.abspath(self.depth_pass),
                                         surface="depth pass"))
        if self.use_scene_geometry:
            surfaces.append(SurfaceInput("scene geometry", bpy.path.abspath(self.geometry_mask) if self.geometry_mask
                                         else None, scene_geometry=True, surface="scene geometry"))
        inputs = MatchInputs(plate_path, self.fov_deg, bpy.path.abspath(self.sky_mask) if self.sky_mask else "",
                             surfaces, self.colorspace.lower(), pitch_deg=self.pitch_deg)
        knowns = match.Knowns()
        if self.sun_known:
            elevation, azimuth = preset_ops.current_sun_angles_rad(scene)
            knowns = match.Knowns(math.degrees(elevation), math.degrees(azimuth))
        if self.exposure_known:
            knowns = match.Knowns(knowns.sun_elevation_deg, knowns.sun_azimuth_deg, scene.view_settings.exposure)
        return inputs, knowns

    def execute(self, context):
        scene = context.scene
        wm = context.window_manager
        try:
            presets.schema.check_name(self.preset_name)
            if presets.is_builtin(self.preset_name):
                raise PresetError(None, self.preset_name, "is a built-in preset's name; pick another")
            target = preset_ops.user_directory() / f"{self.preset_name}.toml"
            if target.exists() and not self.overwrite:
                raise PresetError(target, self.preset_name, "a user preset of that name exists; tick Overwrite or "
                                                            "pick another name")
            inputs, knowns = self._inputs(context)
            starts = start_atmospheres(self.start.lower(), scene)
            plate = build_plate(inputs, (lambda width, height: camera_view(scene, width, height))
                                if self.use_scene_camera else None, scene)
            wm.progress_begin(0, 100)
            try:
                start_name, result = run(plate, starts, knowns,
                                         lambda fraction, text: wm.progress_update(int(100 * fraction)))
            finally:
                wm.progress_end()
            preset = preset_from_fit(result, self.preset_name, inputs.plate_path, start_name)
            if self.apply:
                preset_ops.check_fits_settings(preset)
            presets.save_user_preset(preset, preset_ops.user_directory(), overwrite=self.overwrite)
            if self.apply:
                preset_ops.apply_preset(scene, preset)
                if self.set_exposure:
                    scene.view_settings.exposure = result.look.exposure_ev
        except match.MatchError as error:
            self.report({"ERROR"}, f"Atmos: cannot match the plate: {error}")
            return {"CANCELLED"}
        except PresetError as error:
            self.report({"ERROR"}, preset_ops.describe(error))
            return {"CANCELLED"}
        store_comparison(comparison_pixels(plate, result))
        worst = max(result.regions, key=lambda region: region.colour_error)
        held = f"; held: {', '.join(sorted(result.held))}" if result.held else ""
        self.report({"WARNING"} if result.misfit else {"INFO"},
                    f"Atmos: matched '{Path(inputs.plate_path).name}' from '{start_name}': visibility "
                    f"{result.look.visibility_m / 1000.0:.3g} km, sun {result.look.sun_elevation_deg:.1f} deg, worst "
                    f"region '{worst.name}' {100.0 * worst.colour_error:.2f} % off{held}; saved preset "
                    f"'{preset.name}'" + (f". {result.misfit}" if result.misfit else ""))
        return {"FINISHED"}


CLASSES = (ATMOS_OT_match_plate,)
