# SPDX-License-Identifier: GPL-3.0-or-later
"""The test command of ``./run test``: pytest once per test file, each in its own process, on every core, a crash
retried once.

    .venv/bpy-5.2.3/bin/python tools/run_tests.py [PYTEST OPTIONS]       # every file under tests/
    .venv/bpy-5.2.3/bin/python tools/run_tests.py --blender-only         # tests/blender/ alone (CI's other versions)
    .venv/bpy-5.2.3/bin/python tools/run_tests.py tests/physics -k sun    # paths given: one pytest run of them
    .venv/bpy-5.2.3/bin/python tools/run_tests.py --record-durations     # ... and write tests/durations.json

Why a process per file: the ``bpy`` module of Blender 5.2 and 5.3 has crashed inside ``bpy.ops.render.render`` (a
segmentation fault in Blender's C code, no Python error) at random points of a long test session, while the same
files pass alone. A crash takes the whole pytest process with it, and every test after it. Here a file whose
process dies from a signal is run again once, and the crash is reported by name either way; a test that fails (an
assertion, an exception) is never retried, and a file that crashes twice fails the run.

The files run ``--jobs`` at a time (default: the machine's cores), the longest first (``tests/durations.json``, the
wall time of each file in a recorded run; files it does not list go first), so the last to finish are short ones.
Each file's output is printed whole when it ends. Each process has its own pytest temporary folder, and all share
the tables' store (``tests/conftest.py``; ``ATMOS_TEST_TABLE_STORE``, default ``.venv/table-store``).

Exit status: 0 when every file passed (or collected nothing under ``-k``), 1 otherwise.
"""

from __future__ import annotations

import concurrent.futures
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
TESTS = REPO_ROOT / "tests"
#: Each test file's wall time in a recorded run, s (``--record-durations``): the order files start in.
DURATIONS = TESTS / "durations.json"
#: The tests that need Blender (the rest run on numpy alone, the same on every Blender version).
BLENDER_TESTS = TESTS / "blender"
#: pytest's exit status when a run collected no test (a -k that selects nothing in this file).
NO_TESTS_COLLECTED = 5
#: Files in the tables' store unused for this long are removed at the start of a run, s.
STORE_KEPT_S = 14 * 24 * 3600


def test_files() -> list[Path]:
    """Every test module under tests/, in pytest's own order (directories and files alphabetically)."""
    return sorted(TESTS.rglob("test_*.py"), key=lambda path: path.relative_to(TESTS).parts)


def needs_blender(path: Path) -> bool:
    """True for the test files that run in Blender (under tests/blender/)."""
    return BLENDER_TESTS in path.resolve().parents


def recorded_durations() -> dict[str, float]:
    """tests/durations.json: file (relative to the checkout) -> seconds; empty when there is none."""
    try:
        return {str(name): float(seconds) for name, seconds in json.loads(DURATIONS.read_text()).items()}
    except (OSError, ValueError, AttributeError):
        return {}


def longest_first(files: list[str], durations: dict[str, float]) -> list[str]:
    """``files`` in the order to start them: those without a recorded duration first (they may be long), then the
    longest first (a greedy schedule whose last files are short, so no core idles while one long file runs)."""
    return sorted(files, key=lambda name: (name in durations, -durations.get(name, 0.0), name))


def crash_signal(returncode: int) -> str | None:
    """The signal's name when ``returncode`` says the process was killed by one (negative from subprocess)."""
    if returncode >= 0:
        return None
    try:
        return signal.Signals(-returncode).name
    except ValueError:
        return f"signal {-returncode}"


def run_pytest(targets: list[str], options: list[str], *, stream: bool = True,
               basetemp: Path | None = None) -> tuple[int, str]:
    """One pytest process over ``targets``; its output (streamed when ``stream``) and exit status. ``basetemp``:
    the process's own pytest temporary folder (processes side by side must not share one)."""
    command = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", *targets, *options]
    if basetemp is not None:
        command.append(f"--basetemp={basetemp}")
    process = subprocess.Popen(command, cwd=REPO_ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = []
    for line in process.stdout:
        if stream:
            sys.stdout.write(line)
        lines.append(line)
    if stream:
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


def run(targets: list[str], options: list[str], *, stream: bool = True,
        basetemp: Path | None = None) -> tuple[bool, dict[str, int], list[str], str]:
    """Run ``targets`` with one retry after a crash: (passed, counts, crash reports, the output of every attempt)."""
    crashes, outputs = [], []
    for attempt in (1, 2):
        returncode, output = run_pytest(targets, options, stream=stream, basetemp=basetemp)
        outputs.append(output)
        name = crash_signal(returncode)
        if name is None:
            return returncode in (0, NO_TESTS_COLLECTED), counts(output), crashes, "".join(outputs)
        running = re.findall(r"File \"[^\"]*/(tests/[^\"]+)\", line (\d+) in (test_\w+)", output)
        where = f"{running[-1][0]}::{running[-1][2]}" if running else " ".join(targets)
        crashes.append(f"{' '.join(targets)}: Blender crashed ({name}) in {where}, attempt {attempt}")
        note = f"\n=== {crashes[-1]}" + ("; running the file again\n" if attempt == 1 else "\n")
        outputs.append(note)
        if stream:
            print(note, end="", flush=True)
    return False, counts(output), crashes, "".join(outputs)


def prune_store(folder: Path, kept_s: float = STORE_KEPT_S) -> None:
    """Remove the files of the tables' store that no run has used for ``kept_s`` (stale code's tables)."""
    now = time.time()
    for path in folder.glob("*") if folder.is_dir() else []:
        try:
            if now - max(path.stat().st_atime, path.stat().st_mtime) > kept_s:
                path.unlink()
        except OSError:
            pass


def run_all(groups: list[list[str]], options: list[str], jobs: int) -> tuple[list[str], list[str], dict, dict]:
    """Run each group of targets in its own pytest process, ``jobs`` at a time (one at a time: its output streamed;
    else each group's output printed whole when it ends): (failed groups, crash reports, summed counts, seconds
    per group)."""
    failed, crashes, total, took = [], [], {}, {}
    with tempfile.TemporaryDirectory(prefix="atmos-tests-") as scratch:

        def one(index: int, targets: list[str]) -> tuple[list[str], tuple, float]:
            began = time.perf_counter()
            result = run(targets, options, stream=jobs == 1, basetemp=Path(scratch) / str(index))
            return targets, result, time.perf_counter() - began

        with concurrent.futures.ThreadPoolExecutor(max_workers=max(jobs, 1)) as pool:
            futures = [pool.submit(one, index, targets) for index, targets in enumerate(groups)]
            for future in concurrent.futures.as_completed(futures):
                targets, (passed, found, crashed, output), seconds = future.result()
                name = " ".join(targets)
                took[name] = seconds
                if jobs > 1:
                    print(f"\n=== {name} ({seconds:.0f} s)\n{output}", end="", flush=True)
                crashes += crashed
                for kind, number in found.items():
                    total[kind] = total.get(kind, 0) + number
                if not passed:
                    failed.append(name)
    return sorted(failed), crashes, total, took


def parse(argv: list[str]) -> tuple[list[str], list[str], dict]:
    """(paths, pytest options, the runner's own options) from the command line."""
    own = {"jobs": os.cpu_count() or 1, "blender_only": False, "numpy_only": False, "record": False}
    rest = []
    arguments = iter(argv)
    for arg in arguments:
        if arg in ("-j", "--jobs"):
            own["jobs"] = int(next(arguments))
        elif arg.startswith("--jobs="):
            own["jobs"] = int(arg.split("=", 1)[1])
        elif arg == "--blender-only":
            own["blender_only"] = True
        elif arg == "--numpy-only":
            own["numpy_only"] = True
        elif arg == "--record-durations":
            own["record"] = True
        else:
            rest.append(arg)
    if own["jobs"] < 1:
        raise SystemExit(f"--jobs must be 1 or more, not {own['jobs']}")
    paths = [arg for arg in rest if not arg.startswith("-") and (REPO_ROOT / arg.split("::")[0]).exists()]
    options = [arg for arg in rest if arg not in paths]
    return paths, options, own


def main(argv: list[str]) -> int:
    paths, options, own = parse(argv)
    if paths:
        groups = [paths]
    else:
        files = [path for path in test_files()
                 if not (own["blender_only"] and not needs_blender(path))
                 and not (own["numpy_only"] and needs_blender(path))]
        names = longest_first([str(path.relative_to(REPO_ROOT)) for path in files], recorded_durations())
        groups = [[name] for name in names]
    store = os.environ.get("ATMOS_TEST_TABLE_STORE")
    if store:
        prune_store(Path(store))
    jobs = min(own["jobs"], len(groups))
    print(f"=== {len(groups)} pytest run(s), {jobs} at a time", flush=True)
    start = time.perf_counter()
    failed, crashes, total, took = run_all(groups, options, jobs)
    summary = ", ".join(f"{number} {kind}" for kind, number in sorted(total.items())) or "no tests"
    print(f"\n=== {summary} in {len(groups)} pytest run(s), {jobs} at a time, {time.perf_counter() - start:.0f} s")
    for report in crashes:
        print(f"=== crash: {report}")
    for name in failed:
        print(f"=== FAILED: {name}")
    if own["record"] and not paths:
        recorded = recorded_durations()
        recorded.update({name: round(seconds, 1) for name, seconds in took.items()})
        DURATIONS.write_text(json.dumps(dict(sorted(recorded.items())), indent=1) + "\n")
        print(f"=== wrote {DURATIONS.relative_to(REPO_ROOT)}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
