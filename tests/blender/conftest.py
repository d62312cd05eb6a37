# SPDX-License-Identifier: GPL-3.0-or-later
"""The Blender tests' shared fixtures: an empty factory file with the add-on registered, and a user preset folder
of the test's own (no test reads or writes the real user configuration).

A test module that needs the add-on in every test says ``pytestmark = pytest.mark.usefixtures("addon")``; a test
that wants the scene takes ``addon`` as an argument.
"""

import bpy
import pytest

import atmos_addon
from atmos_addon import presets


@pytest.fixture
def user_presets(tmp_path):
    """The user preset folder for this test (not created until a preset is saved)."""
    folder = tmp_path / "user_presets"
    presets.set_user_directory(folder)
    yield folder
    presets.set_user_directory(None)


@pytest.fixture
def addon(user_presets):
    """An empty factory file (no world, no objects) with Atmos registered; yields its scene."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    atmos_addon.register()
    yield bpy.context.scene
    atmos_addon.unregister()
