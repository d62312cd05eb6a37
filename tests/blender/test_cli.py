# SPDX-License-Identifier: GPL-3.0-or-later
"""The command line in a subprocess (``python -m atmos_addon``), as a pipeline would call it.

Success paths render tiny images; every error path must end in exit code 2 and one line
``atmos: error: ...`` on stderr, never a traceback.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from cli_utils import REPO_ROOT, assert_one_line_error, run_cli

VACUUM_PRESET = textwrap.dedent(
    """
    schema_version = 1
    [preset]
    name = "vacuum"
    description = "No air: the render without any atmosphere"
    [atmosphere]
    rayleigh_scattering_per_m = [0.0, 0.0, 0.0]
    mie_scattering_per_m = [0.0, 0.0, 0.0]
    mie_absorption_per_m = [0.0, 0.0, 0.0]
    """
)

# Two emissive planes: the left half of the view 50 m away, the right half 20 km away.
SCENE_SCRIPT = textwrap.dedent(
    """
    import sys, bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = 2.0
    cam.data.clip_end = 30000.0
    cam.rotation_euler = (1.5707963, 0.0, 0.0)
    scene.collection.objects.link(cam)
    if sys.argv[2] == "camera":
        scene.camera = cam
    for name, x, y in (("Near", -0.5, 50.0), ("Far", 0.5, 20000.0)):
        mesh = bpy.data.meshes.new(name)
        mesh.from_pydata([(x - 0.5, y, -1), (x + 0.5, y, -1), (x + 0.5, y, 1), (x - 0.5, y, 1)], [], [(0, 1, 2, 3)])
        mat = bpy.data.materials.new(name)
        mat.use_nodes = True
        nodes = mat.node_tree.nodes
        nodes.remove(nodes["Principled BSDF"])
        emission = nodes.new("ShaderNodeEmission")
        emission.inputs["Color"].default_value = (0.05, 0.05, 0.05, 1.0)  # dark ground: the haze shows
        mat.node_tree.links.new(emission.outputs[0], nodes["Material Output"].inputs["Surface"])
        mesh.materials.append(mat)
        scene.collection.objects.link(bpy.data.objects.new(name, mesh))
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 1
    scene.render.filter_size = 0.01
    scene.view_settings.view_transform = "Standard"
    bpy.ops.wm.save_as_mainfile(filepath=sys.argv[1])
    """
)


@pytest.fixture(scope="module")
def workdir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("cli")
    (folder / "vacuum.toml").write_text(VACUUM_PRESET, encoding="utf-8")
    for kind in ("camera", "nocamera"):
        subprocess.run([sys.executable, "-c", SCENE_SCRIPT, str(folder / f"{kind}.blend"), kind],
                       cwd=folder, env=dict(os.environ, HOME=str(folder)), check=True, capture_output=True, timeout=300)
    (folder / "garbage.blend").write_bytes(b"this is not a blend file\n" * 10)
    return folder


def read_png(path: Path) -> np.ndarray:
    import bpy

    image = bpy.data.images.load(str(path))
    try:
        pixels = np.array(image.pixels[:], dtype=float).reshape(image.size[1], image.size[0], image.channels)
    finally:
        bpy.data.images.remove(image)
    return pixels[::-1, :, :3]


def test_render_changes_distant_pixels_and_barely_near_ones(workdir: Path) -> None:
    outputs = {}
    for preset in ("clear", str(workdir / "vacuum.toml")):
        out = workdir / f"render_{Path(preset).stem}.png"
        proc = run_cli("render", str(workdir / "camera.blend"), "--preset", preset, "--resolution", "16x8",
                       "--samples", "1", "--output", str(out), cwd=workdir)
        assert proc.returncode == 0, proc.stderr[-3000:]
        assert "s per frame" in proc.stderr and "frame 1" in proc.stderr
        outputs[Path(preset).stem] = read_png(out)
    hazy, plain = outputs["clear"], outputs["vacuum"]
    near = np.abs(hazy[:, 1:7] - plain[:, 1:7]).max()
    far = np.abs(hazy[:, 9:15] - plain[:, 9:15]).mean(axis=(0, 1))
    assert near < 0.01, near
    assert far.max() > 0.05, far  # 20 km of clear air: dimmed and veiled


def test_render_frames_write_one_file_per_frame(workdir: Path) -> None:
    out = workdir / "frames" / "shot_####.png"
    proc = run_cli("render", str(workdir / "camera.blend"), "--preset", "clear", "--resolution", "8x4",
                   "--samples", "1", "--frames", "2-3", "--output", str(out), cwd=workdir)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert sorted(p.name for p in out.parent.iterdir()) == ["shot_0002.png", "shot_0003.png"]
    assert "rendered 2 frame(s)" in proc.stderr


def test_apply_writes_a_blend_with_the_effect(workdir: Path) -> None:
    out = workdir / "applied.blend"
    proc = run_cli("apply", str(workdir / "camera.blend"), "--preset", "sunset", "--output", str(out), cwd=workdir)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert out.is_file() and out.stat().st_size > 1000
    assert "blender -b" in proc.stderr


def test_apply_in_render_mode_writes_the_domes(workdir: Path) -> None:
    import bpy

    out = workdir / "in_render.blend"
    proc = run_cli("apply", str(workdir / "camera.blend"), "--preset", "clear", "--engine", "cycles",
                   "--mode", "in-render", "--output", str(out), cwd=workdir)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "In-Render mode" in proc.stderr

    with bpy.data.libraries.load(str(out)) as (data_from, _data_to):
        objects = list(data_from.objects)
    assert "Atmos Dome (molecules)" in objects and "Atmos Dome (aerosols)" in objects


def test_render_in_per_pixel_mode_writes_its_aovs(workdir: Path) -> None:
    """--mode per-pixel renders, and the multilayer EXR carries the distance and view AOVs it composites from."""
    out = workdir / "per_pixel.exr"
    proc = run_cli("render", str(workdir / "camera.blend"), "--preset", "clear", "--engine", "cycles", "--mode",
                   "per-pixel", "--resolution", "8x4", "--samples", "1", "--output", str(out), cwd=workdir)
    assert proc.returncode == 0, proc.stderr[-3000:]
    header = out.read_bytes()[:20000]
    for name in (b"atmos_distance", b"atmos_view", b"atmos_coverage"):
        assert name in header, name


def test_apply_with_a_quality_level(workdir: Path) -> None:
    out = workdir / "fast.blend"
    proc = run_cli("apply", str(workdir / "camera.blend"), "--preset", "clear", "--quality", "fast",
                   "--output", str(out), cwd=workdir)
    assert proc.returncode == 0, proc.stderr[-3000:]
    from atmos_addon.physics.quality import Level, level_summary   # the level's measured error and cost

    assert f"atmos: Fast: {level_summary(Level.FAST, True, 'PER_PIXEL')}" in proc.stderr
    proc = run_cli("apply", str(workdir / "camera.blend"), "--preset", "clear", "--quality", "balanced",
                   "--output", str(workdir / "balanced.blend"), cwd=workdir)
    assert proc.returncode == 2 and "the Balanced quality level was retired" in proc.stderr, proc.stderr[-3000:]
    assert "use precise" in proc.stderr and not (workdir / "balanced.blend").exists()
    proc = run_cli("apply", str(workdir / "camera.blend"), "--preset", "clear", "--quality", "auto",
                   "--output", str(workdir / "auto.blend"), cwd=workdir)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "atmos: Auto chose " in proc.stderr
    precise = workdir / "precise.blend"
    proc = run_cli("apply", str(workdir / "camera.blend"), "--preset", "clear", "--quality", "precise",
                   "--output", str(precise), cwd=workdir)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert 'atmos: Precise: baked 1 table tile into the image "Atmos Precise Table"' in proc.stderr
    import bpy

    with bpy.data.libraries.load(str(precise)) as (data_from, _data_to):
        assert "Atmos Precise Table" in list(data_from.images)


@pytest.mark.parametrize(
    "args, fragments",
    [
        (("render", "camera.blend", "--preset", "clear", "--quality", "exact", "--output", "x.png"),
         ("--quality", "exact")),
        (("render", "missing.blend", "--preset", "clear", "--output", "x.png"), ("missing.blend", "does not exist")),
        (("render", "garbage.blend", "--preset", "clear", "--output", "x.png"), ("garbage.blend", "cannot read")),
        (("render", "camera.blend", "--preset", "no-such-preset", "--output", "x.png"), ("no-such-preset",)),
        (("render", "camera.blend", "--preset", "clear", "--samples", "0", "--output", "x.png"), ("--samples",)),
        (("render", "camera.blend", "--preset", "clear", "--sun-elevation", "95", "--output", "x.png"),
         ("--sun-elevation", "95")),
        (("render", "camera.blend", "--preset", "clear", "--output", "x.jpg"), (".png or .exr",)),
        (("render", "nocamera.blend", "--preset", "clear", "--output", "x.png"), ("no camera",)),
        (("render", "camera.blend", "--preset", "clear", "--engine", "eevee", "--mode", "in-render", "--output",
          "x.png"), ("--mode in-render", "Cycles")),
        (("presets", "show", "nope"), ("nope",)),
        (("presets", "validate", "camera.blend"), ("camera.blend",)),
    ],
)
def test_error_paths_exit_2_with_one_line(workdir: Path, args: tuple[str, ...], fragments: tuple[str, ...]) -> None:
    assert_one_line_error(run_cli(*args, cwd=workdir), *fragments)
    assert not (workdir / "x.png").exists() and not (workdir / "x.jpg").exists()


def test_a_python_script_using_the_api_exits_cleanly(workdir: Path) -> None:
    """A pipeline script with the pip bpy module: the add-on stays registered until the process ends (4.5's bpy
    crashed at exit, code -11, after a successful run)."""
    script = ("import sys, bpy\nfrom atmos_addon import api\n"
              "bpy.ops.wm.open_mainfile(filepath=sys.argv[1])\n"
              "api.enable(bpy.context.scene, preset='clear')\nprint('enabled', api.is_enabled(bpy.context.scene))\n")
    proc = subprocess.run([sys.executable, "-c", script, str(workdir / "camera.blend")], cwd=workdir,
                          env=dict(os.environ, HOME=str(workdir), PYTHONPATH=str(REPO_ROOT)), capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "enabled True" in proc.stdout


def test_presets_list_show_validate(workdir: Path) -> None:
    listed = run_cli("presets", "list", cwd=workdir)
    assert listed.returncode == 0
    names = [line.split("\t")[0] for line in listed.stdout.splitlines()]
    assert names[:4] == ["clear", "overcast", "sunset", "mars"]
    shown = run_cli("presets", "show", "mars", cwd=workdir)
    assert shown.returncode == 0 and 'name = "mars"' in shown.stdout and "planet_radius_m" in shown.stdout
    valid = run_cli("presets", "validate", str(workdir / "vacuum.toml"), cwd=workdir)
    assert valid.returncode == 0 and "valid preset 'vacuum'" in valid.stdout
    bad = workdir / "bad.toml"
    bad.write_text(VACUUM_PRESET.replace("mie_absorption_per_m", "mie_absorbtion_per_m"), encoding="utf-8")
    assert_one_line_error(run_cli("presets", "validate", str(bad), cwd=workdir), "bad.toml", "mie_absorbtion_per_m")


def test_blender_command_is_registered_with_the_add_on() -> None:
    import atmos_addon
    from atmos_addon.blender.ui import cli_command

    atmos_addon.register()
    try:
        assert cli_command._handle is not None
        assert cli_command._run(["presets", "list"]) == 0
    finally:
        atmos_addon.unregister()
    assert cli_command._handle is None
