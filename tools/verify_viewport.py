# SPDX-License-Identifier: GPL-3.0-or-later
"""What a real (GUI) Blender's 3D viewport shows with Atmos on: Rendered shading, viewport compositor, camera view.

The tests run on the pip ``bpy`` module, which cannot draw a viewport; this script runs inside a GUI Blender (an X
server is needed; Xvfb with Mesa's llvmpipe is enough, no GPU) and measures the viewport's own pixels:

    xvfb-run -s "-screen 0 1280x800x24" blender --factory-startup --python tools/verify_viewport.py -- \\
        --engine EEVEE --mode COMPOSITOR --out /work/viewport_out --tag 5.2.2_eevee_compositor
    python3 tools/verify_viewport.py --table /work/viewport_out       # the results table of every case run

(``tools/verify_viewport_chroot.sh`` sets up Debian chroots with Blender 4.3 and 5.2 and runs every case.)

The scene is the parity scene of ``tests/blender/test_aerial_application.py``: a camera at the origin looking
along +Y (20 deg field of view, 2:1 frame), three emissive planes of known radiance L0 at 300 m, 3 km and 20 km,
a constant world, a sun 30 deg up, quality Fast. The script hides the 3D viewport's headers, regions, overlays
and gizmos, looks through the camera in Rendered shading with the viewport compositor on (Always), waits until
the sampled pixels stop changing, and samples the 8-bit screen at the planes' centres and at three sky points
(the median of a 7 x 7 patch), in four phases:

* ``off``: Atmos disabled: expected sRGB(L0), which calibrates the viewport's colour pipeline;
* ``on``: Atmos enabled with its sky off (the plain world stays): expected sRGB(L0 F_ex + L_in) from
  ``atmos_addon.physics``, the sky sRGB(world colour);
* ``sky``: the Atmos sky on as well: the sky points against a final render (F12 path, the one the tests check)
  of the same scene, sampled at the same directions; the planes must stay as in ``on``;
* ``pass`` (Compositor and Per Pixel modes): the compositor's output linked straight to the Render Layers'
  ``atmos_coverage`` pass, so the screen shows whether the viewport compositor receives the AOV at all
  (1 on the planes: 255; 0 in the sky).

With the view transform Standard, look None, exposure 0, gamma 1 and dithering 0 a display pixel is the
sRGB-encoded scene-linear value. The screen is read from the X server (ImageMagick's ``import``):
``screen.screenshot_area`` gives a black image under Xvfb + llvmpipe. Each phase's screenshot of the viewport
area is saved as ``<tag>_<phase>.png``, the whole screen once as ``<tag>_window.png``; the numbers go to
``<tag>.json`` and to stdout (lines starting ``VIEWPORT``). Blender quits when done, also after an error.

The view layer's AOVs as Atmos declared them go to the JSON too: Eevee in Blender 5.2 writes 0 into a view
layer's first AOV when it is a Value AOV, which this script found (Per Pixel mode then rendered as if the effect
were off, in the viewport and in F12 renders); Atmos now declares a colour AOV first
(``atmos_addon.plan.AOVS``).
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
import traceback
from pathlib import Path

import numpy as np

try:
    import bpy
    from bpy_extras import view3d_utils
    from bpy_extras.object_utils import world_to_camera_view
    from mathutils import Vector
except ImportError:  # plain Python: only --table
    bpy = None

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "tests" / "blender"))   # the tests' scene helpers (render_utils)
sys.dont_write_bytecode = True  # Blender's Python (a chroot's 3.13 or 3.14) leaves no caches in the checkout
sys.path.insert(0, str(REPO / "tools"))
if bpy is not None:
    from gui_steps import run_steps
    from render_utils import emission_material, fast_segment, parity_world_camera_sun, render_exr, view_direction

WORLD_COLOUR = (0.05, 0.1, 0.2)
FOV = math.radians(20.0)
GRID_W, GRID_H = 32, 16          # the tests' 32 x 16 pixel grid, used to place the planes and the sky points
RENDER_W, RENDER_H = 1280, 640   # the camera frame's aspect (2:1, as the tests); also the final render's size
PLANES = (  # name, L0, distance (m), grid column, row (row 0 at the bottom): the tests' planes
    ("Near", (0.2, 0.5, 0.8), 300.0, 6, 8),
    ("Middle", (0.6, 0.4, 0.3), 3000.0, 16, 8),
    ("Far", (0.5, 0.5, 0.5), 20000.0, 26, 8),
)
SKY_POINTS = (("Sky up", 16, 14), ("Sky left", 2, 13), ("Sky down", 16, 1))  # name, grid column, row
SUN_ROTATION = (math.radians(30.0), 0.0, math.radians(40.0))  # the tests' "high" sun
PATCH = 3                        # half-size of the sampled patch, pixels (median of 7 x 7)
POLL_S = 4.0                     # seconds between screenshots while waiting for the viewport to settle
MIN_WAIT_S = 20.0                # before the first one: Eevee's shader compiles under llvmpipe are not a job
PATIENCE_S = 150.0               # how long a phase that still looks like "off" is given to change
TOLERANCE_8BIT = 3               # levels: what "matches" means in the table
PHASES = ("off", "on", "sky", "pass")


def parse_args() -> argparse.Namespace:
    argv = sys.argv[sys.argv.index("--") + 1:] if bpy is not None and "--" in sys.argv else sys.argv[1:]
    parser = argparse.ArgumentParser(prog="verify_viewport.py")
    parser.add_argument("--engine", choices=("EEVEE", "CYCLES"))
    parser.add_argument("--mode", choices=("COMPOSITOR", "PER_PIXEL", "IN_RENDER"), default="COMPOSITOR")
    parser.add_argument("--out", type=Path, help="folder for the screenshots and the JSON")
    parser.add_argument("--tag", help="file name prefix of this case")
    parser.add_argument("--timeout", type=float, default=600.0, help="seconds to wait for one phase to settle")
    parser.add_argument("--no-final-render", action="store_true", help="skip the F12 render of the sky phase")
    parser.add_argument("--table", type=Path, metavar="DIR", help="print the table of the JSON files in DIR")
    args = parser.parse_args(argv)
    if args.table is None and (bpy is None or not (args.engine and args.out and args.tag)):
        parser.error("inside Blender: --engine, --out and --tag; outside: --table DIR")
    return args


def srgb8(linear) -> np.ndarray:
    """8-bit sRGB encoding of scene-linear values (the Standard view transform on an sRGB display)."""
    x = np.clip(np.asarray(linear, dtype=float), 0.0, 1.0)
    encoded = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
    return np.round(encoded * 255.0)


# -- scene -------------------------------------------------------------------------------------------------


def grid_direction(column: float, row: float) -> Vector:
    """World direction through a grid cell centre (row 0 at the bottom) of the camera at the origin looking
    along +Y, Z up."""
    return view_direction(column, row, GRID_W, GRID_H, FOV)


def build_scene(engine: str) -> bpy.types.Scene:
    """Empty the startup file's data and build the parity scene in its (only) scene."""
    scene = bpy.context.scene
    for collection in (bpy.data.objects, bpy.data.meshes, bpy.data.materials, bpy.data.cameras, bpy.data.lights,
                       bpy.data.worlds):
        for block in list(collection):
            collection.remove(block)
    sun = parity_world_camera_sun(scene, WORLD_COLOUR, FOV)
    sun.rotation_euler = SUN_ROTATION
    camera = scene.camera.data
    camera.sensor_fit, camera.clip_start, camera.passepartout_alpha = "HORIZONTAL", 1.0, 0.0
    for name, radiance, distance, column, row in PLANES:
        direction = grid_direction(column, row)
        h = distance * 3.0 * math.tan(FOV / 2.0) / (GRID_W / 2.0)  # 3 grid cells: about 100 screen pixels
        mesh = bpy.data.meshes.new(name)
        mesh.from_pydata([(-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0)], [], [(0, 1, 2, 3)])
        mesh.materials.append(emission_material(name, radiance))
        plane = bpy.data.objects.new(name, mesh)
        plane.location = direction * distance
        plane.rotation_euler = (-direction).to_track_quat("Z", "Y").to_euler()  # faces the camera
        scene.collection.objects.link(plane)

    render = scene.render
    render.engine = engine
    render.resolution_x, render.resolution_y, render.resolution_percentage = RENDER_W, RENDER_H, 100
    render.film_transparent = False
    render.dither_intensity = 0.0
    if engine == "CYCLES":
        cycles = scene.cycles
        cycles.device = "CPU"
        cycles.samples = cycles.preview_samples = 32  # fewer leave the viewport at a coarse resolution
        cycles.use_adaptive_sampling = False
        if hasattr(cycles, "use_preview_adaptive_sampling"):
            cycles.use_preview_adaptive_sampling = False
        cycles.use_denoising = cycles.use_preview_denoising = False
        render.preview_pixel_size = "1"
    else:
        scene.eevee.taa_samples = 4
        scene.eevee.taa_render_samples = 4
    view = scene.view_settings
    view.view_transform, view.look, view.exposure, view.gamma = "Standard", "None", 0.0, 1.0
    scene.display_settings.display_device = "sRGB"
    bpy.context.view_layer.update()
    return scene


def expected_plane(scene, radiance, distance: float, column: int, row: int) -> np.ndarray:
    """L0 F_ex + L_in of the physics core for a plane (as ``test_aerial_application._expected``)."""
    transmittance, inscattered = fast_segment(scene, grid_direction(column, row), distance)
    return np.asarray(radiance) * transmittance + inscattered


def sample_points() -> list[tuple[str, Vector, tuple | None]]:
    """(name, world point, the plane's (L0, distance, column, row) or None for a sky point) of every sample."""
    points = [(name, grid_direction(c, r) * d, (l0, d, c, r)) for name, l0, d, c, r in PLANES]
    points += [(name, grid_direction(c, r) * 50_000.0, None) for name, c, r in SKY_POINTS]
    return points


def show_coverage_pass(scene) -> None:
    """Link the Render Layers' ``atmos_coverage`` output straight to the compositor's output (as the tests'
    ``_show_pass``), so the screen shows the pass the viewport compositor receives."""
    from atmos_addon.blender.apply import compositor

    tree = compositor.current_tree(scene)
    combine = tree.nodes[compositor.COMPOSITE_NODE]
    layers = combine.inputs["Image"].links[0].from_node
    output = next(n for n in tree.nodes if n.bl_idname in ("NodeGroupOutput", "CompositorNodeComposite"))
    tree.links.new(layers.outputs["atmos_coverage"], output.inputs[0])


# -- the viewport --------------------------------------------------------------------------------------------


def view3d(window):
    """The largest 3D viewport of ``window`` and its main region."""
    area = max((a for a in window.screen.areas if a.type == "VIEW_3D"), key=lambda a: a.width * a.height)
    return area, next(r for r in area.regions if r.type == "WINDOW")


def prepare_viewport(window) -> list[str]:
    """Rendered shading through the camera, the viewport compositor on, nothing drawn over the render.

    No ``screen.screen_full_area``: called from a timer it crashes Blender 4.3.2 (segfault, with or without a
    screen in the context override); hiding the area's own regions leaves its main region alone in it.
    Returns the ``use_compositor`` choices of this version."""
    area, region = view3d(window)
    space = area.spaces.active
    for name in ("show_region_header", "show_region_tool_header", "show_region_toolbar", "show_region_ui",
                 "show_region_hud", "show_region_asset_shelf"):
        try:
            setattr(space, name, False)
        except AttributeError:  # absent in this version, or read-only (5.2's asset shelf in Object Mode)
            pass
    space.overlay.show_overlays = False
    space.show_gizmo = False
    space.shading.type = "RENDERED"
    choices = list(space.shading.bl_rna.properties["use_compositor"].enum_items.keys())
    space.shading.use_compositor = "ALWAYS"
    space.region_3d.view_perspective = "CAMERA"
    with bpy.context.temp_override(window=window, area=area, region=region):
        bpy.ops.view3d.view_center_camera()
    area.tag_redraw()
    return choices


def screenshot(window, path: Path) -> np.ndarray:
    """Screenshot of the 3D viewport area from the X server to ``path`` (PNG), as RGB levels, row 0 at the bottom.

    The window is at the screen's top-left corner (Xvfb, one window; :func:`run` checks it)."""
    area, _ = view3d(window)
    top = window.height - (area.y + area.height)
    subprocess.run(["import", "-window", "root", "-crop", f"{area.width}x{area.height}+{area.x}+{top}", "+repage",
                    str(path)], check=True, timeout=60)
    image = bpy.data.images.load(str(path), check_existing=False)
    try:
        width, height, channels = *image.size, image.channels
        pixels = np.empty(width * height * channels, dtype=np.float32)
        image.pixels.foreach_get(pixels)  # a byte image: the stored levels / 255, no colour conversion
    finally:
        bpy.data.images.remove(image)
    return np.round(pixels.reshape(height, width, channels)[..., :3] * 255.0).astype(np.int16)


def area_pixels(window, points) -> dict[str, tuple[int, int]]:
    """Screenshot pixel (x, y from the bottom) of each world point, through the viewport's own projection."""
    area, region = view3d(window)
    rv3d = area.spaces.active.region_3d
    result = {}
    for name, point, _ in points:
        xy = view3d_utils.location_3d_to_region_2d(region, rv3d, point)
        result[name] = (int(round(xy.x + region.x - area.x)), int(round(xy.y + region.y - area.y)))
    return result


def patch(image: np.ndarray, xy: tuple[int, int]) -> list[float]:
    x, y = xy
    block = image[max(y - PATCH, 0):y + PATCH + 1, max(x - PATCH, 0):x + PATCH + 1].reshape(-1, 3)
    return [float(v) for v in np.median(block, axis=0)]


def compiling() -> bool:
    return bool(bpy.app.is_job_running("SHADER_COMPILATION"))


def settle(window, path: Path, timeout: float, where: dict, like_off: dict | None):
    """Screenshots every POLL_S seconds until the sampled patches agree to 1 level over three successive ones
    while no shader-compilation job runs; a phase whose patches still equal ``like_off`` (the ``off`` phase's)
    waits on up to PATIENCE_S, in case a shader is still compiling. Gives up after ``timeout``.

    The whole image is not required to settle: Eevee's viewport under llvmpipe keeps redrawing the planes'
    edges (measured in 4.3.2 and 5.2.2: some 3000 pixels inside the planes' bounding box change by up to
    about 50 levels between screenshots). A generator for the timer: yields delays, returns
    (image, seconds waited, settled, pixels still changing)."""
    start = time.monotonic()
    previous, agreeing, changing = None, 0, -1
    yield MIN_WAIT_S
    while True:
        image = screenshot(window, path)
        busy = compiling()
        waited = time.monotonic() - start
        if previous is not None and previous.shape == image.shape:
            difference = np.max(np.abs(image - previous), axis=-1)
            changing = int(np.count_nonzero(difference > 1))
            patches = max(max(abs(a - b) for a, b in zip(patch(image, xy), patch(previous, xy)))
                          for xy in where.values())
            agreeing = agreeing + 1 if patches <= 1 and not busy else 0
            rows, columns = np.nonzero(difference > 1)
            box = f"x {columns.min()}-{columns.max()}, y {rows.min()}-{rows.max()}" if changing else "none"
            print(f"VIEWPORT   poll {waited:5.0f} s: compiling={busy}, sampled patches change {patches:.0f}, "
                  f"{changing} pixels change by more than 1 (largest {int(difference.max())}, {box})", flush=True)
        if agreeing >= 2:
            unchanged = like_off is not None and all(
                max(abs(a - b) for a, b in zip(patch(image, xy), like_off[name])) <= 1 for name, xy in where.items())
            if not unchanged or waited > PATIENCE_S:
                return image, waited, True, changing
        if waited > timeout:
            return image, waited, False, changing
        previous = image
        yield POLL_S


def final_render(scene, points, folder: Path) -> dict[str, list[float]]:
    """F12-path render of the scene to EXR (scene-linear), sampled at the points (nearest pixel)."""
    pixels = render_exr(scene, folder / "final.exr")
    height, width = pixels.shape[:2]
    result = {}
    for name, point, _ in points:
        uv = world_to_camera_view(scene, scene.camera, point)
        column, row = min(int(uv.x * width), width - 1), min(int(uv.y * height), height - 1)
        result[name] = [float(v) for v in pixels[row, column]]
    return result


# -- the driver ----------------------------------------------------------------------------------------------


def run(args: argparse.Namespace, result: dict):
    """The whole measurement into ``result``, as a generator of timer delays."""
    import gpu

    import atmos_addon

    result["gpu"] = f"{gpu.platform.vendor_get()} | {gpu.platform.renderer_get()} | {gpu.platform.version_get()}"
    print(f"VIEWPORT Blender {bpy.app.version_string}, GPU {result['gpu']}", flush=True)
    engine = "CYCLES" if args.engine == "CYCLES" else (
        "BLENDER_EEVEE_NEXT" if bpy.app.version < (5, 0, 0) else "BLENDER_EEVEE")
    scene = build_scene(engine)
    stage = "register"
    try:
        atmos_addon.register()
        window = bpy.context.window_manager.windows[0]
        stage = "viewport"
        result["use_compositor_items"] = prepare_viewport(window)
        yield 3.0
        full = args.out / f"{args.tag}_window.png"  # the whole screen once: the window must fill it from (0, 0)
        subprocess.run(["import", "-window", "root", str(full)], check=True, timeout=60)
        image = bpy.data.images.load(str(full), check_existing=False)
        result["screen_size"], result["window"] = list(image.size), [window.x, window.y, window.width,
                                                                     window.height]
        bpy.data.images.remove(image)
        if result["screen_size"] != [window.width, window.height] or (window.x, window.y) != (0, 0):
            raise RuntimeError(f"window {result['window']} does not fill the screen {result['screen_size']}")
        points = sample_points()
        where = area_pixels(window, points)
        temp = Path(tempfile.mkdtemp(prefix="atmos-viewport-"))
        for phase in PHASES:
            stage = phase
            if phase == "on":
                import atmos_addon.api as atmos
                from atmos_addon.blender import facts

                report = atmos.enable(scene, quality="FAST", render_mode=args.mode, sky_enabled=False)
                result["effective_mode"] = facts.plan_of(scene).mode
                result["view_layer_aovs"] = [aov.name for aov in scene.view_layers[0].aovs]
                result["enable_messages"] = list(getattr(report, "messages", []))
            elif phase == "sky":
                scene.atmos.sky_enabled = True
            elif phase == "pass":
                if result["effective_mode"] == "IN_RENDER":
                    break  # no AOVs, no compositor group
                show_coverage_pass(scene)
            bpy.context.view_layer.update()
            png = args.out / f"{args.tag}_{phase}.png"
            off = result["phases"].get("off")
            like_off = {name: entry["viewport8"] for name, entry in off["samples"].items()} \
                if off and phase in ("on", "pass") else None
            image, waited, settled, changing = yield from settle(window, png, args.timeout, where, like_off)
            samples = {}
            for name, _, plane in points:
                entry = {"xy": where[name], "viewport8": patch(image, where[name])}
                if phase == "pass":
                    entry["expected8"] = [255.0] * 3 if plane is not None else [0.0] * 3
                elif plane is not None:
                    entry["off_expected8"] = srgb8(plane[0]).tolist()
                    linear = expected_plane(scene, *plane)
                    entry["expected_linear"] = linear.tolist()
                    entry["expected8"] = srgb8(linear).tolist() if phase != "off" else entry["off_expected8"]
                elif phase != "sky":
                    entry["expected8"] = srgb8(WORLD_COLOUR).tolist()
                samples[name] = entry
            result["phases"][phase] = {"png": str(png), "seconds": round(waited, 1), "settled": settled,
                                       "pixels_changing": changing, "samples": samples}
            print(f"VIEWPORT phase {phase}: settled={settled} after {waited:.0f} s", flush=True)
            for name, entry in samples.items():
                print(f"VIEWPORT   {name:9s} viewport {entry['viewport8']} expected {entry.get('expected8')}",
                      flush=True)
            if phase == "sky" and not args.no_final_render:
                for name, linear in final_render(scene, points, temp).items():
                    samples[name]["final_linear"], samples[name]["final8"] = linear, srgb8(linear).tolist()
                    print(f"VIEWPORT   {name:9s} final render {samples[name]['final8']}", flush=True)
            yield 0.5
    except Exception:
        result["errors"].append(f"{stage}: {traceback.format_exc()}")
        print(f"VIEWPORT ERROR in {stage}\n{traceback.format_exc()}", flush=True)


def main_in_blender(args: argparse.Namespace) -> None:
    bpy.context.preferences.view.show_splash = False  # read before the startup splash opens (after this script)
    args.out.mkdir(parents=True, exist_ok=True)
    result = {"blender": bpy.app.version_string, "engine": args.engine, "mode": args.mode, "phases": {},
              "errors": []}

    def finish():
        (args.out / f"{args.tag}.json").write_text(json.dumps(result, indent=1))
        print(f"VIEWPORT wrote {args.out / (args.tag + '.json')}", flush=True)
        bpy.ops.wm.quit_blender()

    run_steps(run(args, result), result["errors"], finish)


# -- the table (plain Python) ---------------------------------------------------------------------------------


def _levels(values) -> str:
    return "-" if values is None else "(" + ", ".join(f"{v:.0f}" for v in values) + ")"


def _largest(a, b) -> float:
    return max(abs(x - y) for x, y in zip(a, b))


def _verdict(case: dict) -> str:
    """Does the viewport show the effect: the far plane changed from ``off`` and every plane within tolerance."""
    on, off = case["phases"].get("on", {}).get("samples"), case["phases"].get("off", {}).get("samples")
    if not on or not off:
        return "not measured"
    changed = _largest(on["Far"]["viewport8"], off["Far"]["viewport8"]) > TOLERANCE_8BIT
    matches = all(_largest(on[name]["viewport8"], on[name]["expected8"]) <= TOLERANCE_8BIT for name, *_ in PLANES)
    if changed:
        return "**yes**, as expected" if matches else "yes, but not as expected"
    return "**no** (image as with the effect off)"


def print_table(folder: Path) -> None:
    """Markdown: one row per case and plane (8-bit levels), then one row per case for the verdict, the sky and
    the coverage pass."""
    cases = [json.loads(path.read_text()) | {"tag": path.stem} for path in sorted(folder.glob("*.json"))]
    print("| case | plane | effect off: viewport / sRGB(L0) | effect on: viewport / expected sRGB(L0 F_ex + L_in) "
          "| final render (F12) | viewport - expected | viewport on - off |")
    print("|---|---|---|---|---|---|---|")
    for case in cases:
        phases = case["phases"]
        label = f"{case['blender']} {case['engine']} {case['mode']}" + (
            f" (runs as {case['effective_mode']})" if case.get("effective_mode", case["mode"]) not in case["mode"]
            else "")
        if case["errors"]:
            print(f"| {label} | ERROR | {case['errors'][0].strip().splitlines()[-1]} | | | | |")
        for name, *_ in PLANES:
            off = phases.get("off", {}).get("samples", {}).get(name)
            on = phases.get("on", {}).get("samples", {}).get(name)
            final = phases.get("sky", {}).get("samples", {}).get(name, {}).get("final8")
            if off is None or on is None:
                continue
            print(f"| {label} | {name} | {_levels(off['viewport8'])} / {_levels(off['expected8'])} | "
                  f"{_levels(on['viewport8'])} / {_levels(on['expected8'])} | {_levels(final)} | "
                  f"{_largest(on['viewport8'], on['expected8']):.0f} | "
                  f"{_largest(on['viewport8'], off['viewport8']):.0f} |")
    print()
    print("| case | effect in the viewport | sky: viewport / final render (Atmos sky on; max difference) "
          "| planes changed by the sky | coverage pass in the viewport compositor: planes / sky (255 / 0 if received) "
          "| seconds per phase |")
    print("|---|---|---|---|---|---|")
    for case in cases:
        phases = case["phases"]
        sky = phases.get("sky", {}).get("samples", {})
        sky_points = [sky[name] for name, *_ in SKY_POINTS if name in sky]
        sky_text = "; ".join(f"{name}: {_levels(sky[name]['viewport8'])} / {_levels(sky[name].get('final8'))}"
                             for name, *_ in SKY_POINTS if name in sky)
        if sky_points and all("final8" in e for e in sky_points):
            sky_text += f" ({max(_largest(e['viewport8'], e['final8']) for e in sky_points):.0f})"
        planes_same = "-"
        if "on" in phases and "sky" in phases:
            on, with_sky = phases["on"]["samples"], phases["sky"]["samples"]
            largest = max(_largest(with_sky[n]["viewport8"], on[n]["viewport8"]) for n, *_ in PLANES)
            planes_same = f"{largest:.0f} levels"
        coverage = "-"
        if "pass" in phases:
            s = phases["pass"]["samples"]
            coverage = (" ".join(_levels(s[n]["viewport8"]) for n, *_ in PLANES) + " / "
                        + " ".join(_levels(s[n]["viewport8"]) for n, *_ in SKY_POINTS))
        seconds = ", ".join(f"{p} {v['seconds']:.0f}{'' if v['settled'] else ' (not settled)'}"
                            for p, v in phases.items())
        print(f"| {case['blender']} {case['engine']} {case['mode']} | {_verdict(case)} | {sky_text or '-'} | "
              f"{planes_same} | {coverage} | {seconds} |")


if __name__ == "__main__":
    ARGS = parse_args()
    if ARGS.table is not None:
        print_table(ARGS.table)
    else:
        main_in_blender(ARGS)
