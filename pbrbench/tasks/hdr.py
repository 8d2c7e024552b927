"""HDR: radiometric calibration and merging of a simulated exposure bracket (SCIENCE.md §4).

Scene (naming contract): ``hdr_scene`` (dynamic range >= 1e4).  Its ``radiance`` render (full
light transport, hence the base condition ``global``) is the linear truth; a simulated camera
(:class:`pbrbench.camera.Camera`: film-like S-shaped response, 8 bits, clipping) turns it into an
exposure bracket whose times cover the scene's range (:func:`pbrbench.camera.bracket_exposure_times`).
Radiometric calibration does not care about light transport; its conditions are camera
conditions, appended to the base:

* ``global+noise0``: no noise, exposures one stop apart covering the range;
* ``global+readnoise0.002``: Gaussian read noise of 0.2 % of full scale, plus shot noise with a
  full well of 10000 electrons;
* ``global+3x3stops``: only 3 exposures, 3 stops apart;
* ``global+clipped``: the brightest 2 % of the pixels clip even in the shortest exposure.

Algorithms: each calibration of :mod:`pbrbench.infer.hdr` followed by
:func:`pbrbench.infer.hdr.merge_hdr` (Mitsunaga–Nayar with its re-estimated exposure times),
``baseline:ignore_response`` (pixel values taken as linear) and ``floor:true_response`` (the
camera's true inverse response: the quantisation/noise floor of merging).

Metrics (:mod:`pbrbench.metrics.hdr`): log2 radiance RMSE after the one free global scale
(``log2_rmse``, stops; per channel ``log2_rmse_c0..2``), the same on the brightest and darkest 1 %
(``bright1``, ``dark1``), ``invalid_fraction``, and the response-curve RMSE against the true
inverse (``response_rmse``, stops, per-channel scale removed).

Draft quality: Mitsunaga–Nayar with a fixed degree 5 instead of its held-out degree search
(``DRAFT_OPTIONS``; the search is about 20x slower).
"""

from __future__ import annotations

import numpy as np

from pbrbench.camera import Camera, bracket_exposure_times
from pbrbench.infer.hdr import CALIBRATION_METHODS, CameraResponse, merge_hdr
from pbrbench.metrics.hdr import hdr_scores, response_rmse
from pbrbench.tasks import _common as C
from pbrbench.tasks.base import Job, JobResult, Task

SCENES = ("hdr_scene",)
RESPONSE = "film"
BIT_DEPTH = 8
CALIBRATIONS = CALIBRATION_METHODS
IGNORE = "baseline:ignore_response"
TRUE = "floor:true_response"
# at draft quality Mitsunaga-Nayar uses a fixed degree instead of its held-out search over 2..8
# (the search is ~20x slower; the regression run must stay short)
DRAFT_OPTIONS = {"mitsunaga1999": {"degree": 5}}
CONDITIONS = ("global+noise0", "global+readnoise0.002", "global+3x3stops", "global+clipped")
DIRECTIONS = {"response_rmse": "lower", "invalid_fraction": "lower"}


def camera_setup(condition: str, radiance: np.ndarray) -> tuple[Camera, np.ndarray]:
    """The simulated camera and exposure times of a condition (see the module docstring)."""
    _, mods = C.parse_condition(condition)
    read = mods.get("readnoise", 0.0)
    cam = Camera(RESPONSE, bit_depth=BIT_DEPTH, read_noise=read, full_well=1e4 if read > 0 else None)
    if "3x3stops" in mods:
        times = bracket_exposure_times(radiance, stops=3.0, count=3)
    elif "clipped" in mods:
        times = bracket_exposure_times(radiance, stops=1.0, headroom=1.0, bright_percentile=98.0)
    else:
        times = bracket_exposure_times(radiance, stops=1.0)
    return cam, times


def linear_response(levels: int, channels: int) -> CameraResponse:
    """The "ignore the response" baseline: pixel value / top level taken as linear exposure
    (the lowest level gets the value of level 1 / 2 so the inverse stays positive)."""
    z = np.arange(levels, dtype=float) / (levels - 1)
    z[0] = 0.5 / (levels - 1)
    return CameraResponse(np.repeat(z[:, None], channels, axis=1), levels, "linear")


def true_response(inverse: np.ndarray) -> CameraResponse:
    inv = np.asarray(inverse, float).copy()
    pos = inv[inv > 0]
    inv[0] = np.where(inv[0] > 0, inv[0], 0.5 * pos.min())  # level 0 carries no weight in merging
    inv = np.maximum.accumulate(np.maximum(inv, 1e-12), axis=0)
    return CameraResponse(inv, inv.shape[0], "true")


class HDRTask(Task):
    name = "hdr"
    description = ("Radiometric calibration (Debevec–Malik 1997, Robertson 1999/2003, Mitsunaga–"
                   "Nayar 1999) and HDR merging of a simulated camera's bracket of a rendered scene.")
    algorithms = tuple(CALIBRATIONS) + (IGNORE, TRUE)
    conditions = CONDITIONS
    headline_metric = "log2_rmse"
    headline_better = "lower"
    scenes = SCENES

    def jobs(self, quality: str) -> list[Job]:
        out = []
        for fam in self.scenes:
            for s in C.family_scenes(fam):
                p = (("draft", True),) if quality == "draft" else ()
                out += [Job(self.name, s.name, c, p) for c in self.conditions]
        return out

    def run_job(self, job: Job, gts: dict, *, seed: int = 0) -> JobResult:
        gt = gts[job.scene]
        rad = np.maximum(np.asarray(gt["radiance"], np.float64), 0.0)
        mask = np.all(rad > 0, axis=-1)
        cam, times = camera_setup(job.condition, rad[mask])
        cap_seed = int(C.job_rng(job, seed).integers(0, 2 ** 31 - 1))
        br = cam.capture(rad, times, seed=cap_seed)
        book = C.ScoreBook(job, C.scene_hash(gt))
        res = JobResult(job)
        res.images["linear:truth (radiance)"] = C.display(rad)
        k_mid = len(times) // 2
        res.images[f"input: exposure {k_mid + 1} of {len(times)}"] = C.display(br.images[k_mid].astype(float) / (br.levels - 1))
        levels = np.arange(br.levels)
        curves = {"true": np.log2(np.maximum(br.true_inverse[:, 1], 1e-12))}
        responses = {}
        for alg in self.algorithms:
            with C.Timer() as t:
                if alg in CALIBRATIONS:
                    opts = dict(DRAFT_OPTIONS.get(alg, {})) if job.param("draft") else {}
                    if alg == "debevec1997":
                        opts["seed"] = seed
                    resp = CALIBRATIONS[alg](br.images, br.exposure_times, **opts)
                elif alg == IGNORE:
                    resp = linear_response(br.levels, rad.shape[-1])
                else:
                    resp = true_response(br.true_inverse)
                tt = resp.exposure_times if resp.exposure_times is not None else br.exposure_times
                est = merge_hdr(br.images, tt, resp)
            responses[alg] = resp
            sc = hdr_scores(est, rad, mask=mask)
            if alg != TRUE:
                sc["response_rmse"] = response_rmse(resp.inverse, br.true_inverse)
                curves[alg] = np.log2(np.maximum(resp.inverse[:, min(1, resp.inverse.shape[1] - 1)], 1e-12))
            book.add_all(alg, sc, t.seconds, DIRECTIONS)
            if alg in ("debevec1997", IGNORE):
                res.images[f"linear:merged: {alg}"] = C.display(est / np.exp(np.mean(np.log(est[mask] / rad[mask]))))
                with np.errstate(divide="ignore", invalid="ignore"):
                    lr = np.log2(C.grey(est) / C.grey(rad))
                lr = np.where(mask, lr - np.nanmedian(lr[mask]), np.nan)
                res.error_maps[f"log2 radiance error (stops): {alg}"] = C.display_map(lr)
        res.plots["inverse response (green channel)"] = C.profile_plot(
            levels, curves, "pixel level", "log2 relative exposure f^-1(z)",
            note="gauge: f^-1(top level) = 1 for every curve")
        res.scores = book.scores
        return res


TASK = HDRTask()
