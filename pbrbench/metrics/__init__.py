"""Scores: each function compares an estimate with the ground truth.

One module per area (``hdr``, ``lightness``, ``specular``, ``normals``, ``sfs``, ``interreflection``); the public
functions are re-exported here, so ``from pbrbench.metrics import lmse`` works.  Each module's
``METRICS`` table gives every score name its direction ("lower" / "higher" is better), unit and
meaning; :data:`METRICS` merges them and :func:`metric` looks one up (``docs/adding.md`` says how
to add one: a function plus one row).
"""

from pbrbench.metrics.hdr import (
    hdr_scores,
    invalid_fraction,
    log_radiance_rmse,
    log_radiance_rmse_extremes,
    response_rmse,
)
from pbrbench.metrics.interreflection import chromaticity_error, delta_e2000, radiosity_scores
from pbrbench.metrics.lightness import (
    albedo_abs_error,
    intrinsic_lmse,
    lmse,
    lmse_map,
    ratio_errors,
    si_mse,
)
from pbrbench.metrics.normals import (
    albedo_relative_error,
    angular_error_map,
    angular_error_stats,
    height_rmse,
    height_rmse_scaled,
)
from pbrbench.metrics.ps_checks import check_error_correlation, check_maps, check_scores
from pbrbench.metrics.sfs import (
    ambiguity_aware_scores,
    flat_baseline,
    floor_height,
    floor_scores,
    height_errors,
    normal_angle,
    sfs_scores,
)
from pbrbench.metrics.specular import (
    mask_iou,
    removal_errors,
    specular_mask_from_twin,
    specular_scores,
)
from pbrbench.metrics.table import STATUS, Metric, merge


def _tables():
    from pbrbench.metrics import hdr, interreflection, lightness, normals, ps_checks, sfs, specular

    return merge(STATUS, normals.METRICS, sfs.METRICS, lightness.METRICS, hdr.METRICS, specular.METRICS,
                 interreflection.METRICS, ps_checks.METRICS)


METRICS: dict[str, Metric] = _tables()


def metric(name: str) -> Metric:
    """The table row of metric ``name``; ``ValueError`` when no metrics module lists it."""
    try:
        return METRICS[name]
    except KeyError:
        raise ValueError(f"metric {name!r} is in no metrics table; add a row to the METRICS table of its "
                         "pbrbench/metrics/<area>.py module (direction, unit, meaning)") from None

__all__ = [
    "METRICS", "Metric", "metric", "specular_scores",
    "albedo_abs_error", "albedo_relative_error", "ambiguity_aware_scores", "angular_error_map",
    "angular_error_stats", "check_error_correlation", "check_maps", "check_scores", "chromaticity_error", "delta_e2000", "flat_baseline", "floor_height", "floor_scores", "hdr_scores",
    "height_errors", "height_rmse", "height_rmse_scaled", "intrinsic_lmse", "invalid_fraction",
    "lmse", "lmse_map", "log_radiance_rmse", "log_radiance_rmse_extremes", "mask_iou",
    "normal_angle", "radiosity_scores", "ratio_errors", "removal_errors", "response_rmse", "sfs_scores", "si_mse",
    "specular_mask_from_twin",
]
