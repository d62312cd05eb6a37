# SPDX-License-Identifier: GPL-3.0-or-later
"""Contact sheet for look development: the scene rendered for several presets x sun elevations in one image.

Rows are presets, columns sun elevations. Each cell is a small render of the scene's camera with
the preset's atmosphere and the sun at that elevation (azimuth: the preset's when it sets one,
else the scene's), with a label strip under it ("SUNSET 5°") drawn with :mod:`.bitmap_font`. The
sheet is saved as an 8-bit PNG and kept as an Image data-block ("Atmos Contact Sheet") to view in
the Image Editor. Cells are the renderer's display-referred output (view transform applied),
copied byte for byte.

:func:`render_contact_sheet` is the plain core (the CLI uses it); :class:`ATMOS_OT_contact_sheet`
runs it one cell per timer step with progress and Esc to cancel, or all at once in background
mode. Whatever happens (success, error, cancel) the scene gets back its settings, sun, preset
name and render settings exactly (:mod:`.scene_state`).
"""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path

import bpy
import numpy as np
from bpy.props import IntProperty, StringProperty

from ... import presets
from ...presets import Preset, PresetError
from .. import orchestrator, scene_state
from . import bitmap_font, preset_ops

DEFAULT_ELEVATIONS_DEG = (60.0, 20.0, 5.0, 1.0)
DEFAULT_CELL_SIZE = (160, 90)
IMAGE_NAME = "Atmos Contact Sheet"
#: Label strip colours (display-referred sRGB, 0-1) and the space around the text, pixels at scale 1.
LABEL_BACKGROUND = (0.08, 0.08, 0.08, 1.0)
LABEL_INK = (0.92, 0.92, 0.92, 1.0)
LABEL_MARGIN = 1
#: Cycles world importance-map resolution for cells: a cell is tiny, and the default map (evaluating
#: the sky shader at 1024 x 512 texels before every render) would cost more than the cell itself.
CELL_WORLD_MAP_RESOLUTION = 64


class ContactSheetCancelled(Exception):
    """The contact sheet was cancelled (``should_cancel`` said so, or Esc); the scene is restored."""


def label_scale(cell_width: int) -> int:
    """Font scale for a cell width: 1 below 320 px, then one step more per 320 px."""
    return 1 + cell_width // 320


def label_height(cell_width: int) -> int:
    """Height of the label strip under each cell, pixels."""
    scale = label_scale(cell_width)
    return (bitmap_font.GLYPH_HEIGHT + 2 * LABEL_MARGIN) * scale


def sheet_size(preset_count: int, elevation_count: int, cell_size: Sequence[int]) -> tuple[int, int]:
    """(width, height) of a sheet: one column per elevation, one row per preset, each row a cell plus its label."""
    width, height = int(cell_size[0]), int(cell_size[1])
    return elevation_count * width, preset_count * (height + label_height(width))


def cell_label(preset_name: str, elevation_deg: float) -> str:
    return f"{preset_name} {elevation_deg:g}\u00b0"


def default_output_path() -> Path:
    """``//contact_sheet.png`` beside a saved blend file, else ``atmos_contact_sheet.png`` in the temp folder."""
    if bpy.data.filepath:
        return Path(bpy.path.abspath("//contact_sheet.png"))
    return Path(tempfile.gettempdir()) / "atmos_contact_sheet.png"


def _update_view_layers(scene) -> None:
    for layer in scene.view_layers:
        layer.update()


def read_png(path: Path) -> np.ndarray:
    """An 8-bit PNG's stored values as floats in 0-1, shape (H, W, 4), row 0 at the top (no colour conversion)."""
    image = bpy.data.images.load(str(path), check_existing=False)
    try:
        width, height = image.size
        pixels = np.empty(width * height * 4, dtype=np.float32)
        image.pixels.foreach_get(pixels)
    finally:
        bpy.data.images.remove(image)
    return pixels.reshape(height, width, 4)[::-1]


def _store_image(sheet: np.ndarray, path: Path):
    """Save the sheet as PNG and keep it as the ``Atmos Contact Sheet`` Image data-block (replaced in place)."""
    height, width = sheet.shape[:2]
    image = bpy.data.images.get(IMAGE_NAME)
    if image is not None and tuple(image.size) != (width, height):
        image.scale(width, height)
    if image is None:
        image = bpy.data.images.new(IMAGE_NAME, width, height, alpha=True, float_buffer=False)
    image.pixels.foreach_set(np.ascontiguousarray(sheet[::-1], dtype=np.float32).ravel())
    path.parent.mkdir(parents=True, exist_ok=True)
    image.filepath_raw = str(path)
    image.file_format = "PNG"
    image.save()
    return image


class ContactSheetJob:
    """One contact sheet, rendered cell by cell: :meth:`start`, :meth:`step` until :attr:`remaining` is 0,
    :meth:`finish`; :meth:`close` (always) restores the scene."""

    def __init__(self, scene, preset_list: Sequence[Preset], elevations_deg: Sequence[float],
                 cell_size: Sequence[int] = DEFAULT_CELL_SIZE, output_path: str | Path | None = None,
                 samples: int = 0):
        if not preset_list:
            raise ValueError("the contact sheet needs at least one preset")
        if not elevations_deg:
            raise ValueError("the contact sheet needs at least one sun elevation")
        width, height = int(cell_size[0]), int(cell_size[1])
        if width < 4 or height < 4:
            raise ValueError(f"cells of {width}x{height} px: Blender renders at least 4x4 pixels")
        if scene.camera is None:
            raise ValueError(f"scene '{scene.name}' has no camera to render")
        for preset in preset_list:
            preset_ops.check_fits_settings(preset)  # refuse before changing anything
        self.scene = scene
        self.presets = list(preset_list)
        self.elevations = [float(value) for value in elevations_deg]
        self.cell_size = (width, height)
        self.output_path = Path(output_path) if output_path else default_output_path()
        self.samples = int(samples)
        self.cells = [(row, column) for row in range(len(self.presets)) for column in range(len(self.elevations))]
        self.done = 0
        self._state = None
        self._folder = None
        self._sheet = None
        self._azimuth = 0.0

    @property
    def total(self) -> int:
        return len(self.cells)

    @property
    def remaining(self) -> int:
        return self.total - self.done

    def next_label(self) -> str:
        row, column = self.cells[min(self.done, self.total - 1)]
        return cell_label(self.presets[row].name, self.elevations[column])

    def start(self) -> None:
        """Record the scene and set the render up for small PNG cells."""
        scene = self.scene
        self._state = scene_state.capture(scene)
        self._azimuth = preset_ops.current_sun_angles_rad(scene)[1]
        self._folder = tempfile.TemporaryDirectory(prefix="atmos-contact-")
        width, height = sheet_size(len(self.presets), len(self.elevations), self.cell_size)
        self._sheet = np.empty((height, width, 4), dtype=np.float32)
        self._sheet[:] = LABEL_BACKGROUND
        render = scene.render
        render.resolution_x, render.resolution_y = self.cell_size
        render.resolution_percentage = 100
        settings = render.image_settings
        if hasattr(settings, "media_type"):
            settings.media_type = "IMAGE"
        settings.file_format = "PNG"
        settings.color_mode = "RGBA"
        settings.color_depth = "8"
        render.filepath = os.path.join(self._folder.name, "cell.png")
        world = scene.world
        if render.engine == "CYCLES" and world is not None and hasattr(world, "cycles"):
            world.cycles.sampling_method = "MANUAL"
            world.cycles.sample_map_resolution = CELL_WORLD_MAP_RESOLUTION
        if self.samples > 0:
            if render.engine == "CYCLES":
                scene.cycles.samples = self.samples
            elif hasattr(scene, "eevee"):
                scene.eevee.taa_render_samples = self.samples

    def step(self) -> None:
        """Render the next cell into the sheet."""
        scene = self.scene
        row, column = self.cells[self.done]
        preset = self.presets[row]
        elevation = self.elevations[column]
        azimuth = self._azimuth if preset.sun_azimuth_deg is None else math.radians(preset.sun_azimuth_deg)
        with orchestrator.batch(scene):
            orchestrator.apply_atmosphere(scene, preset.atmosphere)
            preset_ops.set_sun_angles(scene, math.radians(elevation), azimuth)
            _update_view_layers(scene)  # the sync at the end of the batch reads the lamp's new matrix
        bpy.ops.render.render(write_still=True, scene=scene.name)
        cell = read_png(Path(scene.render.filepath))
        width, height = self.cell_size
        strip = label_height(width)
        top, left = row * (height + strip), column * width
        self._sheet[top:top + height, left:left + width] = cell[:height, :width]
        self._sheet[top:top + height, left:left + width, 3] = 1.0
        scale = label_scale(width)
        bitmap_font.draw_text(self._sheet, cell_label(preset.name, elevation), left + LABEL_MARGIN * scale,
                              top + height + LABEL_MARGIN * scale, LABEL_INK, scale)
        # keep the label inside its own cell
        self._sheet[top + height:top + height + strip, left + width - scale:left + width] = LABEL_BACKGROUND
        self.done += 1

    def finish(self) -> Path:
        """Restore the scene, then save the sheet and keep it as an Image data-block; returns the PNG path."""
        self.close()
        _store_image(self._sheet, self.output_path)
        return self.output_path

    def close(self) -> None:
        """Put the scene back as :meth:`start` found it (safe to call more than once)."""
        if self._state is not None:
            state, self._state = self._state, None
            scene_state.restore(self.scene, state)
        if self._folder is not None:
            folder, self._folder = self._folder, None
            folder.cleanup()


def render_contact_sheet(scene, presets: Sequence[Preset | str],
                         elevations_deg: Sequence[float] = DEFAULT_ELEVATIONS_DEG,
                         cell_size: Sequence[int] = DEFAULT_CELL_SIZE, output_path: str | Path | None = None,
                         progress: Callable[[int, int], None] | None = None,
                         should_cancel: Callable[[], bool] | None = None, samples: int = 0) -> Path:
    """Render ``presets`` (Preset values or library names) x ``elevations_deg`` and save the sheet; return its path.

    ``progress(done, total)`` is called after each cell; ``should_cancel()`` before each cell, and
    True raises :class:`ContactSheetCancelled`. ``samples`` > 0 overrides the render samples. The
    scene comes back exactly as it was in every case. Raises :class:`PresetError` for a bad preset
    (before anything changes) and ``ValueError`` for a bad request.
    """
    preset_list = [preset_ops.load(item) if isinstance(item, str) else item for item in presets]
    job = ContactSheetJob(scene, preset_list, elevations_deg, cell_size, output_path, samples)
    job.start()
    try:
        while job.remaining:
            if should_cancel is not None and should_cancel():
                raise ContactSheetCancelled(f"cancelled after {job.done} of {job.total} cells")
            job.step()
            if progress is not None:
                progress(job.done, job.total)
        return job.finish()
    finally:
        job.close()


def parse_elevations(text: str) -> list[float]:
    """'60, 20, 5, 1' -> [60.0, 20.0, 5.0, 1.0]; each in [-10, 90] degrees."""
    values = []
    for item in text.replace(";", ",").split(","):
        if not item.strip():
            continue
        try:
            value = float(item.strip().rstrip("\u00b0"))
        except ValueError:
            raise ValueError(f"sun elevation {item.strip()!r} is not a number of degrees") from None
        if not -10.0 <= value <= 90.0:
            raise ValueError(f"sun elevation {value:g} degrees is outside -10 to 90")
        values.append(value)
    if not values:
        raise ValueError("give at least one sun elevation, e.g. '60, 20, 5, 1'")
    return values


def parse_preset_names(text: str) -> list[str]:
    """'clear, mars' -> ['clear', 'mars']; empty -> every built-in preset."""
    names = [item.strip() for item in text.split(",") if item.strip()]
    return names or list(presets.BUILTIN_NAMES)


class ATMOS_OT_contact_sheet(bpy.types.Operator):
    """Render the scene for several presets and sun elevations into one labelled image (Esc cancels)"""

    bl_idname = "atmos.contact_sheet"
    bl_label = "Render Contact Sheet"
    bl_options = {"REGISTER", "UNDO"}

    presets: StringProperty(
        name="Presets",
        description="Presets to compare, separated by commas (empty: every built-in preset)",
        default="",
    )
    elevations: StringProperty(
        name="Sun Elevations",
        description="Sun elevations above the horizon in degrees, separated by commas (one column each)",
        default="60, 20, 5, 1",
    )
    cell_width: IntProperty(name="Cell Width", description="Width of each cell, pixels", default=160, min=4,
                            soft_min=16, soft_max=640, subtype="PIXEL")
    cell_height: IntProperty(name="Cell Height", description="Height of each cell, pixels", default=90, min=4,
                             soft_min=16, soft_max=360, subtype="PIXEL")
    samples: IntProperty(name="Samples", description="Render samples per pixel for the cells (0: the scene's)",
                         default=16, min=0, soft_max=256)
    filepath: StringProperty(
        name="Output",
        description="PNG file to write (empty: contact_sheet.png beside the blend file, or in the temp folder)",
        subtype="FILE_PATH",
        default="",
    )

    _job: ContactSheetJob | None = None
    _timer = None

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self)

    def _make_job(self, context) -> ContactSheetJob | None:
        try:
            preset_list = [preset_ops.load(name) for name in parse_preset_names(self.presets)]
            output = Path(bpy.path.abspath(self.filepath)) if self.filepath else None
            return ContactSheetJob(context.scene, preset_list, parse_elevations(self.elevations),
                                   (self.cell_width, self.cell_height), output, self.samples)
        except PresetError as error:
            self.report({"ERROR"}, preset_ops.describe(error))
        except ValueError as error:
            self.report({"ERROR"}, f"Atmos contact sheet: {error}")
        return None

    def execute(self, context):
        job = self._make_job(context)
        if job is None:
            return {"CANCELLED"}
        if not context.scene.atmos.enabled:
            self.report({"WARNING"}, "Atmos is off for this scene: the sheet shows it without the atmosphere")
        if bpy.app.background or context.window is None:
            job.start()
            try:
                while job.remaining:
                    job.step()
                path = job.finish()
            except (RuntimeError, OSError, ValueError) as error:
                self.report({"ERROR"}, f"Atmos contact sheet failed: {error}")
                return {"CANCELLED"}
            finally:
                job.close()
            self.report({"INFO"}, f"Atmos: contact sheet saved to {path}")
            return {"FINISHED"}
        self._job = job
        job.start()
        manager = context.window_manager
        manager.progress_begin(0, job.total)
        self._timer = manager.event_timer_add(0.05, window=context.window)
        manager.modal_handler_add(self)
        self._status(context)
        return {"RUNNING_MODAL"}

    def _status(self, context, text: str | None = "") -> None:
        job = self._job
        if text == "" and job is not None:
            text = f"Atmos contact sheet: cell {job.done + 1} of {job.total} ({job.next_label()}), Esc to cancel"
        if context.workspace is not None:
            context.workspace.status_text_set(text)
        if context.area is not None:
            context.area.header_text_set(text)

    def _end(self, context) -> None:
        manager = context.window_manager
        if self._timer is not None:
            manager.event_timer_remove(self._timer)
            self._timer = None
        manager.progress_end()
        self._status(context, None)
        if self._job is not None:
            self._job.close()

    def modal(self, context, event):
        if event.type == "ESC":
            self._end(context)
            self.report({"WARNING"}, "Atmos contact sheet cancelled; the scene is as it was")
            return {"CANCELLED"}
        if event.type != "TIMER" or event.timer is not self._timer:
            return {"RUNNING_MODAL"}
        job = self._job
        try:
            if job.remaining:
                job.step()
                context.window_manager.progress_update(job.done)
                self._status(context)
                if job.remaining:
                    return {"RUNNING_MODAL"}
            path = job.finish()
        except (RuntimeError, OSError, ValueError) as error:
            self._end(context)
            self.report({"ERROR"}, f"Atmos contact sheet failed: {error}")
            return {"CANCELLED"}
        self._end(context)
        _show(context, bpy.data.images.get(IMAGE_NAME))
        self.report({"INFO"}, f"Atmos: contact sheet saved to {path}")
        return {"FINISHED"}

    def cancel(self, context):
        self._end(context)


def _show(context, image) -> None:
    """Show the sheet in an open Image Editor, if there is one."""
    if image is None or context.screen is None:
        return
    for area in context.screen.areas:
        if area.type == "IMAGE_EDITOR":
            area.spaces.active.image = image
            return


CLASSES = (ATMOS_OT_contact_sheet,)
