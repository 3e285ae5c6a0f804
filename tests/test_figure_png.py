"""primitives.io.figure_png: the PNG plan-trial's figures are written as holds the pixels
matplotlib's own PNG holds (RGB when the figure is opaque, matplotlib's RGBA when not)."""

from __future__ import annotations

import io

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from PIL import Image  # noqa: E402

from primitives.io import figure_png  # noqa: E402


def _figure(transparent: bool = False):
    fig, ax = plt.subplots(figsize=(3.3, 2.1))  # a size whose pixels at 110 dpi are not whole numbers
    ax.plot([0, 1, 2], [0.3, 1.7, 0.9], lw=1.5, label="line")
    ax.fill_between([0, 1, 2], 0, [0.2, 0.5, 0.1], alpha=0.4)
    ax.set_title("title ä°", fontsize=9)
    ax.legend(fontsize=7)
    if transparent:
        fig.patch.set_alpha(0.0)
    return fig


def _pixels(data: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(data)).convert("RGBA"))


def _matplotlib_png(fig, dpi: float) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def test_opaque_figure_is_rgb_with_matplotlibs_pixels_and_metadata():
    fig = _figure()
    try:
        ours, theirs = figure_png(fig, 110), _matplotlib_png(fig, 110)
    finally:
        plt.close(fig)
    im, ref = Image.open(io.BytesIO(ours)), Image.open(io.BytesIO(theirs))
    assert im.mode == "RGB" and ref.mode == "RGBA"
    assert im.size == ref.size
    np.testing.assert_array_equal(_pixels(ours), _pixels(theirs))
    assert im.info["Software"] == ref.info["Software"]
    assert np.allclose(im.info["dpi"], ref.info["dpi"])
    assert figure_png(fig, 110) == ours  # the same figure gives the same bytes


def test_transparent_figure_keeps_its_alpha():
    fig = _figure(transparent=True)
    try:
        ours, theirs = figure_png(fig, 80), _matplotlib_png(fig, 80)
    finally:
        plt.close(fig)
    assert Image.open(io.BytesIO(ours)).mode == "RGBA"
    np.testing.assert_array_equal(_pixels(ours), _pixels(theirs))
