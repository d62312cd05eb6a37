# SPDX-License-Identifier: GPL-3.0-or-later
"""What Atmos builds for a scene, and why: the one place that reduces 3 modes x 4 quality settings x 2 engines (x
Open Shading Language, x the other scenes of the file) to the configuration actually built.

Pure Python (no ``bpy``): :class:`SceneFacts` holds what the rules depend on, read off a scene by the Blender layer
(``atmos_addon.blender.facts``) or written by hand in a test; :func:`plan_for` returns the :class:`Plan`. The
orchestrator computes one plan per user action and hands it to the appliers, which build what it lists; the panel
and the CLI print its notes. Every
fallback is decided here, once, with the sentence that explains it:

- **Mode.** Compositor (both engines: the materials write AOVs, the compositor combines them per pixel), Per Pixel
  (both engines: the materials write distance and direction, the compositor evaluates the level per pixel) or
  In-Render (Cycles: haze volumes and per-segment emission). In-Render asked for in another engine renders with the
  Compositor mode. Cycles with Open Shading Language writes no shader AOVs (measured: they come out empty), so
  there the Compositor and Per Pixel modes render In-Render instead.
- **Level.** Fast or Precise; Auto's last choice for Auto (made from a summary of the scene, outside the plan).
  In-Render evaluates every ray segment at the Fast level: a reflected ray does not start at the camera, around
  which the Precise table is baked.
- **Key tiles.** At the Precise level a camera or sun that moves over time gets key tiles along its path (the
  table holds several): every lookup of the aerial, sky and lighting groups then blends the frame's two keys, which
  doubles their texel fetches; a still scene's single tile is read directly.
- **Sky.** The Precise level's sky is its table's; every other level shows the virtual-dome sky. Cycles' rays
  other than camera rays see the world's lighting table, or at the Precise level the camera's sky (the table
  does not factor into the lighting table's elevation curves).
- **Passes.** The AOVs of the mode; the one material group every managed material carries holds the outputs of
  every AOV mode the file's enabled scenes use (Eevee compiles each AOV output of a material, used or not).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

MODES = ("COMPOSITOR", "PER_PIXEL", "IN_RENDER")
#: The modes whose materials write AOVs that the compositor reads.
AOV_MODES = ("COMPOSITOR", "PER_PIXEL")
QUALITIES = ("FAST", "PRECISE", "AUTO")
#: The levels a scene's aerial perspective is built at. No Balanced level: against the complete reference it is no
#: more accurate than Fast at Precise's cost; a file saved with it opens at Fast, which shares its sky
#: (``blender.migration``).
LEVELS = ("fast", "precise")
#: Why "balanced" is not a quality (the migration's console note, the CLI's and the API's refusals).
RETIRED_BALANCED_NOTE = ("the Balanced quality level was retired (against every scattering order it was no more "
                         "accurate than Fast, at Precise's cost)")
EEVEE_ENGINES = frozenset({"BLENDER_EEVEE", "BLENDER_EEVEE_NEXT"})

#: The view-layer AOVs (name, kind). Compositor mode: the per-sample transmittance, its square and cube (the
#: moments the compositor reads two surfaces' transmittances from, ``nodes.composite``), the in-scattering and the
#: coverage. Per Pixel mode: the view direction, the coverage, the distance (km) and the moments of the distance's
#: q = s / (s + s_0). The colour AOVs come first: Eevee writes 0 into a Value AOV that a colour AOV follows
#: (``blender.apply.compositor.aovs_out_of_order``).
AOV_TRANSMITTANCE = "atmos_transmittance"
AOV_TRANSMITTANCE_SQUARED = "atmos_transmittance2"
AOV_TRANSMITTANCE_CUBED = "atmos_transmittance3"
AOV_INSCATTERING = "atmos_inscattering"
AOV_COVERAGE = "atmos_coverage"
AOV_DISTANCE = "atmos_distance"
AOV_VIEW = "atmos_view"
AOV_MOMENTS = "atmos_moments"
#: Object custom property (read by an Object Attribute node in the AOV outputs group) that Atmos sets to 1 on the
#: objects a collection holds out in every rendered view layer: their materials then write no AOVs, so a pixel
#: at a held-out object's edge is composited from the visible surface's samples alone.
HOLDOUT_ATTRIBUTE = "atmos_holdout"
AOVS = {
    "COMPOSITOR": ((AOV_TRANSMITTANCE, "COLOR"), (AOV_INSCATTERING, "COLOR"), (AOV_TRANSMITTANCE_SQUARED, "COLOR"),
                   (AOV_TRANSMITTANCE_CUBED, "COLOR"), (AOV_COVERAGE, "VALUE")),
    "PER_PIXEL": ((AOV_VIEW, "COLOR"), (AOV_MOMENTS, "COLOR"), (AOV_COVERAGE, "VALUE"), (AOV_DISTANCE, "VALUE")),
    "IN_RENDER": (),
}
def material_aovs(mode: str) -> tuple[str, ...]:
    """The names of the AOVs the materials write in ``mode``."""
    return tuple(name for name, _ in AOVS[mode])


#: The render pass of the sky a pixel shows (the Render Layers output "Environment"; "Env" in Blender 4.5), which the
#: AOV modes' compositor reads (``nodes.composite``).
ENVIRONMENT_PASS = "Environment"

#: Eevee's world goes one flat colour above this camera clip end / clip start (float32 precision of the projection;
#: measured on 4.5.15, 5.2.3 and 5.3.0 with Blender's own Sky Texture, Eevee at 32x16 px, the camera 80 deg up from
#: straight down: every clip start from 1 mm to 10 m rendered the sky up to 1.6e7, none from 2.2e7).
EEVEE_CLIP_RATIO_LIMIT = 1.6e7

NOTE_IN_RENDER_NEEDS_CYCLES = "In-Render mode needs Cycles: this engine renders with the Compositor mode"
NOTE_OSL = ("Open Shading Language is on: Cycles writes no AOVs with it, so the haze is applied In-Render "
            "(turn OSL off for the Compositor or Per Pixel mode)")
NOTE_IN_RENDER_FAST = "In-Render mode applies Fast on every ray segment"


@dataclass(frozen=True)
class SceneFacts:
    """What the plan depends on, as plain values: the scene's Atmos settings, its engine and camera, and the modes
    the file's other enabled scenes render with."""

    render_mode: str = "PER_PIXEL"    #: the Mode setting (:data:`MODES`)
    quality: str = "PRECISE"          #: the Quality setting (:data:`QUALITIES`)
    auto_level: str = "fast"          #: Auto's last choice (:data:`LEVELS`)
    engine: str = "CYCLES"            #: ``scene.render.engine``
    osl: bool = False                 #: Cycles' Open Shading Language on
    mie: bool = True                  #: any Mie scattering coefficient > 0
    absorption: bool = True           #: any Mie absorption coefficient > 0
    sky: bool = True                  #: the Sky setting
    sky_ground: str = "ALBEDO"        #: what the sky shows below the horizon
    sun_lamp: bool = True             #: the Drive Sun Lamp setting
    multiple_scattering: bool = True  #: the Multiple Scattering setting (Precise level)
    other_modes: tuple[str, ...] = ()  #: the modes the file's other enabled scenes render with
    clip_ratio: float | None = None   #: the scene camera's clip end / clip start (None: no camera)
    clip_end_m: float | None = None   #: the scene camera's clip end, m
    key_tiles: int = 1                #: key tiles the scene's Precise table holds (> 1: a camera or sun that moves)
    animated_settings: tuple[str, ...] = ()  #: the Atmos settings keys or drivers change over time (interface names)
    holdout: bool = False             #: a collection is held out in some rendered view layers, not all
    blurs: tuple[str, ...] = ()       #: "depth of field", "motion blur": what the scene's camera and render blur

    def __post_init__(self) -> None:
        if self.render_mode not in MODES:
            raise ValueError(f"render_mode must be one of {MODES}; got {self.render_mode!r}")
        if self.quality not in QUALITIES:
            raise ValueError(f"quality must be one of {QUALITIES}; got {self.quality!r}")


@dataclass(frozen=True)
class Plan:
    """What is built for one scene (see the module docstring for the rules)."""

    mode: str                        #: the mode rendered (:data:`MODES`)
    level: str                       #: the aerial perspective's level (:data:`LEVELS`)
    mie: bool                        #: the node groups hold the Mie phase term
    absorption: bool                 #: ... and the Mie absorption term
    sky: bool                        #: the Atmos sky is in the world
    sky_level: str                   #: "precise" (the table's sky) or "fast" (the virtual dome)
    sky_ground: str                  #: what the sky shows below the horizon
    lighting: str                    #: what Cycles' rays other than camera rays see: "table" or "sky"
    sun_lamp: bool                   #: Atmos drives the sun lamp's colour and strength
    tables: bool                     #: the Precise level's tables are baked
    multiple_scattering: bool        #: ... with multiple scattering
    blend: bool                      #: ... and each frame blends two key tiles (the table holds several)
    aovs: tuple[tuple[str, str], ...]  #: the view layer's Atmos AOVs
    surface_modes: tuple[str, ...]   #: the AOV modes whose outputs the shared material group holds
    notes: tuple[str, ...]           #: one sentence per fallback or warning, for the panel, the report, the CLI
    viewport: str                    #: what the 3D viewport's Rendered shading shows of the haze
    facts: SceneFacts = field(repr=False)  #: what the plan was made from (:meth:`with_facts`)

    def with_facts(self, **changes) -> Plan:
        """The plan once the action holding this one has itself changed some of its facts (Auto's choice of level,
        a bake's number of key tiles): made from :attr:`facts` with ``changes``, the scene not read again; this
        plan itself where they change nothing."""
        if all(getattr(self.facts, name) == value for name, value in changes.items()):
            return self
        return plan_for(replace(self.facts, **changes))

    @property
    def compositor(self) -> str | None:
        """The compositor evaluation installed ("COMPOSITOR", "PER_PIXEL"), None in In-Render mode."""
        return self.mode if self.mode in AOV_MODES else None

    @property
    def aerial_key(self) -> str:
        """The aerial feature key the node groups are stamped with: "rayleigh+mie+abs", "rayleigh+mie+abs+precise"..."""
        return ("rayleigh" + ("+mie" if self.mie else "") + ("+abs" if self.absorption else "")
                + ("" if self.level == "fast" else f"+{self.level}") + ("+blend" if self.blend else ""))


def mode_for(facts: SceneFacts) -> tuple[str, str | None]:
    """The mode the scene renders with, and the sentence that says why it is not the setting's (or None)."""
    wanted = facts.render_mode
    if wanted == "IN_RENDER" and facts.engine != "CYCLES":
        return "COMPOSITOR", NOTE_IN_RENDER_NEEDS_CYCLES
    if wanted != "IN_RENDER" and facts.engine == "CYCLES" and facts.osl:
        return "IN_RENDER", NOTE_OSL
    return wanted, None


def chosen_level(quality: str, auto_level: str) -> str:
    """The level a Quality setting asks for: its own, or for Auto its last choice ("fast" before it has chosen)."""
    if quality == "AUTO":
        return auto_level if auto_level in LEVELS else "fast"
    return quality.lower()


def level_for(facts: SceneFacts, mode: str) -> tuple[str, str | None]:
    """The aerial perspective's level, and the sentence that says why it is not the setting's (or None)."""
    level = chosen_level(facts.quality, facts.auto_level)
    if mode == "IN_RENDER" and level != "fast":
        return "fast", NOTE_IN_RENDER_FAST
    return level, None


#: Eevee's viewport shows the haze through the viewport compositor, which the user switches on.
VIEWPORT_EEVEE_HINT = "Viewport: Shading > Compositor to Always"


def viewport_note(engine: str, mode: str) -> str:
    """What the 3D viewport's Rendered shading shows of the aerial perspective, in one line.

    Measured in GUI Blender 4.3.2 and 5.2.2 (``tools/verify_viewport.py``, docs/viewport.md): the In-Render mode is
    shading and shows in the viewport exactly; the Compositor and Per Pixel modes need the viewport compositor,
    which gets Eevee's AOVs but no passes at all from Cycles. Other engines (Workbench) run no material nodes.
    """
    if engine == "CYCLES" and mode == "IN_RENDER":
        return "Viewport: haze shows in Rendered shading"
    if engine not in EEVEE_ENGINES and engine != "CYCLES":
        return "This engine renders no Atmos haze"
    if engine == "CYCLES":
        return "Cycles viewport: no haze; In-Render has it"
    return VIEWPORT_EEVEE_HINT


def clip_note(facts: SceneFacts) -> str | None:
    """The warning for an Eevee camera whose clip range flattens the world (with the Clip Start that fixes it), or
    None."""
    if facts.engine not in EEVEE_ENGINES or facts.clip_ratio is None or facts.clip_ratio <= EEVEE_CLIP_RATIO_LIMIT:
        return None
    fix = "" if facts.clip_end_m is None else f" to at least {facts.clip_end_m / EEVEE_CLIP_RATIO_LIMIT:.3g} m"
    return (f"Camera Clip End / Clip Start is {facts.clip_ratio:.2g}, over Eevee's limit of "
            f"{EEVEE_CLIP_RATIO_LIMIT:.2g}, so Eevee renders the sky one flat colour: raise Clip Start{fix} (or lower "
            "Clip End)")


def animated_settings_note(facts: SceneFacts) -> str | None:
    """The warning for Atmos settings that are keyframed or driven, or None. The shader parameters, the sun lamp's
    drivers and the Precise tables are written when a setting is edited, not on every frame (a farm renders without
    the add-on), so a key changes nothing the render reads."""
    if not facts.animated_settings:
        return None
    return (f"Keyframed or driven Atmos settings ({', '.join(facts.animated_settings)}) are not followed: every frame "
            "renders with the values last applied (animate the sun lamp or the camera, or render each value as a shot)")


#: A collection held out in some rendered view layers and not in others: its objects are not marked (one object
#: property cannot say both), so where their hole meets a hazed surface behind it their AOVs still count in the
#: pixel (tools/measure_silhouettes.py with the marks off, Cycles 5.2.3: 5.5 % mean, 59 % max).
NOTE_HOLDOUT = ("Holdout differs between view layers: pixels at a held-out object's edge are off by 6 % on "
                "average, up to 59 % (docs/silhouettes.md)")


def holdout_note(facts: SceneFacts, mode: str) -> str | None:
    """The note on held-out objects' edges (the modes that read the materials' AOVs in the compositor), or None."""
    return NOTE_HOLDOUT if facts.holdout and mode in AOV_MODES else None


#: Eevee applies depth of field and motion blur to its image after shading, but not to the AOVs Atmos reads, so
#: the edges they blur are off (tools/measure_silhouettes.py, Eevee 5.2.3: depth of field 2.5 % mean and 31 % max at
#: a ridge against the sky, motion blur 8.1 % mean and 26 % max where a near surface moves over a far one).
EEVEE_BLUR_ERRORS = {"depth of field": "31 %", "motion blur": "26 %"}


def eevee_blur_note(facts: SceneFacts, mode: str) -> str | None:
    """The note on Eevee's depth of field and motion blur with the AOV modes, or None."""
    blurs = [blur for blur in facts.blurs if blur in EEVEE_BLUR_ERRORS]
    if facts.engine not in EEVEE_ENGINES or mode not in AOV_MODES or not blurs:
        return None
    errors = ", ".join(f"{blur} up to {EEVEE_BLUR_ERRORS[blur]}" for blur in blurs)
    return (f"Eevee blurs the image but not Atmos's passes: edges are off ({errors}); Cycles keeps them within "
            "3 % (docs/silhouettes.md)")


def plan_for(facts: SceneFacts) -> Plan:
    """The :class:`Plan` for ``facts`` (module docstring: the rules)."""
    mode, mode_note = mode_for(facts)
    level, level_note = level_for(facts, mode)
    aov_modes = {m for m in (mode, *facts.other_modes) if m in AOV_MODES}
    precise = level == "precise"
    notes = tuple(note for note in (mode_note, level_note, clip_note(facts), animated_settings_note(facts),
                                    holdout_note(facts, mode), eevee_blur_note(facts, mode)) if note)
    return Plan(mode=mode, level=level, mie=facts.mie, absorption=facts.absorption, sky=facts.sky,
                sky_level="precise" if precise else "fast", sky_ground=facts.sky_ground,
                lighting="sky" if precise else "table", sun_lamp=facts.sun_lamp, tables=precise,
                multiple_scattering=precise and facts.multiple_scattering, blend=precise and facts.key_tiles > 1,
                aovs=AOVS[mode],
                surface_modes=tuple(sorted(aov_modes)) or ("COMPOSITOR",), notes=notes,
                viewport=viewport_note(facts.engine, mode), facts=facts)
