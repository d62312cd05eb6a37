# SPDX-License-Identifier: GPL-3.0-or-later
"""docs/benchmarks.md is written whole by ``./run bench`` (tools/bench.py): its notes come from the script's NOTES, so
a note written into the page alone is lost at the next run (stop 52's were, at stop 53). Plain pytest, no Blender."""

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tools"))

import bench  # noqa: E402


def test_the_benchmarks_page_carries_the_bench_scripts_notes():
    page = (ROOT / "docs" / "benchmarks.md").read_text(encoding="utf-8")
    heading = bench.NOTES.splitlines()[0]
    assert heading in page
    assert page[page.index(heading):].rstrip("\n") == bench.NOTES.rstrip("\n"), (
        "docs/benchmarks.md's notes differ from tools/bench.py's NOTES: edit NOTES (./run bench writes the page)")
