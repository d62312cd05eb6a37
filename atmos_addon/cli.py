# SPDX-License-Identifier: GPL-3.0-or-later
"""The Atmos command line: ``python -m atmos_addon ARGS`` (pip ``bpy``) or ``blender --command atmos ARGS``.

Sub-commands (``--help`` on each for its options):
  render SCENE [--preset P] --output PATH   render frames with the effect (PNG, or multilayer EXR with AOVs)
  apply SCENE [--preset P] --output OUT.blend  write a .blend with the effect set up, for farms without Atmos
  contact-sheet SCENE --presets a,b --elevations 60,20 --output sheet.png
  presets list | show NAME | validate FILE
  match PLATE --fov DEG --sky-mask MASK [--region MASK:DISTANCE_M] --output look.toml
                                            fit the atmosphere to a photograph and write it as a preset
  demo [--output DIR]                       render the sample scenes with every preset (the README's first command)
SCENE is a .blend file, or the name of a sample scene (valley, mars) when run from a source checkout. Without
--preset, render and apply use the file's own Atmos settings (a shot set up in the panel); a file without an Atmos
set-up needs --preset.
Progress goes to stderr; a failure ends in one line ``atmos: error: ...`` and exit code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import math
import os
import sys
import time
from pathlib import Path

from . import api
from . import presets as preset_library
from .plan import RETIRED_BALANCED_NOTE

SAMPLE_SCENES = ("valley", "mars")
ENGINES = ("cycles", "eevee")
QUALITY_LEVELS = ("fast", "precise", "auto")
#: --mode values and the scene setting each selects (``scene.atmos.render_mode``).
MODES = {"compositor": "COMPOSITOR", "per-pixel": "PER_PIXEL", "in-render": "IN_RENDER"}
EXIT_ERROR = 2


class CliError(Exception):
    """A user-facing failure: printed as one line, exit code 2."""


class _Parser(argparse.ArgumentParser):
    """argparse that reports a bad argument in one line (``atmos: error: ...``) instead of the usage block."""

    def error(self, message: str) -> None:  # type: ignore[override]
        raise CliError(f"{message} (try: {self.prog} --help)")


def _log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


# ---------------------------------------------------------------------------------------------- argument values

def _resolution(text: str) -> tuple[int, int]:
    try:
        width, height = (int(part) for part in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"resolution must look like 480x270, got '{text}'") from None
    if not (1 <= width <= 16384 and 1 <= height <= 16384):
        raise argparse.ArgumentTypeError(f"resolution {width}x{height} is outside 1..16384 pixels")
    return width, height


def _frames(text: str) -> tuple[int, int]:
    try:
        first, _, last = text.partition("-")
        start, end = int(first), int(last or first)
    except ValueError:
        raise argparse.ArgumentTypeError(f"frames must look like 1-10 or 5, got '{text}'") from None
    if end < start:
        raise argparse.ArgumentTypeError(f"frame range {text} ends before it starts")
    return start, end


def _degrees(low: float, high: float):
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"'{text}' is not a number of degrees") from None
        if not (math.isfinite(value) and low <= value <= high):
            raise argparse.ArgumentTypeError(f"{value:g} degrees is outside [{low:g}, {high:g}]")
        return value
    return parse


def _quality(text: str) -> str:
    value = text.strip().lower()
    if value == "balanced":
        raise argparse.ArgumentTypeError(f"'balanced': {RETIRED_BALANCED_NOTE}; use precise (every scattering "
                                         "order) or fast")
    if value not in QUALITY_LEVELS:
        raise argparse.ArgumentTypeError(f"'{text}' is not one of {', '.join(QUALITY_LEVELS)}")
    return value


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} must be at least 1")
    return value


def _csv(kind):
    def parse(text: str) -> list:
        items = [item.strip() for item in text.split(",") if item.strip()]
        if not items:
            raise argparse.ArgumentTypeError("give at least one value, separated by commas")
        return [kind(item) for item in items]
    return parse


# ---------------------------------------------------------------------------------------------- scene handling

def _open_scene(spec: str):
    """Open the .blend ``spec`` (or build the sample scene of that name) and return its active scene."""
    import bpy

    path = Path(spec)
    if spec in SAMPLE_SCENES and not path.exists():
        return importlib.import_module(f"{__package__}.sample_scenes.{spec}").build()
    if not path.is_file():
        raise CliError(f"scene file '{spec}' does not exist (give a .blend file, or one of: "
                       f"{', '.join(SAMPLE_SCENES)})")
    try:
        bpy.ops.wm.open_mainfile(filepath=str(path.resolve()), load_ui=False)
    except RuntimeError as error:
        first_line = str(error).strip().splitlines()[0] if str(error).strip() else "unknown reason"
        raise CliError(f"cannot read '{spec}' as a .blend file: {first_line}") from error
    return bpy.context.scene


def _configure(scene, args: argparse.Namespace) -> None:
    """Apply the render options shared by render, apply and contact-sheet."""
    if getattr(args, "engine", None):
        scene.render.engine = "CYCLES" if args.engine == "cycles" else _eevee_engine_id()
    if getattr(args, "samples", None):
        scene.cycles.samples = args.samples
        if hasattr(scene, "eevee"):
            scene.eevee.taa_render_samples = args.samples
    if getattr(args, "resolution", None):
        scene.render.resolution_x, scene.render.resolution_y = args.resolution
        scene.render.resolution_percentage = 100


def set_output_format(image_settings, multilayer_exr: bool) -> None:
    """PNG, or 32-bit multilayer OpenEXR (every pass, the atmosphere AOVs included).

    Blender 5.0 chooses multilayer output through ``media_type``; 4.5 has it as a file format.
    """
    if "media_type" in image_settings.bl_rna.properties:
        image_settings.media_type = "MULTI_LAYER_IMAGE" if multilayer_exr else "IMAGE"
    image_settings.file_format = "OPEN_EXR_MULTILAYER" if multilayer_exr else "PNG"
    if multilayer_exr:
        image_settings.color_depth = "32"
        image_settings.exr_codec = "ZIP"   # lossless: the atmosphere AOVs are data to composite with


def render_settings(scene) -> str:
    """The settings a render depends on beyond the scene's content, in one line: what a farm must use to render the
    same pixels (Cycles' denoiser, for one, is the file's setting: on in a new Cycles scene)."""
    render = scene.render
    size = (f"{render.resolution_x * render.resolution_percentage // 100}x"
            f"{render.resolution_y * render.resolution_percentage // 100} px")
    if render.engine == "CYCLES":
        cycles = scene.cycles
        return (f"Cycles, {cycles.samples} samples, denoising {'on' if cycles.use_denoising else 'off'}, seed "
                f"{cycles.seed}, {size}")
    samples = getattr(getattr(scene, "eevee", None), "taa_render_samples", None)
    return f"{render.engine.replace('BLENDER_', '').title()}, {samples} samples, {size}"


def _eevee_engine_id() -> str:
    import bpy

    engines = {item.identifier for item in bpy.types.RenderSettings.bl_rna.properties["engine"].enum_items}
    return "BLENDER_EEVEE_NEXT" if "BLENDER_EEVEE_NEXT" in engines else "BLENDER_EEVEE"


def _prepare_scene(args: argparse.Namespace, *, with_preset: bool = True):
    """Open SCENE, check it has a camera, apply the render options, enable the effect; return the scene."""
    scene = _open_scene(args.scene)
    if scene.camera is None:
        raise CliError(f"scene '{scene.name}' has no camera: add one or pick another scene")
    _configure(scene, args)
    if with_preset and args.preset is None:
        if not api.is_enabled(scene):
            raise CliError(f"scene '{scene.name}' has no Atmos set-up (the effect is off in the file): give --preset "
                           "NAME, or turn Atmos on in the file")
        _log(f"atmos: no --preset: using the Atmos settings saved in the file (scene '{scene.name}')")
    overrides = {}
    mode = getattr(args, "mode", None)
    if mode is not None:
        if mode == "in-render" and scene.render.engine != "CYCLES":
            raise CliError("--mode in-render needs Cycles (add --engine cycles); Eevee renders with --mode compositor")
        overrides["render_mode"] = MODES[mode]
    if getattr(args, "quality", None) is not None:
        overrides["quality"] = args.quality.upper()
    if with_preset:
        report = api.enable(scene, preset=args.preset, sun_elevation_deg=args.sun_elevation,
                            sun_azimuth_deg=args.sun_azimuth, **overrides)
    else:
        report = api.enable(scene, **overrides)
    for line in report.messages:
        if line:
            _log(f"atmos: {line}")
    return scene


def _frame_path(output: Path, frame: int, several: bool) -> Path:
    if "#" in output.name:
        digits = output.name.count("#")
        return output.with_name(output.name.replace("#" * digits, f"{frame:0{digits}d}", 1))
    if several:
        return output.with_name(f"{output.stem}_{frame:04d}{output.suffix}")
    return output


class _SampleProgress:
    """Prints Blender's render statistics (with the sample count) to stderr, at most twice a second."""

    def __init__(self) -> None:
        self._last = 0.0

    def __call__(self, stats: str, *_args) -> None:
        now = time.monotonic()
        if now - self._last >= 0.5 and "Sample" in str(stats):
            self._last = now
            _log(f"  {str(stats).strip()}")


# ---------------------------------------------------------------------------------------------- sub-commands

def cmd_render(args: argparse.Namespace) -> int:
    import bpy

    output = Path(args.output).resolve()
    exr = output.suffix.lower() == ".exr"
    if output.suffix.lower() not in {".png", ".exr"}:
        raise CliError(f"--output must end in .png or .exr (multilayer EXR with the atmosphere AOVs), "
                       f"got '{output.name}'")
    scene = _prepare_scene(args)
    set_output_format(scene.render.image_settings, multilayer_exr=exr)
    _log(f"atmos: {render_settings(scene)}")
    start, end = args.frames or (scene.frame_current, scene.frame_current)
    output.parent.mkdir(parents=True, exist_ok=True)
    progress = _SampleProgress()
    bpy.app.handlers.render_stats.append(progress)
    times = []
    try:
        for frame in range(start, end + 1):
            scene.frame_set(frame)
            path = _frame_path(output, frame, several=end > start)
            scene.render.filepath = str(path)
            _log(f"atmos: frame {frame} ({frame - start + 1}/{end - start + 1}) -> {path}")
            began = time.perf_counter()
            bpy.ops.render.render(write_still=True, scene=scene.name)
            times.append(time.perf_counter() - began)
            print(path)
    finally:
        bpy.app.handlers.render_stats.remove(progress)
    _log(f"atmos: rendered {len(times)} frame(s), {sum(times) / len(times):.2f} s per frame")
    return 0


def cmd_apply(args: argparse.Namespace) -> int:
    import bpy

    output = Path(args.output).resolve()
    if output.suffix.lower() != ".blend":
        raise CliError(f"--output must be a .blend file, got '{output.name}'")
    _prepare_scene(args)
    output.parent.mkdir(parents=True, exist_ok=True)
    bpy.ops.wm.save_as_mainfile(filepath=str(output), copy=True, compress=True)
    print(output)
    _log(f"atmos: wrote {output}: renders with plain `blender -b {output.name} -f N`, no add-on needed")
    return 0


def cmd_contact_sheet(args: argparse.Namespace) -> int:
    output = Path(args.output).resolve()
    if output.suffix.lower() != ".png":
        raise CliError(f"--output must be a .png file, got '{output.name}'")
    for name in args.presets:
        api.load_preset(name)  # refuse an unknown or bad preset before opening the scene
    scene = _prepare_scene(args, with_preset=False)
    from .blender.ui import contact_sheet

    total = len(args.presets) * len(args.elevations)

    def progress(done: int, label: str) -> None:
        _log(f"atmos: contact sheet cell {done}/{total}: {label}")

    began = time.perf_counter()
    path = contact_sheet.render_contact_sheet(scene, args.presets, args.elevations, cell_size=args.cell,
                                              output_path=output, progress=progress)
    _log(f"atmos: contact sheet of {total} cells in {time.perf_counter() - began:.1f} s")
    print(path)
    return 0


def cmd_presets(args: argparse.Namespace) -> int:
    try:
        if args.action == "list":
            for name in preset_library.names():
                print(f"{name}\t{'built-in' if preset_library.is_builtin(name) else 'user'}")
        elif args.action == "show":
            from .presets import writer

            print(writer.dumps(preset_library.to_document(preset_library.load(args.target))), end="")
        else:
            preset = preset_library.validate_file(Path(args.target))
            print(f"{args.target}: valid preset '{preset.name}'")
    except preset_library.PresetError as error:
        raise CliError(str(error)) from error
    return 0


def _region(text: str) -> tuple[str, float, str]:
    """MASK:DISTANCE_M[:SURFACE] (a mask image, the surface's distance in metres, the name of its kind of surface)."""
    parts = text.rsplit(":", 2)
    if len(parts) == 3 and not _is_number(parts[2]) and _is_number(parts[1]):
        mask, distance, surface = parts
    else:
        mask, _, distance = text.rpartition(":")
        surface = "ground"
    if not mask or not _is_number(distance):
        raise argparse.ArgumentTypeError(f"a region must look like far_hills.png:12000 (mask:distance in metres), "
                                         f"got '{text}'")
    return mask, float(distance), surface


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _finite(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"'{text}' is not a finite number")
    return value


class _MatchProgress:
    """One progress line on stderr per step of at least 10 % (or a new stage), as the fit goes."""

    def __init__(self) -> None:
        self._last = -1.0

    def __call__(self, fraction: float, text: str) -> None:
        if fraction >= 1.0 or fraction - self._last >= 0.1:
            self._last = fraction
            _log(f"atmos: match {100.0 * fraction:3.0f} % {text}")


def cmd_match(args: argparse.Namespace) -> int:
    from .blender.ui import match_plate
    from .blender.ui.preset_ops import user_directory
    from .physics import match
    from .presets import schema

    output = Path(args.output).resolve()
    if output.suffix.lower() != ".toml":
        raise CliError(f"--output must be a .toml preset file, got '{output.name}'")
    if args.comparison and Path(args.comparison).suffix.lower() != ".png":
        raise CliError(f"--comparison must be a .png file, got '{Path(args.comparison).name}'")
    name = args.save_preset or args.name or (output.stem if schema.is_valid_name(output.stem) else "matched plate")
    try:
        schema.check_name(name)
        if args.save_preset:
            if preset_library.is_builtin(name):
                raise preset_library.PresetError(None, name, "is a built-in preset's name; pick another")
            target = user_directory() / f"{name}.toml"
            if target.exists() and not args.overwrite:
                raise preset_library.PresetError(target, name, "a user preset of that name exists; add --overwrite "
                                                               "or pick another name")
        surfaces = [match_plate.SurfaceInput(f"region {index + 1} ({Path(mask).name})", mask, distance,
                                             surface=surface)
                    for index, (mask, distance, surface) in enumerate(args.region or [])]
        if args.depth:
            surfaces.append(match_plate.SurfaceInput("depth pass", args.depth_mask, depth_path=args.depth,
                                                     depth_planar=not args.depth_range, surface="depth pass"))
        elif args.depth_mask:
            raise CliError("--depth-mask needs --depth")
        inputs = match_plate.MatchInputs(args.plate, args.fov, args.sky_mask, surfaces, args.colorspace,
                                         pitch_deg=args.pitch, horizon_fraction=args.horizon,
                                         heading_deg=args.heading, altitude_m=args.camera_altitude)
        starts = match_plate.start_atmospheres(args.start)
        knowns = match.Knowns(args.sun_elevation, args.sun_azimuth, args.exposure)
        plate = match_plate.build_plate(inputs)
        _log(f"atmos: matching {Path(args.plate).name} ({plate.camera.width}x{plate.camera.height} px, "
             f"{len(plate.regions)} regions) from {', '.join(starts)}")
        began = time.perf_counter()
        start_name, result = match_plate.run(plate, starts, knowns, _MatchProgress())
        seconds = time.perf_counter() - began
        preset = match_plate.preset_from_fit(result, name, args.plate, start_name)
        preset_library.save(preset, output)
        if args.save_preset:
            saved = preset_library.save_user_preset(preset, user_directory(), overwrite=args.overwrite)
            _log(f"atmos: saved user preset '{name}' to {saved}")
    except match.MatchError as error:
        raise CliError(f"cannot match the plate: {error}") from error
    except preset_library.PresetError as error:
        raise CliError(str(error)) from error
    print(f"start: {start_name} (the best of {len(starts)}; {seconds:.1f} s)" if len(starts) > 1 else
          f"start: {start_name} ({seconds:.1f} s)")
    for line in match.describe(result):
        print(line)
    if args.comparison:
        path = Path(args.comparison).resolve()
        match_plate.store_comparison(match_plate.comparison_pixels(plate, result), path, keep=False)
        _log(f"atmos: wrote the comparison (plate | Atmos | difference x 4) to {path}")
    _log(f"atmos: wrote {output}")
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    """Render the valley with every built-in preset and the Mars scene; write a contact sheet and an EXR."""
    from .blender.ui import contact_sheet

    output = Path(args.output).resolve()
    output.mkdir(parents=True, exist_ok=True)
    began = time.perf_counter()
    scene = _open_scene("valley")
    scene.cycles.samples = args.samples
    api.enable(scene)
    valley_presets = [name for name in preset_library.BUILTIN_NAMES if name != "mars"]
    elevations = [60.0, 20.0, 5.0, 1.0, -4.0]   # through a low sun to the blue hour

    def progress(done: int, label: str) -> None:
        _log(f"atmos: demo cell {done}/{len(valley_presets) * len(elevations)}: {label}")

    sheet = contact_sheet.render_contact_sheet(scene, valley_presets, elevations, cell_size=tuple(args.cell),
                                               output_path=output / "contact_sheet.png", progress=progress)
    exr = output / "valley_aovs.exr"
    scene.render.resolution_x, scene.render.resolution_y = args.cell
    set_output_format(scene.render.image_settings, multilayer_exr=True)
    scene.render.filepath = str(exr)
    scene.atmos.render_mode = "COMPOSITOR"   # its per-sample passes; the default Per Pixel mode writes distances
    _log(f"atmos: rendering {exr} (multilayer EXR with the transmittance and in-scattering passes, Compositor mode)")
    import bpy

    bpy.ops.render.render(write_still=True, scene=scene.name)
    mars = _open_scene("mars")
    mars.cycles.samples = args.samples
    mars.render.resolution_x, mars.render.resolution_y = args.cell
    api.enable(mars, preset="mars")
    mars_png = output / "mars.png"
    set_output_format(mars.render.image_settings, multilayer_exr=False)
    mars.render.filepath = str(mars_png)
    _log(f"atmos: rendering {mars_png}")
    bpy.ops.render.render(write_still=True, scene=mars.name)
    for path in (sheet, exr, mars_png):
        print(f"wrote {path}")
    _log(f"atmos: demo finished in {time.perf_counter() - began:.0f} s")
    return 0


# ---------------------------------------------------------------------------------------------- parser

def _add_effect_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scene", help="a .blend file, or a sample scene name: " + ", ".join(SAMPLE_SCENES))
    parser.add_argument("--preset", help="built-in or user preset name, or a .toml file (default: the Atmos settings "
                                         "saved in the file, when it has them)")
    parser.add_argument("--sun-elevation", type=_degrees(-90.0, 90.0), help="sun elevation in degrees")
    parser.add_argument("--sun-azimuth", type=_degrees(-360.0, 360.0), help="sun azimuth in degrees, clockwise from +Y")
    parser.add_argument("--engine", choices=ENGINES, help="render engine (default: the scene's)")
    parser.add_argument("--samples", type=_positive_int, help="render samples")
    parser.add_argument("--resolution", type=_resolution, help="WIDTHxHEIGHT in pixels")
    parser.add_argument("--mode", choices=tuple(MODES),
                        help="per-pixel (both engines: the quality level evaluated once per pixel in the compositor, "
                             "no per-sample cost; a new scene's default), compositor (both engines: evaluated per "
                             "sample into AOVs, with the transmittance and in-scattering passes) or in-render (Cycles: "
                             "exact per ray segment, reflections and refractions included); default: the scene's "
                             "setting")
    parser.add_argument("--quality", type=_quality, metavar="{" + ",".join(QUALITY_LEVELS) + "}",
                        help="accuracy level: fast (constant density, single scattering, Hoffman & Preetham 2002), "
                             "precise (numerically integrated over the curved planet with every scattering order, "
                             "baked into a packed table image: key tiles along a moving camera's or sun's path) or "
                             "auto (the cheapest level within 2%% for the scene); default: the scene's setting")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="atmos", description="Atmos: physically based aerial perspective, sky and sunlight.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    render = sub.add_parser("render", help="render a scene with the effect")
    _add_effect_options(render)
    render.add_argument("--frames", type=_frames, help="frame range A-B (default: the current frame)")
    render.add_argument("--output", required=True, help="output .png or .exr (multilayer, with the AOVs); "
                                                         "#### in the name is replaced by the frame number")
    render.set_defaults(func=cmd_render)

    apply = sub.add_parser("apply", help="write a .blend with the effect set up (farm-ready, no add-on needed)")
    _add_effect_options(apply)
    apply.add_argument("--output", required=True, help="the .blend file to write")
    apply.set_defaults(func=cmd_apply)

    sheet = sub.add_parser("contact-sheet", help="render presets x sun elevations into one labelled image")
    sheet.add_argument("scene", help="a .blend file, or a sample scene name: " + ", ".join(SAMPLE_SCENES))
    sheet.add_argument("--presets", type=_csv(str), default=list(preset_library.BUILTIN_NAMES))
    sheet.add_argument("--elevations", type=_csv(_degrees(-90.0, 90.0)), default=[60.0, 20.0, 5.0, 1.0])
    sheet.add_argument("--cell", type=_resolution, default=(160, 90), help="cell size WIDTHxHEIGHT")
    sheet.add_argument("--engine", choices=ENGINES)
    sheet.add_argument("--samples", type=_positive_int)
    sheet.add_argument("--output", required=True, help="the .png to write")
    sheet.set_defaults(func=cmd_contact_sheet)

    presets = sub.add_parser("presets", help="list, show or validate presets")
    presets.add_argument("action", choices=("list", "show", "validate"))
    presets.add_argument("target", nargs="?", help="preset name (show) or file (validate)")
    presets.set_defaults(func=cmd_presets)

    fit = sub.add_parser("match", help="fit the atmosphere to a photograph (a plate) and write it as a preset")
    fit.add_argument("plate", help="the photograph: EXR (scene-linear), PNG or JPEG")
    fit.add_argument("--output", required=True, help="the preset .toml to write")
    fit.add_argument("--fov", type=_degrees(1.0, 170.0), required=True, help="horizontal field of view, degrees")
    view = fit.add_mutually_exclusive_group()
    view.add_argument("--horizon", type=_finite, help="the horizon's row as a fraction of the plate's height from "
                                                      "the top (0.5: a level camera)")
    view.add_argument("--pitch", type=_degrees(-89.0, 89.0), help="camera pitch above the horizon, degrees (default 0)")
    fit.add_argument("--heading", type=_degrees(-360.0, 360.0), default=0.0,
                     help="the azimuth the camera looks toward, degrees clockwise from +Y (default 0): the fitted sun "
                          "azimuth is in the same frame")
    fit.add_argument("--camera-altitude", type=_finite, default=0.0, help="camera height above the ground, m")
    fit.add_argument("--sky-mask", required=True, help="image, white where the plate shows sky (leave the sun out)")
    fit.add_argument("--region", type=_region, action="append", metavar="MASK:DISTANCE_M",
                     help="a surface at a known distance: mask image and metres (repeat for each; regions share one "
                          "unknown surface colour unless given MASK:DISTANCE_M:NAME)")
    fit.add_argument("--depth", help="EXR depth pass (first channel, metres; Blender's Z pass): its surfaces are "
                                     "fitted")
    fit.add_argument("--depth-mask", help="image, white where the depth pass's surfaces count (default: all but sky)")
    fit.add_argument("--depth-range", action="store_true", help="the depth pass holds distances along each ray, not "
                                                                "depths along the camera axis")
    fit.add_argument("--sun-elevation", type=_degrees(-90.0, 90.0), help="known sun elevation, degrees (else fitted)")
    fit.add_argument("--sun-azimuth", type=_degrees(-360.0, 360.0), help="known sun azimuth, degrees (else fitted)")
    fit.add_argument("--exposure", type=_finite, help="known exposure in stops: plate = 2^EV x radiance (else fitted)")
    fit.add_argument("--colorspace", choices=("auto", "srgb", "linear"), default="auto",
                     help="the plate's encoding: auto (EXR linear, PNG/JPEG sRGB; default), srgb or linear")
    fit.add_argument("--start", default="auto", help="start preset: auto (every built-in, the best kept; default), a "
                                                     "preset name or a .toml file")
    fit.add_argument("--name", help="the preset's name (default: the output file's name)")
    fit.add_argument("--save-preset", metavar="NAME", help="also save the preset to your library under NAME")
    fit.add_argument("--overwrite", action="store_true", help="replace a user preset of the same name")
    fit.add_argument("--comparison", help="write plate | Atmos | difference side by side to this .png")
    fit.set_defaults(func=cmd_match)

    demo = sub.add_parser("demo", help="render the sample scenes with every preset into a contact sheet")
    demo.add_argument("--output", default="out", help="output folder (default: out)")
    demo.add_argument("--cell", type=_resolution, default=(240, 135), help="cell size WIDTHxHEIGHT")
    demo.add_argument("--samples", type=_positive_int, default=16)
    demo.set_defaults(func=cmd_demo)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the exit code (0 success, 2 refused input or failure)."""
    try:
        args = build_parser().parse_args(argv)
        if args.command == "presets" and args.action in {"show", "validate"} and not args.target:
            raise CliError(f"presets {args.action} needs a {'name' if args.action == 'show' else 'file'}")
        return args.func(args)
    except CliError as error:
        _log(f"atmos: error: {error}")
        return EXIT_ERROR
    except api.AtmosError as error:
        _log(f"atmos: error: {error}")
        return EXIT_ERROR
    except Exception as error:  # a bug, not bad input: one line, the traceback only on request
        if os.environ.get("ATMOS_DEBUG"):
            raise
        _log(f"atmos: error: internal error {type(error).__name__}: {error} (set ATMOS_DEBUG=1 for the traceback "
             "and please report it)")
        return EXIT_ERROR
