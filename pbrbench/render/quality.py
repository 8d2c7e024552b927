"""Quality presets: how a scene's nominal resolution and samples per pixel are scaled.

A scene file states its ``standard`` settings.  ``draft`` (CI: seconds per scene) divides the
resolution by 4 (at least 32 px) and the samples by 16 (at least 4); ``high`` keeps the
resolution and multiplies the samples by 4.  Every ground truth records its preset.
"""

from __future__ import annotations

from dataclasses import dataclass

from pbrbench.errors import UserError


@dataclass(frozen=True)
class Quality:
    name: str
    res_scale: float
    spp_scale: float
    min_res: int = 32
    min_spp: int = 4

    def resolution(self, res: tuple[int, int]) -> tuple[int, int]:
        w, h = res
        if self.res_scale == 1:
            return w, h
        s = max(self.res_scale, self.min_res / min(w, h))
        return max(4, round(w * s)), max(4, round(h * s))

    def spp(self, spp: int) -> int:
        return max(min(self.min_spp, spp), round(spp * self.spp_scale))


PRESETS = {
    "draft": Quality("draft", 0.25, 1 / 16),
    "standard": Quality("standard", 1.0, 1.0),
    "high": Quality("high", 1.0, 4.0),
}


def get_quality(name: str) -> Quality:
    try:
        return PRESETS[name]
    except KeyError:
        raise UserError(f"--quality {name!r} is not known; choose one of {', '.join(PRESETS)}") from None
