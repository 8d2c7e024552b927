"""Scene files: a TOML description validated into an immutable, hashable :class:`SceneSpec`.

Conventions (docs/conventions.md): world frame with the default camera at +z looking at the origin,
x right, y up.  Light ``direction`` vectors point **from the scene toward the source** (the
vision convention); the Mitsuba builder converts them to Mitsuba's direction of travel.
Colours/albedos are a number (grey) or ``[r, g, b]``; all values are linear.

A file may contain a ``[sweep]`` table whose keys are dotted key paths into the file and whose
values are lists (``"materials.paper.albedo" = [0.1, 0.5, 0.9]``): the file then expands into
the Cartesian product of scenes, named ``name[key=value,...]``.
"""

from __future__ import annotations

import hashlib
import inspect
import json
import math
import re
import zlib
from typing import Annotated, Any, Literal

from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    StrictBool,
    field_validator,
    model_validator,
)

SPEC_VERSION = 1

# ------------------------------------------------------------------------------ number ranges
# Every number of a scene is finite and inside a range that float32 rendering handles: positions
# within MAX_COORD of the origin, lengths in [MIN_LENGTH, MAX_LENGTH], powers up to MAX_POWER.
MAX_COORD = 1e6
MIN_LENGTH = 1e-6
MAX_LENGTH = 1e6
MAX_CLIP = 1e7
MAX_POWER = 1e12
MAX_ANGLE = 36000.0           # degrees (100 turns)
MAX_SEED = (1 << 21) - 1      # the renderer derives 32-bit seeds as 2000 * seed + pass offsets
SEED_SPAN = (1 << 18) - (1 << 12)   # a scene without a seed gets one in 1 .. SEED_SPAN (default_seed)
MAX_DEPTH = 1024
MAX_NAME = 200                # characters of a scene name (it is also a file name)
MAX_SURFACE_INT = 1000        # integer parameters of an analytic surface (counts)
MAX_SURFACE_LIST = 64         # items of a list parameter of an analytic surface


class At(ValueError):
    """A ValueError raised for a location below the validated one (e.g. ``params.radius`` of a
    heightfield): the error formatter appends :attr:`sub` to the reported key path."""

    def __init__(self, sub: tuple, msg: str):
        super().__init__(msg)
        self.sub = tuple(sub)


def _range_text(lo, hi, lo_open=False, hi_open=False) -> str:
    return f"{'>' if lo_open else '>='} {lo:g} and {'<' if hi_open else '<='} {hi:g}"


def _real(value, lo: float, hi: float, *, lo_open: bool = False, hi_open: bool = False, what: str = "") -> float:
    """``value`` as a finite float in the range, else ValueError saying the range."""
    rng = _range_text(lo, hi, lo_open, hi_open)
    pre = f"{what}: " if what else ""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        hint = " (a string: remove the quotes)" if isinstance(value, str) else ""
        raise ValueError(f"{pre}must be a number {rng}, got {value!r}{hint}")
    try:
        x = float(value)
    except OverflowError:
        x = math.inf
    if not math.isfinite(x) or (x <= lo if lo_open else x < lo) or (x >= hi if hi_open else x > hi):
        raise ValueError(f"{pre}must be a finite number {rng}, got {value!r}")
    return x


def _number(lo: float, hi: float, *, lo_open: bool = False, hi_open: bool = False):
    return BeforeValidator(lambda v: _real(v, lo, hi, lo_open=lo_open, hi_open=hi_open))


def _integer(lo: int, hi: int, note: str = ""):
    """An integer field: bools, strings and fractional numbers are refused, the range is stated."""
    def check(v):
        if isinstance(v, bool) or not isinstance(v, int):
            if isinstance(v, float) and v.is_integer():
                v = int(v)
            else:
                raise ValueError(f"must be an integer >= {lo} and <= {hi}{note}, got {v!r}")
        if not lo <= v <= hi:
            raise ValueError(f"must be an integer >= {lo} and <= {hi}{note}, got {v!r}")
        return v
    return BeforeValidator(check)


Coord = Annotated[float, _number(-MAX_COORD, MAX_COORD)]
Length = Annotated[float, _number(MIN_LENGTH, MAX_LENGTH)]
Clip = Annotated[float, _number(MIN_LENGTH, MAX_CLIP)]
Angle = Annotated[float, _number(-MAX_ANGLE, MAX_ANGLE)]
Vec3 = tuple[Coord, Coord, Coord]


def _rgb(v) -> tuple[float, float, float]:
    if isinstance(v, bool) or isinstance(v, str) or not isinstance(v, (int, float, list, tuple)):
        raise ValueError(f"expected a number or [r, g, b], got {v!r}")
    if isinstance(v, (int, float)):
        return (v,) * 3
    v = tuple(v)
    if len(v) == 1:
        return v * 3
    if len(v) != 3:
        raise ValueError(f"expected a number or [r, g, b], got {len(v)} values")
    return v


class Model(BaseModel):
    # allow_inf_nan=False: a backstop for any float field without its own range check
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


RGB = Annotated[tuple[float, float, float], Field(description="grey value or [r, g, b]")]


def _nonneg_rgb(v, what, hi: float = MAX_POWER):
    return tuple(_real(c, 0.0, hi) for c in v)


def _unit_rgb(v, what):
    if any(isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c) and c > 1 for c in v):
        raise ValueError(f"{what} must be in [0, 1] (energy conservation), got {list(v)}")
    return _nonneg_rgb(v, what, 1.0)


def _nonzero(v, what):
    if not all(math.isfinite(c) for c in v) or math.sqrt(sum(c * c for c in v)) < 1e-12:
        raise ValueError(f"{what} must be a finite non-zero vector, got {list(v)}")
    return v


def _norm(v) -> float:
    return math.sqrt(sum(c * c for c in v))


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _parallel(a, b) -> bool:
    return _norm(_cross(a, b)) < 1e-9 * max(_norm(a) * _norm(b), 1e-300)


# ----------------------------------------------------------------------------------- textures
class CheckerTexture(Model):
    type: Literal["checker"]
    color0: RGB = (0.2, 0.2, 0.2)
    color1: RGB = (0.8, 0.8, 0.8)
    scale: Annotated[float, _number(0.0, MAX_LENGTH, lo_open=True)] = Field(8.0, description="squares per unit of uv")

    @field_validator("color0", "color1", mode="before")
    @classmethod
    def _c(cls, v):
        return _unit_rgb(_rgb(v), "texture colour")


class MondrianTexture(Model):
    """Piecewise-constant random papers on a grid (seeded)."""

    type: Literal["mondrian"]
    patches: Annotated[int, _integer(1, 64)] = Field(8, description="papers per side")
    resolution: Annotated[int, _integer(8, 4096)] = 256
    seed: Annotated[int, _integer(0, (1 << 63) - 1)] = 0
    low: Annotated[float, _number(0.0, 1.0)] = 0.1
    high: Annotated[float, _number(0.0, 1.0)] = 0.9
    colour: StrictBool = False
    white: StrictBool = Field(False, description="force one paper to albedo `high` in every channel")

    @model_validator(mode="after")
    def _range(self):
        if self.low > self.high:
            raise ValueError(f"low ({self.low}) must not exceed high ({self.high})")
        return self


class ImageTexture(Model):
    """An albedo image: ``.npy`` (H, W) or (H, W, 3) float in [0, 1]; path relative to the scene file."""

    type: Literal["image"]
    path: str = Field(min_length=1)


Texture = Annotated[CheckerTexture | MondrianTexture | ImageTexture, Field(discriminator="type")]


def _albedo(v):
    if isinstance(v, dict):
        return v
    return _unit_rgb(_rgb(v), "albedo")


# ---------------------------------------------------------------------------------- materials
class Diffuse(Model):
    type: Literal["diffuse"]
    albedo: RGB | Texture = (0.5, 0.5, 0.5)

    _c = field_validator("albedo", mode="before")(classmethod(lambda cls, v: _albedo(v)))


class Plastic(Model):
    """Smooth dielectric coating over a diffuse base: sharp highlights."""

    type: Literal["plastic"]
    albedo: RGB | Texture = (0.5, 0.5, 0.5)
    int_ior: Annotated[float, _number(1.0, 3.0, lo_open=True)] = 1.5

    _c = field_validator("albedo", mode="before")(classmethod(lambda cls, v: _albedo(v)))


class RoughPlastic(Model):
    """Rough dielectric coating (GGX) over a diffuse base: glossy highlights."""

    type: Literal["roughplastic"]
    albedo: RGB | Texture = (0.5, 0.5, 0.5)
    alpha: Annotated[float, _number(0.0, 1.0, lo_open=True)] = 0.1
    int_ior: Annotated[float, _number(1.0, 3.0, lo_open=True)] = 1.5

    _c = field_validator("albedo", mode="before")(classmethod(lambda cls, v: _albedo(v)))


Material = Annotated[Diffuse | Plastic | RoughPlastic, Field(discriminator="type")]
GLOSSY = ("plastic", "roughplastic")


# ------------------------------------------------------------------------------------- shapes
class Rotation(Model):
    axis: Vec3
    angle: Angle = Field(description="degrees, right-handed")

    _n = field_validator("axis")(classmethod(lambda cls, v: _nonzero(v, "rotation axis")))


class _Shape(Model):
    name: str | None = Field(None, description="object name (used for object ids)")
    material: str | Material = Field("default", description="a name from [materials] or an inline table")
    occluder: StrictBool = Field(False, description="removed in the unoccluded-fraction pass")
    rotate: tuple[Rotation, ...] = ()
    flip_normals: StrictBool = False


class Sphere(_Shape):
    type: Literal["sphere"]
    center: Vec3 = (0.0, 0.0, 0.0)
    radius: Length = 1.0


class Rectangle(_Shape):
    """The square [-1, 1]^2 of the z = 0 plane (normal +z), scaled by size/2, rotated, translated."""

    type: Literal["rectangle"]
    center: Vec3 = (0.0, 0.0, 0.0)
    size: tuple[Length, Length] = (2.0, 2.0)


class Box(_Shape):
    type: Literal["box"]
    center: Vec3 = (0.0, 0.0, 0.0)
    size: tuple[Length, Length, Length] = (1.0, 1.0, 1.0)


class Cylinder(_Shape):
    type: Literal["cylinder"]
    p0: Vec3 = (0.0, 0.0, 0.0)
    p1: Vec3 = (0.0, 0.0, 1.0)
    radius: Length = 1.0

    @model_validator(mode="after")
    def _axis(self):
        if _norm([a - b for a, b in zip(self.p1, self.p0, strict=True)]) < MIN_LENGTH:
            raise ValueError(f"p0 and p1 are the same point {list(self.p0)}; a cylinder needs two end points at least "
                             f"{MIN_LENGTH:g} apart")
        return self


class Disk(_Shape):
    type: Literal["disk"]
    center: Vec3 = (0.0, 0.0, 0.0)
    radius: Length = 1.0


class Heightfield(_Shape):
    """A triangle mesh ``z = f(x, y)`` over ``|x|, |y| <= half_width`` from a named analytic surface
    (:mod:`pbrbench.shading.surfaces`) or a ``.npy`` height array (path relative to the scene file)."""

    type: Literal["heightfield"]
    surface: str | None = None
    params: dict[str, Any] = Field(default_factory=dict, description="keyword parameters of the named surface "
                                   "(checked against its signature)")
    path: str | None = Field(None, min_length=1)
    half_width: Length = 1.0
    resolution: Annotated[int, _integer(4, 2048)] = Field(256, description="grid vertices per side")
    center: Vec3 = (0.0, 0.0, 0.0)
    z_scale: Annotated[float, _number(-MAX_LENGTH, MAX_LENGTH)] = 1.0

    @model_validator(mode="after")
    def _one_source(self):
        if (self.surface is None) == (self.path is None):
            raise ValueError("give exactly one of 'surface' (a named analytic surface) or 'path' (a .npy file)")
        if self.surface is not None:
            from pbrbench.shading.surfaces import SURFACES

            if self.surface not in SURFACES:
                raise ValueError(f"unknown surface {self.surface!r}; choose one of {', '.join(sorted(SURFACES))}")
            _check_surface_params(self)
        elif self.params:
            raise At(("params",), "params apply to a named surface only; drop them, or give surface = NAME "
                                  "instead of path")
        return self


def _param_kind(default) -> str:
    if isinstance(default, bool):
        return "bool"
    if isinstance(default, int):
        return "int"
    if isinstance(default, float):
        return "number"
    if isinstance(default, tuple) and default and all(isinstance(d, tuple) for d in default):
        return "pairs"
    if isinstance(default, tuple):
        return "pair" if len(default) == 2 and not isinstance(default[0], tuple) else "numbers"
    return "any"


def _at(at: tuple, fn, *args, **kw):
    try:
        return fn(*args, **kw)
    except At:
        raise
    except ValueError as exc:
        raise At(at, str(exc)) from None


def _check_surface_params(hf: Heightfield) -> None:
    """Check a heightfield's ``params`` against the signature of its named surface, then build the
    surface once on the mesh grid: it must be finite and leave at least one triangle."""
    import difflib

    from pbrbench.shading import surfaces

    fn = surfaces.SURFACES[hf.surface]
    sig = {n: p.default for n, p in inspect.signature(fn).parameters.items()
           if p.kind is inspect.Parameter.KEYWORD_ONLY}
    clean = {}
    for key, v in hf.params.items():
        if key not in sig:
            close = difflib.get_close_matches(key, list(sig), n=1, cutoff=0.6)
            hint = f"did you mean {close[0]!r}?" if close else f"{hf.surface!r} takes {', '.join(sig) or 'no parameters'}"
            raise At(("params", key), f"unknown parameter of surface {hf.surface!r} ({hint})")
        kind = _param_kind(sig[key])
        at = ("params", key)
        if kind == "int":
            if isinstance(v, bool) or not isinstance(v, int):
                raise At(at, f"must be an integer, got {v!r}")
            lo, hi = (0, (1 << 63) - 1) if key == "seed" else (1, MAX_SURFACE_INT)
            if not lo <= v <= hi:
                raise At(at, f"must be an integer >= {lo}" + (f" and <= {hi}" if key != "seed" else "") + f", got {v!r}")
            clean[key] = v
        elif kind == "number":
            if isinstance(v, list):
                raise At(at, f"must be a number, got a list {v!r}")
            clean[key] = _at(at, _real, v, -MAX_LENGTH, MAX_LENGTH)
        elif kind in ("numbers", "pair"):
            if not isinstance(v, list):
                raise At(at, f"must be a list of numbers{' [x, y]' if kind == 'pair' else ''}, got {v!r}")
            if kind == "pair" and len(v) != 2:
                raise At(at, f"must be a point [x, y], got {len(v)} values")
            if not 1 <= len(v) <= MAX_SURFACE_LIST:
                raise At(at, f"must be a list of 1..{MAX_SURFACE_LIST} numbers, got {len(v)}")
            if any(isinstance(x, list) for x in v):
                raise At(at, f"must be a list of numbers, got nested lists {v!r}")
            clean[key] = tuple(_at(at, _real, x, -MAX_LENGTH, MAX_LENGTH) for x in v)
        elif kind == "pairs":
            if not isinstance(v, list) or not 1 <= len(v) <= MAX_SURFACE_LIST:
                raise At(at, f"must be a list of 1..{MAX_SURFACE_LIST} points [x, y], got {v!r}")
            pts = []
            for x in v:
                if not isinstance(x, list) or len(x) != 2:
                    raise At(at, f"must be a list of points [x, y], got the item {x!r}")
                pts.append(tuple(_at(at, _real, c, -MAX_LENGTH, MAX_LENGTH) for c in x))
            clean[key] = tuple(pts)
        else:  # pragma: no cover - no surface has such a parameter today
            clean[key] = v
    key = json.dumps([hf.surface, sorted(clean.items()), hf.resolution, hf.half_width, hf.z_scale], default=str)
    problem = _SURFACE_CHECKS.get(key)
    if problem is None:
        problem = _surface_problem(hf, clean)
        if len(_SURFACE_CHECKS) > 512:
            _SURFACE_CHECKS.clear()
        _SURFACE_CHECKS[key] = problem
    if problem:
        raise At(("params",), problem)


_SURFACE_CHECKS: dict[str, str] = {}   # the members of a sweep share their heightfield: built once


def _surface_problem(hf: Heightfield, clean: dict) -> str:
    """'' if the surface builds on the mesh grid (finite, within range, at least one triangle),
    else what is wrong."""
    import numpy as np

    from pbrbench.shading import surfaces

    n = hf.resolution
    xs = np.linspace(-hf.half_width, hf.half_width, n)
    x, y = np.meshgrid(xs, xs[::-1])
    try:
        with np.errstate(all="ignore"):
            surf = surfaces.evaluate(hf.surface, x, y, **clean)
    except Exception as exc:  # noqa: BLE001 - any failure of the surface is the parameters' fault
        return (f"surface {hf.surface!r} rejects these parameters ({type(exc).__name__}: {exc}); "
                "see pbrbench/shading/surfaces.py for its parameters")
    zs = surf.z * hf.z_scale
    if not (np.isfinite(zs).all() and np.isfinite(surf.fx).all() and np.isfinite(surf.fy).all()):
        return f"surface {hf.surface!r} is not finite with these parameters; choose smaller values"
    if np.abs(zs).max(initial=0.0) > MAX_COORD:
        return f"surface {hf.surface!r} reaches heights above {MAX_COORD:g} (times z_scale); choose smaller values"
    m = surf.mask
    if not (m[:-1, :-1] & m[1:, :-1] & m[:-1, 1:]).any() and not (m[:-1, 1:] & m[1:, :-1] & m[1:, 1:]).any():
        return (f"surface {hf.surface!r} has no triangle inside |x|, |y| <= half_width with these "
                "parameters (its domain is empty); enlarge it (e.g. its radius or extent)")
    return ""


Shape = Annotated[Sphere | Rectangle | Box | Cylinder | Disk | Heightfield, Field(discriminator="type")]


# ------------------------------------------------------------------------------------- lights
def _power(v, what):
    return _nonneg_rgb(_rgb(v), what)


class Directional(Model):
    """A distant source; ``direction`` points from the scene toward the source."""

    type: Literal["directional"]
    direction: Vec3
    irradiance: RGB = (1.0, 1.0, 1.0)

    _d = field_validator("direction")(classmethod(lambda cls, v: _nonzero(v, "direction")))
    _p = field_validator("irradiance", mode="before")(classmethod(lambda cls, v: _power(v, "irradiance")))


class Point(Model):
    type: Literal["point"]
    position: Vec3
    intensity: RGB = (1.0, 1.0, 1.0)

    _p = field_validator("intensity", mode="before")(classmethod(lambda cls, v: _power(v, "intensity")))


class AreaRect(Model):
    """A one-sided rectangular emitter of uniform radiance, facing ``normal``."""

    type: Literal["area"]
    center: Vec3
    size: tuple[Length, Length] = (1.0, 1.0)
    normal: Vec3 = (0.0, 0.0, -1.0)
    up: Vec3 = (0.0, 1.0, 0.0)
    radiance: RGB = (1.0, 1.0, 1.0)

    _n = field_validator("normal", "up")(classmethod(lambda cls, v: _nonzero(v, "normal/up")))
    _p = field_validator("radiance", mode="before")(classmethod(lambda cls, v: _power(v, "radiance")))

    @model_validator(mode="after")
    def _basis(self):
        if _parallel(self.normal, self.up):
            raise ValueError(f"up {list(self.up)} is parallel to normal {list(self.normal)}; give an up vector that "
                             "is not parallel to the normal (it orients the rectangle)")
        return self


class Ambient(Model):
    """A constant environment of uniform radiance (the chapter's ambient term)."""

    type: Literal["ambient"]
    radiance: RGB = (1.0, 1.0, 1.0)

    _p = field_validator("radiance", mode="before")(classmethod(lambda cls, v: _power(v, "radiance")))


Light = Annotated[Directional | Point | AreaRect | Ambient, Field(discriminator="type")]


# ----------------------------------------------------------------------------- camera, render
class Camera(Model):
    type: Literal["orthographic", "perspective"] = "orthographic"
    origin: Vec3 = (0.0, 0.0, 5.0)
    target: Vec3 = (0.0, 0.0, 0.0)
    up: Vec3 = (0.0, 1.0, 0.0)
    half_width: Length = Field(1.0, description="orthographic: film covers [-hw, hw] in x")
    fov: Annotated[float, _number(1e-3, 179.9)] = Field(40.0, description="perspective: horizontal field of view, degrees")
    near_clip: Clip = 0.01
    far_clip: Clip = 1000.0

    @model_validator(mode="after")
    def _frame(self):
        d = [t - o for t, o in zip(self.target, self.origin, strict=True)]
        _nonzero(d, "target - origin")
        _nonzero(self.up, "up")
        if _parallel(d, self.up):
            raise ValueError("up must not be parallel to the viewing direction")
        if self.near_clip >= self.far_clip:
            raise ValueError("near_clip must be smaller than far_clip")
        return self


class Render(Model):
    resolution: tuple[int, int] = Field((256, 256), description="[width, height] or one number")
    spp: Annotated[int, _integer(1, 1 << 20)] = 64
    max_depth: Annotated[int, _integer(-1, MAX_DEPTH)] = Field(-1, description="-1: unlimited (full global illumination)")
    rr_depth: Annotated[int, _integer(1, MAX_DEPTH)] = 5
    seed: Annotated[int, _integer(0, MAX_SEED, " (the renderer derives 32-bit seeds from it)")] = 0
    sampler: Literal["multijitter", "independent", "stratified", "orthogonal", "ldsampler"] = "multijitter"
    min_resolution: Annotated[int, _integer(4, 8192)] | None = Field(
        None, description="the fewest pixels a side a reduced profile (draft) may render: for scenes whose task needs "
                          "enough pixels in every part of the image (an HDR bracket's calibration)")
    min_groups: Annotated[int, _integer(2, 16)] | None = Field(
        None, description="the fewest independent sample groups every pass is rendered with, at every profile (more "
                          "than the profile's: every score's standard error gets groups - 1 degrees of freedom); for "
                          "scenes that a task's headline rests on nearly alone and whose scores are cheap to repeat")

    @field_validator("resolution", mode="before")
    @classmethod
    def _res(cls, v):
        if isinstance(v, int) and not isinstance(v, bool):
            v = (v, v)
        if not isinstance(v, (list, tuple)):
            raise ValueError(f"resolution must be an integer 4..8192 or [width, height], got {v!r}")
        v = tuple(v)
        if len(v) != 2 or any((not isinstance(x, int)) or isinstance(x, bool) or x < 4 or x > 8192 for x in v):
            raise ValueError(f"resolution must be an integer 4..8192 or [width, height], got {v!r}")
        return v

    @model_validator(mode="after")
    def _depth(self):
        if self.max_depth in (0, 1):
            raise ValueError("max_depth 0/1 renders no reflected light; use 2 (direct) or -1 (global)")
        if self.min_resolution is not None and self.min_resolution > min(self.resolution):
            raise ValueError(f"min_resolution ({self.min_resolution}) must not exceed the smaller side of resolution "
                             f"{list(self.resolution)}; lower it or raise resolution")
        if self.min_groups is not None and self.min_groups > self.spp:
            raise ValueError(f"min_groups ({self.min_groups}) must not exceed spp ({self.spp}): every sample group needs "
                             "a sample per pixel; lower min_groups or raise spp")
        return self


def default_seed(name: str) -> int:
    """The ``render.seed`` of a scene whose file gives none: ``crc32(name) mod SEED_SPAN + 1``.

    Scenes rendered with one seed share their Monte Carlo noise wherever they trace the same
    paths: the members of a sweep (the same geometry, another albedo) and two files of the same
    content (a twin that repeats another scene at one of its sweep values) would then give
    correlated scores, and a mean over them would get a standard error too small for it (the
    report adds independent scenes' errors in quadrature).  A seed derived from the name makes
    every scene's noise its own, deterministically.  Below ``2^18 - 2^12`` the renderer's pass
    seeds ``16 (1000 seed + offset) + group`` stay below ``2^32`` (no wrap-around) for every
    ``--render-seed`` offset up to 4096."""
    return zlib.crc32(name.encode("utf-8")) % SEED_SPAN + 1


# -------------------------------------------------------------------------------------- scene
_NAME_CHARS = re.compile(r"^[A-Za-z0-9_.\-\[\]=,+ ]+$")
NAME_RULE = (f"a scene name is also a file name: 1..{MAX_NAME} letters, digits, spaces and _ . - [ ] = , +, "
             "starting with a letter, digit or _ and not ending in a space or a dot")


def check_scene_name(v: str) -> str:
    """``v`` if it is a safe scene name (a file name on every system), else ValueError."""
    if not isinstance(v, str):
        raise ValueError(f"must be a string, got {v!r}")
    if not v:
        raise ValueError(f"is empty; {NAME_RULE}")
    if len(v) > MAX_NAME:
        raise ValueError(f"is {len(v)} characters long; {NAME_RULE}")
    if not _NAME_CHARS.match(v):
        bad = sorted({c for c in v if not _NAME_CHARS.match(c)})
        raise ValueError(f"{v!r} holds {', '.join(repr(c) for c in bad)}; {NAME_RULE}")
    if not (v[0].isalnum() or v[0] == "_") or v[-1] in " .":
        raise ValueError(f"{v!r} must start with a letter, digit or _ and not end in a space or a dot "
                         f"(no '.', '..' or hidden names); {NAME_RULE}")
    return v


def _power_of(light) -> tuple[str, tuple]:
    for key in ("irradiance", "intensity", "radiance"):
        if hasattr(light, key):
            return key, getattr(light, key)
    raise TypeError(light)  # pragma: no cover


class SceneSpec(Model):
    """A validated scene: immutable, hashable by :meth:`content_hash`."""

    name: str
    description: str
    reference: str = Field("", description="section/figure of the chapter it reproduces")
    tags: tuple[str, ...] = ()
    camera: Camera = Camera()
    render: Render = Render()
    materials: dict[str, Material] = Field(default_factory=dict)
    shapes: tuple[Shape, ...] = Field(min_length=1)
    lights: tuple[Light, ...] = ()
    light_set: tuple[Light, ...] = Field((), description="lights rendered one at a time")
    sweep: dict[str, list] = Field(default_factory=dict)
    base_dir: str = Field("", exclude=True, description="directory of the scene file (for relative paths)")
    source: str = Field("", exclude=True)
    data_dirs: tuple[str, ...] = Field((), exclude=True, description="other directories its data files may lie in")

    @field_validator("name")
    @classmethod
    def _name(cls, v):
        return check_scene_name(v)

    @model_validator(mode="after")
    def _check(self):
        for table in ("lights", "light_set"):
            for k, light in enumerate(getattr(self, table)):
                key, power = _power_of(light)
                if max(power) <= 0:
                    raise At((table, k, key), f"{list(power)} emits nothing; give a positive value (a light that "
                                              "emits nothing renders black)")
        names = set(self.materials) | {"default"}
        for i, s in enumerate(self.shapes):
            if isinstance(s.material, str) and s.material not in names:
                raise ValueError(
                    f"shapes[{i}].material: {s.material!r} is not defined; define [materials.{s.material}] "
                    f"or use one of {', '.join(sorted(names))}"
                )
        if not self.lights and not self.light_set:
            raise ValueError("the scene has no light; add a [[lights]] or [[light_set]] entry")
        seen = set()
        for i, s in enumerate(self.shapes):
            if s.name is not None:
                if s.name in seen:
                    raise ValueError(f"shapes[{i}].name: {s.name!r} is used twice; shape names must be unique")
                seen.add(s.name)
        if "seed" not in self.render.model_fields_set:   # no render.seed in the file: one of its own
            object.__setattr__(self, "render", self.render.model_copy(update={"seed": default_seed(self.name)}))
        return self

    # ------------------------------------------------------------------------- derived
    def material_of(self, shape) -> Material:
        if isinstance(shape.material, str):
            if shape.material == "default" and "default" not in self.materials:
                return Diffuse(type="diffuse")
            return self.materials[shape.material]
        return shape.material

    @property
    def has_glossy(self) -> bool:
        return any(self.material_of(s).type in GLOSSY for s in self.shapes)

    @property
    def has_occluders(self) -> bool:
        return any(s.occluder for s in self.shapes)

    @property
    def data_root(self):
        """Where the data files of this scene may lie: its file's directory, with the extra
        ``data_dirs`` it was loaded with (:class:`pbrbench.scene.data.DataDir`)."""
        from pbrbench.scene.data import DataDir

        return DataDir(self.base_dir, self.data_dirs)

    @property
    def n_passes(self) -> int:
        """The rendered passes of this scene's ground truth (progress steps and the work limit):
        radiance, direct, two per light of the light set, the unoccluded and diffuse-only passes
        where they apply, and the AOVs."""
        return 3 + 2 * len(self.light_set) + int(self.has_occluders) + int(self.has_glossy)

    def shape_names(self) -> list[str]:
        return [s.name or f"shape{i}" for i, s in enumerate(self.shapes)]

    def canonical(self) -> dict:
        """JSON-ready dict of everything that affects the render (no paths, no sweep)."""
        d = self.model_dump(mode="json", exclude={"base_dir", "source", "data_dirs", "sweep", "description", "reference", "tags"})
        for k in ("min_resolution", "min_groups"):   # unset: the hash of a file that does not use it is unchanged
            if d["render"].get(k) is None:
                d["render"].pop(k, None)
        return d

    def content_hash(self) -> str:
        """sha256 of the canonical JSON, plus the bytes of every file the scene reads."""
        return self._digest(self.canonical())

    def noise_hash(self) -> str:
        """:meth:`content_hash` without ``render.seed``: what the distribution of the scene's
        Monte Carlo noise depends on.  Renders of one scene at different seeds are draws from one
        distribution, so a spread measured over render seeds (``scripts/noise_scales.py``)
        holds at any of them."""
        d = self.canonical()
        d["render"] = {k: v for k, v in d["render"].items() if k != "seed"}
        return self._digest(d)

    def _digest(self, canonical: dict) -> str:
        """sha256 of ``canonical`` as JSON, plus the bytes of every file the scene reads."""
        h = hashlib.sha256(json.dumps(canonical, sort_keys=True, separators=(",", ":")).encode())
        for p in self.referenced_files():
            with open(p, "rb") as f:
                h.update(f.read())
        return h.hexdigest()

    def referenced_files(self) -> list[str]:
        import os

        return [os.path.join(self.base_dir, rel) for _, rel, _ in self.referenced_data()]

    def referenced_data(self) -> list[tuple[str, str, str]]:
        """``(key path, path as written, kind)`` of every data file the scene reads; kind is
        ``"texture"`` (an albedo image) or ``"height"`` (a heightfield array)."""
        out = []
        for name, m in self.materials.items():
            if isinstance(m.albedo, ImageTexture):
                out.append((f"materials.{name}.albedo.path", m.albedo.path, "texture"))
        for i, s in enumerate(self.shapes):
            if not isinstance(s.material, str) and isinstance(s.material.albedo, ImageTexture):
                out.append((f"shapes[{i}].material.albedo.path", s.material.albedo.path, "texture"))
            if isinstance(s, Heightfield) and s.path:
                out.append((f"shapes[{i}].path", s.path, "height"))
        return out
