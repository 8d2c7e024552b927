"""HDR benchmark: calibration + merge error and time, ours against OpenCV and colour-hdri.

Standard synthetic case: 512 x 512 x 3 radiance spanning 1e-2 .. 1e2 (dynamic range
1e4: smooth log-gradients, coloured, with bright highlight disks and dark vignetted corners),
seen by an 8-bit camera with a different random monotone response per channel, 7 exposures one
stop apart.  Conditions:

- ``no_noise``: quantisation only;
- ``read_noise``: Gaussian read noise, sigma = 0.002 of full scale (sensor domain);
- ``3x3stops``: 3 exposures 3 stops apart, no noise;
- ``clipped``: highlight disks at 1e4, clipped even in the shortest exposure (the error is
  measured on the pixels not saturated in every exposure; ``invalid`` is over all pixels).

Errors: log2 radiance RMSE (stops) after the best global scale; response error in stops (per-
channel scale removed); ``invalid`` = fraction of NaN/inf/<= 0 outputs.  Times: wall-clock
seconds, best of ``repeats``.  Peers are optional: skipped when not installed.

Run: ``python -m pbrbench.perf.hdr`` (``--quick`` for 128 x 128).
"""

from __future__ import annotations

import sys
import time

import numpy as np

from pbrbench.camera import Camera, bracket_exposure_times
from pbrbench.infer import hdr
from pbrbench.metrics.hdr import hdr_scores, response_rmse

BENCH = "hdr"


def synthetic_radiance(size: int = 512, *, highlight: float = 80.0, seed: int = 0) -> np.ndarray:
    """Seeded (size, size, 3) HDR radiance: 1e-2 .. 1e2 plus highlight disks of ``highlight``."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:size, 0:size] / (size - 1.0)
    ph = rng.uniform(0, 2 * np.pi, 4)
    # log10 luminance: a diagonal ramp with smooth waves, in [-1.2, 1.9] before the corners
    s = 0.5 * (x + y) + 0.08 * np.sin(2 * np.pi * (1.3 * x + ph[0])) * np.cos(2 * np.pi * (0.9 * y + ph[1]))
    s = (s - s.min()) / (s.max() - s.min())
    logl = -1.2 + 3.1 * s
    # dark vignetted corners reaching 1e-2
    r = np.sqrt((x - 0.5) ** 2 + (y - 0.5) ** 2) / np.sqrt(0.5)
    logl -= np.clip((r - 0.8) / 0.2, 0, 1) ** 2 * (logl + 2.0)
    lum = 10.0**logl
    # smooth chroma, in [0.55, 1] per channel
    chroma = np.stack([0.775 + 0.225 * np.sin(2 * np.pi * (x * (0.7 + 0.2 * c) + y * 0.4 * c) + ph[c % 4] + c)
                       for c in range(3)], axis=2)
    L = lum[..., None] * chroma
    for _ in range(5):
        cx, cy = rng.uniform(0.15, 0.85, 2)
        rad = rng.uniform(0.02, 0.05)
        d = np.sqrt((x - cx) ** 2 + (y - cy) ** 2)
        disk = np.clip((rad - d) / (0.25 * rad), 0, 1)
        L = L * (1 - disk[..., None]) + highlight * disk[..., None] * rng.uniform(0.8, 1.0, 3)
    return np.clip(L, 1e-2, None).astype(np.float32)


def _conditions(size: int):
    base = synthetic_radiance(size)
    t7 = bracket_exposure_times(base, stops=1.0, count=7, headroom=0.9)
    t3 = bracket_exposure_times(base, stops=3.0, count=3, headroom=0.9)
    cam = dict(response="random", bit_depth=8, seed=3)
    return [
        ("no_noise", base, Camera(**cam), t7),
        ("read_noise", base, Camera(**cam, read_noise=0.002), t7),
        ("3x3stops", base, Camera(**cam), t3),
        ("clipped", synthetic_radiance(size, highlight=1e4), Camera(**cam), t7),
    ]


def _timed(fn, repeats):
    best, out = np.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return out, best


def _ours(method):
    cal = hdr.CALIBRATION_METHODS[method]

    def run(images, times, repeats):
        resp, t_cal = _timed(lambda: cal(images, times), repeats)
        tm = resp.exposure_times if resp.exposure_times is not None else times
        rad, t_merge = _timed(lambda: hdr.merge_hdr(images, tm, resp), repeats)
        return rad, resp.inverse, t_cal, t_merge

    return run


def _opencv(kind):
    def run(images, times, repeats):
        import cv2

        imgs = [np.ascontiguousarray(im) for im in images]
        tt = np.asarray(times, np.float32)
        cal = cv2.createCalibrateDebevec() if kind == "debevec" else cv2.createCalibrateRobertson()
        mrg = cv2.createMergeDebevec() if kind == "debevec" else cv2.createMergeRobertson()
        resp, t_cal = _timed(lambda: cal.process(imgs, tt), repeats)
        rad, t_merge = _timed(lambda: mrg.process(imgs, tt, resp), repeats)
        return rad, resp.reshape(-1, resp.shape[-1]).astype(np.float64), t_cal, t_merge

    return run


def _colour_hdri(images, times, repeats):
    import colour_hdri as ch

    def stack():
        st = ch.ImageStack()
        for im, tk in zip(images, times, strict=True):
            st.append(ch.Image(data=im.astype(np.float64) / 255.0,
                               metadata=ch.Metadata(f_number=1.0, exposure_time=float(tk), iso=100.0)))
        return st

    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        crf, t_cal = _timed(lambda: ch.camera_response_functions_Debevec1997(stack()), repeats)
        rad, t_merge = _timed(lambda: ch.image_stack_to_HDRI(stack(), camera_response_functions=crf), repeats)
    return rad, crf, t_cal, t_merge


def _methods():
    out = [(f"ours-{m}", _ours(m)) for m in hdr.CALIBRATION_METHODS]
    try:
        import cv2  # noqa: F401
        out += [("opencv-debevec", _opencv("debevec")), ("opencv-robertson", _opencv("robertson"))]
    except ImportError:
        pass
    try:
        import colour_hdri  # noqa: F401
        out += [("colour_hdri-debevec", _colour_hdri)]
    except ImportError:
        pass
    return out


def run(quick: bool = False) -> list[dict]:
    size = 128 if quick else 512
    repeats = 1 if quick else 3
    rows = []
    for case, L, cam, times in _conditions(size):
        br = cam.capture(L, times, seed=11)
        ok = ~br.saturated
        for name, fn in _methods():
            if quick and (name.startswith("colour_hdri") or (name.startswith("opencv") and "robertson" in name)):
                continue  # quick mode: colour-hdri's calibration alone takes minutes
            try:
                rad, inv, t_cal, t_merge = fn(br.images, br.exposure_times, repeats)
            except Exception as exc:  # a peer failing is reported, not fatal
                print(f"[hdr perf] {name} on {case} failed: {exc}", file=sys.stderr)
                continue
            rad = np.asarray(rad, dtype=np.float64)
            sc = hdr_scores(rad, L, mask=ok)
            with np.errstate(all="ignore"):
                r_err = response_rmse(np.maximum(inv, 1e-12), br.true_inverse)
            for metric, value, unit in (
                ("log2_rmse", sc["log2_rmse"], "stops"),
                ("dark1", sc["dark1"], "stops"),
                ("bright1", sc["bright1"], "stops"),
                ("invalid", sc["invalid_fraction"], "fraction"),
                ("response_rmse", r_err, "stops"),
                ("calibrate_time", t_cal, "s"),
                ("merge_time", t_merge, "s"),
            ):
                rows.append({"benchmark": BENCH, "case": case, "method": name, "metric": metric,
                             "value": float(value), "unit": unit})
    return rows


def main(argv=None) -> None:
    argv = sys.argv[1:] if argv is None else argv
    rows = run(quick="--quick" in argv)
    metrics = ["log2_rmse", "dark1", "bright1", "invalid", "response_rmse", "calibrate_time", "merge_time"]
    table: dict[tuple[str, str], dict[str, float]] = {}
    for r in rows:
        table.setdefault((r["case"], r["method"]), {})[r["metric"]] = r["value"]
    head = f"{'case':<11}{'method':<22}" + "".join(f"{m:>15}" for m in metrics)
    print(head)
    print("-" * len(head))
    for (case, method), vals in table.items():
        print(f"{case:<11}{method:<22}" + "".join(f"{vals.get(m, np.nan):>15.4g}" for m in metrics))


if __name__ == "__main__":
    main()
