"""HDR: radiometric calibration and merging of a simulated exposure bracket.

Scene: ``hdr_scene`` (dynamic range >= 1e4).  Its ``radiance`` render (full light transport, hence
the base condition ``global``) is the linear truth; a simulated camera
(:class:`pbrbench.camera.Camera`: film-like S-shaped response, 8 bits, clipping) turns it into an
exposure bracket whose times cover the scene's range (:func:`pbrbench.camera.bracket_exposure_times`:
from a visible emitter's radiance, known from the scene file, to the 0.5th percentile of the
positive radiance; the brightest and the darkest pixel are the render's noisiest statistics, and a
bracket designed from them changed its length between render seeds and between sample groups).
Radiometric calibration does not care about light transport; its conditions are camera
conditions, appended to the base:

* ``global+noise0``: no noise, exposures one stop apart covering the range;
* ``global+readnoise0.002``: Gaussian read noise of 0.2 % of full scale, plus shot noise with a
  full well of 10000 electrons;
* ``global+3x3stops``: only 3 exposures, 3 stops apart;
* ``global+clipped``: the brightest 2 % of the pixels clip even in the shortest exposure;
* ``global+unregistered``: the noise-free bracket of ``global+noise0``, each exposure captured
  from its own crop of the radiance, offset by up to :data:`SHIFT` pixels in x and y from the
  common crop (offsets uniform integers from the job's seeded generator,
  :func:`~pbrbench.tasks.common.inputs.job_rng`; an exposure may draw no offset).  Calibration
  gets the shifted exposures; the chapter (section 1.3.1) notes that registration is not needed
  when the exposures show the same histogram of radiance, which is what
  ``grossberg_nayar2003`` uses.  A merge of misregistered exposures is misaligned whatever the
  response, so here the response is judged by ``response_rmse`` and by the merge of the
  *registered* bracket (the common crop, same camera) with the response calibrated on the
  shifted one; everything is scored on the common crop;
* ``global+rough_times0.07``: the noise-free bracket, exposed for the true times ``t_k
  exp(N(0, 0.07^2))`` (about 7 % error, :class:`pbrbench.camera.Camera` ``exposure_error``)
  while every method, the merge and the floor are given the stated ``t_k``; the truth is the
  radiance the true times exposed.  Only ``mitsunaga1999`` re-estimates the ratios (its merge
  uses its own times).  The scores remove one global scale, not an exponent: the response and
  ratios are ambiguous up to ``f^{-1} -> (f^{-1})^gamma, t -> t^gamma`` when the ratios are
  re-estimated, and Mitsunaga-Nayar fix ``gamma`` by keeping the stated span ``t_0 / t_{K-1}``,
  so an error in that span shows in their score as a wrong exponent (as it would in use);
  the other methods trust every stated ratio.

Algorithms (from the registry), each called as ``fn(images, exposure_times)`` (and ``seed=`` when
it takes one) returning a :class:`~pbrbench.infer.hdr.CameraResponse`, which the task merges with
:func:`pbrbench.infer.hdr.merge_hdr` (with the response's re-estimated exposure times when it has
them): every method of :data:`pbrbench.infer.hdr.CALIBRATION_METHODS` and any plugin;
``baseline:ignore_response`` (pixel values taken as linear); ``floor:true_response`` (the camera's
true inverse response, given the bracket as ``truth``: the quantisation/noise floor of merging).

Metrics (:mod:`pbrbench.metrics.hdr`): log2 radiance RMSE after the one free global scale, per
channel, on the brightest and darkest 1 %, ``invalid_fraction``, and the response-curve RMSE
against the true inverse (``response_rmse``, not for the floor).  The radiance errors are scored on
the pixels the bracket *measures* (in every channel, at least one exposure neither black nor
saturated); what no exposure measures is a property of the bracket, not of the calibration, and is
scored separately as ``bracket_coverage`` (the measured fraction; the same for every algorithm).
Without this, a bracket that misses part of the scene's range (``3x3stops``, ``clipped``) scores
the guesses made for unmeasured pixels, and the true-response floor can lose to a baseline.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from pbrbench.camera import Camera, bracket_exposure_times
from pbrbench.checks import method_options
from pbrbench.metrics.hdr import hdr_scores, response_rmse
from pbrbench.registry import Algorithm, pipeline_hash
from pbrbench.tasks.base import Job, JobResult, Prediction, Task, parse_condition
from pbrbench.tasks.common.figures import display, display_map, profile_plot
from pbrbench.tasks.common.inputs import grey, job_rng
from pbrbench.tasks.common.scoring import (
    ScoreBook,
    Timer,
    attribute,
    call,
    check_array,
    one_line,
    scene_hash,
)

SCENES = ("hdr_scene",)
RESPONSE = "film"
BIT_DEPTH = 8
ROUGH_TIMES = 0.07   # standard deviation of ln(true / stated exposure time), global+rough_times0.07
SHIFT = 3            # largest offset (pixels, in x and in y) of an exposure, global+unregistered
DARK_PERCENTILE = 0.5   # the bracket's dark end: this percentile of the positive radiance
EMITTER_SEEN = 0.1      # an emitter is in view when the brightest pixel reaches this fraction of its radiance
CONDITIONS = ("global+noise0", "global+readnoise0.002", "global+3x3stops", "global+clipped",
              "global+unregistered", f"global+rough_times{ROUGH_TIMES:g}")


def camera_setup(condition: str, radiance: np.ndarray, bright: float | None = None) -> tuple[Camera, np.ndarray]:
    """The simulated camera and exposure times of a condition (see the module docstring).

    ``bright``: the bright end when it is known without render noise (the radiance of a
    visible emitter, :func:`visible_emitter_radiance`); else the brightest pixel.  The dark end
    is the :data:`DARK_PERCENTILE` of the positive radiance (the single darkest pixel is the
    noisiest)."""
    _, mods = parse_condition(condition)
    read = mods.get("readnoise", 0.0)
    cam = Camera(RESPONSE, bit_depth=BIT_DEPTH, read_noise=read, full_well=1e4 if read > 0 else None,
                 exposure_error=mods.get("rough_times", 0.0))
    if "3x3stops" in mods:
        times = bracket_exposure_times(radiance, stops=3.0, count=3, bright=bright)
    elif "clipped" in mods:
        times = bracket_exposure_times(radiance, stops=1.0, headroom=1.0, bright_percentile=98.0,
                                       dark_percentile=DARK_PERCENTILE)
    else:
        times = bracket_exposure_times(radiance, stops=1.0, bright=bright, dark_percentile=DARK_PERCENTILE)
    return cam, times


def visible_emitter_radiance(spec, radiance: np.ndarray) -> float | None:
    """The largest radiance of the scene's area emitters when the image sees one (its brightest
    pixel reaches :data:`EMITTER_SEEN` of it), else None.  A bracket designed from the brightest
    pixel follows the render's noise: at draft an emitter covers a few pixels partially, their
    values are Monte Carlo estimates of its coverage, and they moved the shortest time by a stop
    (and the number of exposures by one) between render seeds and between sample groups."""
    if spec is None:
        return None
    L = max((max(light.radiance) for light in (*spec.lights, *spec.light_set) if light.type == "area"), default=0.0)
    hi = float(np.max(radiance, initial=0.0))
    return float(L) if L > 0 and hi >= EMITTER_SEEN * L else None


def unregistered_bracket(cam: Camera, radiance: np.ndarray, exposure_times, offsets, *, shift: int = SHIFT,
                         seed: int = 0):
    """The registered bracket of the common crop and the same exposures captured unregistered.

    Parameters
    ----------
    cam : Camera
    radiance : (H, W, C) array
        Linear radiance, larger than ``2 shift`` in both directions.
    exposure_times : (K,) array, ascending
    offsets : (K, 2) int array
        Per exposure ``(dy, dx)``, each in ``[-shift, shift]``.
    shift : int
        The margin: the common crop is ``radiance[shift:H - shift, shift:W - shift]``.
    seed : int
        The registered capture's seed; exposure ``k`` of the unregistered one uses ``seed + k``.

    Returns
    -------
    common : (H - 2 shift, W - 2 shift, C) array
        The common crop (the truth both brackets are scored on).
    registered : :class:`pbrbench.camera.Bracket`
        The bracket of the common crop.
    images : (K, H - 2 shift, W - 2 shift, C) array
        Exposure ``k`` captured from ``radiance[shift + dy:H - shift + dy, shift + dx:W - shift + dx]``:
        pixel ``(i, j)`` of exposure ``k`` sees the scene point that pixel ``(i + dy, j + dx)``
        of the common crop sees.
    """
    rad = np.asarray(radiance, np.float64)
    H, W = rad.shape[:2]
    off = np.asarray(offsets, int).reshape(-1, 2)
    t = np.sort(np.asarray(exposure_times, float).ravel())
    if off.shape[0] != t.size or np.abs(off).max(initial=0) > shift:
        raise ValueError(f"offsets: need {t.size} (dy, dx) pairs within +-{shift}, got {off.tolist()}")
    if H <= 2 * shift or W <= 2 * shift:
        raise ValueError(f"radiance: {H}x{W} pixels leave no common crop for shifts of {shift}")
    common = rad[shift:H - shift, shift:W - shift]
    registered = cam.capture(common, t, seed=seed)
    images = np.empty_like(registered.images)
    for k, (dy, dx) in enumerate(off):
        crop = rad[shift + dy:H - shift + dy, shift + dx:W - shift + dx]
        images[k] = cam.capture(crop, t[k:k + 1], seed=seed + k).images[0]
    return common, registered, images


def ignore_response(images, exposure_times):
    """``baseline:ignore_response``: pixel value / top level taken as linear exposure (the lowest
    level gets the value of level 1 / 2 so the inverse stays positive)."""
    from pbrbench.infer.hdr import CameraResponse

    imgs = np.asarray(images)
    levels = 1 << max(8, int(np.ceil(np.log2(int(imgs.max()) + 1))))  # 8-bit data: 256 levels
    channels = imgs.shape[-1] if imgs.ndim == 4 else 1
    z = np.arange(levels, dtype=float) / (levels - 1)
    z[0] = 0.5 / (levels - 1)
    return CameraResponse(np.repeat(z[:, None], channels, axis=1), levels, "linear")


def _radiance_scores(book, res, alg, est, err, seconds, rad, domain, coverage) -> dict | None:
    """The radiance scores of a merged ``est`` (None, with the failure recorded, when ``err``)."""
    if err is not None:
        book.add(alg.name, {"failed": 1.0}, seconds)
        res.failures[alg.name] = err
        return None
    sc = hdr_scores(est, rad, mask=domain) if domain.any() else {}
    sc["bracket_coverage"] = coverage
    return sc


MERGE_SEP = "+merge:"


def default_merge() -> str:
    """``merge_hdr``'s default merge method (its signature decides it)."""
    import inspect

    from pbrbench.infer.hdr import merge_hdr

    return inspect.signature(merge_hdr).parameters["method"].default


def merge_of(name: str) -> str:
    """The merge an algorithm's response is merged with: ``<calibration>+merge:<merge>``, else the default."""
    return name.partition(MERGE_SEP)[2] or default_merge()


def true_response(images, exposure_times, *, truth):
    """``floor:true_response``: the camera's own inverse response (``truth`` is the bracket)."""
    from pbrbench.infer.hdr import CameraResponse

    inv = np.asarray(truth.true_inverse, float).copy()
    pos = inv[inv > 0]
    inv[0] = np.where(inv[0] > 0, inv[0], 0.5 * pos.min())  # level 0 carries no weight in merging
    inv = np.maximum.accumulate(np.maximum(inv, 1e-12), axis=0)
    return CameraResponse(inv, inv.shape[0], "true")


def _check_response(out, channels: int):
    inv = attribute(out, "inverse")
    if inv is None:
        raise ValueError("output: return a CameraResponse (or anything with an `inverse` (levels, channels) array)")
    inv = np.asarray(inv, float)
    if inv.ndim != 2 or inv.shape[1] not in (1, channels):
        raise ValueError(f"inverse: returned shape {inv.shape}, expected (levels, {channels})")
    if not np.isfinite(inv).all():
        raise ValueError("inverse: non-finite values in the returned response")
    return out


class HDRTask(Task):
    name = "hdr"
    description = ("Radiometric calibration (Debevec–Malik 1997, Robertson 2003, Mitsunaga–Nayar 1999, "
                   "Grossberg–Nayar 2003) and HDR merging of a simulated camera's bracket of a rendered scene.")
    conditions = CONDITIONS
    headline_metric = "log2_rmse"
    families = SCENES
    reference_condition = "global+noise0"
    notes = ("Radiometric calibration does not depend on light transport (the camera sees radiance, "
             "however it arose), so this task has no local/area/global axis: its conditions are the "
             "camera's (noise, bracket, clipping), and the reference is the noise-free bracket.")

    def seed_dependent(self, job) -> bool:
        return True  # the camera's noise and the calibrations' pixel samples follow the seed

    def builtin_algorithms(self) -> list[Algorithm]:
        from pbrbench.infer.hdr import CALIBRATION_METHODS, MERGE_METHODS

        # draft: Mitsunaga-Nayar with a fixed degree instead of its held-out degree search (about 20x slower)
        budgets = {"mitsunaga1999": {"draft": {"degree": 5}}}
        out = [Algorithm(n, self.name, fn, budgets=budgets.get(n, {})) for n, fn in CALIBRATION_METHODS.items()]
        # calibration x merge: each calibration merged by every other merge of the table (the plain
        # entry uses merge_hdr's default), on the reference condition only, where the merges differ
        # by their weighting alone
        out += [Algorithm(f"{n}{MERGE_SEP}{m}", self.name, fn, budgets=budgets.get(n, {}), variant_of=n,
                          conditions=(self.reference_condition,), figures=False,
                          description=f"{n} calibration, {m} merge")
                for n, fn in CALIBRATION_METHODS.items() for m in MERGE_METHODS if m != default_merge()]
        # every merge of the methods table, given the camera's true response: the merges compared alone
        out += [Algorithm(f"merge:{n}", self.name, fn, interface="merge", figures=False,
                          description=f"the {n} merge with the true inverse response (the merge alone)")
                for n, fn in MERGE_METHODS.items()]
        out += [Algorithm("baseline:ignore_response", self.name, ignore_response, kind="baseline"),
                Algorithm("floor:true_response", self.name, true_response, kind="floor")]
        # the task merges every response with a merge of the table: that merge's code is part of the
        # version of each entry scored through it (a change to the default merge changes every calibration's
        # radiance scores); the merges alone carry their own
        return [a if a.interface == "merge" else
                replace(a, fingerprint=pipeline_hash(a.fn, MERGE_METHODS[merge_of(a.name)])) for a in out]

    # --------------------------------------------------- export / evaluate (pbrbench.bench.external)
    input_names = ("images", "exposure_times")
    predictions = (
        Prediction("response", "levels,C", False, "inverse response f^-1(z) per pixel level z (rows) and channel "
                   "(columns), any scale (divided by its last row); merged by the task like a built-in's"),
        Prediction("exposure_times", "K", False, "re-estimated exposure times for the merge (with response)"),
        Prediction("radiance", "H,W,3", False, "the merged linear radiance (scored without response_rmse); "
                   "give response or radiance"),
    )

    def frame_shape(self, inputs: dict) -> tuple[int, int]:
        return tuple(np.shape(inputs["images"])[1:3])

    def prediction_output(self, files: dict, inputs: dict):
        from pbrbench.infer.hdr import CameraResponse

        if "response" not in files:
            raise ValueError("prediction: write response (levels x channels) or radiance (H, W, 3)")
        inv = np.asarray(files["response"], float)
        inv = inv[:, None] if inv.ndim == 1 else inv
        times = files.get("exposure_times")
        return CameraResponse(inv / inv[-1:], inv.shape[0], "external",
                              None if times is None else np.asarray(times, float).ravel())

    def score_outputs(self, job: Job, gts: dict, files: dict, *, algorithm, seed: int = 0, quality=None):
        if "radiance" not in files or "response" in files:
            return None
        gt = gts[job.scene]
        rad, mask, _, domain, coverage, _ = self._bracket(job, gt, seed)
        book = ScoreBook(job, scene_hash(gt), [algorithm])
        res = JobResult(job)
        try:
            est = check_array(files["radiance"], "radiance", rad.shape, where=mask)
            sc = hdr_scores(est, rad, mask=domain) if domain.any() else {}
        except ValueError as e:
            book.add(algorithm.name, {"failed": 1.0}, 0.0)
            res.failures[algorithm.name] = one_line(e)
        else:
            book.add(algorithm.name, dict(sc, bracket_coverage=coverage), 0.0)
        res.scores = book.scores
        return res

    def jobs(self, quality) -> list[Job]:
        out = []
        for fam in quality.pick(self.families, ()):
            for s in self.scenes.family(fam):
                out += [Job(self.name, s.name, c) for c in self.conditions]
        return out

    def _bracket(self, job: Job, gt, seed: int):
        """(radiance, its positive pixels, the simulated bracket, the pixels it measures (in every
        channel some exposure neither black nor saturated), their fraction, the images calibration
        is given).  Under ``unregistered`` the radiance is the common crop, the bracket its
        registered one and the images the shifted exposures (:func:`unregistered_bracket`)."""
        rad = np.maximum(np.asarray(gt["radiance"], np.float64), 0.0)
        _, mods = parse_condition(job.condition)
        rng = job_rng(job, seed)
        cap_seed = int(rng.integers(0, 2 ** 31 - 1))
        if "unregistered" in mods:
            inner = rad[SHIFT:rad.shape[0] - SHIFT, SHIFT:rad.shape[1] - SHIFT]
            pos = inner[np.all(inner > 0, axis=-1)]
            cam, times = camera_setup(job.condition, pos, visible_emitter_radiance(self.library_spec(job.scene), pos))
            offsets = rng.integers(-SHIFT, SHIFT + 1, (len(times), 2))
            rad, br, images = unregistered_bracket(cam, rad, times, offsets, shift=SHIFT, seed=cap_seed)
            mask = np.all(rad > 0, axis=-1)
        else:
            mask = np.all(rad > 0, axis=-1)
            cam, times = camera_setup(job.condition, rad[mask], visible_emitter_radiance(self.library_spec(job.scene), rad[mask]))
            br = cam.capture(rad, times, seed=cap_seed)
            images = br.images
        top = br.levels - 1
        measured = np.all(np.any((br.images > 0) & (br.images < top), axis=0), axis=-1)
        domain = mask & measured
        return rad, mask, br, domain, float(domain.sum() / max(mask.sum(), 1)), images

    def run_job(self, job: Job, gts: dict, *, seed: int = 0, algorithms=(), quality=None) -> JobResult:
        from pbrbench.infer.hdr import merge_hdr

        algorithms = [a for a in algorithms if a.applies(job.condition)]
        merges = [a for a in algorithms if a.interface == "merge"]
        algorithms = [a for a in algorithms if a.interface != "merge"]
        gt = gts[job.scene]
        rad, mask, br, domain, coverage, images = self._bracket(job, gt, seed)
        times = br.exposure_times
        book = ScoreBook(job, scene_hash(gt), algorithms + merges)   # the merges' versions too
        res = JobResult(job)
        res.images["linear:truth (radiance)"] = display(rad)
        k_mid = len(times) // 2
        res.images[f"input: exposure {k_mid + 1} of {len(times)}"] = display(images[k_mid].astype(float) / (br.levels - 1))
        res.images["pixels no exposure measures (white)"] = display((mask & ~domain).astype(float))
        levels = np.arange(br.levels)
        curves = {"true": _log2_inverse(br.true_inverse[:, 1])}
        fig_1_10 = job.condition == self.reference_condition
        if fig_1_10:
            res.images[f"Fig 1.10 exposure bracket: 4 of the {len(times)} exposures, shortest to longest"] = \
                bracket_montage(images, br.levels)
        shown = set()
        for alg in algorithms:
            kw = {"truth": br} if alg.kind == "floor" else {}
            if "seed" in method_options(alg.fn) and "seed" not in alg.options:
                kw["seed"] = seed
            est = None
            with Timer() as t:
                resp, _, err = call(alg, images, br.exposure_times, quality=quality,
                                      check=lambda o: _check_response(o, rad.shape[-1]), **kw)
                if err is None:
                    tt = resp.exposure_times if getattr(resp, "exposure_times", None) is not None else br.exposure_times
                    try:
                        est = merge_hdr(br.images, tt, resp, method=merge_of(alg.name))
                    except Exception as e:  # noqa: BLE001 - an unusable response is the algorithm's failure
                        err = one_line(e)
            sc = _radiance_scores(book, res, alg, est, err, t.seconds, rad, domain, coverage)
            if sc is None:
                continue
            if alg.kind != "floor":
                sc["response_rmse"] = response_rmse(resp.inverse, br.true_inverse)
                curves[alg.name] = _log2_inverse(resp.inverse[:, min(1, resp.inverse.shape[1] - 1)])
                if fig_1_10 and alg.kind == "method" and "Fig 1.10" not in " ".join(res.plots):
                    res.plots[f"Fig 1.10 inverse response of each channel: {alg.name}"] = channel_curves(resp, br)
                    res.images[f"Fig 1.10 composite ({alg.name}): whole range, and the boxes each scaled to "
                               "the print range"] = composite_with_boxes(est, dom=domain if domain.any() else mask)
            book.add(alg.name, sc, t.seconds)
            if alg.kind in ("method", "baseline") and alg.kind not in shown:  # the first of each
                shown.add(alg.kind)
                dom = domain if domain.any() else mask
                res.images[f"linear:merged: {alg.name}"] = display(est / np.exp(np.mean(np.log(est[dom] / rad[dom]))))
                with np.errstate(divide="ignore", invalid="ignore"):
                    lr = np.log2(grey(est) / grey(rad))
                lr = np.where(dom, lr - np.nanmedian(lr[dom]), np.nan)
                res.error_maps[f"log2 radiance error (stops): {alg.name}"] = display_map(lr)
        if merges:     # the merges of the methods table, each given the true response
            truth = true_response(images, times, truth=br)
            for alg in merges:
                with Timer() as t:
                    est, _, err = call(alg, br.images, times, truth, quality=quality,
                                       check=lambda o: check_array(o, "radiance", rad.shape))
                sc = _radiance_scores(book, res, alg, est, err, t.seconds, rad, domain, coverage)
                if sc is not None:
                    book.add(alg.name, sc, t.seconds)
        res.plots["inverse response (green channel)"] = profile_plot(
            levels, curves, "pixel level", "log2 relative exposure f^-1(z)",
            note="gauge: f^-1(top level) = 1 for every curve; level 0 (black) has no exposure")
        res.scores = book.scores
        return res


def _log2_inverse(inv) -> np.ndarray:
    """``log2 f^-1(z)`` for plotting; NaN at level 0 and wherever ``f^-1`` is not positive (black
    records no exposure: its -40 would squash every curve)."""
    v = np.asarray(inv, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(v > 0, np.log2(np.where(v > 0, v, 1.0)), np.nan)
    out[:1] = np.nan
    return out


def bracket_montage(images, levels: int, n: int = 4, gap: int = 2) -> np.ndarray:
    """``n`` exposures of the bracket, evenly spaced from the shortest to the longest, side by
    side as the camera recorded them (pixel value / top level) with white gaps: Fig 1.10's row."""
    imgs = np.asarray(images, float) / (levels - 1)
    ks = np.unique(np.round(np.linspace(0, imgs.shape[0] - 1, min(n, imgs.shape[0]))).astype(int))
    H = imgs.shape[1]
    parts = []
    for i, k in enumerate(ks):
        if i:
            parts.append(np.ones((H, gap, imgs.shape[-1])))
        parts.append(imgs[k])
    return display(np.concatenate(parts, axis=1), max_size=1 << 16)   # the report sizes the strip


def channel_curves(resp, br) -> dict:
    """Fig 1.10's plot: ``log2 f^-1(z)`` of each channel of a calibrated response (solid) and the
    camera's true inverse (dashed), levels 1 to the top."""
    levels = np.arange(br.levels)
    series = {}
    for c, (name, col) in enumerate(zip("RGB", ("#d62728", "#2ca02c", "#1f77b4"), strict=True)):
        cc = min(c, resp.inverse.shape[1] - 1)
        series[f"{name}: calibrated"] = {"x": levels.tolist(), "y": _nan_list(_log2_inverse(resp.inverse[:, cc])),
                                         "color": col, "marker": ""}
        series[f"{name}: true"] = {"x": levels.tolist(), "y": _nan_list(_log2_inverse(br.true_inverse[:, min(c, br.true_inverse.shape[1] - 1)])),
                                   "color": col, "marker": "", "linestyle": "--"}
    return {"x": None, "series": series, "xlabel": "pixel level z", "ylabel": "log2 relative exposure f^-1(z)",
            "title": f"Fig 1.10: inverse response per channel ({resp.method}; dashed: the camera's, one curve for R, G, B)"}


def _nan_list(a) -> list:
    return [None if not np.isfinite(v) else float(v) for v in np.asarray(a, float)]


def composite_with_boxes(est, dom, box_frac: float = 0.25) -> np.ndarray:
    """Fig 1.10's composite: the merged radiance over its whole range (log-mapped to [0, 1]),
    and beside it, enlarged to the same height, its brightest and its darkest box (each side
    ``box_frac`` of the image) each scaled linearly to the print range [0, 1] (its 90th percentile
    white: an emitter in the box clips, the surfaces around it show); the boxes are
    outlined on the whole view (red: bright, blue: dark).  Display-ready RGB."""
    L = np.where(np.asarray(dom, bool)[..., None], np.maximum(np.asarray(est, float), 0.0), 0.0)
    Y = L.mean(-1)
    H, W = Y.shape
    b = max(2, int(round(box_frac * min(H, W))))
    pos = Y[Y > 0]
    if pos.size == 0 or H < b or W < b:
        return display(np.zeros((H, W, 3)))
    lo, hi = np.percentile(pos, 0.5), np.percentile(pos, 99.9)
    whole = np.clip(np.log(np.maximum(L, lo) / lo) / np.log(max(hi / lo, 1.0 + 1e-9)), 0.0, 1.0)
    # box means of the luminance on a grid of box positions; the brightest and darkest (lit) box
    cs = np.cumsum(np.cumsum(np.pad(Y, ((1, 0), (1, 0))), 0), 1)
    sums = cs[b:, b:] - cs[:-b, b:] - cs[b:, :-b] + cs[:-b, :-b]
    lit = np.cumsum(np.cumsum(np.pad((Y > 0).astype(float), ((1, 0), (1, 0))), 0), 1)
    full = (lit[b:, b:] - lit[:-b, b:] - lit[b:, :-b] + lit[:-b, :-b]) >= 0.9 * b * b
    means = np.where(full, sums / (b * b), np.nan)
    if not np.isfinite(means).any():
        return display(whole)
    boxes = [np.unravel_index(np.nanargmax(means), means.shape), np.unravel_index(np.nanargmin(means), means.shape)]
    panels, out = [], whole.copy()
    for (i, j), col in zip(boxes, ((1.0, 0.0, 0.0), (0.0, 0.3, 1.0)), strict=True):
        crop = L[i:i + b, j:j + b]
        top = np.percentile(crop[crop > 0], 90.0) if (crop > 0).any() else 1.0   # an emitter in the box clips
        k = max(1, H // b)
        panels.append(np.kron(np.clip(crop / top, 0.0, 1.0), np.ones((k, k, 1)))[:H])
        out[i, j:j + b] = out[i + b - 1, j:j + b] = col
        out[i:i + b, j] = out[i:i + b, j + b - 1] = col
    gap = np.ones((H, 2, 3))
    rows = [out]
    for p in panels:
        pad = np.zeros((H, p.shape[1], 3))
        pad[:p.shape[0]] = p
        rows += [gap, pad]
    return display(np.concatenate(rows, axis=1), max_size=1 << 16)


TASK = HDRTask()
