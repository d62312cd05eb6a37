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
    passed, found, crashes, _ = run_tests.run([str(path)], ["-q"])
    assert passed and found == {"passed": 1}
    assert len(crashes) == 1 and "SIGSEGV" in crashes[0]
    assert path.with_suffix(".ran").read_text() == "2"


def test_a_failing_test_is_not_retried(tmp_path):
    path = _write(tmp_path, "test_fails.py", FAILS)
    passed, found, crashes, _ = run_tests.run([str(path)], ["-q"])
    assert not passed and found == {"failed": 1} and crashes == []
    assert path.with_suffix(".ran").read_text() == "1"


def test_two_crashes_fail_the_run(tmp_path):
    path = _write(tmp_path, "test_always_crashes.py", ALWAYS_CRASHES)
    passed, _, crashes, _ = run_tests.run([str(path)], ["-q"])
    assert not passed and len(crashes) == 2


def test_every_test_module_is_run_in_pytest_order():
    files = [path.relative_to(run_tests.TESTS).as_posix() for path in run_tests.test_files()]
    assert files == sorted(files, key=lambda name: name.split("/")) and "test_run_tests.py" in files
    assert files[0].startswith("blender/") and "physics/test_sun.py" in files


def test_the_longest_files_start_first_and_unknown_ones_before_them():
    order = run_tests.longest_first(["a.py", "b.py", "c.py", "new.py"], {"a.py": 5.0, "b.py": 50.0, "c.py": 20.0})
    assert order == ["new.py", "b.py", "c.py", "a.py"]


def test_blender_only_and_numpy_only_split_the_files_between_them():
    files = run_tests.test_files()
    blender = [path for path in files if run_tests.needs_blender(path)]
    assert blender and len(blender) < len(files)
    assert all(path.parent.name == "blender" for path in blender)
    assert not any(run_tests.needs_blender(path) for path in files if path.parts[-2] == "physics")


def test_files_run_side_by_side_each_with_its_own_output(tmp_path, capsys):
    for index in range(3):
        _write(tmp_path, f"test_side_{index}.py", f"def test_{index}():\n    assert {index} < 3\n")
    fails = _write(tmp_path, "test_side_fails.py", FAILS)
    groups = [[str(path)] for path in sorted(tmp_path.glob("test_side_*.py"))]
    failed, crashes, total, took = run_tests.run_all(groups, ["-q"], 2)
    assert failed == [str(fails)] and crashes == [] and total == {"passed": 3, "failed": 1}
    assert set(took) == {group[0] for group in groups}
    output = capsys.readouterr().out
    assert all(output.count(f"=== {group[0]} (") == 1 for group in groups)
