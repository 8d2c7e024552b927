"""Analytic Mondrians: piecewise-constant albedo under smooth (or shadowed) illumination.

The test scene of the lightness chapter (docs/science.md §5; Land & McCann, "Lightness and retinex
theory", JOSA 1971): a collage of flat matte papers seen frontally, so the linear image is
``C(x) = I(x) rho(x)`` (the camera gain absorbed into ``I``).  Everything here is NumPy and
seeded; no renderer is involved, so the exact albedo and shading are known.

Objects
-------
- :func:`mondrian_albedo` -- guillotine partition into rectangles, grey or colour papers, with a
  minimum log-contrast between neighbouring papers; returns ``(albedo, labels)``.
- :func:`point_source_shading` -- irradiance of a frontal plane lit by a nearby point source.
- :func:`smooth_shading` -- a random low-frequency positive field.
- :func:`cast_shadow` -- a multiplicative field with a sharp (or blurred) disc-shaped shadow.
- :func:`mondrian_scene` -- all of the above composed into ``image = albedo * shading``.
- :func:`colour_mondrian_scene` -- a colour Mondrian with iso-luminant paint edges under a
  coloured, spatially varying light (the case that separates colour from grey retinex).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from pbrbench.shading.surfaces import pixel_grid

__all__ = ["mondrian_albedo", "point_source_shading", "smooth_shading", "cast_shadow",
           "mondrian_scene", "colour_mondrian_scene"]


def _guillotine(shape, n_patches, min_size, rng):
    """Split the rectangle recursively (largest piece first) into ``n_patches`` rectangles."""
    h, w = shape
    rects = [(0, h, 0, w)]
    while len(rects) < n_patches:
        # split the largest rectangle that can still be split
        rects.sort(key=lambda r: (r[1] - r[0]) * (r[3] - r[2]), reverse=True)
        for k, (r0, r1, c0, c1) in enumerate(rects):
            hh, ww = r1 - r0, c1 - c0
            can_h, can_w = hh >= 2 * min_size, ww >= 2 * min_size
            if not (can_h or can_w):
                continue
            horiz = can_h and (not can_w or rng.random() < hh / (hh + ww))
            if horiz:
                cut = int(rng.integers(r0 + min_size, r1 - min_size + 1))
                new = [(r0, cut, c0, c1), (cut, r1, c0, c1)]
            else:
                cut = int(rng.integers(c0 + min_size, c1 - min_size + 1))
                new = [(r0, r1, c0, cut), (r0, r1, cut, c1)]
            rects[k:k + 1] = new
            break
        else:
            break  # nothing can be split any more
    labels = np.empty(shape, dtype=np.int64)
    for k, (r0, r1, c0, c1) in enumerate(rects):
        labels[r0:r1, c0:c1] = k
    return labels


def _adjacency(labels):
    n = int(labels.max()) + 1
    adj = [set() for _ in range(n)]
    for a, b in ((labels[:, :-1], labels[:, 1:]), (labels[:-1, :], labels[1:, :])):
        d = a != b
        for u, v in set(zip(a[d].tolist(), b[d].tolist(), strict=True)):
            adj[u].add(v)
            adj[v].add(u)
    return adj


def mondrian_albedo(size, *, n_patches: int = 24, seed: int = 0, colour: bool = False,
                    albedo_range=(0.1, 0.9), min_log_contrast: float = 0.15,
                    white_patch: float | None = None, min_size: int | None = None):
    """A seeded Mondrian: rectangles of constant albedo with a minimum contrast between neighbours.

    Parameters
    ----------
    size : int or (H, W)
        Image size in pixels.
    n_patches : int
        Number of rectangles of the guillotine partition (fewer if ``min_size`` forbids more).
    seed : int
        Seed of the NumPy generator (the only source of randomness).
    colour : bool
        If True, the albedo is (H, W, 3) with independent channels in ``albedo_range``.
    albedo_range : (low, high)
        Albedos are drawn log-uniformly in this range.
    min_log_contrast : float
        Every pair of neighbouring papers differs by at least this much in ``log`` albedo
        (in at least one channel for colour: the RMS over channels is used), so that a
        retinex threshold below it keeps every paper edge.
    white_patch : float, optional
        If given, the albedo of the largest paper is set to this value (all channels), e.g.
        ``1.0`` for the "brightest paper is white" anchor; it must be the brightest value.
    min_size : int, optional
        Minimum side of a rectangle in pixels (default ``max(4, min(H, W) // 16)``).

    Returns
    -------
    albedo : (H, W) or (H, W, 3) float64
    labels : (H, W) int64 paper index, 0 .. n-1
    """
    h, w = (size, size) if np.isscalar(size) else tuple(int(s) for s in size)
    if h < 2 or w < 2:
        raise ValueError(f"size: need at least 2x2 pixels, got {(h, w)}")
    lo, hi = (float(v) for v in albedo_range)
    if not (0 < lo < hi):
        raise ValueError(f"albedo_range: need 0 < low < high, got {albedo_range!r}")
    if white_patch is not None and white_patch < hi:
        raise ValueError(f"white_patch: {white_patch} must be >= the top of albedo_range ({hi}) "
                         "so that the white paper is the brightest")
    rng = np.random.default_rng(seed)
    min_size = max(4, min(h, w) // 16) if min_size is None else int(min_size)
    labels = _guillotine((h, w), int(n_patches), min_size, rng)
    n = int(labels.max()) + 1
    adj = _adjacency(labels)
    nc = 3 if colour else 1
    values = np.zeros((n, nc))
    fixed = -1
    if white_patch is not None:
        fixed = int(np.argmax(np.bincount(labels.ravel(), minlength=n)))
        values[fixed] = white_patch
    llo, lhi = np.log(lo), np.log(hi)
    for k in range(n):
        if k == fixed:
            continue
        best, best_sep = None, -np.inf
        for _ in range(200):
            cand = rng.uniform(llo, lhi, nc)
            done = [j for j in adj[k] if j < k or j == fixed]
            sep = min((np.sqrt(np.mean((cand - np.log(values[j])) ** 2)) for j in done),
                      default=np.inf)
            if sep >= min_log_contrast:
                best = cand
                break
            if sep > best_sep:
                best, best_sep = cand, sep
        values[k] = np.exp(best)
    albedo = values[labels]
    return (albedo if colour else albedo[..., 0]), labels


def point_source_shading(size, *, position=(0.6, 0.4, 1.2), intensity: float = 1.0,
                         half_width: float = 1.0, colour=None):
    """Irradiance on the frontal plane ``z = 0`` from an isotropic point source.

    ``E(x, y) = I h / r^3`` with ``r^2 = (x - sx)^2 + (y - sy)^2 + h^2`` (cosine law times
    inverse square; docs/conventions.md), for a source at ``(sx, sy, h)`` in the world frame of
    :func:`pbrbench.shading.surfaces.pixel_grid` (x right, y up, film ``[-half_width,
    half_width]``).  ``colour`` (length-3) multiplies the field per channel.
    """
    h, w = (size, size) if np.isscalar(size) else tuple(int(s) for s in size)
    x, y = pixel_grid(h, w, half_width)
    sx, sy, sh = (float(v) for v in position)
    if sh <= 0:
        raise ValueError(f"position: the source height must be > 0, got {sh}")
    r2 = (x - sx) ** 2 + (y - sy) ** 2 + sh * sh
    e = intensity * sh / r2 ** 1.5
    if colour is not None:
        e = e[..., None] * np.asarray(colour, float)[None, None, :]
    return e


def smooth_shading(size, *, seed: int = 0, n_waves: int = 6, max_frequency: float = 1.5,
                   log_amplitude: float = 0.5):
    """A positive random low-frequency field ``exp(sum_k a_k cos(2 pi f_k . x + phi_k))``.

    Frequencies are at most ``max_frequency`` cycles over the image, so the per-pixel log
    gradient is at most about ``2 pi max_frequency log_amplitude / min(H, W)``.
    """
    h, w = (size, size) if np.isscalar(size) else tuple(int(s) for s in size)
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w]
    u, v = xx / max(h, w), yy / max(h, w)
    log_e = np.zeros((h, w))
    amps = rng.normal(size=n_waves)
    amps *= log_amplitude / np.sum(np.abs(amps))
    for a in amps:
        f = rng.uniform(-max_frequency, max_frequency, 2)
        phi = rng.uniform(0, 2 * np.pi)
        log_e += a * np.cos(2 * np.pi * (f[0] * u + f[1] * v) + phi)
    return np.exp(log_e)


def cast_shadow(size, *, center=(0.35, 0.4), radius: float = 0.22, level: float = 0.3,
                penumbra: float = 0.0):
    """A multiplicative shadow field: 1 in the light, ``level`` inside a disc (the umbra).

    ``center`` and ``radius`` are fractions of the image width/height (column, row).
    ``penumbra`` is the standard deviation in pixels of a Gaussian blur of the edge
    (0: a sharp edge, the case that breaks retinex; docs/science.md §5).
    """
    h, w = (size, size) if np.isscalar(size) else tuple(int(s) for s in size)
    if not (0 < level <= 1):
        raise ValueError(f"level: must be in (0, 1], got {level}")
    yy, xx = np.mgrid[0:h, 0:w]
    inside = (xx + 0.5 - center[0] * w) ** 2 + (yy + 0.5 - center[1] * h) ** 2 <= (radius * min(h, w)) ** 2
    f = np.where(inside, level, 1.0)
    if penumbra > 0:
        f = ndimage.gaussian_filter(f, penumbra, mode="nearest")
    return f


def mondrian_scene(size: int = 256, *, seed: int = 0, colour: bool = False,
                   illumination: str = "point", shadow: bool = False, white_patch=None,
                   n_patches: int = 24, illuminant_colour=(1.0, 0.9, 0.75), **albedo_kw):
    """Compose a Mondrian image ``image = albedo * shading`` with known ground truth.

    Parameters
    ----------
    illumination : {"point", "smooth", "uniform"}
        Nearby point source (:func:`point_source_shading`), random smooth field
        (:func:`smooth_shading`) or constant 1.
    shadow : bool
        Multiply the shading by a sharp :func:`cast_shadow`.
    illuminant_colour : length-3
        Colour of the light for a colour Mondrian.

    Returns
    -------
    dict with ``image``, ``albedo``, ``shading`` (same shape as image) and ``labels`` (H, W).
    """
    if illumination not in ("point", "smooth", "uniform"):
        raise ValueError(f"illumination={illumination!r} is not known; choose one of "
                         "'point', 'smooth', 'uniform'")
    albedo, labels = mondrian_albedo(size, n_patches=n_patches, seed=seed, colour=colour,
                                     white_patch=white_patch, **albedo_kw)
    if illumination == "point":
        shading = point_source_shading(size)
    elif illumination == "smooth":
        shading = smooth_shading(size, seed=seed + 1)
    else:
        shading = np.ones(labels.shape)
    if shadow:
        shading = shading * cast_shadow(size)
    if colour:
        shading = shading[..., None] * np.asarray(illuminant_colour, float)[None, None, :]
    return {"image": albedo * shading, "albedo": albedo, "shading": shading, "labels": labels}


def colour_mondrian_scene(size: int = 256, *, seed: int = 0, n_patches: int = 24,
                          iso_luminant: float = 0.5, chroma_contrast: float = 0.1,
                          albedo_range=(0.1, 0.9), light_colour_amplitude: float = 0.25,
                          shading_amplitude: float = 0.8, shading_frequency: float = 2.0):
    """A colour Mondrian under a coloured, spatially varying light, with iso-luminant edges.

    Papers are the guillotine partition of :func:`mondrian_albedo`.  A fraction
    ``iso_luminant`` of them copies the log-luminance (mean of the log channels) of an already
    painted neighbour and differs from it only in chromaticity (a zero-mean log-RGB offset of
    RMS ``chroma_contrast``): edges that a luminance threshold cannot see.  The others are
    drawn log-uniformly in ``albedo_range`` per channel.  The light is a smooth random field
    (:func:`smooth_shading`, log amplitude ``shading_amplitude``, up to ``shading_frequency``
    cycles per image: its luminance gradients compete with the weaker paper edges) times a slowly varying colour
    (a smooth field per channel, log amplitude ``light_colour_amplitude``, normalised to a
    geometric mean of 1): its chromaticity changes across the image, but slowly.

    Returns
    -------
    dict with ``image``, ``albedo``, ``shading`` ((H, W, 3), ``image = albedo * shading``),
    ``labels`` (H, W) and ``iso_luminant`` (bool per paper: copied a neighbour's luminance).
    """
    if not 0 <= iso_luminant <= 1:
        raise ValueError(f"iso_luminant: must be a fraction in [0, 1], got {iso_luminant!r}")
    h, w = (size, size) if np.isscalar(size) else tuple(int(s) for s in size)
    rng = np.random.default_rng(seed)
    labels = _guillotine((h, w), int(n_patches), max(4, min(h, w) // 16), rng)
    n = int(labels.max()) + 1
    adj = _adjacency(labels)
    llo, lhi = np.log(albedo_range[0]), np.log(albedo_range[1])
    logv = np.zeros((n, 3))
    iso = np.zeros(n, bool)
    for k in range(n):
        done = [j for j in adj[k] if j < k]
        if done and rng.random() < iso_luminant:
            j = done[int(rng.integers(len(done)))]
            v = rng.normal(size=3)
            v -= v.mean()
            v *= chroma_contrast / np.sqrt(np.mean(v * v))
            logv[k] = logv[j].mean() + v
            iso[k] = True
        else:
            logv[k] = rng.uniform(llo, lhi, 3)
    albedo = np.exp(logv)[labels]
    shading = smooth_shading((h, w), seed=seed + 1, log_amplitude=shading_amplitude,
                             max_frequency=shading_frequency)
    tint = np.stack([np.log(smooth_shading((h, w), seed=seed + 10 + c, log_amplitude=light_colour_amplitude,
                                           max_frequency=0.8)) for c in range(3)], axis=-1)
    tint -= tint.mean(axis=-1, keepdims=True)
    shading = shading[..., None] * np.exp(tint) * np.array([1.0, 0.9, 0.75])
    return {"image": albedo * shading, "albedo": albedo, "shading": shading, "labels": labels,
            "iso_luminant": iso}
