# SPDX-License-Identifier: GPL-3.0-or-later
"""The command line as a user runs it, for the CLI tests: ``python -m atmos_addon ...`` in a fresh process with its own
HOME, and the one-line refusal every bad input gets."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[2]


def run_cli(*args: str, cwd: Path, **env: str) -> subprocess.CompletedProcess:
    """``python -m atmos_addon ARGS`` in ``cwd``, which is also its HOME; ``env``: more environment variables."""
    environment = dict(os.environ, HOME=str(cwd), PYTHONPATH=str(REPO_ROOT), **env)
    return subprocess.run([sys.executable, "-m", "atmos_addon", *args], cwd=cwd, env=environment,
                          capture_output=True, text=True, timeout=600)


def assert_one_line_error(proc: subprocess.CompletedProcess, *fragments: str) -> None:
    """``proc`` refused with exit status 2 and one ``atmos: error:`` line holding every fragment, no traceback."""
    assert proc.returncode == 2, proc.stderr[-2000:]
    errors = [line for line in proc.stderr.splitlines() if line.startswith("atmos: error: ")]
    assert len(errors) == 1, proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr
    for fragment in fragments:
        assert fragment in errors[0], errors[0]
