"""A simulated digital camera that turns linear radiance into an exposure bracket.

The forward model (docs/science.md §4), per pixel, channel ``c`` and exposure ``k``::

    x      = gain * L * t_k'                       (normalised sensor exposure; x = 1 clips)
    x      <- Poisson(x * full_well) / full_well   (shot noise, only when ``full_well`` is set)
    x      <- x + N(0, read_noise**2)              (read noise, in units of full scale)
    y      = f_c(clip(x, 0, 1))                    (camera response, f(0) = 0, f(1) = 1)
    Z      = round(y * (2**bit_depth - 1))         (quantisation to unsigned integers)

``t_k'`` is the true exposure time: the stated time ``t_k`` times ``exp(N(0, exposure_error**2))``
(small shutter errors, the case Mitsunaga & Nayar's ratio re-estimation is designed for).
The true inverse response, tabulated at every pixel level, is
``true_inverse[z, c] = f_c^{-1}(z / (2**bit_depth - 1))``: it maps a level to normalised sensor
exposure, with ``true_inverse[-1, c] == 1`` (the clipping point) for every channel.

Response curves (:func:`response_curve`): ``"linear"``, ``"gamma"`` (``x ** (1/gamma)``, 2.2 by
default), ``"film"`` (an S-shaped Naka–Rushton curve, film-like in log exposure),
``"polynomial"`` (the inverse is a polynomial, the model of Mitsunaga & Nayar 1999) and
``"random"`` (a seeded generator of plausible monotone curves).

Pure NumPy; every random draw comes from ``numpy.random.default_rng(seed)``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "Bracket",
    "Camera",
    "RESPONSE_NAMES",
    "ResponseCurve",
    "bracket_exposure_times",
    "response_curve",
]

RESPONSE_NAMES = ("linear", "gamma", "film", "polynomial", "random")
BIT_DEPTHS = (8, 10, 12, 14, 16)

_TABLE_SIZE = 1 << 16  # samples of tabulated (numerically inverted) curves


@dataclass(frozen=True)
class ResponseCurve:
    """A monotone camera response ``y = f(x)`` on ``[0, 1]`` with ``f(0) = 0`` and ``f(1) = 1``.

    ``forward`` maps normalised sensor exposure to normalised pixel value, ``inverse`` the other
    way; both accept arrays and are strictly increasing.
    """

    name: str
    forward: Callable[[np.ndarray], np.ndarray] = field(repr=False)
    inverse: Callable[[np.ndarray], np.ndarray] = field(repr=False)


def _tabulated(name: str, inv: Callable[[np.ndarray], np.ndarray]) -> ResponseCurve:
    """A curve defined by its inverse; the forward map is the inverse table read backwards."""
    ys = np.linspace(0.0, 1.0, _TABLE_SIZE + 1)
    xs = inv(ys)
    xs[0], xs[-1] = 0.0, 1.0
    if not np.all(np.diff(xs) > 0):
        raise ValueError(f"response {name!r}: the inverse is not strictly increasing; choose other parameters")

    def forward(x):
        return np.interp(x, xs, ys)

    return ResponseCurve(name, forward, inv)


def response_curve(name: str = "gamma", *, gamma: float = 2.2, contrast: float = 1.6,
                   knee: float = 0.3, coefficients: Sequence[float] = (0.0, 0.3, 0.5, 0.2),
                   seed: int | None = 0) -> ResponseCurve:
    """Build a named camera response curve.

    Parameters
    ----------
    name : {"linear", "gamma", "film", "polynomial", "random"}
        ``linear``: ``y = x``. ``gamma``: ``y = x**(1/gamma)``. ``film``: the S-shaped curve
        ``y = x**p (1 + k**p) / (x**p + k**p)`` with ``p = contrast`` and ``k = knee``.
        ``polynomial``: ``x = f^{-1}(y) = sum_n c_n y**n`` with ``c = coefficients``
        (must satisfy ``sum c_n = 1``, ``c_0 = 0`` and be increasing on [0, 1]).
        ``random``: ``f^{-1}(y) = H(y)**g`` with ``g`` drawn in [1.5, 2.8] and ``H`` a smooth
        random monotone warp of [0, 1] (slope ``exp`` of a random low-frequency series), seeded.
    gamma, contrast, knee, coefficients, seed
        Parameters of the curves above (``seed`` only for ``random``).

    Returns
    -------
    ResponseCurve
    """
    if name == "linear":
        return ResponseCurve("linear", lambda x: np.asarray(x, dtype=float) * 1.0,
                             lambda y: np.asarray(y, dtype=float) * 1.0)
    if name == "gamma":
        g = float(gamma)
        if not np.isfinite(g) or g <= 0:
            raise ValueError(f"gamma: must be a finite number > 0, got {gamma!r}")
        return ResponseCurve(f"gamma{g:g}", lambda x: np.power(np.asarray(x, dtype=float), 1.0 / g),
                             lambda y: np.power(np.asarray(y, dtype=float), g))
    if name == "film":
        p, k = float(contrast), float(knee)
        if not (p > 0 and k > 0 and np.isfinite(p) and np.isfinite(k)):
            raise ValueError(f"contrast, knee: must be finite and > 0, got {contrast!r}, {knee!r}")
        a = 1.0 + k**p

        def fwd(x):
            xp = np.power(np.asarray(x, dtype=float), p)
            return a * xp / (xp + k**p)

        def inv(y):
            y = np.asarray(y, dtype=float)
            return k * np.power(y / np.maximum(a - y, 1e-300), 1.0 / p)

        return ResponseCurve("film", fwd, inv)
    if name == "polynomial":
        c = np.asarray(coefficients, dtype=float)
        if c.ndim != 1 or c.size < 2 or not np.all(np.isfinite(c)):
            raise ValueError("coefficients: pass a 1-D sequence of at least 2 finite numbers")
        if abs(c.sum() - 1.0) > 1e-9 or abs(c[0]) > 1e-12:
            raise ValueError(f"coefficients: need c[0] = 0 and sum(c) = 1 so that f(0)=0, f(1)=1; got {c.tolist()}")

        def pinv(y):
            return np.polynomial.polynomial.polyval(np.asarray(y, dtype=float), c)

        return _tabulated("polynomial", pinv)
    if name == "random":
        rng = np.random.default_rng(seed)
        g = rng.uniform(1.5, 2.8)
        n_terms = 5
        amp = rng.normal(0.0, 0.35, n_terms) / np.arange(1, n_terms + 1)
        phase = rng.uniform(0, 2 * np.pi, n_terms)
        grid = np.linspace(0.0, 1.0, 4097)
        slope = np.exp(sum(a * np.sin(np.pi * (i + 1) * grid + ph) for i, (a, ph) in enumerate(zip(amp, phase, strict=True))))
        warp = np.concatenate([[0.0], np.cumsum(0.5 * (slope[1:] + slope[:-1]) * np.diff(grid))])
        warp /= warp[-1]

        def rinv(y):
            return np.power(np.interp(np.asarray(y, dtype=float), grid, warp), g)

        return _tabulated(f"random(seed={seed})", rinv)
    raise ValueError(f"name={name!r} is not known; choose one of {', '.join(repr(n) for n in RESPONSE_NAMES)}")


@dataclass(frozen=True)
class Bracket:
    """An exposure bracket produced by :meth:`Camera.capture`.

    Attributes
    ----------
    images : ndarray, (K, H, W, C), uint8 (8-bit) or uint16
        Pixel levels, sorted by increasing exposure time.
    exposure_times : ndarray, (K,)
        Stated exposure times in seconds (what a user would pass to calibration).
    true_exposure_times : ndarray, (K,)
        The times actually used (differ from ``exposure_times`` when ``exposure_error > 0``).
    true_inverse : ndarray, (levels, C)
        ``f_c^{-1}(z / (levels - 1))``: level -> normalised sensor exposure, 1 at the top level.
    saturated : ndarray, (H, W, C), bool
        Pixels whose noise-free sensor exposure clips even in the shortest exposure.
    bit_depth, gain : int, float
        Camera settings: radiance ``L`` gives sensor exposure ``gain * L * t``.
    """

    images: np.ndarray
    exposure_times: np.ndarray
    true_exposure_times: np.ndarray
    true_inverse: np.ndarray
    saturated: np.ndarray
    bit_depth: int
    gain: float

    @property
    def levels(self) -> int:
        return 1 << self.bit_depth


class Camera:
    """A simulated camera: response curve, shot and read noise, quantisation, clipping.

    Parameters
    ----------
    response : str, ResponseCurve or sequence of them
        One curve for all channels, or one per channel (a name is passed to
        :func:`response_curve`; ``"random"`` draws a different curve per channel from ``seed``).
    bit_depth : {8, 10, 12, 14, 16}
    gain : float
        Sensor exposure per unit radiance-second; ``gain * L * t = 1`` is the clipping point.
    full_well : float or None
        Electrons at the clipping point. When set, shot noise ``Poisson(x * full_well) /
        full_well`` is applied; ``None`` means no shot noise.
    read_noise : float
        Standard deviation of Gaussian read noise, as a fraction of full scale (sensor domain).
    exposure_error : float
        Standard deviation of the log of (true time / stated time), e.g. 0.05 for ~5 %.
    seed : int
        Seed for the ``"random"`` response curves.
    """

    def __init__(self, response="gamma", *, bit_depth: int = 8, gain: float = 1.0,
                 full_well: float | None = None, read_noise: float = 0.0,
                 exposure_error: float = 0.0, seed: int = 0):
        if bit_depth not in BIT_DEPTHS:
            raise ValueError(f"bit_depth={bit_depth!r} is not supported; choose one of {BIT_DEPTHS}")
        for nm, v in (("gain", gain),):
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{nm}: must be a finite number > 0, got {v!r}")
        if full_well is not None and not (np.isfinite(full_well) and full_well > 0):
            raise ValueError(f"full_well: must be None (no shot noise) or a finite number > 0, got {full_well!r}")
        for nm, v in (("read_noise", read_noise), ("exposure_error", exposure_error)):
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"{nm}: must be a finite number >= 0, got {v!r}")
        self.bit_depth = int(bit_depth)
        self.gain = float(gain)
        self.full_well = None if full_well is None else float(full_well)
        self.read_noise = float(read_noise)
        self.exposure_error = float(exposure_error)
        self.seed = seed
        self._response = response

    @property
    def levels(self) -> int:
        return 1 << self.bit_depth

    def curves(self, channels: int) -> list[ResponseCurve]:
        """The response curve of each of ``channels`` channels."""
        r = self._response
        if isinstance(r, ResponseCurve):
            return [r] * channels
        if isinstance(r, str):
            if r == "random":
                return [response_curve("random", seed=(self.seed, c)) for c in range(channels)]
            return [response_curve(r)] * channels
        curves = [response_curve(x) if isinstance(x, str) else x for x in r]
        if len(curves) != channels or not all(isinstance(x, ResponseCurve) for x in curves):
            raise ValueError(f"response: got {len(curves)} curves for {channels} channels; pass one per channel")
        return curves

    def true_inverse(self, channels: int) -> np.ndarray:
        """``(levels, channels)`` table of ``f_c^{-1}(z / (levels - 1))``."""
        y = np.arange(self.levels) / (self.levels - 1)
        inv = np.stack([np.asarray(c.inverse(y), dtype=float) for c in self.curves(channels)], axis=1)
        inv[0], inv[-1] = 0.0, 1.0
        return inv

    def capture(self, radiance, exposure_times, *, seed: int = 0) -> Bracket:
        """Expose ``radiance`` (H, W[, C]) linear, >= 0, for each of ``exposure_times`` seconds.

        Returns a :class:`Bracket`; images are sorted by increasing time.
        """
        L = np.asarray(radiance, dtype=np.float64)
        if L.ndim == 2:
            L = L[..., None]
        if L.ndim != 3:
            raise ValueError(f"radiance: expected shape (H, W) or (H, W, C), got {L.shape}")
        if not np.all(np.isfinite(L)) or np.any(L < 0):
            raise ValueError("radiance: must be finite and >= 0; clip negatives (np.maximum(L, 0))")
        t = np.asarray(exposure_times, dtype=np.float64).ravel()
        if t.size < 1 or not np.all(np.isfinite(t)) or np.any(t <= 0):
            raise ValueError("exposure_times: pass at least one finite time > 0 (seconds)")
        t = np.sort(t)
        rng = np.random.default_rng(seed)
        t_true = t * np.exp(rng.normal(0.0, self.exposure_error, t.size)) if self.exposure_error > 0 else t.copy()
        C = L.shape[2]
        curves = self.curves(C)
        top = self.levels - 1
        dtype = np.uint8 if self.bit_depth == 8 else np.uint16
        out = np.empty((t.size,) + L.shape, dtype=dtype)
        for k, tk in enumerate(t_true):
            x = (self.gain * tk) * L
            if self.full_well is not None:
                x = rng.poisson(np.minimum(x, 4.0) * self.full_well) / self.full_well
            if self.read_noise > 0:
                x = x + rng.normal(0.0, self.read_noise, x.shape)
            np.clip(x, 0.0, 1.0, out=x)
            for c, curve in enumerate(curves):
                out[k, ..., c] = np.rint(np.clip(curve.forward(x[..., c]), 0.0, 1.0) * top).astype(dtype)
        saturated = self.gain * t_true[0] * L >= 1.0
        return Bracket(out, t, t_true, self.true_inverse(C), saturated, self.bit_depth, self.gain)


def bracket_exposure_times(radiance, *, stops: float = 1.0, count: int | None = None,
                           gain: float = 1.0, headroom: float = 0.8, dark_target: float = 0.25,
                           dark_percentile: float = 0.0, bright_percentile: float = 100.0,
                           bright: float | None = None) -> np.ndarray:
    """Exposure times (ascending) whose bracket covers the range of a radiance image.

    The shortest time maps the bright end (``bright_percentile`` of the positive radiance, or
    ``bright`` when given: a radiance known without noise, such as a visible emitter's) to
    sensor exposure ``headroom`` (below clipping); the longest maps the dark end
    (``dark_percentile``) to ``dark_target``. Times are ``stops`` apart; ``count`` forces the
    number of exposures (starting from the shortest) instead of covering the dark end.
    """
    L = np.asarray(radiance, dtype=np.float64)
    pos = L[np.isfinite(L) & (L > 0)]
    if pos.size == 0:
        raise ValueError("radiance: no finite positive value; cannot choose exposure times")
    if not stops > 0:
        raise ValueError(f"stops: must be > 0, got {stops!r}")
    if bright is not None and not (np.isfinite(bright) and bright > 0):
        raise ValueError(f"bright: must be a positive radiance, got {bright!r}")
    hi = float(bright) if bright is not None else np.percentile(pos, bright_percentile)
    lo = np.percentile(pos, dark_percentile)
    t_short = headroom / (gain * hi)
    if count is None:
        t_long = dark_target / (gain * lo)
        count = max(1, int(np.ceil(np.log2(max(t_long / t_short, 1.0)) / stops - 1e-9)) + 1)
    if int(count) < 1:
        raise ValueError(f"count: must be >= 1, got {count!r}")
    return t_short * 2.0 ** (stops * np.arange(int(count)))
