# SPDX-License-Identifier: GPL-3.0-or-later
"""Interpolation in the package's tables, numpy alone: bilinear (an image texture's linear filter, edge samples
clamped), and log-linear, low^(1 - f) high^f, for light that falls by orders of magnitude between two nodes (the
multiple-scattering table across the terminator).
"""

from __future__ import annotations

import numpy as np


def table_cell(rows: int, columns: int, i: np.ndarray, k: np.ndarray) -> tuple[np.ndarray, ...]:
    """(i0, k0, fi, fk): the lower corner of the table cell that holds the fractional indices (i, k), edge samples
    clamped (an image texture's filter), and the fractions within it."""
    i = np.clip(i, 0, rows - 1)
    k = np.clip(k, 0, columns - 1)
    i0 = np.minimum(np.floor(i).astype(int), rows - 2)
    k0 = np.minimum(np.floor(k).astype(int), columns - 2)
    return i0, k0, i - i0, k - k0


def log_linear(low: np.ndarray, high: np.ndarray, fraction: np.ndarray) -> np.ndarray:
    """low^(1 - f) high^f: the straight line between two values in log space (light that falls exponentially), or
    the straight line itself where either is not positive."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        result = high / low
        result **= fraction
        result *= low
    positive = (low > 0.0) & (high > 0.0)
    if not positive.all():      # (the same numbers as np.where over both, a third of the time: few cells are dark)
        linear = low + fraction * (high - low)
        result[~positive] = np.broadcast_to(linear, result.shape)[~positive]
    return result


def linear_then_log_linear(table: np.ndarray, i: np.ndarray, k: np.ndarray) -> np.ndarray:
    """Interpolation of a table (rows, columns, channels) at fractional indices (i, k), edge samples clamped: linear
    along the rows in each of the two columns around k, then :func:`log_linear` between the columns."""
    columns = table.shape[1]
    i0, k0, fi, fk = table_cell(table.shape[0], columns, i, k)
    fi, fk = fi[..., None], fk[..., None]
    flat = table.reshape(-1, table.shape[2])
    first = i0 * columns + k0
    second = first + columns
    a, b, c, d = (np.take(flat, index, axis=0) for index in (first, second, first + 1, second + 1))
    low = a + fi * (b - a)
    high = c + fi * (d - c)
    return log_linear(low, high, fk)


def bilinear(table: np.ndarray, i: np.ndarray, k: np.ndarray, slice_index=None) -> np.ndarray:
    """Bilinear interpolation at fractional indices (i, k), edge samples clamped (an image texture's filter), of
    a table (rows, columns[, channels]) or, with per-point ``slice_index``, of its slices
    (rows, slices, columns, channels)."""
    columns = table.shape[1] if slice_index is None else table.shape[2]
    i0, k0, fi, fk = table_cell(table.shape[0], columns, i, k)
    fi, fk = fi.astype(table.dtype), fk.astype(table.dtype)
    if table.ndim == 3 or slice_index is not None:
        fi, fk = fi[..., None], fk[..., None]

    if slice_index is None:     # one flat gather per corner (the same values as table[r, c], faster)
        flat = table.reshape((-1,) + table.shape[2:])

        def at(r, c):
            return np.take(flat, r * columns + c, axis=0)
    else:
        def at(r, c):
            return table[r, slice_index, c]

    return ((1 - fi) * ((1 - fk) * at(i0, k0) + fk * at(i0, k0 + 1))
            + fi * ((1 - fk) * at(i0 + 1, k0) + fk * at(i0 + 1, k0 + 1)))
