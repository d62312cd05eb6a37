# SPDX-License-Identifier: GPL-3.0-or-later
"""Validate and build the Atmos extension zip with Blender's own extension tool.

The tool (``blender_ext.py``) ships inside the ``bpy`` wheel under
``bpy/<version>/scripts/addons_core/bl_pkg/cli/``; it is run with the current interpreter so no
Blender executable is needed. Usage: ``python tools/build_extension.py --output-dir dist``.
"""

from __future__ import annotations

import argparse
import importlib.util
import subprocess
import sys
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent


def blender_ext_tool() -> Path:
    """Path of ``blender_ext.py`` inside the installed ``bpy`` wheel (without importing bpy)."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        raise SystemExit("error: the bpy module is not installed in this interpreter (run ./run build)")
    for location in spec.submodule_search_locations:
        found = sorted(Path(location).glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
        if found:
            return found[-1]
    raise SystemExit("error: blender_ext.py was not found inside the bpy wheel")


def run_tool(*args: str) -> str:
    """Run ``blender_ext.py`` with ``args``; raise SystemExit with its output on failure."""
    result = subprocess.run([sys.executable, str(blender_ext_tool()), *args], capture_output=True, text=True)
    output = (result.stdout + result.stderr).strip()
    if result.returncode != 0 or "FATAL_ERROR" in output:
        raise SystemExit(f"error: blender_ext {args[0]} failed:\n{output}")
    return output


def build(output_dir: Path) -> Path:
    """Validate the manifest, build the zip into ``output_dir`` and return its path."""
    run_tool("validate", str(REPO_ROOT))
    output_dir.mkdir(parents=True, exist_ok=True)
    output = run_tool("build", "--source-dir", str(REPO_ROOT), "--output-dir", str(output_dir))
    zips = [line.split('"')[1] for line in output.splitlines() if line.startswith("created:")]
    if not zips:
        raise SystemExit(f"error: blender_ext build did not report a zip:\n{output}")
    return Path(zips[0])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output-dir", type=Path, default=REPO_ROOT / "dist")
    args = parser.parse_args(argv)
    print(build(args.output_dir.resolve()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
