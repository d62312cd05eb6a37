# SPDX-License-Identifier: GPL-3.0-or-later
"""Silhouette scenes built from scratch and their per-sample reference, shared by ``test_silhouettes.py`` and
``tools/measure_silhouettes.py``.

The scene: an empty factory file, a camera at the origin looking along +Y (20 deg field of view), a sun lamp, no
world (Atmos makes its sky), the "clear" preset with the sun 30 deg up. Its surfaces are emissive with a noise
texture (a known radiance that changes across them): a plane 20 km away whose slanted top edge stands against the
sky (the ridge), and in front of its lower left a plane 200 m away with a slanted edge (near over far).

The reference is the same render with the atmosphere applied to every sample inside the shader: each surface's
emission replaced by I F_ex + L_in from the "Atmos Aerial Perspective" shader group (the Compositor mode's, at the
scene's level), the compositor off. It has the same pixels, filter, samples and seed, so it differs from Atmos's
composite only by what compositing filtered passes cannot know. The edge pixels are those a surface covers in part
(another render: the surfaces as flat colours, Film > Transparent), the interior ones those more than a pixel from
any edge.
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass
from pathlib import Path

import bpy
import numpy as np

import render_utils as ru

#: The Atmos group every managed material carries (``atmos_addon.node_groups.surface``).
SURFACE_GROUP = "Atmos Surface AOVs"

FOV = math.radians(20.0)
NEAR_M, FAR_M = 200.0, 20000.0
NEAR_RADIANCE, FAR_RADIANCE = (0.2, 0.5, 0.8), (0.6, 0.4, 0.3)
#: The two kinds of edge: the ridge against the sky, the near plane over the far one.
EDGES = ("ridge", "near/far")
#: Cycles' and Eevee's defaults: a 1.5 px Blackman-Harris filter (Cycles), a 1.5 px filter (Eevee).
DEFAULT_FILTER_PX = 1.5


def _textured_emission(name: str, radiance, scale: float) -> bpy.types.Material:
    """An emission of ``radiance`` times 0.6 + 0.8 noise (a Noise texture of ``scale`` on the object's coordinates)."""
    material = ru.emission_material(name, radiance)
    tree = material.node_tree
    emission = next(node for node in tree.nodes if node.bl_idname == "ShaderNodeEmission")
    coordinates = tree.nodes.new("ShaderNodeTexCoord")
    noise = tree.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = scale
    tree.links.new(coordinates.outputs["Object"], noise.inputs["Vector"])
    ramp = tree.nodes.new("ShaderNodeMath")
    ramp.operation = "MULTIPLY_ADD"
    ramp.inputs[1].default_value, ramp.inputs[2].default_value = 0.8, 0.6
    tree.links.new(noise.outputs["Fac"], ramp.inputs[0])
    tint = tree.nodes.new("ShaderNodeVectorMath")
    tint.operation = "SCALE"
    tint.inputs[0].default_value = radiance
    tree.links.new(ramp.outputs[0], tint.inputs["Scale"])
    tree.links.new(tint.outputs[0], emission.inputs["Color"])
    material["atmos_test_radiance"] = tint.name   # the node whose output is the surface's radiance I
    return material


def _quad(scene, name: str, corners, material) -> bpy.types.Object:
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(c) for c in corners], [], [(0, 1, 2, 3)])
    mesh.update()
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    scene.collection.objects.link(obj)
    return obj


def build(engine: str, mode: str, width: int, height: int, samples: int, *, quality: str = "PRECISE",
          textured: bool = True):
    """An empty factory file with the camera, a sun lamp and the two planes (module docstring), Atmos enabled in
    ``mode`` at ``quality``, rendered by ``engine`` at ``width`` x ``height`` with ``samples`` and the default
    filter."""
    import atmos_addon
    import atmos_addon.api

    if hasattr(bpy.types.Scene, "atmos"):
        atmos_addon.unregister()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    atmos_addon.register()
    scene = bpy.context.scene
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.data.sensor_fit = "HORIZONTAL"
    camera.data.angle = FOV
    camera.data.clip_start, camera.data.clip_end = 1.0, 30000.0
    camera.rotation_euler = (math.pi / 2.0, 0.0, 0.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    scene.collection.objects.link(bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN")))
    half = math.tan(FOV / 2.0)
    vhalf = half * height / width
    far = _textured_emission("Far", FAR_RADIANCE, 0.002) if textured else ru.emission_material("Far", FAR_RADIANCE)
    near = _textured_emission("Near", NEAR_RADIANCE, 0.2) if textured else ru.emission_material("Near", NEAR_RADIANCE)
    # The ridge: its top edge rises from 0.23 below the middle at the left to 0.41 above it at the right (in units
    # of the half height); the near plane: below 0.45 under the middle, its right edge slanted across 0.3 of the
    # half width. Slanted edges: every coverage occurs.
    far_x, far_z = 1.5 * FAR_M * half, 1.5 * FAR_M * vhalf
    _quad(scene, "Far", [(-far_x, FAR_M, -far_z), (far_x, FAR_M, -far_z), (far_x, FAR_M, 0.41 * FAR_M * vhalf),
                         (-far_x, FAR_M, -0.23 * FAR_M * vhalf)], far)
    x, z = 1.5 * NEAR_M * half, 1.5 * NEAR_M * vhalf
    _quad(scene, "Near", [(-x, NEAR_M, -z), (-0.05 * NEAR_M * half, NEAR_M, -z),
                          (-0.35 * NEAR_M * half, NEAR_M, -0.45 * NEAR_M * vhalf), (-x, NEAR_M, -0.45 * NEAR_M * vhalf)],
          near)
    scene.atmos.render_mode, scene.atmos.quality = mode, quality
    configure(scene, engine, width, height, samples)
    atmos_addon.api.enable(scene, preset="clear", sun_elevation_deg=30.0, sun_azimuth_deg=150.0)
    return scene


def hold_out(scene, name: str) -> None:
    """Move object ``name`` into a new collection that the view layer holds out (Collection > Holdout)."""
    obj = bpy.data.objects[name]
    collection = bpy.data.collections.new("Held out")
    scene.collection.children.link(collection)
    collection.objects.link(obj)
    scene.collection.objects.unlink(obj)
    scene.view_layers[0].layer_collection.children[collection.name].holdout = True


def configure(scene, engine: str, width: int, height: int, samples: int,
              filter_px: float = DEFAULT_FILTER_PX) -> None:
    """``engine`` at ``width`` x ``height``, ``samples`` per pixel, a ``filter_px`` pixel filter, compositing on."""
    ru.set_engine(scene, engine, width=width, height=height)
    scene.render.use_compositing = True
    if scene.render.engine == "CYCLES":
        scene.cycles.samples = samples
        scene.cycles.pixel_filter_type, scene.cycles.filter_width = "BLACKMAN_HARRIS", filter_px
        scene.cycles.seed = 0
    else:
        scene.eevee.taa_render_samples = samples
        scene.render.filter_size = filter_px


@dataclass
class Images:
    """The composited render, its per-sample reference and the surfaces' coverage (near, all), rows at the top."""

    composited: np.ndarray
    reference: np.ndarray
    near_coverage: np.ndarray
    coverage: np.ndarray


def render(scene) -> np.ndarray:
    """RGB of one render as the scene's compositor leaves it (linear, row 0 at the top)."""
    return ru.render_to_array(scene)[..., :3].astype(np.float64)


def _swap_emission(material, build_colour) -> tuple:
    """Feed ``material``'s Emission from ``build_colour(tree, radiance socket)``; returns what to put back."""
    tree = material.node_tree
    emission = next(node for node in tree.nodes if node.bl_idname == "ShaderNodeEmission")
    colour = emission.inputs["Color"]
    before = colour.links[0].from_socket if colour.is_linked else None
    default = tuple(colour.default_value)
    radiance = tree.nodes[material["atmos_test_radiance"]].outputs[0] if "atmos_test_radiance" in material else None
    tree.links.new(build_colour(tree, radiance, default), colour)
    return material, before, default


def _restore(saved) -> None:
    for material, before, default in saved:
        tree = material.node_tree
        emission = next(node for node in tree.nodes if node.bl_idname == "ShaderNodeEmission")
        colour = emission.inputs["Color"]
        for link in list(colour.links):
            tree.links.remove(link)
        colour.default_value = default
        if before is not None:
            tree.links.new(before, colour)


def surface_materials(scene) -> list:
    return [slot.material for obj in scene.objects if obj.type == "MESH" for slot in obj.material_slots]


def per_sample_reference(scene) -> np.ndarray:
    """The render with I F_ex + L_in evaluated at every sample (module docstring), the compositor off."""
    from atmos_addon.blender import facts, scene_reading

    aerial = scene_reading.groups().aerial_perspective.ensure_aerial_perspective_group(
        facts.aerial_features(facts.plan_of(scene)))

    def hazed(tree, radiance, default):
        group = tree.nodes.new("ShaderNodeGroup")
        group.node_tree = aerial
        attenuated = tree.nodes.new("ShaderNodeVectorMath")
        attenuated.operation = "MULTIPLY_ADD"
        if radiance is not None:
            tree.links.new(radiance, attenuated.inputs[0])
        else:
            attenuated.inputs[0].default_value = default[:3]
        tree.links.new(group.outputs["Transmittance"], attenuated.inputs[1])
        tree.links.new(group.outputs["Inscattering"], attenuated.inputs[2])
        return attenuated.outputs[0]

    saved = [_swap_emission(material, hazed) for material in surface_materials(scene)]
    # Atmos's AOV outputs are not read here; muted, Eevee does not compile the aerial group for them once more.
    muted = [node for material in surface_materials(scene) for node in material.node_tree.nodes
             if node.bl_idname == "ShaderNodeGroup" and node.node_tree is not None
             and node.node_tree.name == SURFACE_GROUP and not node.mute]
    for node in muted:
        node.mute = True
    scene.render.use_compositing = False
    try:
        return render(scene)
    finally:
        scene.render.use_compositing = True
        for node in muted:
            node.mute = False
        _restore(saved)


def coverages(scene) -> tuple[np.ndarray, np.ndarray]:
    """(the near surface's coverage, every surface's), per pixel: the surfaces as flat colours over a transparent
    film (near red, the others green), the compositor off."""
    def flat(colour):
        def build_colour(tree, radiance, default):
            node = tree.nodes.new("ShaderNodeRGB")
            node.outputs[0].default_value = (*colour, 1.0)
            return node.outputs[0]
        return build_colour

    saved = [_swap_emission(material, flat((1.0, 0.0, 0.0) if material.name == "Near" else (0.0, 1.0, 0.0)))
             for material in surface_materials(scene)]
    scene.render.use_compositing = False
    scene.render.film_transparent = True
    try:
        pixels = ru.render_to_array(scene)
    finally:
        scene.render.film_transparent = False
        scene.render.use_compositing = True
        _restore(saved)
    return pixels[..., 0].astype(np.float64), pixels[..., 3].astype(np.float64)


def images(scene) -> Images:
    """The composited render, the per-sample reference and the coverages of ``scene`` as it is configured."""
    composited = render(scene)
    reference = per_sample_reference(scene)
    near, every = coverages(scene)
    return Images(composited, reference, near, every)


def edge_pixels(edge: str, result: Images, *, low: float = 0.02) -> np.ndarray:
    """The pixels of one kind of edge (:data:`EDGES`): the ridge covering the pixel in part against the sky, or the
    near plane in part over the far one."""
    if edge == "ridge":
        return (result.coverage > low) & (result.coverage < 1.0 - low) & (result.near_coverage < 1e-3)
    return (result.near_coverage > low) & (result.near_coverage < 1.0 - low) & (result.coverage > 1.0 - 1e-3)


def interior_pixels(result: Images) -> np.ndarray:
    """The pixels more than one pixel from every pixel a surface covers in part (and not at the image's border)."""
    edge = ((result.coverage > 1e-4) & (result.coverage < 1.0 - 1e-4)) | (
        (result.near_coverage > 1e-4) & (result.near_coverage < 1.0 - 1e-4))
    grown = edge.copy()
    padded = np.pad(edge, 1)
    for dy in range(3):
        for dx in range(3):
            grown |= padded[dy:dy + edge.shape[0], dx:dx + edge.shape[1]]
    grown[0, :] = grown[-1, :] = grown[:, 0] = grown[:, -1] = True
    return ~grown


def inside_frame(pixels: np.ndarray) -> np.ndarray:
    """``pixels`` without the image's outermost rows and columns (whose 3 x 3 neighbourhood the frame cuts)."""
    kept = pixels.copy()
    kept[0, :] = kept[-1, :] = kept[:, 0] = kept[:, -1] = False
    return kept


def errors(result: Images, pixels: np.ndarray) -> np.ndarray:
    """|composited - reference| / reference, the largest over RGB, over ``pixels``."""
    relative = np.abs(result.composited - result.reference) / np.maximum(result.reference, 1e-6)
    return relative.max(axis=-1)[pixels]


def save_pair(result: Images, folder: Path | None = None) -> Path:
    """Write the composited and reference renders as .npy files (for inspection); the folder."""
    folder = Path(folder or tempfile.mkdtemp(prefix="atmos-silhouettes-"))
    np.save(folder / "composited.npy", result.composited)
    np.save(folder / "reference.npy", result.reference)
    return folder
