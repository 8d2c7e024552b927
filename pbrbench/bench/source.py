"""Where a run's ground truths come from: the render cache, rendering what is missing.

A :class:`GroundTruthSource` is given its :class:`~pbrbench.render.cache.RenderCache` (injected,
so tests substitute their own or a subclass that synthesises ground truths) and keeps the last
few ground truths it loaded in memory, per instance.  It is picklable: Dask ships it to workers,
where the worker plugin keeps one instance per source identity so consecutive jobs on a worker
share its memory cache (:mod:`pbrbench.bench.executors`).

Mitsuba must not be driven from two Python threads at once (a Dask worker may run tasks on
several threads): :data:`RENDER_LOCK` serialises every render and job of a process.
"""

from __future__ import annotations

import threading
from collections import OrderedDict

from pbrbench.errors import UserError

RENDER_LOCK = threading.RLock()


class GroundTruthSource:
    """Ground truths of ``quality`` from ``cache`` (rendered with ``variant`` when missing)."""

    memory_size = 4     # ground truths kept in memory (consecutive jobs share a scene)

    def __init__(self, quality, cache, variant: str | None = None, *, library=None, render_seed: int = 0):
        from pbrbench.quality import require
        from pbrbench.scene.load import SceneLibrary

        self.quality = require(quality)
        if cache is None:
            raise TypeError("cache: None is not a render cache; pass a pbrbench.render.cache.RenderCache "
                            "(RenderCache(Settings.from_env().cache) for pbrbench's own)")
        self.cache = cache
        self.variant = variant
        self.library = library if library is not None else SceneLibrary()   # where the scenes are found
        self.render_seed = int(render_seed)  # added to every scene's render.seed (independent renders)
        self._memory: OrderedDict = OrderedDict()

    # ------------------------------------------------------------------ pickling
    def __getstate__(self):
        d = dict(self.__dict__)
        d["_memory"] = OrderedDict()  # never ship arrays
        return d

    def identity(self) -> str:
        return f"{type(self).__name__}:{self.cache.root}:{self.quality.name}:{self.variant}:{self.render_seed}"

    # ------------------------------------------------------------------ variant and specs
    def resolve_variant(self) -> str:
        """The variant the renders use (decided without importing mitsuba)."""
        from pbrbench.render.variant import choose_variant, current_choice

        if self.variant is None:
            choice = current_choice() or choose_variant(None)
            self.variant = choice.variant
        return self.variant

    def specs(self, names: list[str]) -> dict:
        """Scene name -> SceneSpec for every name (library names, sweep members, families of one)."""
        lib = self.library.all()
        out = {}
        for n in names:
            if n in lib:
                out[n] = lib[n]
                continue
            got = self.library.resolve([n])
            if len(got) != 1:
                raise UserError(f"scene {n!r} names a family of {len(got)} scenes; a job needs one scene")
            out[n] = got[0]
        return {n: reseeded(s, self.render_seed) for n, s in out.items()}

    def gt_key(self, spec) -> str:
        """The render-cache key of ``spec``'s ground truth (what identifies its content)."""
        from pbrbench.render.cache import cache_key

        return cache_key(spec, self.quality, self.resolve_variant())

    # ------------------------------------------------------------------ ground truths
    def cached_meta(self, spec) -> dict | None:
        """The cached ground truth's metadata, or None if it has to be rendered (no render here)."""
        return self.cache.meta(self.gt_key(spec))

    def render(self, spec) -> tuple[dict, bool]:
        """Render ``spec`` into the cache if missing; returns (metadata, from_cache)."""
        gt, cached = self._fetch(spec)
        self._remember(spec, gt)
        return dict(gt.meta), cached

    def load(self, spec):
        """The ground truth of ``spec`` (memory, else the cache, else rendered)."""
        key = spec.content_hash()
        if key in self._memory:
            self._memory.move_to_end(key)
            return self._memory[key]
        gt, _ = self._fetch(spec)
        self._remember(spec, gt)
        return gt

    def _fetch(self, spec):
        from pbrbench.render.cache import ground_truth

        with RENDER_LOCK:
            return ground_truth(spec, self.quality, cache=self.cache, variant=self.resolve_variant())

    def _remember(self, spec, gt):
        key = spec.content_hash()
        self._memory[key] = gt
        self._memory.move_to_end(key)
        while len(self._memory) > self.memory_size:
            self._memory.popitem(last=False)


def reseeded(spec, offset: int):
    """``spec`` with ``render.seed`` increased by ``offset`` (an independent render of the same
    scene; its content hash changes with the seed, so the render cache keeps both)."""
    if not offset:
        return spec
    from pbrbench.scene.spec import MAX_SEED

    seed = (spec.render.seed + int(offset)) % (MAX_SEED + 1)
    return spec.model_copy(update={"render": spec.render.model_copy(update={"seed": seed})})
