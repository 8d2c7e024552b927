"""Shared analytic data for the HDR tests: a log-uniform scene, its error, the true response."""

import numpy as np

from pbrbench.infer.hdr import CameraResponse

TIMES = 2.0 ** np.arange(-6, 1)  # 7 exposures one stop apart


def scene(n=48, channels=3, lo=-1.5, hi=0.5, seed=0):
    """log-uniform radiance in [10**lo, 10**hi] (shuffled), per-channel tint."""
    rng = np.random.default_rng(seed)
    v = 10 ** rng.permutation(np.linspace(lo, hi, n * n)).reshape(n, n)
    tint = np.linspace(1.0, 0.6, channels)
    return v[..., None] * tint


def log2_rmse(est, truth):
    d = np.log2(est) - np.log2(truth)
    return float(np.sqrt(np.mean((d - d.mean()) ** 2)))


def true_response(br):
    return CameraResponse(np.maximum(br.true_inverse, 1e-12), br.levels, "true")


def linear_bracket():
    """Radiance j/255 (j = 1..255) seen by a linear 8-bit camera with times 1, 2, 4."""
    from pbrbench.camera import Camera

    j = np.arange(1, 256, dtype=float)
    L = np.tile(j / 255.0, (4, 1))
    return L, Camera("linear", bit_depth=8).capture(L, [1.0, 2.0, 4.0])


def check_linear_response(cal):
    """Known answer: a linear camera gives a linear inverse response and an exact merge."""
    from pbrbench.infer.hdr import merge_hdr

    L, br = linear_bracket()
    resp = cal(br.images, br.exposure_times)
    z = np.arange(8, 255)
    err = np.log2(resp.inverse[z, 0]) - np.log2(z / 255.0)
    assert np.max(np.abs(err)) < 0.02, cal.__name__
    rad = merge_hdr(br.images, br.exposure_times, resp)
    assert log2_rmse(rad[..., 0], L) < 0.02, cal.__name__
