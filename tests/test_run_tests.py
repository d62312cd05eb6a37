# SPDX-License-Identifier: GPL-3.0-or-later
"""tools/run_tests.py, the runner of ``./run test``: a crashed test process is run again once and reported; a failing
test is never retried; a file that crashes twice fails the run. Plain pytest, no Blender."""

import sys
import textwrap
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tools"))

import run_tests  # noqa: E402

CRASH_ONCE = """
    import ctypes
    from pathlib import Path

    def test_crashes_the_first_time():
        marker = Path(__file__).with_suffix(".ran")
        runs = int(marker.read_text()) if marker.exists() else 0
        marker.write_text(str(runs + 1))
        if runs == 0:
            ctypes.string_at(0)   # a segmentation fault, as Blender's render crashes
"""
FAILS = """
    from pathlib import Path

    def test_fails():
        marker = Path(__file__).with_suffix(".ran")
        marker.write_text(str(int(marker.read_text()) + 1 if marker.exists() else 1))
        assert False
"""
ALWAYS_CRASHES = """
    import ctypes

    def test_crashes():
        ctypes.string_at(0)
"""


def _write(folder: Path, name: str, source: str) -> Path:
    path = folder / name
    path.write_text(textwrap.dedent(source))
    return path


def test_a_crash_is_run_again_once_and_reported(tmp_path):
    path = _write(tmp_path, "test_crash_once.py", CRASH_ONCE)
    passed, found, crashes = run_tests.run([str(path)], ["-q"])
    assert passed and found == {"passed": 1}
    assert len(crashes) == 1 and "SIGSEGV" in crashes[0]
    assert path.with_suffix(".ran").read_text() == "2"


def test_a_failing_test_is_not_retried(tmp_path):
    path = _write(tmp_path, "test_fails.py", FAILS)
    passed, found, crashes = run_tests.run([str(path)], ["-q"])
    assert not passed and found == {"failed": 1} and crashes == []
    assert path.with_suffix(".ran").read_text() == "1"


def test_two_crashes_fail_the_run(tmp_path):
    path = _write(tmp_path, "test_always_crashes.py", ALWAYS_CRASHES)
    passed, _, crashes = run_tests.run([str(path)], ["-q"])
    assert not passed and len(crashes) == 2


def test_every_test_module_is_run_in_pytest_order():
    files = [path.relative_to(run_tests.TESTS).as_posix() for path in run_tests.test_files()]
    assert files == sorted(files, key=lambda name: name.split("/")) and "test_run_tests.py" in files
    assert files[0].startswith("blender/") and "physics/test_sun.py" in files
