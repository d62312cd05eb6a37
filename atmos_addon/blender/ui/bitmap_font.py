# SPDX-License-Identifier: GPL-3.0-or-later
"""A 5 x 7 pixel bitmap font (A-Z, 0-9, space, '.', '-', '_', '°') for labelling images with numpy alone.

Blender's Python has no imaging library; contact-sheet labels are drawn straight into the pixel
array. Lower case is drawn as upper case; any other character as a small box, so a label never
silently loses a character. No ``bpy`` here.
"""

from __future__ import annotations

import numpy as np

GLYPH_WIDTH = 5
GLYPH_HEIGHT = 7
#: Horizontal advance per character, pixels (glyph plus one pixel of spacing) at scale 1.
ADVANCE = GLYPH_WIDTH + 1

_ROWS = {
    "A": (".###.", "#...#", "#...#", "#####", "#...#", "#...#", "#...#"),
    "B": ("####.", "#...#", "#...#", "####.", "#...#", "#...#", "####."),
    "C": (".###.", "#...#", "#....", "#....", "#....", "#...#", ".###."),
    "D": ("####.", "#...#", "#...#", "#...#", "#...#", "#...#", "####."),
    "E": ("#####", "#....", "#....", "####.", "#....", "#....", "#####"),
    "F": ("#####", "#....", "#....", "####.", "#....", "#....", "#...."),
    "G": (".###.", "#...#", "#....", "#.###", "#...#", "#...#", ".####"),
    "H": ("#...#", "#...#", "#...#", "#####", "#...#", "#...#", "#...#"),
    "I": (".###.", "..#..", "..#..", "..#..", "..#..", "..#..", ".###."),
    "J": ("..###", "...#.", "...#.", "...#.", "...#.", "#..#.", ".##.."),
    "K": ("#...#", "#..#.", "#.#..", "##...", "#.#..", "#..#.", "#...#"),
    "L": ("#....", "#....", "#....", "#....", "#....", "#....", "#####"),
    "M": ("#...#", "##.##", "#.#.#", "#.#.#", "#...#", "#...#", "#...#"),
    "N": ("#...#", "#...#", "##..#", "#.#.#", "#..##", "#...#", "#...#"),
    "O": (".###.", "#...#", "#...#", "#...#", "#...#", "#...#", ".###."),
    "P": ("####.", "#...#", "#...#", "####.", "#....", "#....", "#...."),
    "Q": (".###.", "#...#", "#...#", "#...#", "#.#.#", "#..#.", ".##.#"),
    "R": ("####.", "#...#", "#...#", "####.", "#.#..", "#..#.", "#...#"),
    "S": (".####", "#....", "#....", ".###.", "....#", "....#", "####."),
    "T": ("#####", "..#..", "..#..", "..#..", "..#..", "..#..", "..#.."),
    "U": ("#...#", "#...#", "#...#", "#...#", "#...#", "#...#", ".###."),
    "V": ("#...#", "#...#", "#...#", "#...#", "#...#", ".#.#.", "..#.."),
    "W": ("#...#", "#...#", "#...#", "#.#.#", "#.#.#", "#.#.#", ".#.#."),
    "X": ("#...#", "#...#", ".#.#.", "..#..", ".#.#.", "#...#", "#...#"),
    "Y": ("#...#", "#...#", ".#.#.", "..#..", "..#..", "..#..", "..#.."),
    "Z": ("#####", "....#", "...#.", "..#..", ".#...", "#....", "#####"),
    "0": (".###.", "#...#", "#..##", "#.#.#", "##..#", "#...#", ".###."),
    "1": ("..#..", ".##..", "..#..", "..#..", "..#..", "..#..", ".###."),
    "2": (".###.", "#...#", "....#", "...#.", "..#..", ".#...", "#####"),
    "3": ("#####", "...#.", "..#..", "...#.", "....#", "#...#", ".###."),
    "4": ("...#.", "..##.", ".#.#.", "#..#.", "#####", "...#.", "...#."),
    "5": ("#####", "#....", "####.", "....#", "....#", "#...#", ".###."),
    "6": ("..##.", ".#...", "#....", "####.", "#...#", "#...#", ".###."),
    "7": ("#####", "....#", "...#.", "..#..", ".#...", ".#...", ".#..."),
    "8": (".###.", "#...#", "#...#", ".###.", "#...#", "#...#", ".###."),
    "9": (".###.", "#...#", "#...#", ".####", "....#", "...#.", ".##.."),
    " ": (".....",) * 7,
    ".": (".....", ".....", ".....", ".....", ".....", ".##..", ".##.."),
    "-": (".....", ".....", ".....", "#####", ".....", ".....", "....."),
    "_": (".....", ".....", ".....", ".....", ".....", ".....", "#####"),
    "\u00b0": (".##..", "#..#.", "#..#.", ".##..", ".....", ".....", "....."),
}
_UNKNOWN = ("#####", "#...#", "#...#", "#...#", "#...#", "#...#", "#####")

#: Glyph masks, shape (7, 5), True where ink is, row 0 at the top.
GLYPHS: dict[str, np.ndarray] = {
    char: np.array([[cell == "#" for cell in row] for row in rows], dtype=bool) for char, rows in _ROWS.items()
}
_UNKNOWN_MASK = np.array([[cell == "#" for cell in row] for row in _UNKNOWN], dtype=bool)


def glyph(char: str) -> np.ndarray:
    """The (7, 5) mask of one character (lower case drawn as upper case; unknown ones as a box)."""
    return GLYPHS.get(char.upper(), _UNKNOWN_MASK)


def text_mask(text: str, scale: int = 1) -> np.ndarray:
    """The ink of ``text`` as a boolean array of shape (7 * scale, len(text) * 6 * scale), row 0 at the top."""
    if not text:
        return np.zeros((GLYPH_HEIGHT * scale, 0), dtype=bool)
    mask = np.zeros((GLYPH_HEIGHT, ADVANCE * len(text)), dtype=bool)
    for index, char in enumerate(text):
        mask[:, index * ADVANCE:index * ADVANCE + GLYPH_WIDTH] = glyph(char)
    mask = mask[:, :-1]  # no spacing after the last character
    return np.repeat(np.repeat(mask, scale, axis=0), scale, axis=1)


def draw_text(image: np.ndarray, text: str, x: int, y: int, colour, scale: int = 1) -> None:
    """Draw ``text`` into ``image`` (H, W, C floats, row 0 at the top) with its top-left corner at (x, y).

    Ink outside the image is clipped; ``colour`` has C values.
    """
    mask = text_mask(text, scale)
    height, width = image.shape[:2]
    x0, y0 = max(x, 0), max(y, 0)
    x1, y1 = min(x + mask.shape[1], width), min(y + mask.shape[0], height)
    if x1 <= x0 or y1 <= y0:
        return
    region = mask[y0 - y:y1 - y, x0 - x:x1 - x]
    image[y0:y1, x0:x1][region] = np.asarray(colour, dtype=image.dtype)
