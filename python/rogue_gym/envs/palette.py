"""Screens as pictures: one pixel per cell, coloured by glyph."""

from __future__ import annotations

import numpy as np

__all__ = ["screen_to_rgb"]

#: The colour of each glyph that has its own; letters (monsters) are red, other printable
#: characters light blue, blanks black.
_COLOURS = {
    "@": (255, 255, 0),
    "#": (120, 120, 120),
    ".": (60, 60, 60),
    "-": (200, 200, 200),
    "|": (200, 200, 200),
    "%": (0, 255, 0),
    "+": (180, 120, 40),
    "*": (255, 200, 0),
    ":": (200, 80, 80),
}


def _palette() -> np.ndarray:
    palette = np.zeros((256, 3), np.uint8)
    for ch, rgb in _COLOURS.items():
        palette[ord(ch)] = rgb
    for c in range(ord("A"), ord("Z") + 1):
        palette[c] = (255, 0, 0)
    for c in range(ord("!"), ord("~") + 1):
        if not palette[c].any():
            palette[c] = (150, 150, 255)
    return palette


_PALETTE = _palette()


def screen_to_rgb(screen: str) -> np.ndarray:
    """A ``(rows, cols, 3)`` uint8 image of a text screen, one pixel per cell, colour by glyph."""
    rows = screen.split("\n")
    width = max(len(r) for r in rows)
    codes = np.zeros((len(rows), width), np.uint8)
    for y, row in enumerate(rows):
        codes[y, : len(row)] = np.frombuffer(row.encode("ascii", "replace"), np.uint8)
    return _PALETTE[codes]
