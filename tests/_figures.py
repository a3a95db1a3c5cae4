"""Checks of saved figures that look at what is drawn, not only at the file size.

``capture_figures()`` records every matplotlib figure saved inside it (the figure object: axes,
artists, legend); ``assert_png_drawn`` decodes a PNG and asserts it is an image with content (not
blank, more than a couple of colours, optionally of a given size).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
from matplotlib.figure import Figure


@contextmanager
def capture_figures() -> Iterator[list]:
    """Within the block, every ``Figure.savefig`` call also appends its figure to the yielded
    list."""
    saved: list = []
    original = Figure.savefig

    def savefig(self, *args, **kwargs):
        saved.append(self)
        return original(self, *args, **kwargs)

    Figure.savefig = savefig  # type: ignore[method-assign]
    try:
        yield saved
    finally:
        Figure.savefig = original  # type: ignore[method-assign]


def assert_png_drawn(
    path: str | Path,
    size: tuple[int, int] | None = None,
    min_colours: int = 16,
    min_ink: float = 0.02,
) -> np.ndarray:
    """Decode ``path``; assert its (width, height), at least ``min_colours`` distinct colours and at
    least ``min_ink`` of the pixels differing from the most common (background) colour. Returns the
    RGB array."""
    img = mpimg.imread(str(path))
    assert img.ndim == 3 and img.shape[2] in (3, 4), img.shape
    if size is not None:
        assert (img.shape[1], img.shape[0]) == tuple(size)
    rgb = np.round(img[..., :3] * 255).astype(np.uint8).reshape(-1, 3)
    colours, counts = np.unique(rgb, axis=0, return_counts=True)
    assert len(colours) >= min_colours, f"{path}: only {len(colours)} colours"
    ink = 1.0 - counts.max() / rgb.shape[0]
    assert ink >= min_ink, f"{path}: {ink:.1%} of the pixels differ from the background"
    return rgb


def legend_labels(ax) -> list[str]:
    """The legend's texts of ``ax`` (empty without a legend)."""
    leg = ax.get_legend()
    return [] if leg is None else [t.get_text() for t in leg.get_texts()]
