# SPDX-License-Identifier: GPL-3.0-or-later
"""The test command of ``./run test``: pytest once per test file, each in its own process, a crash retried once.

    .venv/bpy-5.2.3/bin/python tools/run_tests.py [PYTEST OPTIONS]       # every file under tests/, one by one
    .venv/bpy-5.2.3/bin/python tools/run_tests.py tests/physics -k sun    # paths given: one pytest run of them

Why per file: the ``bpy`` module of Blender 5.2 and 5.3 has crashed inside ``bpy.ops.render.render`` (a segmentation
fault in Blender's C code, no Python error) at random points of a long test session: on the CI machine in an Eevee
render of ``test_new_user_scenes.py`` (5.2.3 and 5.3.0, stop 31), here once in a Cycles render of
``test_in_render.py`` (5.3.0, stop 32), while the same files pass alone and in other runs of the whole suite. A
crash takes the whole pytest process with it, and every test after it. Here a file whose process dies from a
signal is run again once, and the crash is reported by name either way; a test that fails (an assertion, an
exception) is never retried, and a file that crashes twice fails the run. Exit status: 0 when every file passed
(or collected nothing under ``-k``), 1 otherwise.
"""

from __future__ import annotations

import re
import signal
import subprocess
import sys
import time
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
TESTS = REPO_ROOT / "tests"
#: pytest's exit status when a run collected no test (a -k that selects nothing in this file).
NO_TESTS_COLLECTED = 5


def test_files() -> list[Path]:
    """Every test module under tests/, in pytest's own order (directories and files alphabetically)."""
    return sorted(TESTS.rglob("test_*.py"), key=lambda path: path.relative_to(TESTS).parts)


def crash_signal(returncode: int) -> str | None:
    """The signal's name when ``returncode`` says the process was killed by one (negative from subprocess)."""
    if returncode >= 0:
        return None
    try:
        return signal.Signals(-returncode).name
    except ValueError:
        return f"signal {-returncode}"


def run_pytest(targets: list[str], options: list[str]) -> tuple[int, str]:
    """One pytest process over ``targets``; its output is streamed, and also returned with the exit status."""
    command = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", *targets, *options]
    process = subprocess.Popen(command, cwd=REPO_ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = []
    for line in process.stdout:
        sys.stdout.write(line)
        lines.append(line)
    sys.stdout.flush()
    return process.wait(), "".join(lines)


def counts(output: str) -> dict[str, int]:
    """pytest's summary counts ("12 passed, 1 skipped") from the last summary line of a run's output."""
    summaries = [line for line in output.splitlines()
                 if re.search(r"\b(passed|failed|errors?|skipped|no tests ran)\b.* in [\d.]+s", line)]
    total: dict[str, int] = {}
    for number, kind in re.findall(r"(\d+) (passed|failed|errors?|skipped|xfailed|xpassed)", summaries[-1]
                                   if summaries else ""):
        total["error" if kind.startswith("error") else kind] = int(number)
    return total


def run(targets: list[str], options: list[str]) -> tuple[bool, dict[str, int], list[str]]:
    """Run ``targets`` with one retry after a crash: (passed, counts, crash reports)."""
    crashes = []
    for attempt in (1, 2):
        returncode, output = run_pytest(targets, options)
        name = crash_signal(returncode)
        if name is None:
            return returncode in (0, NO_TESTS_COLLECTED), counts(output), crashes
        running = re.findall(r"File \"[^\"]*/(tests/[^\"]+)\", line (\d+) in (test_\w+)", output)
        where = f"{running[-1][0]}::{running[-1][2]}" if running else " ".join(targets)
        crashes.append(f"{' '.join(targets)}: Blender crashed ({name}) in {where}, attempt {attempt}")
        print(f"\n=== {crashes[-1]}" + ("; running the file again" if attempt == 1 else ""), flush=True)
    return False, counts(output), crashes


def main(argv: list[str]) -> int:
    paths = [arg for arg in argv if not arg.startswith("-") and (REPO_ROOT / arg.split("::")[0]).exists()]
    options = [arg for arg in argv if arg not in paths]
    groups = [paths] if paths else [[str(path.relative_to(REPO_ROOT))] for path in test_files()]
    start = time.perf_counter()
    failed, crashes, total = [], [], {}
    for targets in groups:
        passed, found, crashed = run(targets, options)
        crashes += crashed
        for kind, number in found.items():
            total[kind] = total.get(kind, 0) + number
        if not passed:
            failed.append(" ".join(targets))
    summary = ", ".join(f"{number} {kind}" for kind, number in sorted(total.items())) or "no tests"
    print(f"\n=== {summary} in {len(groups)} pytest run(s), {time.perf_counter() - start:.0f} s")
    for report in crashes:
        print(f"=== crash: {report}")
    for name in failed:
        print(f"=== FAILED: {name}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
