"""Report figures (pbrbench.report.figures): a long plot title is wrapped, not cut at the edges."""

import io

import numpy as np
from PIL import Image

from pbrbench.report.figures import PLOT_SIZE, plot_png, wrap_title

LONG = ("Fig 1.11 lightness in 1-D (Horn 1974) along a row of the grey Mondrian: the log image, its "
        "derivative, the derivative thresholded (paint edges kept, shading gradients dropped)")


def test_a_long_title_is_wrapped_into_lines_that_fit_the_figure():
    wrapped = wrap_title(LONG, PLOT_SIZE[0])
    lines = wrapped.split("\n")
    assert len(lines) >= 2
    assert max(len(x) for x in lines) <= int(PLOT_SIZE[0] * 72 / (0.55 * 11))
    assert " ".join(lines) == LONG                      # nothing lost
    assert wrap_title("short", PLOT_SIZE[0]) == "short"


def test_the_wrapped_title_leaves_the_figure_edges_clear():
    # the title's ink stays inside the image: its first and last columns are white in the rows
    # above the axes (a cut title touches both edges)
    png = plot_png("p", {"x": [0, 1, 2], "series": {"a": [0.0, 1.0, 4.0]}, "title": LONG})
    a = np.asarray(Image.open(io.BytesIO(png)).convert("L"))
    top = a[: a.shape[0] // 8]
    assert (top < 128).any()                            # the title is drawn
    assert top[:, :3].min() > 200 and top[:, -3:].min() > 200
