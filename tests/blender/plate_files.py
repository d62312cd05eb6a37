# SPDX-License-Identifier: GPL-3.0-or-later
"""Plates for the Match Plate tests: a look rendered by the fit's own model (physics.match), saved with Blender's image
writing as an sRGB PNG or a scene-linear EXR, with its masks (white on black PNGs) and a depth pass."""

from __future__ import annotations

from pathlib import Path

import bpy
import numpy as np

from atmos_addon import presets
from atmos_addon.physics import match
from validation import match_plates as model_plates

WIDTH, HEIGHT = 128, 72
FOV_DEG = 55.0
#: The look of the test plates: the sunset preset's haze at 70 % of its amount, the sun 12 deg up at azimuth 60.
TRUTH = match.Look(presets.load("sunset").atmosphere.replace(
    mie_scattering=np.asarray(presets.load("sunset").atmosphere.mie_scattering) * 0.7), 12.0, 60.0, 1.0)
DISTANCES_M = {"far": 15_000.0, "near": 2_000.0}
GROUND = (0.05, 0.04, 0.03)


def bands() -> dict[str, np.ndarray]:
    """The masks of a level camera with the horizon in the middle: sky above, a far and a near band of ground."""
    rows = np.arange(HEIGHT)[:, None] * np.ones((1, WIDTH))
    horizon = HEIGHT / 2
    return {"sky": rows < horizon - 5, "far": (rows >= horizon + 1) & (rows < horizon + 7),
            "near": rows >= horizon + 13}


def camera() -> match.PlateCamera:
    return match.PlateCamera(WIDTH, HEIGHT, FOV_DEG)


def _save(path: Path, rgb: np.ndarray, exr: bool) -> Path:
    image = bpy.data.images.new(path.stem, WIDTH, HEIGHT, alpha=True, float_buffer=exr)
    try:
        if exr:
            image.colorspace_settings.name = "Non-Color"  # saved as given: no view transform on the way out
        pixels = np.concatenate([rgb, np.ones((HEIGHT, WIDTH, 1))], axis=2)[::-1]
        image.pixels.foreach_set(np.ascontiguousarray(pixels, dtype=np.float32).ravel())
        image.filepath_raw = str(path)
        image.file_format = "OPEN_EXR" if exr else "PNG"
        if exr and hasattr(image, "use_half_precision"):
            image.use_half_precision = False
        image.save()
    finally:
        bpy.data.images.remove(image)
    return path


def plane_distances() -> dict[str, np.ndarray]:
    """Ranges (m) of the far and near bands when they are walls across the view at y = 15 and 2 km (the camera at the
    origin looking along +Y): the wall's depth times each pixel's range per unit depth."""
    rows, cols = np.indices((HEIGHT, WIDTH))
    per_depth = camera().range_per_depth(rows, cols)
    return {name: DISTANCES_M[name] * per_depth for name in ("far", "near")}


def write_plate(folder: Path, exr: bool = False, look: match.Look = TRUTH, walls: bool = False) -> dict[str, Path]:
    """The plate (PNG: sRGB 8 bits; EXR: linear float) and its masks and depth pass in ``folder``; returns the paths
    by name (plate, sky, far, near, ground: far and near, depth). ``walls``: the bands are the walls of
    :func:`plane_distances` instead of surfaces at one range each."""
    folder.mkdir(parents=True, exist_ok=True)
    masks = bands()
    distances = plane_distances() if walls else DISTANCES_M
    regions = [("sky", masks["sky"], None)] + [(name, masks[name], distances[name]) for name in ("far", "near")]
    plate = model_plates.synthetic_plate(look, camera(), regions, GROUND, noise=0.005, srgb=not exr, seed=5)
    paths = {"plate": _save(folder / ("plate.exr" if exr else "plate.png"),
                            plate.pixels if exr else match.linear_to_srgb(plate.pixels), exr)}
    masks["ground"] = masks["far"] | masks["near"]
    for name, mask in masks.items():
        paths[name] = _save(folder / f"{name}.png", np.repeat(mask[..., None].astype(float), 3, axis=2), False)
    depth = np.full((HEIGHT, WIDTH), 1.0e10)
    masks = bands()
    rows, cols = np.indices((HEIGHT, WIDTH))
    for name in ("far", "near"):
        planar = DISTANCES_M[name] / camera().range_per_depth(rows, cols)  # Blender's Z pass: along the camera axis
        depth = np.where(masks[name], planar, depth)
    paths["depth"] = _save(folder / "depth.exr", np.repeat(depth[..., None], 3, axis=2), True)
    return paths


def add_walls(scene) -> None:
    """The walls of :func:`plane_distances` as meshes: the far one up to the horizon, the near one up to the row between
    the bands (so the far band's rays pass over it)."""
    half = np.tan(np.radians(FOV_DEG) / 2.0) / (WIDTH / 2.0)
    gap_row = HEIGHT / 2 + 10
    near_top = DISTANCES_M["near"] * (HEIGHT / 2.0 - gap_row) * half
    for name, y, top in (("Far Wall", DISTANCES_M["far"], 0.0), ("Near Wall", DISTANCES_M["near"], near_top)):
        mesh = bpy.data.meshes.new(name)
        mesh.from_pydata([(-1e5, y, -1e5), (1e5, y, -1e5), (1e5, y, top), (-1e5, y, top)], [], [(0, 1, 2, 3)])
        scene.collection.objects.link(bpy.data.objects.new(name, mesh))
