# SPDX-License-Identifier: GPL-3.0-or-later
"""The plan: every combination of mode, quality, engine, OSL and the file's other scenes, against the rules written
out here once more (plain pytest, no Blender)."""

from __future__ import annotations

import itertools
from dataclasses import replace

import pytest

from atmos_addon import plan
from atmos_addon.plan import Plan, SceneFacts, plan_for

ENGINES = ("CYCLES", "BLENDER_EEVEE", "BLENDER_EEVEE_NEXT", "BLENDER_WORKBENCH")
OTHER_MODES = ((), ("COMPOSITOR",), ("PER_PIXEL",), ("IN_RENDER",), ("COMPOSITOR", "PER_PIXEL"))
COMBINATIONS = list(itertools.product(plan.MODES, plan.QUALITIES, plan.LEVELS, ENGINES, (False, True), OTHER_MODES,
                                      (False, True)))


def test_every_combination():
    """All 2880 combinations, each against the rules (a failure names its combination)."""
    for combination in COMBINATIONS:
        try:
            _check(*combination)
        except AssertionError as error:
            raise AssertionError(f"mode, quality, auto level, engine, OSL, other scenes, multiple scattering = "
                                 f"{combination}: {error}") from error


def _check(mode, quality, auto_level, engine, osl, others, multiple):
    facts = SceneFacts(render_mode=mode, quality=quality, auto_level=auto_level, engine=engine, osl=osl,
                       other_modes=others, multiple_scattering=multiple)
    result = plan_for(facts)
    assert isinstance(result, Plan)
    # mode
    expected_mode = mode
    if mode == "IN_RENDER" and engine != "CYCLES":
        expected_mode = "COMPOSITOR"
    elif mode != "IN_RENDER" and engine == "CYCLES" and osl:
        expected_mode = "IN_RENDER"
    assert result.mode == expected_mode
    assert (plan.NOTE_IN_RENDER_NEEDS_CYCLES in result.notes) == (mode == "IN_RENDER" and engine != "CYCLES")
    assert (plan.NOTE_OSL in result.notes) == (expected_mode == "IN_RENDER" and mode != "IN_RENDER")
    # level
    asked = auto_level if quality == "AUTO" else quality.lower()
    assert result.level == ("fast" if expected_mode == "IN_RENDER" else asked)
    assert (plan.NOTE_IN_RENDER_FAST in result.notes) == (expected_mode == "IN_RENDER" and asked != "fast")
    # sky, lighting, tables
    precise = result.level == "precise"
    assert result.sky_level == ("precise" if precise else "fast")
    assert result.lighting == ("sky" if precise else "table")
    assert result.tables == precise and result.multiple_scattering == (precise and multiple)
    # passes
    assert result.aovs == plan.AOVS[expected_mode]
    assert result.compositor == (None if expected_mode == "IN_RENDER" else expected_mode)
    used = {m for m in (expected_mode, *others) if m != "IN_RENDER"}
    assert result.surface_modes == (tuple(sorted(used)) or ("COMPOSITOR",))
    # viewport
    if engine == "CYCLES":
        assert ("shows in Rendered shading" in result.viewport) == (expected_mode == "IN_RENDER")
        assert ("no haze" in result.viewport) == (expected_mode != "IN_RENDER")
    elif engine == "BLENDER_WORKBENCH":
        assert "renders no Atmos haze" in result.viewport
    else:
        assert "Compositor to Always" in result.viewport


def test_per_pixel_declares_a_colour_aov_first():
    """Eevee in Blender 5.2 writes 0 into a view layer's first AOV when it is a Value AOV."""
    for mode in plan.AOV_MODES:
        assert plan.AOVS[mode][0][1] == "COLOR"


def test_the_eevee_clip_range_note():
    far = SceneFacts(engine="BLENDER_EEVEE", clip_ratio=5e7, clip_end_m=5e6)
    (note,) = plan_for(far).notes
    assert "raise Clip Start to at least 0.312 m" in note
    assert plan_for(replace(far, clip_ratio=1.5e7)).notes == ()
    assert plan_for(replace(far, engine="CYCLES")).notes == ()
    assert plan_for(replace(far, clip_ratio=None)).notes == ()


def test_the_animated_settings_note():
    (note,) = plan_for(SceneFacts(animated_settings=("Mie Scattering", "Visibility"))).notes
    assert note.startswith("Keyframed or driven Atmos settings (Mie Scattering, Visibility) are not followed")
    assert plan_for(SceneFacts()).notes == ()


def test_the_holdout_note():
    (note,) = plan_for(SceneFacts(holdout=True)).notes
    assert note.startswith("Holdout differs between view layers: pixels at a held-out object's edge are off")
    assert plan_for(SceneFacts(holdout=True, render_mode="COMPOSITOR")).notes == (note,)
    in_render = plan_for(SceneFacts(holdout=True, render_mode="IN_RENDER")).notes   # the shader applies it per sample
    assert note not in in_render


def test_the_eevee_blur_note():
    (note,) = plan_for(SceneFacts(engine="BLENDER_EEVEE", blurs=("depth of field", "motion blur"))).notes
    assert note.startswith("Eevee blurs the image but not Atmos's passes") and "motion blur up to 26 %" in note
    assert plan_for(SceneFacts(engine="CYCLES", blurs=("depth of field",))).notes == ()
    assert plan_for(SceneFacts(engine="BLENDER_EEVEE")).notes == ()


def test_features_and_keys():
    assert plan_for(SceneFacts(quality="PRECISE", mie=False)).aerial_key == "rayleigh+abs+precise"
    with pytest.raises(ValueError, match="quality"):   # retired in December 2026 (files upgrade: migration)
        SceneFacts(quality="BALANCED")
    assert plan_for(SceneFacts(quality="FAST")).aerial_key == "rayleigh+mie+abs"
    assert plan_for(SceneFacts()).aerial_key == "rayleigh+mie+abs+precise", "the default is the complete model"
    default = plan_for(SceneFacts())   # ... evaluated once per pixel: at the cost of Blender's own sky (issue 28)
    assert (default.mode, default.compositor, default.surface_modes) == ("PER_PIXEL", "PER_PIXEL", ("PER_PIXEL",))
    assert plan_for(SceneFacts(quality="PRECISE", absorption=False)).aerial_key == "rayleigh+mie+precise"


def test_bad_settings_are_refused():
    with pytest.raises(ValueError):
        SceneFacts(render_mode="FANCY")
    with pytest.raises(ValueError):
        SceneFacts(quality="EXACT")
