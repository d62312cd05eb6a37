# SPDX-License-Identifier: GPL-3.0-or-later
"""The extension zip: Blender's own tool validates and builds it; it installs and enables headless.

The install runs in a fresh ``bpy`` process with a temporary HOME, so nothing leaks into a real
user configuration and the add-on is loaded the way Blender loads it (``bl_ext.user_default.atmos``).
There, with no checkout on the path (no ``validation``, ``tools`` or ``tests``), every module of the installed
copy imports: what the add-on needs at run time ships with it.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO_ROOT / "tools"))
import build_extension  # noqa: E402

INSTALL_SCRIPT = textwrap.dedent(
    """
    import importlib, importlib.util, json, pkgutil, sys
    import bpy
    result = {}
    ret = bpy.ops.extensions.package_install_files(
        filepath=sys.argv[1], repo="user_default", enable_on_install=True)
    result["install"] = sorted(ret)
    result["enabled"] = "bl_ext.user_default.atmos" in bpy.context.preferences.addons
    result["scene_property"] = hasattr(bpy.types.Scene, "atmos")
    result["module_file"] = sys.modules["bl_ext.user_default.atmos"].__file__
    # Every module of the installed copy imports without the checkout's validation/, tools/ and tests/.
    result["checkout_importable"] = [name for name in ("validation", "tools", "tests")
                                     if importlib.util.find_spec(name) is not None]
    modules, failures = [], {}

    def import_all(package):
        for info in pkgutil.iter_modules(package.__path__):
            # __main__ runs the command line; "atmos_addon" is the extension root on atmos_addon's own path
            if info.name in ("__main__", "atmos_addon"):
                continue
            name = package.__name__ + "." + info.name
            try:
                module = importlib.import_module(name)
            except Exception as error:  # noqa: BLE001 (reported by name)
                failures[name] = repr(error)
                continue
            modules.append(name)
            if info.ispkg:
                import_all(module)

    import_all(importlib.import_module("bl_ext.user_default.atmos.atmos_addon"))
    result["modules_imported"], result["import_failures"] = len(modules), failures
    import addon_utils
    addon_utils.disable("bl_ext.user_default.atmos", default_set=True)
    result["disabled_cleanly"] = not hasattr(bpy.types.Scene, "atmos")
    addon_utils.enable("bl_ext.user_default.atmos", default_set=True)
    result["reenabled"] = hasattr(bpy.types.Scene, "atmos")
    # `blender --command atmos render valley ...` runs this function: the sample scene ships in the extension
    from bl_ext.user_default.atmos.atmos_addon import cli
    result["render_valley"] = cli.main(["render", "valley", "--preset", "clear", "--engine", "cycles",
                                        "--resolution", "16x8", "--samples", "1", "--output", sys.argv[2]])
    print("ATMOS_RESULT " + json.dumps(result))
    """
)


@pytest.fixture(scope="module")
def extension_zip(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_extension.build(tmp_path_factory.mktemp("dist"))


def test_zip_holds_the_extension_and_nothing_else(extension_zip: Path) -> None:
    names = zipfile.ZipFile(extension_zip).namelist()
    assert "blender_manifest.toml" in names
    assert "__init__.py" in names
    assert "atmos_addon/physics/__init__.py" in names
    assert "node_groups/__init__.py" in names
    assert "sample_scenes/valley.py" in names and "sample_scenes/mars.py" in names
    for excluded in ("tests/", ".ci/", "tools/", "validation/", ".venv/", "Makefile", "run", "requirements.txt"):
        assert not any(name == excluded or name.startswith(excluded) for name in names), excluded
    # The references and the retired Balanced model moved to validation/: no copy of them ships anywhere.
    moved = {"reference.py", "multiple_scattering_reference.py", "spectral_reference.py", "balanced.py", "accuracy.py"}
    assert not [name for name in names if name.rsplit("/", 1)[-1] in moved]
    assert not any(name.endswith((".pyc", ".blend")) for name in names)


def test_zip_installs_and_enables_in_a_fresh_blender(extension_zip: Path, tmp_path: Path) -> None:
    env = dict(os.environ, HOME=str(tmp_path), XDG_CONFIG_HOME=str(tmp_path / ".config"))
    env.pop("PYTHONPATH", None)
    proc = subprocess.run(
        [sys.executable, "-c", INSTALL_SCRIPT, str(extension_zip), str(tmp_path / "valley.png")],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600,
    )
    lines = [line for line in proc.stdout.splitlines() if line.startswith("ATMOS_RESULT ")]
    assert proc.returncode == 0 and lines, proc.stdout[-3000:] + proc.stderr[-3000:]
    result = json.loads(lines[-1].removeprefix("ATMOS_RESULT "))
    assert result["install"] == ["FINISHED"]
    assert result["enabled"] and result["scene_property"]
    assert result["module_file"].startswith(str(tmp_path)), "the installed copy must be the one loaded"
    assert result["checkout_importable"] == [], "the checkout leaked onto the installed add-on's path"
    assert result["import_failures"] == {} and result["modules_imported"] > 80, result
    assert result["disabled_cleanly"] and result["reenabled"]
    assert result["render_valley"] == 0 and (tmp_path / "valley.png").is_file(), proc.stderr[-3000:]
