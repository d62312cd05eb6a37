# SPDX-License-Identifier: GPL-3.0-or-later
"""``atmos match`` in a subprocess (``python -m atmos_addon match``), as a pipeline would call it.

The plate is made by the fit's own model (``plate_files.py``): the command writes a valid preset whose visibility and
sun are the plate's, prints the residual per region, saves the preset to the user library when asked and writes the
comparison image; an EXR plate with a depth pass matches too. Every refusal (no sky mask, an overexposed sky, a
distance of 0, a missing option, a name taken) ends in exit code 2 and one line, and writes nothing.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

from atmos_addon import presets

import cli_utils
import plate_files
from cli_utils import assert_one_line_error


def run_cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    """``atmos match ARGS`` with a user preset library of its own."""
    return cli_utils.run_cli("match", *args, cwd=cwd, ATMOS_USER_PRESETS=str(cwd / "library"))


@pytest.fixture(scope="module")
def plate_set(tmp_path_factory):
    folder = tmp_path_factory.mktemp("plate")
    return plate_files.write_plate(folder), folder


def _base(paths, output="look.toml"):
    return [str(paths["plate"]), "--fov", str(plate_files.FOV_DEG), "--horizon", "0.5", "--sky-mask",
            str(paths["sky"]), "--output", output, "--start", "clear"]


def test_match_writes_a_valid_preset_of_the_plates_look(plate_set, tmp_path):
    paths, _ = plate_set
    proc = run_cli(*_base(paths), "--region", f"{paths['far']}:15000", "--region", f"{paths['near']}:2000",
                   "--save-preset", "Plate Look", "--comparison", "comparison.png", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    preset = presets.validate_file(tmp_path / "look.toml")
    assert preset.name == "Plate Look"
    truth = plate_files.TRUTH
    from atmos_addon.physics.visibility import visibility_m

    assert visibility_m(preset.atmosphere) == pytest.approx(truth.visibility_m, rel=0.10)
    assert preset.sun_elevation_deg == pytest.approx(truth.sun_elevation_deg, abs=1.0)
    saved = presets.validate_file(tmp_path / "library" / "Plate Look.toml")
    assert saved == preset
    region_lines = [line for line in proc.stdout.splitlines() if line.startswith("region ")]
    assert len(region_lines) == 3 and all("% off" in line for line in region_lines)
    assert "atmos: match 100 %" in proc.stderr  # the progress line
    comparison = tmp_path / "comparison.png"
    assert comparison.is_file() and comparison.stat().st_size > 1000


def test_an_exr_plate_with_a_depth_pass_matches(tmp_path):
    paths = plate_files.write_plate(tmp_path / "exr", exr=True)
    proc = run_cli(str(paths["plate"]), "--fov", str(plate_files.FOV_DEG), "--pitch", "0", "--sky-mask",
                   str(paths["sky"]), "--depth", str(paths["depth"]), "--output", "depth.toml", "--start", "clear",
                   cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    preset = presets.validate_file(tmp_path / "depth.toml")
    from atmos_addon.physics.visibility import visibility_m

    assert visibility_m(preset.atmosphere) == pytest.approx(plate_files.TRUTH.visibility_m, rel=0.10)
    assert "region 'depth pass'" in proc.stdout


def test_refusals_are_one_line_and_write_nothing(plate_set, tmp_path):
    paths, _ = plate_set
    import bpy

    # an overexposed sky: the plate's sky pushed to white
    image = bpy.data.images.load(str(paths["plate"]), check_existing=False)
    pixels = np.empty(len(image.pixels), dtype=np.float32)
    image.pixels.foreach_get(pixels)
    pixels = pixels.reshape(plate_files.HEIGHT, plate_files.WIDTH, 4)
    pixels[plate_files.HEIGHT // 2 + 5:] = 1.0  # rows from the bottom in Blender's order: the top of the plate
    image.pixels.foreach_set(pixels.ravel())
    image.filepath_raw = str(tmp_path / "blown.png")
    image.save()
    bpy.data.images.remove(image)
    region = ["--region", f"{paths['near']}:2000"]
    cases = [
        ([str(paths["plate"]), "--fov", "55", "--sky-mask", str(tmp_path / "missing.png"), "--output", "a.toml"],
         "mask", "does not exist"),
        ([str(tmp_path / "blown.png"), "--fov", "55", "--sky-mask", str(paths["sky"]), "--output", "a.toml",
          "--start", "clear", *region], "the sky is overexposed"),
        (_base(paths, "a.toml") + ["--region", f"{paths['near']}:0"], "distance 0 m"),
        ([str(paths["plate"]), "--sky-mask", str(paths["sky"]), "--output", "a.toml"], "--fov"),
        (_base(paths, "a.txt"), "must be a .toml"),
        (_base(paths, "a.toml") + ["--region", "near.png"], "mask:distance"),
        (_base(paths, "a.toml") + ["--save-preset", "clear"], "built-in"),
    ]
    for args, *fragments in cases:
        proc = run_cli(*args, cwd=tmp_path)
        assert_one_line_error(proc, *fragments)
        assert not (tmp_path / "a.toml").exists() and not (tmp_path / "a.txt").exists()
    library = tmp_path / "library"
    library.mkdir()
    (library / "Taken.toml").write_text("kept as it was\n")
    proc = run_cli(*_base(paths, "a.toml"), *region, "--save-preset", "Taken", cwd=tmp_path)
    assert_one_line_error(proc, "exists", "--overwrite")
    assert (library / "Taken.toml").read_text() == "kept as it was\n"
    assert not (tmp_path / "a.toml").exists()
