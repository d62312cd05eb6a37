# SPDX-License-Identifier: GPL-3.0-or-later
"""Tiny-render helpers shared by the Blender tests: an empty scene, a camera, planes, one render to numpy.

Renders are read back from a 32-bit float OpenEXR file. EXR output holds the scene-linear render
result, so the view transform, look, exposure and gamma never touch the numbers a test compares
(they are still set to neutral values, in case a caller saves another format). Each pixel is one
sample at the pixel centre: Cycles uses 1 sample with a 0.01 px box filter, Eevee 1 sample with a
zero filter size.
"""

from __future__ import annotations

import math
import os
import tempfile
import textwrap
import warnings
from collections.abc import Sequence
from pathlib import Path

import bpy
import numpy as np
from mathutils import Vector

#: Eevee's engine id: ``BLENDER_EEVEE_NEXT`` in Blender 4.5, ``BLENDER_EEVEE`` from 5.0.
EEVEE_ENGINE = "BLENDER_EEVEE_NEXT" if bpy.app.version < (5, 0, 0) else "BLENDER_EEVEE"
ENGINES = ("CYCLES", EEVEE_ENGINE)


def reset_scene() -> bpy.types.Scene:
    """Load an empty factory file and return its scene (no objects, no world)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return bpy.context.scene


def make_camera(scene: bpy.types.Scene, *, location: Sequence[float] = (0.0, 0.0, 0.0),
                rotation_euler: Sequence[float] = (0.0, 0.0, 0.0), fov_rad: float = math.radians(60.0),
                orthographic_scale: float | None = None, clip_start: float = 0.1,
                clip_end: float = 1000.0) -> bpy.types.Object:
    """Add a camera (perspective with horizontal field of view ``fov_rad``, or orthographic) and make it active.

    With the default rotation the camera looks down -Z with +Y up, the image's +x to the right.
    Keep ``clip_end / clip_start`` at about 1e4 or less: with a much larger ratio (1e-3 to 1e6 measured)
    Eevee silently drops objects that do not cover the view centre (measured in 4.2 and 5.0).
    """
    data = bpy.data.cameras.new("Test Camera")
    data.sensor_fit = "HORIZONTAL"
    if orthographic_scale is None:
        data.type = "PERSP"
        data.angle = fov_rad
    else:
        data.type = "ORTHO"
        data.ortho_scale = orthographic_scale
    data.clip_start = clip_start
    data.clip_end = clip_end
    camera = bpy.data.objects.new("Test Camera", data)
    camera.location = location
    camera.rotation_euler = rotation_euler
    scene.collection.objects.link(camera)
    scene.camera = camera
    return camera


def make_plane(scene: bpy.types.Scene, name: str, corners: Sequence[Sequence[float]],
               material: bpy.types.Material | None = None) -> bpy.types.Object:
    """Add a quad with the four given world-space corners (counter-clockwise seen from the front)."""
    points = np.asarray(corners, dtype=np.float64)
    centre = points.mean(axis=0)
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(p) for p in (points - centre).tolist()], [], [(0, 1, 2, 3)])
    mesh.update()
    if material is not None:
        mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    obj.location = tuple(centre)
    scene.collection.objects.link(obj)
    return obj


def set_engine(scene: bpy.types.Scene, engine: str, *, width: int, height: int) -> None:
    """Select ``"CYCLES"`` or ``"EEVEE"`` (either Eevee id works) and set one centred sample per pixel."""
    if engine.startswith("BLENDER_EEVEE") or engine == "EEVEE":
        engine = EEVEE_ENGINE
    scene.render.engine = engine
    render = scene.render
    if width < 4 or height < 4:
        raise ValueError(f"render size {width}x{height}: Blender renders at least 4x4 pixels; use 4 or more")
    render.resolution_x = width
    render.resolution_y = height
    render.resolution_percentage = 100
    render.pixel_aspect_x = render.pixel_aspect_y = 1.0
    render.film_transparent = False
    render.use_compositing = False
    render.use_sequencer = False
    render.threads_mode = "FIXED"
    render.threads = 2
    if engine == "CYCLES":
        cycles = scene.cycles
        cycles.device = "CPU"
        cycles.samples = 1
        cycles.use_adaptive_sampling = False
        cycles.use_denoising = False
        cycles.pixel_filter_type = "BOX"
        cycles.filter_width = 0.01
        cycles.max_bounces = 0
    else:
        scene.eevee.taa_render_samples = 1
        render.filter_size = 0.0
    view = scene.view_settings
    view.view_transform = "Standard"
    view.look = "None"
    view.exposure = 0.0
    view.gamma = 1.0
    scene.display_settings.display_device = "sRGB"


def render_to_array(scene: bpy.types.Scene | None = None) -> np.ndarray:
    """Render the active camera and return the linear float RGBA image, shape (height, width, 4), row 0 at the top.

    The render is written to a temporary 32-bit OpenEXR file and read back through ``bpy.data.images``.
    """
    scene = scene or bpy.context.scene
    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR"
    settings.color_mode = "RGBA"
    settings.color_depth = "32"
    settings.exr_codec = "ZIP"
    with tempfile.TemporaryDirectory(prefix="atmos-render-") as folder:
        path = os.path.join(folder, "render.exr")
        scene.render.filepath = path
        bpy.ops.render.render(write_still=True, scene=scene.name)
        image = bpy.data.images.load(path, check_existing=False)
        try:
            width, height = image.size
            pixels = np.empty(width * height * 4, dtype=np.float32)
            image.pixels.foreach_get(pixels)
        finally:
            bpy.data.images.remove(image)
    return pixels.reshape(height, width, 4)[::-1].copy()


def route_compositor_output(scene: bpy.types.Scene, socket_name: str | None) -> None:
    """Send a Render Layers output (or, for None, the Atmos composite) to the compositor's final output."""
    from atmos_addon.blender.apply import compositor

    tree = compositor.current_tree(scene)
    combine = tree.nodes[compositor.COMPOSITE_NODE]
    output = next(n for n in tree.nodes if n.bl_idname in ("NodeGroupOutput", "CompositorNodeComposite"))
    layers = combine.inputs["Image"].links[0].from_node
    source = combine.outputs["Image"] if socket_name is None else layers.outputs[socket_name]
    tree.links.new(source, output.inputs[0])


def pixel_centre_directions(camera: bpy.types.Object, width: int, height: int) -> np.ndarray:
    """World-space unit view directions through each pixel centre of a perspective camera, shape (height, width, 3).

    Row 0 is the top of the image (as :func:`render_to_array` returns it).
    """
    data = camera.data
    if data.type != "PERSP" or data.sensor_fit != "HORIZONTAL":
        raise ValueError("pixel_centre_directions needs a perspective camera with sensor_fit 'HORIZONTAL'")
    half = math.tan(data.angle / 2.0)
    x = ((np.arange(width) + 0.5) / width * 2.0 - 1.0) * half
    y = ((np.arange(height) + 0.5) / height * 2.0 - 1.0) * half * height / width
    y = y[::-1]
    xx, yy = np.meshgrid(x, y)
    local = np.stack([xx, yy, -np.ones_like(xx)], axis=-1)
    rotation = np.array(camera.matrix_world.to_3x3(), dtype=np.float64)
    world = local @ rotation.T
    return world / np.linalg.norm(world, axis=-1, keepdims=True)


# -- the parity scenes (camera at the origin looking along +Y, Z up; emissive planes of known radiance) ----


def set_use_nodes(idblock, value: bool = True) -> None:
    """``idblock.use_nodes = value`` without Blender 5.0's deprecation warning (4.5 still needs it set)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        idblock.use_nodes = value


def view_direction(column: float, row: float, width: int, height: int, fov_rad: float) -> Vector:
    """World direction through a pixel centre (row 0 at the bottom) of a camera at the origin looking along +Y,
    Z up, horizontal field of view ``fov_rad`` (rotation (pi/2, 0, 0))."""
    half = math.tan(fov_rad / 2.0)
    x = (column + 0.5 - width / 2.0) / (width / 2.0) * half
    z = (row + 0.5 - height / 2.0) / (width / 2.0) * half
    return Vector((x, 1.0, z)).normalized()


def emission_material(name: str, radiance: Sequence[float]) -> bpy.types.Material:
    """A material whose only shader is an Emission of ``radiance`` (strength 1): a surface of known L0."""
    material = bpy.data.materials.new(name)
    set_use_nodes(material, True)
    tree = material.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    emission = tree.nodes.new("ShaderNodeEmission")
    emission.inputs["Color"].default_value = (*radiance, 1.0)
    tree.links.new(emission.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    return material


def render_exr(scene: bpy.types.Scene, path: Path) -> np.ndarray:
    """Render ``scene`` to a 32-bit EXR at ``path`` (kept, for inspection) and return its RGB, row 0 at the bottom."""
    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR"
    settings.color_depth = "32"
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(str(path), check_existing=False)
    width, height = image.size
    pixels = np.array(image.pixels[:], dtype=float).reshape(height, width, 4)[..., :3]
    bpy.data.images.remove(image)
    return pixels


def ground_sun(scene: bpy.types.Scene, atmosphere=None) -> tuple[float, np.ndarray]:
    """The sun as the add-on writes it for ``scene``: its elevation (rad) and E_sun at the ground (the
    limb-darkened disk of the scene's settings)."""
    from atmos_addon.blender import scene_reading, settings_io
    from atmos_addon.physics import sun_irradiance_ground

    settings = scene.atmos
    atmosphere = atmosphere or settings_io.atmosphere_from_settings(settings)
    sun_dir, _ = scene_reading.sun_direction(scene)
    elevation = math.asin(float(np.clip(sun_dir[2], -1.0, 1.0)))
    e_sun = np.asarray(sun_irradiance_ground(elevation, atmosphere, 0.0, 0.5 * settings.sun_angular_diameter,
                                             settings.sun_limb_darkening), dtype=float)
    return elevation, e_sun


def fast_segment(scene: bpy.types.Scene, direction, distance: float) -> tuple[np.ndarray, np.ndarray]:
    """(F_ex, L_in) of the physics core (Fast, eq. 19) for ``distance`` scene units along the unit ``direction``
    from the camera, with the scene's Atmos settings and sun: what the composite of a surface should be."""
    from atmos_addon.blender import scene_reading, settings_io
    from atmos_addon.physics.aerial_perspective import extinction, inscattering

    atmosphere = settings_io.atmosphere_from_settings(scene.atmos)
    sun_dir, _ = scene_reading.sun_direction(scene)
    _, e_sun = ground_sun(scene, atmosphere)
    metres = distance * scene_reading.metres_per_unit(scene)
    mu = float(np.dot(np.asarray(direction), sun_dir))
    return extinction(metres, atmosphere), inscattering(metres, mu, atmosphere, e_sun)


def parity_world_camera_sun(scene: bpy.types.Scene, world_colour: Sequence[float], fov_rad: float):
    """A plain world of ``world_colour``, a camera at the origin looking along +Y (Z up, clip end 100 km) and a
    sun lamp, for the parity scenes of :func:`view_direction`; returns the sun object."""
    world = bpy.data.worlds.new("World")
    scene.world = world
    set_use_nodes(world, True)
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (*world_colour, 1.0)
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.data.angle = fov_rad
    camera.data.clip_end = 100_000.0
    camera.rotation_euler = (math.pi / 2.0, 0.0, 0.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    scene.collection.objects.link(sun)
    return sun


def user_compositor(scene: bpy.types.Scene):
    """Render Layers -> Glare -> output: a user's own compositor graph (5.0's node group, or 4.x's scene tree)."""
    if bpy.app.version >= (5, 0, 0):
        tree = bpy.data.node_groups.new("User Compositor", "CompositorNodeTree")
        tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
        output = tree.nodes.new("NodeGroupOutput")
        scene.compositing_node_group = tree
    else:
        scene.use_nodes = True
        tree = scene.node_tree
        tree.nodes.clear()
        output = tree.nodes.new("CompositorNodeComposite")
    layers = tree.nodes.new("CompositorNodeRLayers")
    glare = tree.nodes.new("CompositorNodeGlare")
    tree.links.new(layers.outputs["Image"], glare.inputs["Image"])
    tree.links.new(glare.outputs["Image"], output.inputs[0])
    return tree


def snapshot_tree(tree) -> tuple | None:
    """Nodes (name, type, location, label, active output, input values) and links of a node tree, for exact
    before/after comparisons."""
    if tree is None:
        return None
    nodes = []
    for node in tree.nodes:
        values = tuple(
            (s.identifier, tuple(s.default_value) if hasattr(s.default_value, "__len__") else s.default_value)
            for s in node.inputs if hasattr(s, "default_value")
        )
        nodes.append((node.name, node.bl_idname, tuple(node.location), node.label,
                      getattr(node, "is_active_output", None), values))
    links = sorted(
        (link.from_node.name, link.from_socket.identifier, link.to_node.name, link.to_socket.identifier)
        for link in tree.links
    )
    return sorted(nodes), links


#: A farm machine without the add-on: opens each (blend, output stem) pair of its arguments, renders it to a 32-bit
#: EXR and saves the RGB pixels (row 0 at the top) as ``<stem>.npy``; prints whether the add-on was imported. Run with
#: ``sys.executable -I`` and a HOME of the test's own (tests of ``apply`` then a farm).
FARM_SCRIPT = textwrap.dedent("""
    import json, sys
    import bpy
    import numpy as np
    for blend, out in zip(sys.argv[1::2], sys.argv[2::2]):
        bpy.ops.wm.open_mainfile(filepath=blend)
        scene = bpy.context.scene
        assert not any(name.startswith("atmos_addon") for name in sys.modules), "the add-on was imported"
        settings = scene.render.image_settings
        if "media_type" in settings.bl_rna.properties:
            settings.media_type = "IMAGE"
        settings.file_format, settings.color_depth, settings.color_mode = "OPEN_EXR", "32", "RGB"
        scene.render.filepath = out + ".exr"
        bpy.ops.render.render(write_still=True)
        image = bpy.data.images.load(out + ".exr", check_existing=False)
        width, height = image.size
        pixels = np.empty(width * height * 4, dtype=np.float32)
        image.pixels.foreach_get(pixels)
        np.save(out + ".npy", pixels.reshape(height, width, 4)[::-1, :, :3])
    print(json.dumps({"addon_loaded": "atmos_addon" in sys.modules}))
""")


def run_farm(folder: Path, arguments: Sequence[str], script: str = FARM_SCRIPT) -> dict:
    """Run ``script`` (default :data:`FARM_SCRIPT`) with ``arguments`` in a fresh Python (``-I``: no add-on on its
    path, no PYTHON* or BLENDER_* variables, HOME ``folder``) as a farm machine without the add-on would; its last
    line of output, parsed as JSON. Fails the test when it does not exit cleanly."""
    import json
    import subprocess
    import sys

    path = Path(folder) / "farm.py"
    path.write_text(script)
    env = {key: value for key, value in os.environ.items() if not key.startswith(("PYTHON", "BLENDER_"))}
    env["HOME"] = str(folder)
    result = subprocess.run([sys.executable, "-I", str(path), *arguments], cwd=str(folder), env=env,
                            capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-2000:]
    return json.loads(result.stdout.strip().splitlines()[-1])
