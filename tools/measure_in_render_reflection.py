# SPDX-License-Identifier: GPL-3.0-or-later
"""Reflection residual of In-Render mode: a mirror lake in the sample valley, In-Render against Compositor mode.

    .venv/bpy-5.2.3/bin/python tools/measure_in_render_reflection.py [--resolution 320x180] [--samples 16]

In In-Render mode the world is multiplied by exp(tau_dome(d)) on camera, glossy and transmission rays, the
optical depth of the camera-centred domes along d. A sky ray reflected at a point p leaves the domes after
l_i(p, d) instead of R_i(d); without the domes' transparent filters (``atmos_addon.node_groups.in_render.dome_filter``)
the reflected sky would be off by the factor

    r = exp(sum_i sigma_i (R_i(d) - l_i(p, d)))
      ~ exp(sum_i sigma_i (p - c) . n_i / (n_i . d))     to first order in |p - c| / R_i

(sigma_R = beta_R for the molecules' dome, sigma_M = beta_M + beta_M,abs for the aerosols'; n_i the dome's
normal where the ray leaves it). Where the dome is locally a sphere (n_i = d) this is exp(beta_ex dot(p - c, d));
where it is locally flat (n_i = up, the dome high above the ground: R_i(e) ~ H_i / sin e) it is
exp(-sum_i sigma_i h / sin e), h the height of the camera above p. The filters multiply the leaving ray by
exp(sigma_i l_i - tau_i(d)), which cancels r: this tool measures what is left (expected: 0 up to noise and the
pixel filter) next to the r the filters remove (the "without the filters" columns).

Scene: ``atmos_addon/sample_scenes/valley.py`` with its lake made a perfect mirror (Glossy BSDF, white, roughness 0) and
extended from the shore (y = -5 m) to the foot of the first ridge (y = 1000 m), x = +-1000 m, at the lake's
height (z = -0.3 m); the "clear" preset, the Atmos sky, Cycles on the CPU, Standard view transform, 32-bit EXR.

Reference: the same file in Compositor mode. There the mirror sees the Atmos sky unattenuated (no domes, no
compensation): the reflected sky is exact, and the compositor applies the first segment (camera -> lake),
out = I T + L with the lake's AOVs (coverage 1 on the lake). In-Render mode gives T (I r) + L with the same
T and L (the per-material emission and the dome along the first segment), so

- the pixel error In-Render / reference - 1 is the headline number (what a user sees);
- the sky term's residual is measured as r - 1 = (In-Render - reference) / (reference - L), L the compositor's
  in-scattering AOV, and shown beside the r the filters remove: from the dome geometry (l_i solved by
  bisection on the analytic dome R_i(e) of ``physics.dome_mesh``, for the pixel-centre rays) and the sphere
  form exp(beta_ex dot(p - c, d)). Both in the blue channel (the largest coefficients), signed: mean and the value
  of largest magnitude.

Pixels: the lake pixels that reflect sky, found by ray casts through the pixel centres before Atmos is enabled
(camera ray hits the mirror, reflected ray hits nothing), eroded by ``margin`` px so that no pixel-filter
footprint reaches a reflected object or the shore. Baseline: the pixels that see the sky directly (same
erosion), In-Render against Compositor: the two modes' agreement where no reflection is involved.
Errors are relative, max over RGB; mean and max over the pixels.

Cameras: "valley" is the sample's camera (2 m above the ground, 2.3 m above the lake, 3 deg up); there the
ridges hide the reflected sky except within about 25 m of the shore. "raised" puts the camera 50 m above the
lake, 10 deg down, so the lake reflects sky out to a few hundred metres: r grows with h / sin e.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import time
import warnings
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO_ROOT))
sys.path.insert(0, str(REPO_ROOT / "tests" / "blender"))

import bpy  # noqa: E402
import numpy as np  # noqa: E402
from mathutils import Vector  # noqa: E402

import atmos_addon  # noqa: E402
from atmos_addon import api  # noqa: E402
from atmos_addon.blender.apply import in_render  # noqa: E402
from atmos_addon.blender import facts, scene_reading  # noqa: E402
from atmos_addon.physics.dome_mesh import dome_radius  # noqa: E402
from render_utils import render_to_array, route_compositor_output  # noqa: E402
from atmos_addon.sample_scenes import valley  # noqa: E402

LAKE_Z = -0.3
MIRROR_NAME = "Mirror lake"
#: name -> (camera height above the lake in m, camera pitch from straight down in deg)
CAMERAS = {"valley": (valley.CAMERA_HEIGHT_M - LAKE_Z, 93.0), "raised": (50.0, 80.0)}


def _resolution(text: str) -> tuple[int, int]:
    width, height = (int(part) for part in text.lower().split("x"))
    return width, height


def _mirror_material() -> bpy.types.Material:
    material = bpy.data.materials.new("Mirror lake")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        material.use_nodes = True
    tree = material.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    glossy = tree.nodes.new("ShaderNodeBsdfGlossy")
    glossy.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    glossy.inputs["Roughness"].default_value = 0.0
    tree.links.new(glossy.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    return material


def build(args: argparse.Namespace, camera_name: str):
    """The valley with the mirror lake, the given camera, render settings; Atmos not enabled yet."""
    scene = valley.build(args.resolution)
    bpy.data.objects.remove(bpy.data.objects["Lake"])
    valley.grid_object(MIRROR_NAME, np.linspace(-1000.0, 1000.0, 2), np.linspace(-5.0, 1000.0, 2),
                       np.full((2, 2), LAKE_Z), _mirror_material())
    height, pitch = CAMERAS[camera_name]
    scene.camera.location.z = LAKE_Z + height
    scene.camera.rotation_euler = (math.radians(pitch), 0.0, 0.0)
    render = scene.render
    render.resolution_percentage = 100
    render.use_compositing = True
    render.threads_mode = "FIXED"
    render.threads = args.threads
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    cycles = scene.cycles
    cycles.device = "CPU"
    cycles.samples = args.samples
    cycles.use_adaptive_sampling = False
    cycles.use_denoising = False
    cycles.seed = 0
    bpy.context.view_layer.update()  # the camera's matrix_world and the depsgraph the ray casts use
    return scene


def pixel_rays(scene) -> tuple[np.ndarray, np.ndarray]:
    """Camera position (3,) and unit directions (H, W, 3) through the pixel centres, row 0 at the bottom."""
    width, height = scene.render.resolution_x, scene.render.resolution_y
    camera = scene.camera
    frame = [Vector(v) for v in camera.data.view_frame(scene=scene)]  # top right, bottom right, bottom left, top left
    right, bottom, left, top = frame[0].x, frame[1].y, frame[2].x, frame[0].y
    depth = frame[0].z
    xs = left + (np.arange(width) + 0.5) / width * (right - left)
    ys = bottom + (np.arange(height) + 0.5) / height * (top - bottom)
    local = np.stack(np.broadcast_arrays(xs[None, :], ys[:, None], np.full((1, 1), depth)), axis=-1)
    rotation = np.array(camera.matrix_world.to_3x3())
    world = local @ rotation.T
    world /= np.linalg.norm(world, axis=-1, keepdims=True)
    return np.array(camera.matrix_world.translation), world


def classify(scene, directions: np.ndarray, origin: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per pixel: sees the sky directly; reflects sky in the mirror; the mirror point (H, W, 3, NaN elsewhere)."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    height, width, _ = directions.shape
    sky = np.zeros((height, width), dtype=bool)
    reflects_sky = np.zeros((height, width), dtype=bool)
    points = np.full((height, width, 3), np.nan)
    start = Vector(origin)
    for row in range(height):
        for column in range(width):
            d = Vector(directions[row, column])
            hit, location, _normal, _index, obj, _matrix = scene.ray_cast(depsgraph, start, d)
            if not hit:
                sky[row, column] = True
                continue
            if obj is None or obj.name != MIRROR_NAME:
                continue
            out = Vector((d.x, d.y, -d.z))
            again = scene.ray_cast(depsgraph, location + out * 1e-3, out)[0]
            if not again:
                reflects_sky[row, column] = True
                points[row, column] = tuple(location)
    return sky, reflects_sky, points


def erode(mask: np.ndarray, margin: int) -> np.ndarray:
    height, width = mask.shape
    padded = np.pad(mask, margin, constant_values=False)
    out = mask.copy()
    for dy in range(2 * margin + 1):
        for dx in range(2 * margin + 1):
            out &= padded[dy:dy + height, dx:dx + width]
    return out


def render(scene) -> np.ndarray:
    """One render (after the compositor, if any); linear RGB (H, W, 3), row 0 at the bottom."""
    return render_to_array(scene)[::-1, :, :3].astype(np.float64)


def _exit_distance(q0: np.ndarray, d: np.ndarray, planet: float, scale_height: float) -> np.ndarray:
    """l >= 0 with |q0 + l d| = R(elevation of q0 + l d): where a ray from q0 (camera-relative) leaves the dome."""
    low = np.zeros(q0.shape[:-1])
    high = np.full(q0.shape[:-1], 2.0 * float(dome_radius(0.0, planet, scale_height)) + 1.0)
    for _ in range(80):
        middle = 0.5 * (low + high)
        q = q0 + middle[..., None] * d
        distance = np.linalg.norm(q, axis=-1)
        outside = distance > dome_radius(np.arcsin(np.clip(q[..., 2] / distance, -1.0, 1.0)), planet, scale_height)
        high = np.where(outside, middle, high)
        low = np.where(outside, low, middle)
    return 0.5 * (low + high)


def predicted_residual(scene, origin: np.ndarray, points: np.ndarray, out: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(r from the dome geometry, exp(beta_ex dot(p - c, d))), each (N, 3): the reflected sky's extra factor."""
    atmosphere = scene_reading.atmosphere_of(scene)
    metres = scene_reading.metres_per_unit(scene)
    q0 = (points - origin) * metres
    elevation = np.arcsin(np.clip(out[..., 2], -1.0, 1.0))
    log_r = np.zeros(q0.shape[:-1] + (3,))
    for sigma, height in ((atmosphere.rayleigh_scattering, atmosphere.rayleigh_scale_height),
                          (atmosphere.mie_scattering + atmosphere.mie_absorption, atmosphere.mie_scale_height)):
        dome = dome_radius(elevation, atmosphere.planet_radius, height)
        inside = dome - _exit_distance(q0, out, atmosphere.planet_radius, height)
        log_r += inside[..., None] * np.asarray(sigma)[None, :]
    beta_ex = atmosphere.rayleigh_scattering + atmosphere.mie_scattering + atmosphere.mie_absorption
    simple = np.exp(np.sum(q0 * out, axis=-1)[..., None] * np.asarray(beta_ex)[None, :])
    return np.exp(log_r), simple


def _stats(values: np.ndarray) -> str:
    """Mean and max of non-negative errors, in %."""
    if values.size == 0:
        return "n/a | n/a"
    return f"{values.mean():.3%} | {values.max():.3%}"


def _signed(values: np.ndarray) -> str:
    """Mean and the value of largest magnitude (signed), in %."""
    if values.size == 0:
        return "n/a | n/a"
    return f"{values.mean():+.3%} | {values[np.argmax(np.abs(values))]:+.3%}"


def measure(args: argparse.Namespace, camera_name: str) -> dict:
    began = time.perf_counter()
    scene = build(args, camera_name)
    origin, directions = pixel_rays(scene)
    sky, reflects_sky, points = classify(scene, directions, origin)
    sky, lake = erode(sky, args.margin), erode(reflects_sky, args.margin)
    api.enable(scene, preset=args.preset)
    route_compositor_output(scene, "atmos_inscattering")
    inscattering = render(scene)
    route_compositor_output(scene, None)
    reference = render(scene)
    scene.atmos.render_mode = "IN_RENDER"
    if not in_render.is_installed(scene):
        raise SystemExit(f"In-Render mode did not install: {facts.plan_of(scene).notes}")
    hazed = render(scene)
    finite = {"reference": int(np.sum(~np.isfinite(reference))), "In-Render": int(np.sum(~np.isfinite(hazed)))}
    pixel_error = np.max(np.abs(hazed / reference - 1.0), axis=-1)
    measured_r = (hazed - reference) / (reference - inscattering)
    p = points[lake]
    d = directions[lake] * np.array([1.0, 1.0, -1.0])
    exact, simple = predicted_residual(scene, origin, p, d)
    distance = np.linalg.norm(p - origin, axis=-1)
    result = dict(camera=camera_name, lake_px=int(lake.sum()), sky_px=int(sky.sum()),
                  distance=(float(distance.min()), float(distance.max())) if distance.size else None,
                  pixel=pixel_error[lake], measured=measured_r[lake][:, 2], exact=exact[:, 2] - 1.0,
                  simple=simple[:, 2] - 1.0, baseline=pixel_error[sky], nonfinite=finite,
                  seconds=time.perf_counter() - began)
    if args.save_images:
        np.savez_compressed(Path(args.save_images) / f"reflection_{camera_name}.npz", reference=reference,
                            in_render=hazed, inscattering=inscattering, lake=lake, sky=sky)
    return result


def markdown(results: list[dict]) -> str:
    lines = ["| camera | sky-reflecting lake px | lake distance (m) | pixel error, In-Render vs reference: mean | max "
             "| r - 1 (blue), measured: mean | extreme | without the filters, dome geometry: mean | extreme "
             "| without the filters, sphere form exp(beta_ex dot(p - c, d)) - 1: mean | extreme | direct sky px "
             "| baseline (direct sky): mean | max |",
             "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in results:
        span = "n/a" if r["distance"] is None else f"{r['distance'][0]:.0f}-{r['distance'][1]:.0f}"
        lines.append(f"| {r['camera']} | {r['lake_px']} | {span} | {_stats(r['pixel'])} | {_signed(r['measured'])} | "
                     f"{_signed(r['exact'])} | {_signed(r['simple'])} | {r['sky_px']} | {_stats(r['baseline'])} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolution", type=_resolution, default=(320, 180), help="WIDTHxHEIGHT")
    parser.add_argument("--samples", type=int, default=16)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--preset", default="clear")
    parser.add_argument("--cameras", default=",".join(CAMERAS), help="comma-separated: " + ", ".join(CAMERAS))
    parser.add_argument("--margin", type=int, default=2, help="erosion of the pixel masks, px")
    parser.add_argument("--save-images", metavar="DIR", help="write the renders and masks as .npz here")
    args = parser.parse_args(argv)
    atmos_addon.register()
    results = []
    for camera_name in args.cameras.split(","):
        result = measure(args, camera_name.strip())
        results.append(result)
        gap = result["measured"] - result["exact"]
        print(f"{camera_name}: {result['seconds']:.0f} s; non-finite values {result['nonfinite']}; blue channel, "
              f"measured r - r without the filters (dome geometry): mean {gap.mean() if gap.size else float('nan'):+.2e}, "
              f"max |.| {np.abs(gap).max() if gap.size else float('nan'):.2e}", flush=True)
    width, height = args.resolution
    print(f"\nBlender {bpy.app.version_string}, valley with a mirror lake, {width}x{height} px, "
          f"{args.samples} samples, "
          f"preset '{args.preset}', margin {args.margin} px; {platform.system()}, {os.cpu_count()} cores\n")
    print(markdown(results))
    atmos_addon.unregister()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
