# SPDX-License-Identifier: GPL-3.0-or-later
"""The README's contact sheet: the valley sample under Atmos' default (Precise with multiple scattering) for the
clear, overcast and sunset presets, and the same scene under Blender's own physical sky, sun 60, 20, 5, 1 and -4 deg.

    .venv/bpy-5.2.3/bin/python tools/make_contact_sheet.py --output docs/contact_sheet.png

Rows: one per preset (``atmos_addon.blender.ui.contact_sheet``, what ``contact-sheet valley`` renders), then
"BLENDER SKY": the valley with Atmos never enabled, its world a Sky Texture (Multiple Scattering where the running
Blender has it, 5.x; Nishita on 4.5; Blender's defaults: sea-level clear air, ozone on, the sun's disc on) and no
aerial perspective, as an artist using Blender's sky sees it. Blender's sky has its own radiance unit (its noon
zenith is about 30x Atmos' in the sun lamp's unit), so its Background strength is one constant for the whole row:
the one that makes its zenith at a 60 deg sun as bright (luminance) as Atmos' clear zenith there, measured when the
tool runs; every other difference (colour, low sun, twilight) is Blender's. Its sun lamp gets the strength and
colour Atmos' clear preset gives the ground at that elevation (a sun below the horizon: off) and its sun disc is
off (the lamp is the sun), so the two rows differ by the sky and the haze alone. Every cell: Cycles, the same
samples, denoised (OpenImageDenoise), AgX, the same exposure.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

import bpy
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

sys.path.insert(0, str(Path(__file__).resolve().parent))

import atmos_addon  # noqa: E402
import compare_sky_texture  # noqa: E402
from atmos_addon import api, presets  # noqa: E402
from atmos_addon.blender.ui import bitmap_font, contact_sheet  # noqa: E402
from atmos_addon.physics import precise  # noqa: E402
from atmos_addon.physics.sun import LUMINANCE_WEIGHTS, sun_irradiance_ground  # noqa: E402
from atmos_addon.sample_scenes import valley  # noqa: E402

PRESETS = ("clear", "overcast", "sunset")
ELEVATIONS_DEG = (60.0, 20.0, 5.0, 1.0, -4.0)
BLENDER_LABEL = "blender sky"


def valley_scene(cell: tuple[int, int], samples: int):
    """The valley sample at the cell's size, Cycles with ``samples`` samples, denoised."""
    scene = valley.build(resolution=cell)
    scene.cycles.samples = samples
    scene.cycles.use_denoising = True
    return scene


def atmos_rows(cell: tuple[int, int], samples: int, folder: Path) -> np.ndarray:
    """The presets' rows (with their labels), as ``contact-sheet valley`` renders them."""
    scene = valley_scene(cell, samples)
    api.enable(scene)
    path = contact_sheet.render_contact_sheet(scene, list(PRESETS), ELEVATIONS_DEG, cell_size=cell,
                                              output_path=folder / "atmos.png",
                                              progress=lambda done, total: print(f"atmos cell {done}/{total}",
                                                                                 flush=True))
    return contact_sheet.read_png(path)


def sky_model() -> str:
    """Blender's physical Sky Texture model: Multiple Scattering where the running Blender has it, else Nishita."""
    models = {item.identifier for item in bpy.types.ShaderNodeTexSky.bl_rna.properties["sky_type"].enum_items}
    return "MULTIPLE_SCATTERING" if "MULTIPLE_SCATTERING" in models else "NISHITA"


def configure_sky(sky, elevation_deg: float, azimuth_deg: float) -> None:
    """Blender's defaults (sea-level clear air, ozone on), the sun disc off, the sun at (elevation, azimuth clockwise
    from north): Sun Rotation r puts the sun at azimuth r (probed: 0 toward +y, 90 deg toward +x)."""
    sky.sky_type = sky_model()
    sky.sun_disc = False
    sky.sun_elevation = math.radians(elevation_deg)
    sky.sun_rotation = math.radians(azimuth_deg)


def blender_sky_strength(folder: Path) -> float:
    """The Background strength that makes Blender's zenith at a 60 deg sun as bright as Atmos' clear zenith there."""
    scene, sky, camera = compare_sky_texture.setup_scene(bpy, "Calibration")
    configure_sky(sky, 60.0, 0.0)
    blender = compare_sky_texture.render_direction(bpy, scene, camera, 90.0, 0.0, folder / "zenith.exr")
    sun = np.array([0.0, math.cos(math.radians(60.0)), math.sin(math.radians(60.0))])
    ours = precise.sky_radiance(np.array([0.0, 0.0, 1.0]), sun, presets.load("clear").atmosphere)
    return float((ours @ LUMINANCE_WEIGHTS) / (blender @ LUMINANCE_WEIGHTS))


def blender_sky_world(scene, elevation_deg: float, azimuth_deg: float, strength: float) -> None:
    """Make ``scene``'s world Blender's Sky Texture (:func:`configure_sky`) at Background ``strength``."""
    world = bpy.data.worlds.new("Blender sky")
    if hasattr(world, "use_nodes"):
        world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    nodes.clear()
    sky = nodes.new("ShaderNodeTexSky")
    configure_sky(sky, elevation_deg, azimuth_deg)
    background = nodes.new("ShaderNodeBackground")
    background.inputs["Strength"].default_value = strength
    output = nodes.new("ShaderNodeOutputWorld")
    links.new(sky.outputs["Color"], background.inputs["Color"])
    links.new(background.outputs["Background"], output.inputs["Surface"])
    scene.world = world


def blender_row(cell: tuple[int, int], samples: int, folder: Path) -> tuple[np.ndarray, float]:
    """The valley under Blender's sky, one cell per elevation (no label yet); and the sky's Background strength."""
    strength_sky = blender_sky_strength(folder)
    width, height = cell
    row = np.empty((height, width * len(ELEVATIONS_DEG), 4), dtype=np.float32)
    clear = presets.load("clear")
    azimuth = clear.sun_azimuth_deg if clear.sun_azimuth_deg is not None else valley.SUN_AZIMUTH_DEG
    for column, elevation in enumerate(ELEVATIONS_DEG):
        scene = valley_scene(cell, samples)
        blender_sky_world(scene, elevation, azimuth, strength_sky)
        sun = scene.objects["Sun"]
        e, a = math.radians(elevation), math.radians(azimuth)
        sun.rotation_euler = (math.pi / 2 - e, 0.0, math.pi - a)   # valley.place_sun's convention
        irradiance = sun_irradiance_ground(e, clear.atmosphere)
        strength = float(np.asarray(irradiance) @ LUMINANCE_WEIGHTS)
        sun.data.energy = strength
        sun.data.color = tuple(float(c) for c in np.asarray(irradiance) / strength) if strength > 0 else (1, 1, 1)
        settings = scene.render.image_settings
        if hasattr(settings, "media_type"):
            settings.media_type = "IMAGE"
        settings.file_format, settings.color_mode, settings.color_depth = "PNG", "RGBA", "8"
        scene.render.filepath = str(folder / f"blender{column}.png")
        bpy.ops.render.render(write_still=True, scene=scene.name)
        cell_pixels = contact_sheet.read_png(Path(scene.render.filepath))
        row[:, column * width:(column + 1) * width] = cell_pixels[:height, :width]
        row[..., 3] = 1.0
        print(f"blender sky cell {column + 1}/{len(ELEVATIONS_DEG)}", flush=True)
    return row, strength_sky


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", default="docs/contact_sheet.png")
    parser.add_argument("--cell", default="240x135", help="cell size WxH, px")
    parser.add_argument("--samples", type=int, default=32)
    args = parser.parse_args(argv)
    cell = tuple(int(v) for v in args.cell.lower().split("x"))
    began = time.perf_counter()
    atmos_addon.register()
    with tempfile.TemporaryDirectory(prefix="atmos-sheet-") as name:
        folder = Path(name)
        top = atmos_rows(cell, args.samples, folder)
        bottom, strength_sky = blender_row(cell, args.samples, folder)
    width, height = cell
    strip = contact_sheet.label_height(width)
    scale = contact_sheet.label_scale(width)
    labelled = np.empty((height + strip, bottom.shape[1], 4), dtype=np.float32)
    labelled[:] = contact_sheet.LABEL_BACKGROUND
    labelled[:height] = bottom
    for column, elevation in enumerate(ELEVATIONS_DEG):
        left = column * width
        bitmap_font.draw_text(labelled, contact_sheet.cell_label(BLENDER_LABEL, elevation),
                              left + contact_sheet.LABEL_MARGIN * scale, height + contact_sheet.LABEL_MARGIN * scale,
                              contact_sheet.LABEL_INK, scale)
        labelled[height:, left + width - scale:left + width] = contact_sheet.LABEL_BACKGROUND
    sheet = np.concatenate([top, labelled], axis=0)
    output = Path(args.output).resolve()
    image = bpy.data.images.new("sheet", sheet.shape[1], sheet.shape[0], alpha=True, float_buffer=False)
    image.pixels.foreach_set(np.ascontiguousarray(sheet[::-1]).ravel())
    image.filepath_raw = str(output)
    image.file_format = "PNG"
    image.save()
    print(f"wrote {output} ({sheet.shape[1]}x{sheet.shape[0]}; Blender's sky: {sky_model()} at strength "
          f"{strength_sky:.4g}; Blender {bpy.app.version_string}; {time.perf_counter() - began:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
