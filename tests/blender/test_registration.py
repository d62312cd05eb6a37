# SPDX-License-Identifier: GPL-3.0-or-later
"""Registration is symmetric: enabling and disabling twice leaves no class, property or handler behind."""

from __future__ import annotations

import bpy
import numpy as np
import pytest

import atmos_addon
from atmos_addon import presets
from atmos_addon.physics import Atmosphere

from atmos_addon.blender import registration  # noqa: E402


def _our_handlers() -> list[str]:
    names = []
    for handler_list in (bpy.app.handlers.depsgraph_update_post, bpy.app.handlers.load_post):
        names += [f.__module__ for f in handler_list if "atmos_addon" in getattr(f, "__module__", "")]
    return names


@pytest.fixture(autouse=True)
def empty_file():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    yield


def test_register_unregister_twice_leaves_nothing_behind() -> None:
    for _ in range(2):
        atmos_addon.register()
        assert hasattr(bpy.types.Scene, "atmos")
        assert all(cls.is_registered for cls in registration.CLASSES)
        assert len(_our_handlers()) == 2
        assert hasattr(bpy.ops.atmos, "enable")
        atmos_addon.unregister()
        assert not hasattr(bpy.types.Scene, "atmos")
        assert not any(cls.is_registered for cls in registration.CLASSES)
        assert _our_handlers() == []


def test_defaults_are_the_clear_atmosphere_in_per_km() -> None:
    atmos_addon.register()
    try:
        settings = bpy.context.scene.atmos
        clear = presets.load("clear").atmosphere   # the defaults are the Clear preset's
        assert not settings.enabled
        np.testing.assert_allclose(settings.rayleigh_scattering_per_km, clear.rayleigh_scattering * 1000, rtol=1e-6)
        np.testing.assert_allclose(settings.mie_scattering_per_km, clear.mie_scattering * 1000, rtol=1e-6)
        np.testing.assert_allclose(settings.mie_absorption_per_km, clear.mie_absorption * 1000, rtol=1e-6)
        np.testing.assert_allclose(settings.mie_g, clear.mie_g, rtol=1e-6)
        assert settings.planet_radius == pytest.approx(clear.planet_radius)
        np.testing.assert_allclose(settings.sun_irradiance_top, clear.sun_irradiance_top, rtol=1e-6)
        assert settings.rayleigh_scale_height == pytest.approx(clear.rayleigh_scale_height)
        assert settings.distance_scale == 1.0
        from atmos_addon.blender import settings_io

        # The product's default sky holds the Earth's ozone, the Clear preset's; Atmosphere() is the seed's
        # atmosphere without it.
        assert Atmosphere().ozone_column_du == 0.0
        assert clear.ozone_column_du == pytest.approx(300.0) and settings.ozone_column_du == pytest.approx(300.0)
        assert settings_io.atmosphere_from_settings(settings).ozone_column_du == pytest.approx(300.0)
    finally:
        atmos_addon.unregister()


def test_operators_enable_and_disable_with_undo() -> None:
    atmos_addon.register()
    try:
        from atmos_addon.blender.ui import operators

        for cls in operators.CLASSES:
            assert {"REGISTER", "UNDO"} <= set(cls.bl_options)
        scene = bpy.context.scene
        assert bpy.ops.atmos.enable() == {"FINISHED"}
        assert scene.atmos.enabled
        assert bpy.ops.atmos.refresh() == {"FINISHED"}
        assert bpy.ops.atmos.disable() == {"FINISHED"}
        assert not scene.atmos.enabled
    finally:
        atmos_addon.unregister()


def test_settings_round_trip_an_atmosphere_within_float32() -> None:
    """Every Atmosphere field survives settings (float32 properties): the Mars preset comes back within 1e-6."""
    from atmos_addon import presets
    from atmos_addon.blender import orchestrator, settings_io

    atmos_addon.register()
    try:
        scene = bpy.context.scene
        mars = presets.load("mars").atmosphere
        orchestrator.apply_atmosphere(scene, mars)
        back = settings_io.atmosphere_from_settings(scene.atmos)
        for field in ("rayleigh_scattering", "mie_scattering", "mie_absorption", "mie_g", "sun_irradiance_top",
                      "wavelengths_nm"):
            np.testing.assert_allclose(getattr(back, field), getattr(mars, field), rtol=1e-6, err_msg=field)
        for field in ("rayleigh_scale_height", "mie_scale_height", "planet_radius", "atmosphere_height",
                      "ozone_column_du"):
            assert getattr(back, field) == pytest.approx(getattr(mars, field), rel=1e-6), field
        clear = presets.load("clear").atmosphere
        orchestrator.apply_atmosphere(scene, clear)
        assert settings_io.atmosphere_from_settings(scene.atmos).ozone_column_du == pytest.approx(300.0)
    finally:
        atmos_addon.unregister()
