# SPDX-License-Identifier: GPL-3.0-or-later
"""Cycles in-render mode: the dome volumes, the per-material emission and the world compensation.

The mechanism is :mod:`atmos_addon.node_groups.in_render`'s; this module puts it into a scene and takes it out again:

- two dome objects ("Atmos Dome (molecules)", "Atmos Dome (aerosols)") in their own collection "Atmos
  In-Render", meshes from ``physics.dome_mesh`` in metres, scaled to scene units (1 / metres per unit), held on
  the scene camera by a Copy Location constraint (the domes follow an animated camera at render time), not
  selectable, drawn as bounds. Ray visibility: camera, glossy, transmission on; diffuse, shadow, volume
  scatter off;
- in every managed material, two tagged nodes beside the user's: the "Atmos In-Render Surface" group fed by
  the surface that Cycles renders (and the opacity socket, as the AOV path finds it), and a Material Output
  with target Cycles carrying the group's shader and the user's Volume, Displacement and Thickness links.
  Blender picks an output of the engine's own target over an "All" one, so Eevee keeps rendering the user's
  output; the user's nodes and links are not touched. Cycles' emission sampling is set to "None" for a
  material without emission of its own (the added emission is zero on light-sampling rays, so sampling it
  as a light would only waste samples), remembered on the tagged node and restored on removal;
- in the world, a Cycles-target World Output with a Background whose colour is the world's colour times the
  compensation group (the world's own Background, or the Atmos sky's camera-ray Background, is left as it is
  for Eevee; the In-Render output evaluates that sky for every ray, without the table sky of other rays);
- the camera's clip end is raised to beyond the largest dome (Cycles shows the world past the clip end
  without the rest of the dome, which would leave the compensated sky too bright) and restored on removal.

What must be restored is kept in the scene (custom property :data:`STATE_KEY`), so it survives save and reload.
"""

from __future__ import annotations

import warnings

import bpy

from ... import node_groups
from ...physics.dome_mesh import dome_mesh
from ...plan import EEVEE_CLIP_RATIO_LIMIT, Plan
from .. import scene_reading, tree_edits
from ..facts import aerial_features
from ..tree_edits import TAG
from . import materials

STATE_KEY = "atmos_in_render"
COLLECTION_NAME = "Atmos In-Render"
DOME_NAMES = {"MOLECULES": "Atmos Dome (molecules)", "AEROSOLS": "Atmos Dome (aerosols)"}
SURFACE_TAG = "in-render surface"
OUTPUT_TAG = "in-render output"
WORLD_TAGS = ("in-render sky", "in-render background", "in-render world output")
DOME_KEY = "atmos_dome_of"
#: The camera's clip end is raised to this many times the largest dome distance.
CLIP_MARGIN = 1.05
#: Dome crossings a path may make: every dome surface is a transparent filter (``atmos_addon.node_groups.in_render``), and
#: Cycles counts each crossing as a transparent bounce. A camera ray to the sky crosses 2; a reflected ray
#: from beyond a dome enters and leaves it, 4 at most. The scene's transparent bounce limit and its
#: Russian-roulette threshold are raised by this much while In-Render mode is installed (restored on removal),
#: so the domes neither cut paths short nor add noise.
DOME_CROSSINGS = 4


def _groups():
    return node_groups.in_render


def is_installed(scene) -> bool:
    """True when the in-render pieces are in ``scene``."""
    return scene.get(STATE_KEY) is not None


def _state(scene) -> dict:
    state = scene.get(STATE_KEY)
    return state.to_dict() if hasattr(state, "to_dict") else dict(state or {})


# -- materials ------------------------------------------------------------------------------------------


def _emits(tree, seen=None) -> bool:
    """True if ``tree`` (or a group inside it) has an Emission node or a Principled BSDF with emission."""
    seen = set() if seen is None else seen
    for node in tree.nodes:
        if node.get(TAG):
            continue  # Atmos' own nodes
        if node.bl_idname == "ShaderNodeEmission":
            return True
        if node.bl_idname == "ShaderNodeBsdfPrincipled":
            strength = node.inputs.get("Emission Strength")
            if strength is not None and (strength.is_linked or strength.default_value > 0.0):
                return True
        if node.bl_idname == "ShaderNodeGroup" and node.node_tree is not None and node.node_tree not in seen:
            seen.add(node.node_tree)
            if _emits(node.node_tree, seen):
                return True
    return False


def _new_node(tree, bl_idname: str, x: float, y: float):
    node = tree.nodes.new(bl_idname)
    tree_edits.place_last(tree.nodes, x, y)
    return node


def inject(material, surface_group) -> None:
    """Add the in-render nodes to one node-based, editable material (idempotent; module docstring)."""
    materials.strip(material)
    tree = material.node_tree
    nodes = tree.nodes
    x, y = tree_edits.free_spot(nodes)
    user_output = tree_edits.cycles_output(tree)
    opacity_socket, opacity_value, invert = materials.opacity(tree)
    group = _new_node(tree, "ShaderNodeGroup", x, y)
    group.label = "Atmos In-Render Surface"
    group[TAG] = SURFACE_TAG
    group.node_tree = surface_group
    output = _new_node(tree, "ShaderNodeOutputMaterial", x + 250.0, y)
    output.label = "Atmos In-Render Output (Cycles)"
    output[TAG] = OUTPUT_TAG
    output.target = "CYCLES"
    if user_output is not None:
        surface = user_output.inputs["Surface"]
        if surface.is_linked:
            tree.links.new(surface.links[0].from_socket, group.inputs["Surface"])
        for name in ("Volume", "Displacement", "Thickness"):
            tree_edits.copy_input(tree, user_output, output, name)
        tree_edits.take_over_cycles_output(tree, output, user_output)
    tree.links.new(group.outputs["Shader"], output.inputs["Surface"])
    target = group.inputs["Transparency" if invert else "Opacity"]
    if opacity_socket is not None:
        tree.links.new(opacity_socket, target)
    elif opacity_value is not None:
        target.default_value = opacity_value
    cycles = getattr(material, "cycles", None)
    if cycles is not None and hasattr(cycles, "emission_sampling") and not _emits(tree):
        output[tree_edits.EMISSION_SAMPLING_KEY] = cycles.emission_sampling
        cycles.emission_sampling = "NONE"


def inject_scene(scene, surface_group, *, only_new: bool = False) -> materials.MaterialReport:
    """Give every material of the scene's objects the in-render nodes, each once; report the skipped ones."""
    report = materials.MaterialReport()
    found, report.objects_without_material = materials.scene_materials(scene)
    for material in found:
        reason = materials.skip_reason(material)
        if reason is not None:
            report.skipped.append((material.name, reason))
            continue
        report.managed.append(material.name)
        if only_new and any(n.get(TAG) == SURFACE_TAG for n in materials.atmos_nodes(material)):
            continue
        inject(material, surface_group)
        report.injected.append(material.name)
    return report


# -- the domes ------------------------------------------------------------------------------------------


def _dome_key(atmosphere, species: str) -> list[float]:
    height = atmosphere.rayleigh_scale_height if species == "MOLECULES" else atmosphere.mie_scale_height
    return [float(atmosphere.planet_radius), float(height)]


def _fill_mesh(mesh, atmosphere, species: str) -> float:
    """(Re)build ``mesh`` as the dome of ``species`` (m); returns the dome's horizontal radius (m)."""
    planet, height = _dome_key(atmosphere, species)
    dome = dome_mesh(planet, height)
    mesh.clear_geometry()
    mesh.from_pydata(dome.vertices.tolist(), [], dome.triangles.tolist())
    mesh.update()
    mesh[DOME_KEY] = [planet, height]
    mesh["atmos_horizon_radius_m"] = dome.horizon_radius_m
    return dome.horizon_radius_m


def _dome_material(species: str):
    name = DOME_NAMES[species]
    material = bpy.data.materials.get(name)
    if material is None or material.library is not None:
        material = bpy.data.materials.new(name)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        material.use_nodes = True
    tree = material.node_tree
    if not node_groups.stamps.is_current(tree, node_groups.stamps.DOME_VOLUME, species):
        _groups().build_dome_volume(tree, species)
    return material


def _make_dome(scene, collection, species: str, atmosphere, scale: float):
    mesh = bpy.data.meshes.new(DOME_NAMES[species])
    _fill_mesh(mesh, atmosphere, species)
    mesh.materials.append(_dome_material(species))
    obj = bpy.data.objects.new(DOME_NAMES[species], mesh)
    collection.objects.link(obj)
    obj.scale = (scale, scale, scale)
    obj.hide_select = True
    obj.display_type = "BOUNDS"
    obj.visible_diffuse = False
    obj.visible_shadow = False
    obj.visible_volume_scatter = False
    obj.visible_camera = obj.visible_glossy = obj.visible_transmission = True
    obj[TAG] = species
    constraint = obj.constraints.new("COPY_LOCATION")
    constraint.name = "Atmos: follow the camera"
    constraint.target = scene.camera
    return obj


def _domes(scene) -> list:
    collection = bpy.data.collections.get(_state(scene).get("collection", ""))
    return [] if collection is None else [o for o in collection.objects if o.get(TAG) in DOME_NAMES]


def sync_domes(scene, atmosphere, metres_per_unit: float) -> float:
    """Keep the domes' shapes, scale and camera current (values and geometry only; cheap when unchanged); returns
    the clip end (scene units) the camera needs to see the whole largest dome."""
    scale = 1.0 / metres_per_unit
    largest = 0.0
    for obj in _domes(scene):
        species = obj[TAG]
        if list(obj.data.get(DOME_KEY, [])) != _dome_key(atmosphere, species):
            _fill_mesh(obj.data, atmosphere, species)
        largest = max(largest, float(obj.data.get("atmos_horizon_radius_m", 0.0)))
        if any(abs(s - scale) > 1e-9 * scale for s in obj.scale):
            obj.scale = (scale, scale, scale)
        for constraint in obj.constraints:
            if constraint.type == "COPY_LOCATION" and scene.camera is not None and constraint.target != scene.camera:
                constraint.target = scene.camera
    needed = largest * scale * CLIP_MARGIN
    _raise_clip_end(scene, needed)
    return needed


def _raise_transparent_bounces(scene) -> None:
    cycles = getattr(scene, "cycles", None)
    if cycles is None:
        return
    saved = [cycles.transparent_max_bounces, cycles.min_transparent_bounces]
    cycles.transparent_max_bounces += DOME_CROSSINGS  # clamped at Blender's limit (1024)
    cycles.min_transparent_bounces += DOME_CROSSINGS
    scene[STATE_KEY]["transparent_bounces"] = saved + [cycles.transparent_max_bounces, cycles.min_transparent_bounces]


def _restore_transparent_bounces(scene, state) -> None:
    saved = state.get("transparent_bounces")
    cycles = getattr(scene, "cycles", None)
    if saved is None or cycles is None:
        return
    # Give back what was added (saved: before, after); a value the user changed meanwhile keeps the change.
    if cycles.transparent_max_bounces == saved[2]:
        cycles.transparent_max_bounces = saved[0]
    if cycles.min_transparent_bounces == saved[3]:
        cycles.min_transparent_bounces = saved[1]


def _raise_clip_end(scene, needed: float) -> None:
    """Raise the camera's clip end to ``needed``, but never past Eevee's flat-sky limit of the clip range
    (:data:`atmos_addon.plan.EEVEE_CLIP_RATIO_LIMIT`: the file may be rendered with Eevee later); :func:`install`
    warns when it stops short."""
    camera = scene.camera
    if camera is None or camera.type != "CAMERA":
        return
    # the largest clip end within the limit, less one part in 10^6 so the float32 it is stored as stays within
    needed = min(needed, float(camera.data.clip_start) * EEVEE_CLIP_RATIO_LIMIT * (1.0 - 1e-6))
    if needed <= 0.0 or camera.data.clip_end >= needed:
        return
    state = scene[STATE_KEY]
    clips = dict(state.get("clip_end", {}))
    clips.setdefault(camera.data.name, camera.data.clip_end)
    state["clip_end"] = clips
    camera.data.clip_end = needed


# -- the world ------------------------------------------------------------------------------------------


def world_nodes(world) -> list:
    """The nodes in-render mode added to ``world``'s tree."""
    if world is None or world.node_tree is None:
        return []
    return [n for n in world.node_tree.nodes if n.get(TAG) in WORLD_TAGS]


def install_world(scene, features) -> str | None:
    """Compensate the world for the domes on camera, glossy and transmission rays; a warning, or None."""
    world = scene.world
    if world is None or world.node_tree is None:
        return None
    remove_world(world)
    tree = world.node_tree
    output = tree_edits.cycles_output(tree, "ShaderNodeOutputWorld", WORLD_TAGS)
    if output is None or not output.inputs["Surface"].is_linked:
        return None
    from .world import camera_background

    background = camera_background(output.inputs["Surface"].links[0].from_node)
    if background.bl_idname != "ShaderNodeBackground":
        return (f"World '{world.name}': its surface is not a Background shader, so in In-Render mode the sky is "
                "seen through the dome's haze (darker toward the horizon); use the Atmos sky or Compositor mode")
    x, y = output.location
    sky = _new_node(tree, "ShaderNodeGroup", x - 200.0, y - 520.0)
    sky.node_tree = _groups().ensure_sky_group(features)
    sky.label = "Atmos In-Render Sky"
    sky[TAG] = WORLD_TAGS[0]
    ours = _new_node(tree, "ShaderNodeBackground", x, y - 520.0)
    ours.label = "Atmos In-Render Background"
    ours[TAG] = WORLD_TAGS[1]
    world_output = _new_node(tree, "ShaderNodeOutputWorld", x + 200.0, y - 520.0)
    world_output.label = "Atmos In-Render Output (Cycles)"
    world_output.target = "CYCLES"
    world_output[TAG] = WORLD_TAGS[2]
    for name, target in (("Color", sky.inputs["Color"]), ("Strength", ours.inputs["Strength"])):
        source = background.inputs[name]
        if source.is_linked:
            tree.links.new(source.links[0].from_socket, target)
        else:
            target.default_value = source.default_value
    tree.links.new(sky.outputs["Color"], ours.inputs["Color"])
    tree.links.new(ours.outputs["Background"], world_output.inputs["Surface"])
    if output.target == "CYCLES":
        active = next((n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputWorld" and n.is_active_output
                       and n != world_output), None)
        if active is not None:
            world_output[tree_edits.REACTIVATE_KEY] = active.name
        world_output.is_active_output = True
    return None


def remove_world(world) -> None:
    """Delete the world nodes of :func:`install_world` (re-activating the output that was active before)."""
    tagged = world_nodes(world)
    reactivate = next((n.get(tree_edits.REACTIVATE_KEY) for n in tagged if n.get(tree_edits.REACTIVATE_KEY)), None)
    for node in tagged:
        world.node_tree.nodes.remove(node)
    if reactivate and world.node_tree.nodes.get(reactivate) is not None:
        world.node_tree.nodes[reactivate].is_active_output = True


# -- install / remove -----------------------------------------------------------------------------------


def horizon_optical_depth(atmosphere) -> float:
    """The largest per-channel optical depth through the domes at the horizon, beta_R R_R(0) + beta_M,ex R_M(0)."""
    from ...physics.dome_mesh import dome_radius

    r_rayleigh = float(dome_radius(0.0, atmosphere.planet_radius, atmosphere.rayleigh_scale_height))
    r_mie = float(dome_radius(0.0, atmosphere.planet_radius, atmosphere.mie_scale_height))
    return float(max(atmosphere.rayleigh_scattering * r_rayleigh + atmosphere.mie_extinction * r_mie))


def surface_group(plan: Plan):
    """The "Atmos In-Render Surface" group the materials carry for ``plan`` (rebuilt in place when stale)."""
    return _groups().ensure_surface_group(aerial_features(plan))


def install_materials(scene, plan: Plan, *, only_new: bool = False) -> materials.MaterialReport:
    """Give every material ``scene`` renders with the in-render nodes of ``plan`` (:func:`inject_scene`);
    ``only_new``: leave the materials that carry them already."""
    return inject_scene(scene, surface_group(plan), only_new=only_new)


def update_groups(scene, plan: Plan) -> None:
    """Rebuild in place the world compensation's sky group where it is stale for ``plan`` and the domes are in
    ``scene`` (cheap when current; the materials' group: :func:`surface_group`)."""
    if is_installed(scene):
        _groups().ensure_sky_group(aerial_features(plan))


def install(scene, plan: Plan) -> list[str]:
    """Add the domes and the world compensation of ``plan`` to ``scene`` (materials: :func:`install_materials`);
    messages."""
    atmosphere = scene_reading.atmosphere_of(scene)
    metres_per_unit = scene_reading.metres_per_unit(scene)
    messages: list[str] = []
    if not is_installed(scene):
        if scene.camera is None:
            raise ValueError(f"scene '{scene.name}' has no camera: In-Render mode centres its haze domes on it")
        collection = bpy.data.collections.new(COLLECTION_NAME)
        scene.collection.children.link(collection)
        scene[STATE_KEY] = {"collection": collection.name}
        _raise_transparent_bounces(scene)
        for species in DOME_NAMES:
            _make_dome(scene, collection, species, atmosphere, 1.0 / metres_per_unit)
    needed_clip_end = sync_domes(scene, atmosphere, metres_per_unit)
    camera = scene.camera
    if camera.type == "CAMERA" and camera.data.clip_end < needed_clip_end:
        messages.append(f"In-Render: camera '{camera.name}' ends at Clip End {camera.data.clip_end:.4g} before the "
                        f"haze domes ({needed_clip_end:.4g}), and Atmos keeps Clip End / Clip Start within Eevee's "
                        "limit: the sky near the horizon renders too bright; raise Clip Start")
    depth = horizon_optical_depth(atmosphere)
    limit = _groups().MAX_COMPENSATED_OPTICAL_DEPTH
    if depth > limit:
        messages.append(f"In-Render: the haze is so thick that the horizon's optical depth ({depth:.0f}) passes "
                        f"{limit:.0f}, where the sky's compensation stops: the sky within a few degrees of the "
                        "horizon renders darker than in Compositor mode")
    warning = install_world(scene, aerial_features(plan))
    if warning:
        messages.append(warning)
    messages.append("In-Render mode (Cycles): haze domes in collection "
                    f"'{_state(scene)['collection']}', following camera '{scene.camera.name}'")
    return messages


def refresh_world(scene, plan: Plan) -> None:
    """Re-install the world compensation of ``plan`` (after the sky was added to or removed from the world)."""
    if is_installed(scene):
        install_world(scene, aerial_features(plan))


def remove(scene) -> None:
    """Remove the domes, the world nodes and the in-render groups; restore the camera's clip end."""
    if not is_installed(scene):
        return
    state = _state(scene)
    collection = bpy.data.collections.get(state.get("collection", ""))
    if collection is not None:
        for obj in list(collection.objects):
            if obj.get(TAG) in DOME_NAMES:
                mesh = obj.data
                bpy.data.objects.remove(obj)
                if mesh is not None and mesh.users == 0:
                    bpy.data.meshes.remove(mesh)
        if not collection.objects and not collection.children:
            bpy.data.collections.remove(collection)
    for species, name in DOME_NAMES.items():
        material = bpy.data.materials.get(name)
        if material is not None and material.users == 0:
            bpy.data.materials.remove(material)
    for world in bpy.data.worlds:
        remove_world(world)
    for camera_name, clip_end in state.get("clip_end", {}).items():
        camera = bpy.data.cameras.get(camera_name)
        if camera is not None:
            camera.clip_end = clip_end
    _restore_transparent_bounces(scene, state)
    del scene[STATE_KEY]
