# SPDX-License-Identifier: GPL-3.0-or-later
"""One plan per action: an enable or an update makes the scene's plan once (``facts.plan_of``) and every applier's
``install`` gets that plan (``orchestrator``'s module docstring)."""

from __future__ import annotations

import math

import bpy
import pytest

import render_utils as ru
from atmos_addon.blender import facts, orchestrator
from atmos_addon.blender.apply import compositor, in_render, materials, precise_tables, sun_lamp, world

#: The appliers' installs each mode calls (In-Render: Fast on every ray segment, so no tables).
INSTALLS = {
    "PER_PIXEL": ((sun_lamp, "install"), (precise_tables, "install"), (materials, "install"),
                  (compositor, "install"), (world, "install")),
    "COMPOSITOR": ((sun_lamp, "install"), (precise_tables, "install"), (materials, "install"),
                   (compositor, "install"), (world, "install")),
    "IN_RENDER": ((sun_lamp, "install"), (in_render, "install_materials"), (world, "install"),
                  (in_render, "install")),
}


@pytest.fixture
def plans(monkeypatch):
    """The plans ``facts.plan_of`` made, in order."""
    made = []
    plan_of = facts.plan_of

    def counted(scene):
        made.append(plan_of(scene))
        return made[-1]

    monkeypatch.setattr(facts, "plan_of", counted)
    return made


def _received(monkeypatch, mode: str) -> dict[str, list]:
    """Wrap the installs of ``mode``: the plans each received, by "module.function"."""
    received: dict[str, list] = {}
    for module, name in INSTALLS[mode]:
        original = getattr(module, name)
        key = f"{module.__name__.rsplit('.', 1)[-1]}.{name}"
        received[key] = []

        def wrapped(scene, plan, *args, _original=original, _key=key, **kwargs):
            received[_key].append(plan)
            return _original(scene, plan, *args, **kwargs)

        monkeypatch.setattr(module, name, wrapped)
    return received


def _scene(scene, mode: str):
    ru.make_camera(scene, location=(0.0, 0.0, 2.0), rotation_euler=(math.radians(90.0), 0.0, 0.0))
    ru.make_plane(scene, "Ground", [(-50, 20, 0), (50, 20, 0), (50, 120, 0), (-50, 120, 0)],
                  bpy.data.materials.new("Ground"))
    scene.render.engine = "CYCLES"
    scene.atmos.render_mode = mode
    return scene


@pytest.mark.parametrize("mode", ["PER_PIXEL", "COMPOSITOR", "IN_RENDER"])
def test_an_enable_makes_one_plan_and_hands_it_to_every_applier(addon, plans, monkeypatch, mode):
    scene = _scene(addon, mode)
    received = _received(monkeypatch, mode)
    orchestrator.enable_effect(scene)
    assert len(plans) == 1, f"plan_of called {len(plans)} times in one enable"
    (plan,) = plans
    assert plan.mode == mode and plan.tables == (mode != "IN_RENDER")
    for key, got in received.items():
        assert got, f"{key} was not called"
        assert all(each is plan for each in got), f"{key} got another plan than the enable's"


def test_an_update_makes_one_plan(addon, plans):
    scene = _scene(addon, "PER_PIXEL")
    orchestrator.enable_effect(scene)
    plans.clear()
    orchestrator.update(scene)
    assert len(plans) == 1, f"plan_of called {len(plans)} times in one update"


def test_a_bake_that_adds_key_tiles_hands_on_the_plan_with_their_blend(addon, plans, monkeypatch):
    """The bake decides the blend of key tiles: the installs after it get the enable's plan for those tiles, made
    from its facts (``Plan.with_facts``), not a plan read off the scene again."""
    scene = _scene(addon, "PER_PIXEL")
    scene.frame_start, scene.frame_end = 1, 3
    camera = scene.camera
    camera.keyframe_insert("location", index=2, frame=1)
    camera.location.z = 400.0
    camera.keyframe_insert("location", index=2, frame=3)
    received = _received(monkeypatch, "PER_PIXEL")
    orchestrator.enable_effect(scene)
    assert len(plans) == 1
    assert scene[facts.KEY_TILES] > 1 and not plans[0].blend
    (installed,) = received["materials.install"]
    assert installed.blend and installed.facts.key_tiles == scene[facts.KEY_TILES]
    assert installed == plans[0].with_facts(key_tiles=scene[facts.KEY_TILES])
