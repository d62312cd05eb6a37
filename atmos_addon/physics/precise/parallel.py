# SPDX-License-Identifier: GPL-3.0-or-later
"""The threads the Precise bakes run on: the multiple-scattering table's altitudes and a tile's blocks of rows, each
task writing only its own slices, so the results are the same to the bit on any number of threads (numpy's array
loops release the GIL).
"""

from __future__ import annotations

import concurrent.futures
import os
from collections.abc import Callable

#: Threads that build the rows of a table's altitudes or a tile's blocks at once: the machine's
#: cores, at most 4 (each holds about 40 MB of temporaries).
WORKERS = max(1, min(4, os.cpu_count() or 1))


def in_parallel(work: Callable[[int], None], count: int) -> None:
    """work(0), ..., work(count - 1) on :data:`WORKERS` threads; each call must write only its own slices. The
    results are the same to the bit as in one thread; a call's exception is raised here."""
    if WORKERS == 1 or count < 2:
        for index in range(count):
            work(index)
        return
    with concurrent.futures.ThreadPoolExecutor(WORKERS) as pool:
        list(pool.map(work, range(count)))
