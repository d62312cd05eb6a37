# SPDX-License-Identifier: GPL-3.0-or-later
"""Shared pytest set-up: the repo root on sys.path so ``atmos_addon`` (and the sample scenes) import, and the
tables' store that the test processes share.

The store: many tests bake the same per-atmosphere tables and tiles (the default preset, a camera a few metres
up). With ``ATMOS_TEST_TABLE_STORE`` set to a folder (``tools/run_tests.py`` sets it), what one test process built
is read back by the others (``atmos_addon.physics.precise.use_store``) instead of being integrated again. A file's
name is a digest of the inputs, the physics package's source and numpy's version, so a change to any of them builds
afresh; a file is written whole or not at all (a rename), so processes running side by side never read half of one.
"""

import hashlib
import os
import pickle
import sys
import tempfile
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
if str(REPO_ROOT) not in sys.path:
    sys.path.insert(0, str(REPO_ROOT))
# pytest's root is tests/, not the checkout: the checkout's __init__.py (the extension entry) would otherwise make
# it a package that pytest imports by its folder's name, which fails for a checkout named e.g. "atmos-main".


class FolderStore:
    """``physics.precise.TableStore`` over a folder: one pickle per key (trusted: the folder is the test run's own)."""

    def __init__(self, folder: Path) -> None:
        import numpy

        self.folder = folder
        self.folder.mkdir(parents=True, exist_ok=True)
        digest = hashlib.sha1(numpy.__version__.encode())
        for source in sorted((REPO_ROOT / "atmos_addon" / "physics").rglob("*.py")):
            digest.update(source.read_bytes())
        self.salt = digest.hexdigest()

    def _path(self, key: str) -> Path:
        return self.folder / (hashlib.sha1((self.salt + key).encode()).hexdigest() + ".pickle")

    def load(self, key: str):
        try:
            with open(self._path(key), "rb") as file:
                return pickle.load(file)
        except (OSError, EOFError, pickle.UnpicklingError):
            return None

    def save(self, key: str, value) -> None:
        handle, temporary = tempfile.mkstemp(dir=self.folder, suffix=".part")
        with os.fdopen(handle, "wb") as file:
            pickle.dump(value, file, protocol=pickle.HIGHEST_PROTOCOL)
        os.replace(temporary, self._path(key))


if os.environ.get("ATMOS_TEST_TABLE_STORE"):
    from atmos_addon.physics import precise

    precise.use_store(FolderStore(Path(os.environ["ATMOS_TEST_TABLE_STORE"])))


import pytest  # noqa: E402


@pytest.fixture
def without_table_store():
    """The test sees only this process's own tables and tiles (what it asserts of the in-memory caches)."""
    from atmos_addon.physics import precise

    kept = precise.current_store()
    precise.use_store(None)
    yield
    precise.use_store(kept)
