# SPDX-License-Identifier: GPL-3.0-or-later
"""Shared pytest set-up: the repo root on sys.path so ``atmos_addon`` (and the sample scenes) import."""

import sys
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
if str(REPO_ROOT) not in sys.path:
    sys.path.insert(0, str(REPO_ROOT))
