# SPDX-License-Identifier: GPL-3.0-or-later
"""The scene settings of Atmos: one PropertyGroup on ``bpy.types.Scene.atmos``.

Scattering coefficients are stored in 1/km so the interface shows readable numbers
(clear air scatters about 0.006/km of red light); :func:`.settings_io.atmosphere_from_settings`
converts them to the 1/m the physics core uses. Every ``update=`` callback goes to the orchestrator
(:func:`.orchestrator.update`): it edits values (scene custom-property writes) and rebuilds a node group
only when the plan's feature set (Mie on/off, absorption on/off, the level) changed.
"""

from __future__ import annotations

import bpy
from bpy.props import (
    BoolProperty,
    CollectionProperty,
    EnumProperty,
    FloatProperty,
    FloatVectorProperty,
    PointerProperty,
    StringProperty,
)

from .. import presets
from ..physics.spectrum import DEFAULT_OZONE_COLUMN_DU

#: The defaults are the Clear preset's, so a fresh tick shows that preset's own numbers (70 km visibility).
DEFAULT_PRESET = "clear"
_CLEAR = presets.load(DEFAULT_PRESET).atmosphere


def _per_km(values_per_m) -> tuple[float, float, float]:
    return tuple(float(v) * 1000.0 for v in values_per_m)


def _on_enabled(self, context) -> None:
    from . import orchestrator

    orchestrator.apply_enabled_state(self.id_data)


def _on_parameter(self, context) -> None:
    scene = self.id_data
    if self.enabled:
        from . import orchestrator

        if not orchestrator.is_batched(scene):
            orchestrator.update(scene)


def _kilometres(name: str):
    """(get, set) of a kilometre view of the metre property ``name`` (the panel shows planet-sized lengths in km;
    presets and the core keep metres). Setting writes ``name``, whose own update applies the change."""

    def get(self) -> float:
        return getattr(self, name) / 1000.0

    def set_(self, value: float) -> None:
        setattr(self, name, float(value) * 1000.0)

    return get, set_


_PLANET_RADIUS_KM = _kilometres("planet_radius")
_ATMOSPHERE_HEIGHT_KM = _kilometres("atmosphere_height")


def _get_visibility(self) -> float:
    from . import simple_controls

    return simple_controls.get_visibility_km(self)


def _set_visibility(self, value: float) -> None:
    from . import simple_controls

    simple_controls.set_visibility_km(self, value)


def _get_haze_colour(self):
    from . import simple_controls

    return simple_controls.get_haze_colour(self)


def _set_haze_colour(self, value) -> None:
    from . import simple_controls

    simple_controls.set_haze_colour(self, value)


def _get_air_density(self) -> float:
    from . import simple_controls

    return simple_controls.get_air_density(self)


def _set_air_density(self, value: float) -> None:
    from . import simple_controls

    simple_controls.set_air_density(self, value)


def _get_sun_elevation(self) -> float:
    from .apply import sun_lamp

    return sun_lamp.sun_angles(self.id_data)[0]


def _set_sun_elevation(self, value: float) -> None:
    from .apply import sun_lamp

    sun_lamp.set_sun_angles(self.id_data, value, sun_lamp.sun_angles(self.id_data)[1])


def _get_sun_azimuth(self) -> float:
    from .apply import sun_lamp

    return sun_lamp.sun_angles(self.id_data)[1]


def _set_sun_azimuth(self, value: float) -> None:
    from .apply import sun_lamp

    sun_lamp.set_sun_angles(self.id_data, sun_lamp.sun_angles(self.id_data)[0], value)


def _on_sky_enabled(self, context) -> None:
    if self.enabled:
        from . import orchestrator

        orchestrator.apply_sky_state(self.id_data)


def _on_render_mode(self, context) -> None:
    if self.enabled:
        from . import orchestrator

        orchestrator.enable_effect(self.id_data)


def _on_quality(self, context) -> None:
    if self.enabled:
        from . import orchestrator

        if not orchestrator.is_batched(self.id_data):
            orchestrator.change_quality(self.id_data)


def _poll_sun(self, obj) -> bool:
    return obj.type == "LIGHT" and obj.data.type == "SUN"


class AtmosSkippedItem(bpy.types.PropertyGroup):
    """A data-block Atmos left alone, and why (shown in the panel)."""

    reason: StringProperty(name="Reason", description="Why Atmos did not change this data-block")


class AtmosSceneSettings(bpy.types.PropertyGroup):
    """Aerial perspective settings of one scene."""

    enabled: BoolProperty(
        name="Aerial Perspective",
        description=(
            "Apply aerial perspective to every object: materials write transmittance and in-scattered light "
            "to render passes and the compositor combines them with the image"
        ),
        default=False,
        update=_on_enabled,
    )
    rayleigh_scattering_per_km: FloatVectorProperty(
        name="Rayleigh Scattering (1/km)",
        description=(
            "Scattering coefficient of air molecules at sea level for red, green, blue, per kilometre. "
            "Molecules scatter blue far more than red (1/wavelength^4): distant objects turn blue"
        ),
        size=3,
        default=_per_km(_CLEAR.rayleigh_scattering),
        min=0.0,
        soft_max=0.1,
        precision=5,
        step=0.01,
        update=_on_parameter,
    )
    mie_scattering_per_km: FloatVectorProperty(
        name="Mie Scattering (1/km)",
        description=(
            "Scattering coefficient of haze and aerosol particles at sea level, per kilometre. "
            "Larger values make the distance hazier and greyer, with a bright glow around the sun"
        ),
        size=3,
        default=_per_km(_CLEAR.mie_scattering),
        min=0.0,
        soft_max=1.0,
        precision=5,
        step=0.01,
        update=_on_parameter,
    )
    mie_absorption_per_km: FloatVectorProperty(
        name="Mie Absorption (1/km)",
        description=(
            "Absorption coefficient of aerosols (soot, dust) per kilometre: light removed without being "
            "scattered, so distant objects darken instead of brightening"
        ),
        size=3,
        default=_per_km(_CLEAR.mie_absorption),
        min=0.0,
        soft_max=1.0,
        precision=5,
        step=0.01,
        update=_on_parameter,
    )
    mie_g: FloatVectorProperty(
        name="Mie Anisotropy",
        description=(
            "Henyey-Greenstein asymmetry of haze scattering for red, green, blue: positive values scatter "
            "forward (a bright halo when looking towards the sun), 0 scatters equally in all directions. "
            "Different values per channel colour the halo (Mars dust: bluer forward glow)"
        ),
        size=3,
        default=tuple(float(v) for v in _CLEAR.mie_g),
        min=-0.999,
        max=0.999,
        update=_on_parameter,
    )
    rayleigh_scale_height: FloatProperty(
        name="Rayleigh Scale Height",
        description="Height over which the density of air molecules falls by a factor e (metres)",
        default=float(_CLEAR.rayleigh_scale_height),
        min=1.0,
        soft_max=20000.0,
        subtype="DISTANCE",
        unit="LENGTH",
        update=_on_parameter,
    )
    mie_scale_height: FloatProperty(
        name="Mie Scale Height",
        description="Height over which the density of haze falls by a factor e (metres); haze stays low",
        default=float(_CLEAR.mie_scale_height),
        min=1.0,
        soft_max=10000.0,
        subtype="DISTANCE",
        unit="LENGTH",
        update=_on_parameter,
    )
    planet_radius: FloatProperty(
        name="Planet Radius",
        description="Radius of the planet (metres): sets how fast the air thins towards the horizon for the sun",
        default=float(_CLEAR.planet_radius),
        min=1000.0,
        soft_min=1.0e5,
        soft_max=1.0e8,
        subtype="DISTANCE",
        unit="LENGTH",
        update=_on_parameter,
    )
    atmosphere_height: FloatProperty(
        name="Atmosphere Height",
        description="Height of the top of the atmosphere above the ground (metres); above it is vacuum",
        default=float(_CLEAR.atmosphere_height),
        min=100.0,
        soft_max=300000.0,
        subtype="DISTANCE",
        unit="LENGTH",
        update=_on_parameter,
    )
    planet_radius_km: FloatProperty(
        name="Planet Radius (km)",
        description="Radius of the planet in kilometres (Earth 6360, Mars 3390): the Planet Radius setting, in km",
        min=1.0,
        soft_min=100.0,
        soft_max=100000.0,
        precision=0,
        step=10000,
        get=_PLANET_RADIUS_KM[0],
        set=_PLANET_RADIUS_KM[1],
    )
    atmosphere_height_km: FloatProperty(
        name="Atmosphere Height (km)",
        description="Height of the top of the atmosphere above the ground in kilometres: the Atmosphere Height "
                    "setting, in km",
        min=0.1,
        soft_max=300.0,
        precision=0,
        step=100,
        get=_ATMOSPHERE_HEIGHT_KM[0],
        set=_ATMOSPHERE_HEIGHT_KM[1],
    )
    sun_irradiance_top: FloatVectorProperty(
        name="Sun Irradiance at Top (W/m\u00b2)",
        description=(
            "Irradiance of the sun above the atmosphere for red, green, blue, in Blender sun-strength units "
            "(W/m^2). The sun lamp and the haze get this times the transmittance of the air towards the sun. "
            "Default: the solar spectrum's colour, slightly warm as in Blender's own sky, at luminance 4.5"
        ),
        size=3,
        default=tuple(float(v) for v in _CLEAR.sun_irradiance_top),
        min=0.0,
        soft_max=100.0,
        update=_on_parameter,
    )
    ozone_column_du: FloatProperty(
        name="Ozone (DU)",
        description=(
            "Total ozone column in Dobson units (Earth: about 300; 0: none). Ozone lies 10-40 km up and absorbs "
            "orange and green light without scattering it: it keeps the twilight zenith blue and deepens the "
            "low sun's colour. Felt at the Precise level (sky, haze, multiple scattering) and by the sun lamp "
            "at every level"
        ),
        default=DEFAULT_OZONE_COLUMN_DU,
        min=0.0,
        soft_max=600.0,
        precision=0,
        step=1000,
        update=_on_parameter,
    )
    wavelengths_nm: FloatVectorProperty(
        name="Wavelengths (nm)",
        description=(
            "Wavelengths the red, green and blue channels stand for, in nanometres. Default 648.1, 547.4, 443.1: "
            "where air's scattering equals its mean over each of Blender's Rec.709 channels under sunlight, so the "
            "sky renders the colour of the full spectrum. Haze and Air Density are read at 550 nm from them"
        ),
        size=3,
        default=tuple(float(v) for v in _CLEAR.wavelengths_nm),
        min=300.0,
        max=1000.0,
        update=_on_parameter,
    )
    distance_scale: FloatProperty(
        name="Distance Scale",
        description=(
            "Multiplies scene distances before the atmosphere sees them: 10 makes a 1 km model look "
            "like a 10 km landscape"
        ),
        default=1.0,
        min=1e-6,
        soft_min=0.01,
        soft_max=1000.0,
        update=_on_parameter,
    )
    visibility_km: FloatProperty(
        name="Visibility (km)",
        description=(
            "How far you see: the meteorological visibility at the ground in kilometres, V = 3.912 / extinction at "
            "550 nm (Koschmieder), as a visibility sensor reports it. In a uniform haze a black object at V keeps "
            "2 % contrast against the horizon; real haze thins with height, so the horizon behind it is dimmer and "
            "it keeps more (clear preset, 70 km: 4.6 %, docs/visibility.md). Shorter is hazier. Writes the haze's "
            "Mie scattering and absorption, keeping its colour, on top of the air's own Rayleigh extinction"
        ),
        min=0.001,
        soft_min=0.1,
        soft_max=400.0,
        precision=1,
        step=100,
        get=_get_visibility,
        set=_set_visibility,
    )
    haze_colour: FloatVectorProperty(
        name="Haze Colour",
        description=(
            "The tint the haze gives the light it scatters: its Mie scattering per channel over the largest "
            "channel. White is a grey haze; a bluish one is fine aerosol (Angstrom exponent above 1), a warm one "
            "dust. Setting it keeps the visibility and each channel's absorption"
        ),
        size=3,
        subtype="COLOR",
        min=0.0,
        max=1.0,
        get=_get_haze_colour,
        set=_set_haze_colour,
    )
    air_density: FloatProperty(
        name="Air Density",
        description=(
            "Density of the air molecules relative to standard sea-level air (1 = Earth): scales the Rayleigh "
            "scattering that makes distance and sky blue, keeping its colour"
        ),
        min=0.0,
        soft_max=10.0,
        step=1,
        precision=3,
        get=_get_air_density,
        set=_set_air_density,
    )
    preset_name: StringProperty(
        name="Preset",
        description="The atmosphere preset last applied to this scene (its values may have been edited since)",
        default=DEFAULT_PRESET,
    )
    sun_object: PointerProperty(
        name="Sun",
        description=("The sun lamp whose direction lights the atmosphere (empty: the first sun lamp in the scene that "
                     "renders)"),
        type=bpy.types.Object,
        poll=_poll_sun,
        update=_on_parameter,
    )
    # -- sky and sun (see sun_lamp.py, world.py) --
    sun_elevation: FloatProperty(
        name="Sun Elevation",
        description="Height of the sun above the horizon; rotates the sun lamp (always shows the lamp's angle)",
        subtype="ANGLE",
        min=-0.5 * 3.141592653589793,
        max=0.5 * 3.141592653589793,
        get=_get_sun_elevation,
        set=_set_sun_elevation,
    )
    sun_azimuth: FloatProperty(
        name="Sun Azimuth",
        description="Compass direction of the sun, clockwise from north (+Y) toward east (+X); rotates the sun lamp",
        subtype="ANGLE",
        get=_get_sun_azimuth,
        set=_set_sun_azimuth,
    )
    sun_angular_diameter: FloatProperty(
        name="Sun Angular Diameter",
        description="Apparent diameter of the sun's disk (0.53 degrees seen from the Earth): the sky's disk and "
                    "the sun lamp's angle (shadow softness)",
        subtype="ANGLE",
        default=0.009306095571633765,  # 2 x 0.2666 deg = 0.5332 deg
        min=1.0e-4,
        max=0.5,
        soft_max=0.2,
        update=_on_parameter,
    )
    sun_limb_darkening: FloatProperty(
        name="Limb Darkening",
        description="How much darker the sun's disk is at its edge than at its centre (0: a uniform disk)",
        default=0.6,
        min=0.0,
        max=1.0,
        update=_on_parameter,
    )
    drive_sun_lamp: BoolProperty(
        name="Drive Sun Lamp",
        description="Set the sun lamp's colour, strength and angle from the sunlight that reaches the ground",
        default=True,
        update=_on_parameter,
    )
    sky_enabled: BoolProperty(
        name="Sky",
        description="Show the Atmos sky (same atmosphere and sun as the haze) in the scene's world",
        default=True,
        update=_on_sky_enabled,
    )
    render_mode: EnumProperty(
        name="Mode",
        description="Where the aerial perspective is applied",
        items=(
            ("COMPOSITOR", "Compositor",
             "Both engines: the materials evaluate the haze at every sample and write it as AOVs (the transmittance "
             "and in-scattering passes), the compositor applies it once per pixel to the first surface the camera "
             "sees (reflections and refractions are not hazed; silhouettes get a one-pixel fringe). Costs a "
             "per-sample lookup: about 1.7x the render time of Per Pixel at Precise"),
            ("PER_PIXEL", "Per Pixel",
             "The default. Both engines, fastest: the materials write the distance and view direction, and the "
             "compositor evaluates the quality level once per pixel (no per-sample cost; where a near and a far "
             "surface share a pixel, the haze of their mean distance)"),
            ("IN_RENDER", "In-Render (Cycles)",
             "Cycles: exact haze on every ray segment (reflections, refractions, depth of field, motion blur, "
             "silhouettes), no added noise. Eevee renders with the Compositor mode"),
        ),
        default="PER_PIXEL",
        update=_on_render_mode,
    )
    quality: EnumProperty(
        name="Quality",
        description="How the aerial perspective follows the atmosphere's density along each view ray",
        items=(
            # Numbered: the file stores the number. 1 was Balanced, a retired level (a file saved with it opens at
            # Fast: migration.upgrade_retired_settings).
            ("FAST", "Fast", "Constant sea-level density along the ray (Hoffman & Preetham 2002), single "
                             "scattering: ground-level views of nearby land; the cheapest graph", "", 0),
            ("PRECISE", "Precise", "Scattering integrated numerically over the curved planet, baked into a table "
                                   "image packed into the file (0.4-0.8 s per tile; a moving camera or sun gets key "
                                   "tiles along its path, blended per frame); with Multiple Scattering the complete "
                                   "atmosphere", "", 2),
            ("AUTO", "Auto", "Pick the cheapest level whose measured error for this scene (camera and geometry "
                             "heights, view distances, sun) stays under the tolerance; re-evaluated on Refresh",
             "", 3),
        ),
        default="PRECISE",
        update=_on_quality,
    )
    auto_tolerance: FloatProperty(
        name="Tolerance",
        description="Largest relative pixel error Auto accepts, in percent (measured against brute-force single "
                    "scattering; see docs/quality.md)",
        default=2.0,
        min=0.1,
        max=100.0,
        soft_max=20.0,
        subtype="PERCENTAGE",
        update=_on_quality,
    )
    multiple_scattering: BoolProperty(
        name="Multiple Scattering",
        description="Precise quality: add the light scattered more than once, every order, off the air and the "
                    "ground (Ground Albedo), to the haze and the sky: most of a clear day's skylight, a blue zenith "
                    "at a low sun, the blue hour. Within 1-2 % of a Monte Carlo reference by day (docs/quality.md)",
        default=True,
        update=_on_quality,
    )
    origin_altitude: FloatProperty(
        name="Origin Altitude (m)",
        description="Altitude above sea level of the world origin (z = 0), in metres. Precise quality takes the "
                    "camera's altitude as this plus its height: a scene modelled around z = 0 on a 1500 m plateau "
                    "sets 1500",
        default=0.0,
        min=-1000.0,
        max=100000.0,
        soft_max=10000.0,
        update=_on_parameter,
    )
    auto_level: StringProperty(
        name="Auto Level",
        description="The level Auto chose (read-only: written by Atmos)",
        default="fast",
    )
    status_quality: StringProperty(name="Quality", description="The quality level in use and its expected error")
    sky_ground: EnumProperty(
        name="Ground",
        description="What the sky shows below the horizon",
        items=(
            ("ALBEDO", "Lit Ground", "A flat ground of the ground albedo lit by the sun, seen through the haze"),
            ("BLACK", "Black", "A black ground: only the horizon's haze below the horizon"),
        ),
        default="ALBEDO",
        update=_on_parameter,
    )
    ground_albedo: FloatVectorProperty(
        name="Ground Albedo",
        description="Colour (reflectance) of the distant ground the sky shows below the horizon; Precise quality's "
                    "multiple scattering also takes the light it reflects",
        subtype="COLOR",
        size=3,
        default=(0.18, 0.2, 0.15),
        min=0.0,
        max=1.0,
        update=_on_parameter,
    )
    sun_colour_display: FloatVectorProperty(
        name="Sunlight Colour",
        description="Colour of the sunlight at the ground (read-only: set by Atmos from the atmosphere and the sun)",
        subtype="COLOR",
        size=3,
        default=(1.0, 1.0, 1.0),
        min=0.0,
        soft_max=1.0,
    )
    sun_strength_display: FloatProperty(
        name="Sunlight Strength",
        description="Sunlight at the ground, W/m\u00b2 (read-only: set by Atmos from the atmosphere and the sun)",
        default=0.0,
        min=0.0,
    )
    status_built: StringProperty(name="Built", description="What the aerial perspective node group computes")
    status_sun: StringProperty(name="Sun", description="Where the sun direction comes from")
    status_materials: StringProperty(name="Materials", description="How many materials Atmos manages")
    status_objects: StringProperty(name="Objects", description="Objects Atmos cannot affect")
    skipped_materials: CollectionProperty(type=AtmosSkippedItem)

    @classmethod
    def register(cls) -> None:
        bpy.types.Scene.atmos = PointerProperty(type=cls, name="Atmos", description="Atmos aerial perspective")

    @classmethod
    def unregister(cls) -> None:
        del bpy.types.Scene.atmos


CLASSES = (AtmosSkippedItem, AtmosSceneSettings)
