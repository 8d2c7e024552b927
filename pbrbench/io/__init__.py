"""Image I/O, one module per concern; every public name is re-exported here
(``from pbrbench.io import read_image``).

* :mod:`pbrbench.io.exr`: float32 multichannel OpenEXR (lossless, bit-exact), through OpenEXR;
* :mod:`pbrbench.io.images`: every other format, read and written without loss -- PNG, JPEG,
  BMP, TGA, PPM / PGM through Pillow, TIFF through tifffile, PFM, ``.npy`` -- and
  :func:`read_image`, any image file by its suffix;
* :mod:`pbrbench.io.previews`: tone-mapped 8-bit sRGB previews (colour-science, matplotlib);
* :mod:`pbrbench.io.files`: atomic writes and the decoded-size limit every reader checks
  (:data:`MAX_IMAGE_BYTES`) before allocating;
* :mod:`pbrbench.io.renders`: :func:`load_render`, the public loader of renders.

Importing the package imports numpy only; each library is imported inside the function that
needs it, so the command line stays fast.
"""

from __future__ import annotations

import os  # noqa: F401 - tests patch pbrbench.io.os.fsync

from pbrbench.io.exr import (
    RGB,
    SUFFIXES,
    exr_shape,
    flatten_channels,
    group_channels,
    read_exr,
    read_exr_image,
    write_exr,
    write_exr_image,
)
from pbrbench.io.files import (
    MAX_IMAGE_BYTES,
    TooLarge,
    atomic_path,
    check_size,
    copy_file,
    ensure_dir,
    quiet_output,
    write_bytes,
    write_text,
)
from pbrbench.io.images import (
    _PNG_CHANNELS,  # noqa: F401 - pbrbench.bench.external reads PNG headers with it
    PNG_SIGNATURE,
    png_info,
    read_image,
    read_png,
    read_pngs,
    write_image,
    write_mask_png,
    write_png_exact,
)
from pbrbench.io.previews import (
    srgb_encode,
    tonemap,
    write_colormap_png,
    write_normals_png,
    write_png,
    write_preview,
)
from pbrbench.io.renders import Render, load_render

__all__ = [
    "MAX_IMAGE_BYTES", "PNG_SIGNATURE", "RGB", "SUFFIXES", "Render", "TooLarge", "atomic_path", "check_size", "copy_file",
    "ensure_dir", "exr_shape", "flatten_channels", "group_channels", "load_render", "png_info", "quiet_output",
    "read_exr", "read_exr_image", "read_image", "read_png", "read_pngs", "srgb_encode", "tonemap", "write_bytes",
    "write_colormap_png", "write_exr", "write_exr_image", "write_image", "write_mask_png", "write_normals_png",
    "write_png", "write_png_exact", "write_preview", "write_text",
]
