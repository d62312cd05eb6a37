# SPDX-License-Identifier: GPL-3.0-or-later
"""Read the float passes of an OpenEXR file written by Blender, in numpy: single-part or multi-part (multilayer).

Enough of the format (openexr.com, "OpenEXR File Layout") for the files ``render --output x.exr`` writes:
scanline parts, NONE / ZIPS / ZIP compression, HALF and FLOAT channels. Blender's image loader gives no pixels
for a multilayer file, so the CLI tests read the composite and the atmosphere AOVs with this.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np

_LINES_PER_CHUNK = {0: 1, 2: 1, 3: 16}   # NONE, ZIPS, ZIP
_DTYPES = {1: np.dtype("<f2"), 2: np.dtype("<f4"), 0: np.dtype("<u4")}   # HALF, FLOAT, UINT


def _header(data: bytes, pos: int) -> tuple[dict, int]:
    attributes = {}
    while data[pos] != 0:
        end = data.index(b"\0", pos)
        name = data[pos:end].decode()
        type_end = data.index(b"\0", end + 1)
        kind = data[end + 1:type_end].decode()
        size = struct.unpack_from("<i", data, type_end + 1)[0]
        value = data[type_end + 5:type_end + 5 + size]
        pos = type_end + 5 + size
        if kind == "chlist":
            channels, p = [], 0
            while value[p] != 0:
                e = value.index(b"\0", p)
                channels.append((value[p:e].decode(), struct.unpack_from("<i", value, e + 1)[0]))
                p = e + 17
            value = channels
        elif kind == "box2i":
            value = struct.unpack("<4i", value)
        elif kind == "compression":
            value = value[0]
        elif kind in ("int", "string"):
            value = struct.unpack("<i", value)[0] if kind == "int" else value.decode(errors="replace")
        attributes[name] = value
    return attributes, pos + 1


def _unpredict(raw: bytes) -> bytes:
    """Undo OpenEXR's ZIP preprocessing: the byte-delta predictor, then the split of even and odd bytes."""
    deltas = np.frombuffer(raw, np.uint8).astype(np.int64)
    t = ((np.cumsum(deltas - 128) + 128) % 256).astype(np.uint8)   # t[i] = t[i-1] + raw[i] - 128, t[0] = raw[0]
    half = (len(t) + 1) // 2
    out = np.empty_like(t)
    out[0::2], out[1::2] = t[:half], t[half:]
    return out.tobytes()


def read_exr(path: str | Path) -> dict[str, np.ndarray]:
    """Every channel of every part, by full name ("Composite.Combined.R", "ViewLayer.atmos_coverage.V"...): float32
    arrays (height, width), row 0 at the top of the image."""
    data = Path(path).read_bytes()
    if data[:4] != b"\x76\x2f\x31\x01":
        raise ValueError(f"{path}: not an OpenEXR file")
    flags = struct.unpack_from("<I", data, 4)[0]
    multipart = bool(flags & 0x1000)
    pos, headers = 8, []
    while True:
        header, pos = _header(data, pos)
        headers.append(header)
        if not multipart or data[pos] == 0:
            pos += 1 if multipart else 0
            break
    tables = []
    for header in headers:
        x0, y0, x1, y1 = header["dataWindow"]
        lines = _LINES_PER_CHUNK[header["compression"]]
        count = header.get("chunkCount", -(-(y1 - y0 + 1) // lines))
        tables.append(struct.unpack_from(f"<{count}Q", data, pos))
        pos += 8 * count
    result: dict[str, np.ndarray] = {}
    for part, (header, offsets) in enumerate(zip(headers, tables)):
        x0, y0, x1, y1 = header["dataWindow"]
        width, height = x1 - x0 + 1, y1 - y0 + 1
        channels = sorted(header["channels"])
        planes = {name: np.zeros((height, width), np.float32) for name, _ in channels}
        for offset in offsets:
            at = offset + (4 if multipart else 0)
            y, size = struct.unpack_from("<ii", data, at)
            block = data[at + 8:at + 8 + size]
            rows = min(_LINES_PER_CHUNK[header["compression"]], y1 - y + 1)
            expected = rows * width * sum(_DTYPES[kind].itemsize for _, kind in channels)
            if header["compression"] != 0 and size < expected:
                block = _unpredict(zlib.decompress(block))
            cursor = 0
            for row in range(rows):
                for name, kind in channels:
                    dtype = _DTYPES[kind]
                    values = np.frombuffer(block, dtype=dtype, count=width, offset=cursor)
                    planes[name][y - y0 + row] = values.astype(np.float32)
                    cursor += width * dtype.itemsize
        prefix = f"{header['name']}." if multipart and "name" in header else ""
        for name, plane in planes.items():
            key = name if name.startswith(prefix) else prefix + name
            result[key] = plane
    return result


def composite_rgb(path: str | Path) -> np.ndarray:
    """The final image (R, G, B) of a file ``render`` wrote, (height, width, 3), row 0 at the top: the composite,
    or the first view layer's Combined pass where nothing was composited (In-Render mode)."""
    channels = read_exr(path)
    combined = sorted({name[:-1] for name in channels if name.endswith("Combined.R")})
    for stem in ("Composite.Combined.", *combined, ""):
        if all(f"{stem}{c}" in channels for c in "RGB"):
            return np.stack([channels[f"{stem}{c}"] for c in "RGB"], axis=-1)
    raise KeyError(f"{path}: no composite R, G, B among {sorted(channels)[:12]}")
