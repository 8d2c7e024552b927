"""Quality profiles: everything that differs between a draft, a standard and a high run.

A scene file states its ``standard`` render settings.  A profile scales them and says how much
of the benchmark to run:

* ``res_scale`` / ``spp_scale`` (with floors ``min_res``, ``min_spp``): render resolution and
  samples per pixel;
* ``short_subset``: tasks use their short, representative lists of scene families
  (:meth:`Quality.pick`) instead of all of them;
* ``sweep_keep``: how many values of each swept family to keep (first and last included,
  evenly spaced; ``None`` keeps the whole sweep);
* per-algorithm budgets (fewer iterations at draft) are not here: each registry entry carries
  its own (:attr:`pbrbench.registry.Algorithm.budgets`, by profile name);
* ``noise_target`` / ``max_spp_factor``: the relative noise (median, RMS over the lit pure
  pixels) every rendered pass should reach; a pass rendered at the scene's samples per pixel that
  is noisier gets the missing samples, up to ``max_spp_factor`` times the scene's count
  (:meth:`pbrbench.render.groundtruth._Renderer.render_groups`); the achieved noise and samples are
  recorded with the ground truth;
* ``groups``: every pass is rendered as this many independent sample groups (``spp / groups``
  samples each, seeds of their own), so every score gets a delete-one-group jackknife standard
  error with ``groups - 1`` degrees of freedom and a Monte Carlo bias estimate
  (:mod:`pbrbench.bench.uncertainty`); a scene file may ask for more (``render.min_groups``,
  :meth:`Quality.groups_for`).

``draft`` is the CI setting (seconds per scene), ``standard`` the benchmark, ``high`` four times the
samples.  Every ground truth and every run records its profile's name.  No code compares a
profile's name: it asks the profile.
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
    short_subset: bool = False
    sweep_keep: int | None = None
    description: str = ""
    noise_target: tuple[float, float] | None = None   # (median, rms) relative sd of every rendered pass
    max_spp_factor: float = 1.0                         # at most this many times the scene's spp
    groups: int = 4                                     # independent sample groups per pass (jackknife)

    def resolution(self, res: tuple[int, int], floor: int | None = None) -> tuple[int, int]:
        """The rendered ``(width, height)`` of a scene whose file asks for ``res``: scaled by
        ``res_scale``, the smaller side at least ``min_res`` and at least ``floor`` (the scene's
        ``render.min_resolution``, when it sets one)."""
        w, h = res
        if self.res_scale == 1:
            return w, h
        s = max(self.res_scale, max(self.min_res, floor or 0) / min(w, h))
        return max(4, round(w * s)), max(4, round(h * s))

    def groups_for(self, floor: int | None = None) -> int:
        """The number of independent sample groups of a scene whose file asks for at least
        ``floor`` (``render.min_groups``): the larger of the two."""
        return max(self.groups, floor or 0)

    def spp(self, spp: int, groups: int | None = None) -> int:
        """Samples per pixel of a pass whose scene file asks for ``spp``, rendered as ``groups``
        sample groups (default :attr:`groups`): scaled, at least ``min_spp``, and at least two
        per sample group (a group of one sample per pixel loses the sampler's stratification
        inside the pixel: on a draft sphere, 4 groups of 1 sample doubled photometric stereo's
        normal error against 2 groups of 2), never more than the file asks."""
        n = max(min(self.min_spp, spp), round(spp * self.spp_scale))
        return max(n, min(spp, 2 * (groups or self.groups)))

    def render_key(self) -> dict:
        """What of this profile decides a render's content (part of the render cache's key)."""
        return {"name": self.name, "res_scale": self.res_scale, "spp_scale": self.spp_scale,
                "min_res": self.min_res, "min_spp": self.min_spp,
                "noise_target": list(self.noise_target) if self.noise_target else None,
                "max_spp_factor": self.max_spp_factor, "groups": self.groups}

    def pick(self, full, short) -> tuple:
        """``short`` (a task's representative subset) when this profile runs short subsets and
        ``short`` is not empty, else ``full``."""
        return tuple(short) if self.short_subset and short else tuple(full)

    def keep(self, values: list, extra: int = 0) -> list:
        """``sweep_keep + extra`` values spread evenly over ``values`` (all when no limit)."""
        if self.sweep_keep is None:
            return list(values)
        return subsample(values, self.sweep_keep + extra)

    def __reduce__(self):  # MappingProxyType does not pickle
        return (_rebuild, (self.name,))


def subsample(values: list, keep: int) -> list:
    """``keep`` items spread evenly over ``values`` (first and last included), order kept."""
    n = len(values)
    if keep >= n:
        return list(values)
    if keep <= 1:
        return [values[n // 2]]
    idx = sorted({round(i * (n - 1) / (keep - 1)) for i in range(keep)})
    return [values[i] for i in idx]


PRESETS: dict[str, Quality] = {
    "draft": Quality(
        "draft", 0.25, 1 / 16, short_subset=True, sweep_keep=2,
        # the regression run must stay short (every job is also scored on its delete-one-group
        # replicates): the algorithms' draft budgets are on their registry entries (Algorithm.budgets)
        description="CI: resolution / 4 (at least 32 px), spp / 16, short scene lists, two values per sweep"),
    "standard": Quality("standard", 1.0, 1.0, noise_target=(0.01, 0.03), max_spp_factor=2.0,
                        description="the benchmark: the scene files' resolution and samples, up to 2x the samples "
                                    "where a pass is noisier than 1 % median / 3 % rms"),
    "high": Quality("high", 1.0, 4.0, noise_target=(0.005, 0.015), max_spp_factor=4.0,
                    description="standard resolution, 4x the samples, up to 16x where a pass is noisier than 0.5 % / 1.5 %"),
}


DRAFT, STANDARD, HIGH = PRESETS["draft"], PRESETS["standard"], PRESETS["high"]


def require(quality) -> Quality:
    """``quality`` itself when it is a :class:`Quality`; a ``TypeError`` otherwise.

    Below the command line and the API entry points every function is handed the profile
    object: a name is resolved once, where it enters (:func:`get_quality`), never looked up again.
    """
    if not isinstance(quality, Quality):
        raise TypeError(f"quality: expected a pbrbench.quality.Quality, got {quality!r}; resolve a name once "
                        "with pbrbench.quality.get_quality(name)")
    return quality


def _rebuild(name: str) -> Quality:
    return PRESETS[name]


def get_quality(name) -> Quality:
    """The profile named ``name`` (a :class:`Quality` passes through)."""
    if isinstance(name, Quality):
        return name
    try:
        return PRESETS[name]
    except (KeyError, TypeError):
        raise UserError(f"--quality {name!r} is not known; choose one of {', '.join(PRESETS)}") from None


def names() -> list[str]:
    """Profile names, for command-line choices."""
    return list(PRESETS)
