"""Mitsunaga-Nayar on short brackets: the merged log2 RMSE over the true-response floor per
polynomial order, beside the default calibrations (docs/peers.md, HDR).

Synthetic 256 x 256 radiance of ``pbrbench perf hdr`` seen by 8-bit cameras (film, random and
gamma responses, with and without read + shot noise), 3 exposures 3 stops apart and 7 exposures
1 stop apart, capture seed 11.  Each order is fitted with the stated exposure ratios; the last
columns are ``calibrate_mitsunaga1999`` as the benchmark calls it (its order rule),
debevec1997 and robertson2003.  Fetches nothing.

    python scripts/mn_orders.py [--size 256] [--orders 2-10]
"""

from __future__ import annotations

import argparse

import numpy as np

from pbrbench.camera import Camera, bracket_exposure_times
from pbrbench.infer import hdr
from pbrbench.infer.hdr.mitsunaga1999 import calibrate_mitsunaga1999
from pbrbench.metrics.hdr import hdr_scores
from pbrbench.perf.hdr import synthetic_radiance, true_response


def _ratio(br, radiance, resp, floor):
    times = resp.exposure_times if resp.exposure_times is not None else br.exposure_times
    merged = np.asarray(hdr.merge_hdr(br.images, times, resp), float)
    return hdr_scores(merged, radiance, mask=~br.saturated)["log2_rmse"] / floor


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--orders", default="2-10", help="first-last polynomial order (default 2-10)")
    a = ap.parse_args(argv)
    lo, hi = (int(x) for x in a.orders.split("-"))
    orders = range(lo, hi + 1)
    radiance = synthetic_radiance(a.size)
    noise = dict(read_noise=0.002, full_well=1e4)
    cameras = (("film", Camera("film", bit_depth=8)), ("film rs", Camera("film", bit_depth=8, **noise)),
               ("random", Camera("random", bit_depth=8, seed=3)),
               ("random rs", Camera("random", bit_depth=8, seed=3, **noise)), ("gamma", Camera("gamma", bit_depth=8)))
    print("bracket    camera    " + " ".join(f"{'N=' + str(n):>6s}" for n in orders) + "   rule debevec robertson")
    for stops, count in ((3.0, 3), (1.0, 7)):
        times = bracket_exposure_times(radiance, stops=stops, count=count, headroom=0.9)
        for name, cam in cameras:
            br = cam.capture(radiance, times, seed=11)
            floor = hdr_scores(np.asarray(hdr.merge_hdr(br.images, br.exposure_times, true_response(br)), float),
                               radiance, mask=~br.saturated)["log2_rmse"]
            per_order = [_ratio(br, radiance, calibrate_mitsunaga1999(br.images, br.exposure_times, degree=n,
                                                                     estimate_ratios=False), floor) for n in orders]
            rest = [_ratio(br, radiance, hdr.CALIBRATION_METHODS[m](br.images, br.exposure_times), floor)
                    for m in ("mitsunaga1999", "debevec1997", "robertson2003")]
            print(f"{count}x{stops:.0f} stops  {name:9s} " + " ".join(f"{v:6.2f}" for v in per_order)
                  + f"  {rest[0]:5.2f} {rest[1]:7.2f} {rest[2]:9.2f}", flush=True)


if __name__ == "__main__":
    main()
