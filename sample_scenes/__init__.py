"""Scripted sample scenes (the valley, Mars): the CLI builds them by name; they ship in the extension."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path


def write_scene(build: Callable[[], object], description: str) -> None:
    """The command line of a sample-scene script: build the scene and save it to ``--output``."""
    import bpy

    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--output", type=Path, required=True, help="the .blend file to write")
    args = parser.parse_args()
    build()
    bpy.ops.wm.save_as_mainfile(filepath=str(args.output.resolve()))
    print(f"wrote {args.output}")
