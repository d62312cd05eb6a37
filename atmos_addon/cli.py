# SPDX-License-Identifier: GPL-3.0-or-later
"""The Atmos command line (``python -m atmos_addon``).

Sub-commands:
  demo     build the sample valley, render it without and with aerial perspective, write PNGs.
Errors end in a one-line message on stderr and a non-zero exit code, never a traceback.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path


class CliError(Exception):
    """A user-facing failure: printed as one line, exit code 2."""


def _log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def _render_to(scene, path: Path) -> float:
    """Render ``scene`` to ``path`` (PNG) and return the seconds it took."""
    import bpy

    scene.render.image_settings.file_format = "PNG"
    scene.render.filepath = str(path)
    start = time.perf_counter()
    bpy.ops.render.render(write_still=True, scene=scene.name)
    return time.perf_counter() - start


def cmd_demo(args: argparse.Namespace) -> int:
    """Render the valley sample scene without and with the effect into ``args.output``."""
    import atmos_addon
    from atmos_addon import import_sibling
    from atmos_addon.blender import effect

    try:
        valley = import_sibling("sample_scenes.valley")
    except ImportError as error:
        raise CliError(f"the sample scenes are not here ({error}); run the demo from a source checkout") from error
    output = Path(args.output).resolve()
    output.mkdir(parents=True, exist_ok=True)
    atmos_addon.register()
    try:
        scene = valley.build(resolution=(args.width, args.height))
        scene.cycles.samples = args.samples
        plain = output / "valley_plain.png"
        _log(f"rendering {plain} (no atmosphere) ...")
        seconds = _render_to(scene, plain)
        _log(f"  {seconds:.1f} s")
        report = effect.enable_effect(scene)
        for line in report.messages:
            _log(f"  atmos: {line}")
        with_effect = output / "valley.png"
        _log(f"rendering {with_effect} (aerial perspective) ...")
        seconds = _render_to(scene, with_effect)
        _log(f"  {seconds:.1f} s")
    finally:
        atmos_addon.unregister()
    print(f"wrote {plain}\nwrote {with_effect}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="atmos", description="Atmos: physically based aerial perspective.")
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser("demo", help="render the sample valley with and without aerial perspective")
    demo.add_argument("--output", default="out", help="output folder (default: out)")
    demo.add_argument("--width", type=int, default=480)
    demo.add_argument("--height", type=int, default=270)
    demo.add_argument("--samples", type=int, default=32)
    demo.set_defaults(func=cmd_demo)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except CliError as error:
        _log(f"atmos: error: {error}")
        return 2
