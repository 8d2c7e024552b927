"""What every proof shares: the record of one check, the ground truth of a validation scene, and
quiet Mitsuba logging while the checks run."""

from __future__ import annotations

from pbrbench.quality import Quality
from pbrbench.scene.spec import SceneSpec

Record = dict


def record(check: str, measured: float, bound: float, detail: str = "", *, passed: bool | None = None) -> Record:
    ok = bool(measured <= bound) if passed is None else bool(passed)
    return {"check": check, "measured": float(measured), "bound": float(bound), "passed": ok, "detail": detail}


def ground_truth_of(spec: SceneSpec, quality: Quality, cache):
    from pbrbench.render.cache import ground_truth

    gt, _ = ground_truth(spec, quality, cache=cache)
    return gt


def quiet_mitsuba():
    """Silence Mitsuba's warnings (e.g. multijitter rounding a sample count) during validation."""
    try:
        from pbrbench.render.variant import mitsuba

        mi = mitsuba()
        mi.set_log_level(mi.LogLevel.Error)
    except Exception:  # pragma: no cover - validation still runs with warnings
        pass
