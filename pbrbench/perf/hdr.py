"""HDR benchmark: calibration + merge error and time, pbrbench side by side with its peers.

Standard synthetic case: 512 x 512 x 3 radiance spanning 1e-2 .. 1e2 (dynamic range 1e4:
smooth log-gradients, coloured, with bright highlight disks and dark vignetted corners), seen by
an 8-bit camera with a different random monotone response per channel, 7 exposures one stop
apart.  Cases:

- ``no_noise``: quantisation only;
- ``read_noise``: Gaussian read noise, sigma = 0.002 of full scale (sensor domain);
- ``read+shot``: read noise 0.002 and shot noise (full well 1e4 electrons);
- ``film read+shot``: the same noise with the HDR task's film-like S-shaped response;
- ``dark read+shot``: the same noise on a scene whose dark corners reach 1e-3 (the darkest
  pixels have a signal-to-noise ratio below 1 in the longest exposure);
- ``gamma2.2``: a gamma-2.2 camera without noise (the case of Mitsunaga & Nayar's polynomial);
- ``3x3stops``: 3 exposures 3 stops apart, no noise;
- ``film 3x3 read+shot``: the film-like response (toe and shoulder) on 3 exposures 3 stops apart,
  read and shot noise: a short bracket whose toe and shoulder few pixels tie together;
- ``clipped``: highlight disks at 1e4, clipped even in the shortest exposure (the error is
  measured on the pixels not saturated in every exposure; ``invalid`` is over all pixels).

Methods: ``ours-<calibration>`` (each of :data:`pbrbench.infer.hdr.CALIBRATION_METHODS`,
merged by :func:`pbrbench.infer.hdr.merge_hdr` with its default method),
``ours-debevec1997+<merge>`` (the other merge methods on the same response),
``floor:true_response`` (the camera's true inverse response, default merge with the noise
model estimated: the calibration floor) and, on the noisy cases, ``oracle`` (true response,
true noise model, weights ``t^2 / var`` evaluated at the true exposure: the best linear
merge of the bracket).  Peers, when installed (``pip install pbrbench[peers]``):
OpenCV's ``CalibrateDebevec + MergeDebevec`` and ``CalibrateRobertson + MergeRobertson``
(``opencv-python-headless``), colour-hdri's Debevec (1997) calibration and
``image_stack_to_HDRI`` (``colour-hdri``); a missing peer is reported, not fatal.

Errors: log2 radiance RMSE (stops) after the best global scale, overall and on the darkest /
brightest 1 %; response error in stops (per-channel scale removed); ``invalid`` = fraction of
NaN/inf/<= 0 outputs.  Times: wall-clock seconds, best of ``repeats``; pbrbench's merge and
OpenCV's ``MergeDebevec`` are timed alternately in the same process on the same bracket, with
OpenCV single-threaded (``cv2.setNumThreads(1)``; run with ``OPENBLAS_NUM_THREADS=1`` for
single-threaded BLAS) and reported as ``merge_time_ratio_vs_opencv``; the calibrations likewise,
round-robin (:func:`calibration_times`), as ``cal_ratio_vs_opencv-deb`` (ours-debevec1997 /
``CalibrateDebevec``), ``cal_ratio_vs_opencv-rob`` (ours-robertson2003 and ours-mitsunaga1999 /
``CalibrateRobertson``) and ``cal_ratio_vs_robertson`` (ours-mitsunaga1999 /
ours-robertson2003, also without OpenCV), on every case.  Ratio rows
``log2_rmse_ratio_vs_<x>`` / ``dark1_ratio_vs_<x>`` are pbrbench's default pipeline
(``ours-debevec1997``) divided by method ``x`` (lower is better; the targets are <= 1.1 vs the
oracle and <= 1 vs ``opencv-robertson``).

Run: ``pbrbench perf hdr`` or ``python -m pbrbench.perf.hdr`` (``--quick`` for 128 x 128).
"""

from __future__ import annotations

import sys
import time
import warnings

import numpy as np

from pbrbench.camera import Camera, bracket_exposure_times
from pbrbench.infer import hdr
from pbrbench.metrics.hdr import hdr_scores, response_rmse
from pbrbench.perf import row

BENCH = "hdr"
PEERS = {"opencv": ("cv2", "opencv-python-headless"), "colour_hdri": ("colour_hdri", "colour-hdri")}
NOISY = ("read_noise", "read+shot", "film read+shot", "dark read+shot", "film 3x3 read+shot")


def synthetic_radiance(size: int = 512, *, highlight: float = 80.0, seed: int = 0,
                       dark: float = 1e-2) -> np.ndarray:
    """Seeded (size, size, 3) HDR radiance: ``dark`` .. 1e2 plus highlight disks of ``highlight``."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:size, 0:size] / (size - 1.0)
    ph = rng.uniform(0, 2 * np.pi, 4)
    # log10 luminance: a diagonal ramp with smooth waves, in [-1.2, 1.9] before the corners
    s = 0.5 * (x + y) + 0.08 * np.sin(2 * np.pi * (1.3 * x + ph[0])) * np.cos(2 * np.pi * (0.9 * y + ph[1]))
    s = (s - s.min()) / (s.max() - s.min())
    logl = -1.2 + 3.1 * s
    # dark vignetted corners reaching `dark`
    r = np.sqrt((x - 0.5) ** 2 + (y - 0.5) ** 2) / np.sqrt(0.5)
    logl -= np.clip((r - 0.8) / 0.2, 0, 1) ** 2 * (logl - np.log10(dark))
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
    return np.clip(L, dark, None).astype(np.float32)


def _conditions(size: int):
    base = synthetic_radiance(size)
    dark = synthetic_radiance(size, dark=1e-3)
    t7 = bracket_exposure_times(base, stops=1.0, count=7, headroom=0.9)
    t3 = bracket_exposure_times(base, stops=3.0, count=3, headroom=0.9)
    cam = dict(response="random", bit_depth=8, seed=3)
    noise = dict(read_noise=0.002, full_well=1e4)
    return [
        ("no_noise", base, Camera(**cam), t7),
        ("read_noise", base, Camera(**cam, read_noise=0.002), t7),
        ("read+shot", base, Camera(**cam, **noise), t7),
        ("film read+shot", base, Camera("film", bit_depth=8, **noise), t7),
        ("dark read+shot", dark, Camera(**cam, **noise), t7),
        ("gamma2.2", base, Camera("gamma", bit_depth=8), t7),
        ("3x3stops", base, Camera(**cam), t3),
        ("film 3x3 read+shot", base, Camera("film", bit_depth=8, **noise), t3),
        ("clipped", synthetic_radiance(size, highlight=1e4), Camera(**cam), t7),
    ]


def _timed(fn, repeats):
    best, out = np.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return out, best


def _ours(method, merge=None):
    cal = hdr.CALIBRATION_METHODS[method]
    opts = {} if merge is None else {"method": merge}

    def run(images, times, repeats, br=None):
        resp, t_cal = _timed(lambda: cal(images, times), repeats)
        tm = resp.exposure_times if resp.exposure_times is not None else times
        rad, t_merge = _timed(lambda: hdr.merge_hdr(images, tm, resp, **opts), repeats)
        return rad, resp.inverse, t_cal, t_merge

    return run


def true_response(br) -> hdr.CameraResponse:
    """The camera's true inverse response as a CameraResponse (level 0 given half of level 1)."""
    inv = np.asarray(br.true_inverse, float).copy()
    inv[0] = np.where(inv[0] > 0, inv[0], 0.5 * inv[1])
    return hdr.CameraResponse(np.maximum.accumulate(np.maximum(inv, 1e-12), axis=0), inv.shape[0], "true")


def _floor(images, times, repeats, br=None):
    resp = true_response(br)
    rad, t_merge = _timed(lambda: hdr.merge_hdr(images, times, resp), repeats)
    return rad, resp.inverse, 0.0, t_merge


def oracle_merge(br, radiance, read_noise: float, full_well: float | None) -> np.ndarray:
    """The best linear merge of a simulated bracket: true response and noise model, weights
    ``t_k^2 / var_k`` with the variance evaluated at the true (noise-free) exposure
    ``gain L t_k``; black and clipped levels excluded, as in any merge.  Uses the truth, so it
    is a reference, not a method."""
    inv = np.asarray(br.true_inverse, float)
    q = np.gradient(inv, axis=0) ** 2 / 12.0
    top = inv.shape[0] - 1
    L = np.asarray(radiance, float)
    num = np.zeros(L.shape)
    den = np.zeros(L.shape)
    ch = np.arange(L.shape[-1])
    for k, tk in enumerate(br.true_exposure_times):
        z = br.images[k].astype(np.intp)
        xt = np.minimum(br.gain * L * tk, 1.0)
        v = read_noise**2 + (xt / full_well if full_well else 0.0) + q[z, ch]
        w = np.where((z > 0) & (z < top), tk**2 / v, 0.0)
        num += w * inv[z, ch] / tk
        den += w
    est = np.where(den > 0, num / np.where(den > 0, den, 1.0), np.nan)
    pos = est[np.isfinite(est)]
    return np.where(np.isfinite(est), est, pos.min() if pos.size else 1.0)


def _opencv(kind):
    def run(images, times, repeats, br=None):
        import cv2

        cv2.setNumThreads(1)
        imgs = [np.ascontiguousarray(im) for im in images]
        tt = np.asarray(times, np.float32)
        cal = cv2.createCalibrateDebevec() if kind == "debevec" else cv2.createCalibrateRobertson()
        mrg = cv2.createMergeDebevec() if kind == "debevec" else cv2.createMergeRobertson()
        resp, t_cal = _timed(lambda: cal.process(imgs, tt), repeats)
        rad, t_merge = _timed(lambda: mrg.process(imgs, tt, resp), repeats)
        return rad, resp.reshape(-1, resp.shape[-1]).astype(np.float64), t_cal, t_merge

    return run


def _colour_hdri(images, times, repeats, br=None):
    import colour_hdri as ch

    def stack():
        st = ch.ImageStack()
        for im, tk in zip(images, times, strict=True):
            st.append(ch.Image(data=im.astype(np.float64) / 255.0,
                               metadata=ch.Metadata(f_number=1.0, exposure_time=float(tk), iso=100.0)))
        return st

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        crf, t_cal = _timed(lambda: ch.camera_response_functions_Debevec1997(stack()), repeats)
        rad, t_merge = _timed(lambda: ch.image_stack_to_HDRI(stack(), camera_response_functions=crf), repeats)
    return rad, crf, t_cal, t_merge


def installed_peers() -> dict[str, bool]:
    """Which peers can be imported (name -> bool)."""
    import importlib.util

    return {name: importlib.util.find_spec(mod) is not None for name, (mod, _) in PEERS.items()}


def _methods(peers: dict[str, bool]):
    out = [(f"ours-{m}", _ours(m)) for m in hdr.CALIBRATION_METHODS]
    default = hdr.merge_hdr.__kwdefaults__["method"]
    out += [(f"ours-debevec1997+{m}", _ours("debevec1997", m)) for m in hdr.MERGE_METHODS if m != default]
    out += [("floor:true_response", _floor)]
    if peers["opencv"]:
        out += [("opencv-debevec", _opencv("debevec")), ("opencv-robertson", _opencv("robertson"))]
    if peers["colour_hdri"]:
        out += [("colour_hdri-debevec", _colour_hdri)]
    return out


def merge_time_ratio(images, times, repeats: int) -> tuple[float, float, float]:
    """``(ours, opencv, ours / opencv)``: best-of-``repeats`` wall times of pbrbench's default
    merge (on its default calibration) and OpenCV's ``MergeDebevec`` (on OpenCV's calibration,
    single-threaded), timed alternately in this process on the same bracket."""
    import cv2

    cv2.setNumThreads(1)
    resp = hdr.calibrate_response(images, times)
    imgs = [np.ascontiguousarray(im) for im in images]
    tt = np.asarray(times, np.float32)
    crf = cv2.createCalibrateDebevec().process(imgs, tt)
    mrg = cv2.createMergeDebevec()
    ours = theirs = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        hdr.merge_hdr(images, times, resp)
        ours = min(ours, time.perf_counter() - t0)
        t0 = time.perf_counter()
        mrg.process(imgs, tt, crf)
        theirs = min(theirs, time.perf_counter() - t0)
    return ours, theirs, ours / theirs


def calibration_times(images, times, repeats: int, opencv: bool = True) -> dict[str, float]:
    """Best-of-``repeats`` wall times of each of pbrbench's calibrations (``ours-<name>``) and,
    with ``opencv``, OpenCV's ``CalibrateDebevec`` and ``CalibrateRobertson`` (``opencv-debevec``,
    ``opencv-robertson``, single-threaded), timed round-robin in this process on the same
    bracket, so that their ratios compare them under the same load."""
    fns = {f"ours-{m}": (lambda fn=fn: fn(images, times)) for m, fn in hdr.CALIBRATION_METHODS.items()}
    if opencv:
        import cv2

        cv2.setNumThreads(1)
        imgs = [np.ascontiguousarray(im) for im in images]
        tt = np.asarray(times, np.float32)
        fns["opencv-debevec"] = lambda: cv2.createCalibrateDebevec().process(imgs, tt)
        fns["opencv-robertson"] = lambda: cv2.createCalibrateRobertson().process(imgs, tt)
    best = dict.fromkeys(fns, np.inf)
    for _ in range(repeats):
        for name, fn in fns.items():
            t0 = time.perf_counter()
            fn()
            best[name] = min(best[name], time.perf_counter() - t0)
    return best


# calibration time ratios: (ours, reference, metric); the metric names fit the 24 characters
# that ``pbrbench perf`` prints
CALIBRATION_RATIOS = (
    ("ours-debevec1997", "opencv-debevec", "cal_ratio_vs_opencv-deb"),
    ("ours-robertson2003", "opencv-robertson", "cal_ratio_vs_opencv-rob"),
    ("ours-mitsunaga1999", "opencv-robertson", "cal_ratio_vs_opencv-rob"),
    ("ours-mitsunaga1999", "ours-robertson2003", "cal_ratio_vs_robertson"),
)


def _row(case, method, metric, value, unit, *, better):
    return row(BENCH, case, method, metric, value, unit, better=better)


def run(quick: bool = False) -> list[dict]:
    size = 128 if quick else 512
    repeats = 1 if quick else 3
    peers = installed_peers()
    for name, ok in peers.items():
        if not ok:
            print(f"[hdr perf] peer {name} is not installed (pip install {PEERS[name][1]}, or "
                  "pip install 'pbrbench[peers]'): its rows are left out", file=sys.stderr)
    rows = []
    for case, L, cam, times in _conditions(size):
        br = cam.capture(L, times, seed=11)
        ok = ~br.saturated
        scores = {}
        methods = _methods(peers)
        if case in NOISY:
            methods.append(("oracle", lambda *a, br=br, L=L, cam=cam: (
                oracle_merge(br, L, cam.read_noise, cam.full_well), br.true_inverse, 0.0, 0.0)))
        for name, fn in methods:
            if quick and (name.startswith("colour_hdri") or name == "opencv-robertson"):
                continue  # quick mode: colour-hdri's calibration alone takes minutes
            try:
                rad, inv, t_cal, t_merge = fn(br.images, br.exposure_times, repeats, br=br)
            except Exception as exc:  # a peer failing is reported, not fatal
                print(f"[hdr perf] {name} on {case} failed: {exc}", file=sys.stderr)
                continue
            rad = np.asarray(rad, dtype=np.float64)
            sc = hdr_scores(rad, L, mask=ok)
            scores[name] = sc
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
                if name in ("oracle", "floor:true_response") and metric in ("response_rmse", "calibrate_time"):
                    continue
                if name == "oracle" and metric == "merge_time":
                    continue
                rows.append(_row(case, name, metric, value, unit, better="lower"))   # errors, times
        ours = scores.get("ours-debevec1997")
        if ours is not None:
            for ref, sc in scores.items():
                if ref.startswith("ours") or ref.startswith("floor"):
                    continue
                for m in ("log2_rmse", "dark1"):
                    rows.append(_row(case, "ours-debevec1997", f"{m}_ratio_vs_{ref}",
                                     ours[m] / max(sc[m], 1e-12), "x", better="lower"))
        # time ratios on every case (the costs depend on the noise and on how fast each converges)
        if peers["opencv"]:
            t_ours, t_cv, ratio = merge_time_ratio(br.images, br.exposure_times, max(repeats, 10))
            rows.append(_row(case, "ours-debevec1997", "merge_time_ratio_vs_opencv", ratio, "x", better="lower"))
        tc = calibration_times(br.images, br.exposure_times, repeats, opencv=peers["opencv"])
        for ours, ref, metric in CALIBRATION_RATIOS:
            if ours in tc and ref in tc:
                rows.append(_row(case, ours, metric, tc[ours] / tc[ref], "x", better="lower"))
    return rows


def main(argv=None) -> None:
    argv = sys.argv[1:] if argv is None else argv
    rows = run(quick="--quick" in argv)
    metrics = ["log2_rmse", "dark1", "bright1", "invalid", "response_rmse", "calibrate_time", "merge_time"]
    table: dict[tuple[str, str], dict[str, float]] = {}
    ratios = []
    for r in rows:
        if r["metric"] in metrics:
            table.setdefault((r["case"], r["method"]), {})[r["metric"]] = r["value"]
        else:
            ratios.append(r)
    head = f"{'case':<16}{'method':<30}" + "".join(f"{m:>15}" for m in metrics)
    print(head)
    print("-" * len(head))
    for (case, method), vals in table.items():
        print(f"{case:<16}{method:<30}" + "".join(f"{vals.get(m, np.nan):>15.4g}" for m in metrics))
    print()
    for r in ratios:
        print(f"{r['case']:<16}{r['method']:<30}{r['metric']:<40}{r['value']:>10.3f} {r['unit']}")


if __name__ == "__main__":
    main()
