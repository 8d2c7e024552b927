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
import json
import math
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

SPEC_VERSION = 1

Vec3 = tuple[float, float, float]


def _rgb(v) -> tuple[float, float, float]:
    if isinstance(v, (int, float)):
        return (float(v),) * 3
    v = tuple(float(x) for x in v)
    if len(v) == 1:
        return v * 3
    if len(v) != 3:
        raise ValueError(f"expected a number or [r, g, b], got {len(v)} values")
    return v


class Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


RGB = Annotated[tuple[float, float, float], Field(description="grey value or [r, g, b]")]


def _nonneg_rgb(v, what):
    if any((not math.isfinite(c)) or c < 0 for c in v):
        raise ValueError(f"{what} must be finite and >= 0, got {list(v)}")
    return v


def _unit_rgb(v, what):
    _nonneg_rgb(v, what)
    if any(c > 1 for c in v):
        raise ValueError(f"{what} must be in [0, 1] (energy conservation), got {list(v)}")
    return v


def _nonzero(v, what):
    if not all(math.isfinite(c) for c in v) or math.sqrt(sum(c * c for c in v)) < 1e-12:
        raise ValueError(f"{what} must be a finite non-zero vector, got {list(v)}")
    return v


# ----------------------------------------------------------------------------------- textures
class CheckerTexture(Model):
    type: Literal["checker"]
    color0: RGB = (0.2, 0.2, 0.2)
    color1: RGB = (0.8, 0.8, 0.8)
    scale: float = Field(8.0, gt=0, description="squares per unit of uv")

    @field_validator("color0", "color1", mode="before")
    @classmethod
    def _c(cls, v):
        return _unit_rgb(_rgb(v), "texture colour")


class MondrianTexture(Model):
    """Piecewise-constant random papers on a grid (seeded)."""

    type: Literal["mondrian"]
    patches: int = Field(8, ge=1, le=64, description="papers per side")
    resolution: int = Field(256, ge=8, le=4096)
    seed: int = 0
    low: float = Field(0.1, ge=0, le=1)
    high: float = Field(0.9, ge=0, le=1)
    colour: bool = False
    white: bool = Field(False, description="force one paper to albedo `high` in every channel")

    @model_validator(mode="after")
    def _range(self):
        if self.low > self.high:
            raise ValueError(f"low ({self.low}) must not exceed high ({self.high})")
        return self


class ImageTexture(Model):
    """An albedo image: ``.npy`` (H, W) or (H, W, 3) float in [0, 1]; path relative to the scene file."""

    type: Literal["image"]
    path: str


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
    int_ior: float = Field(1.5, gt=1.0, le=3.0)

    _c = field_validator("albedo", mode="before")(classmethod(lambda cls, v: _albedo(v)))


class RoughPlastic(Model):
    """Rough dielectric coating (GGX) over a diffuse base: glossy highlights."""

    type: Literal["roughplastic"]
    albedo: RGB | Texture = (0.5, 0.5, 0.5)
    alpha: float = Field(0.1, gt=0, le=1)
    int_ior: float = Field(1.5, gt=1.0, le=3.0)

    _c = field_validator("albedo", mode="before")(classmethod(lambda cls, v: _albedo(v)))


Material = Annotated[Diffuse | Plastic | RoughPlastic, Field(discriminator="type")]
GLOSSY = ("plastic", "roughplastic")


# ------------------------------------------------------------------------------------- shapes
class Rotation(Model):
    axis: Vec3
    angle: float = Field(description="degrees, right-handed")

    _n = field_validator("axis")(classmethod(lambda cls, v: _nonzero(v, "rotation axis")))


class _Shape(Model):
    name: str | None = Field(None, description="object name (used for object ids)")
    material: str | Material = Field("default", description="a name from [materials] or an inline table")
    occluder: bool = Field(False, description="removed in the unoccluded-fraction pass")
    rotate: tuple[Rotation, ...] = ()
    flip_normals: bool = False


class Sphere(_Shape):
    type: Literal["sphere"]
    center: Vec3 = (0.0, 0.0, 0.0)
    radius: float = Field(1.0, gt=0)


class Rectangle(_Shape):
    """The square [-1, 1]^2 of the z = 0 plane (normal +z), scaled by size/2, rotated, translated."""

    type: Literal["rectangle"]
    center: Vec3 = (0.0, 0.0, 0.0)
    size: tuple[float, float] = (2.0, 2.0)


class Box(_Shape):
    type: Literal["box"]
    center: Vec3 = (0.0, 0.0, 0.0)
    size: Vec3 = (1.0, 1.0, 1.0)


class Cylinder(_Shape):
    type: Literal["cylinder"]
    p0: Vec3 = (0.0, 0.0, 0.0)
    p1: Vec3 = (0.0, 0.0, 1.0)
    radius: float = Field(1.0, gt=0)


class Disk(_Shape):
    type: Literal["disk"]
    center: Vec3 = (0.0, 0.0, 0.0)
    radius: float = Field(1.0, gt=0)


class Heightfield(_Shape):
    """A triangle mesh ``z = f(x, y)`` over ``|x|, |y| <= half_width`` from a named analytic surface
    (:mod:`pbrbench.shading.surfaces`) or a ``.npy`` height array (path relative to the scene file)."""

    type: Literal["heightfield"]
    surface: str | None = None
    params: dict[str, float | int | list[float] | list[list[float]]] = Field(default_factory=dict)
    path: str | None = None
    half_width: float = Field(1.0, gt=0)
    resolution: int = Field(256, ge=4, le=2048, description="grid vertices per side")
    center: Vec3 = (0.0, 0.0, 0.0)
    z_scale: float = 1.0

    @model_validator(mode="after")
    def _one_source(self):
        if (self.surface is None) == (self.path is None):
            raise ValueError("give exactly one of 'surface' (a named analytic surface) or 'path' (a .npy file)")
        if self.surface is not None:
            from pbrbench.shading.surfaces import SURFACES

            if self.surface not in SURFACES:
                raise ValueError(f"unknown surface {self.surface!r}; choose one of {', '.join(sorted(SURFACES))}")
        return self


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
    size: tuple[float, float] = (1.0, 1.0)
    normal: Vec3 = (0.0, 0.0, -1.0)
    up: Vec3 = (0.0, 1.0, 0.0)
    radiance: RGB = (1.0, 1.0, 1.0)

    _n = field_validator("normal", "up")(classmethod(lambda cls, v: _nonzero(v, "normal/up")))
    _p = field_validator("radiance", mode="before")(classmethod(lambda cls, v: _power(v, "radiance")))

    @field_validator("size")
    @classmethod
    def _size(cls, v):
        if min(v) <= 0:
            raise ValueError(f"size must be positive, got {list(v)}")
        return v


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
    half_width: float = Field(1.0, gt=0, description="orthographic: film covers [-hw, hw] in x")
    fov: float = Field(40.0, gt=0, lt=180, description="perspective: horizontal field of view, degrees")
    near_clip: float = Field(0.01, gt=0)
    far_clip: float = Field(1000.0, gt=0)

    @model_validator(mode="after")
    def _frame(self):
        d = [t - o for t, o in zip(self.target, self.origin, strict=True)]
        _nonzero(d, "target - origin")
        _nonzero(self.up, "up")
        cross = (d[1] * self.up[2] - d[2] * self.up[1], d[2] * self.up[0] - d[0] * self.up[2], d[0] * self.up[1] - d[1] * self.up[0])
        if math.sqrt(sum(c * c for c in cross)) < 1e-9:
            raise ValueError("up must not be parallel to the viewing direction")
        if self.near_clip >= self.far_clip:
            raise ValueError("near_clip must be smaller than far_clip")
        return self


class Render(Model):
    resolution: tuple[int, int] = Field((256, 256), description="[width, height] or one number")
    spp: int = Field(64, ge=1, le=1 << 20)
    max_depth: int = Field(-1, ge=-1, description="-1: unlimited (full global illumination)")
    rr_depth: int = Field(5, ge=1)
    seed: int = Field(0, ge=0)
    sampler: Literal["multijitter", "independent", "stratified", "orthogonal", "ldsampler"] = "multijitter"

    @field_validator("resolution", mode="before")
    @classmethod
    def _res(cls, v):
        if isinstance(v, int):
            v = (v, v)
        v = tuple(v)
        if len(v) != 2 or any((not isinstance(x, int)) or x < 4 or x > 8192 for x in v):
            raise ValueError(f"resolution must be an integer 4..8192 or [width, height], got {v!r}")
        return v

    @model_validator(mode="after")
    def _depth(self):
        if self.max_depth in (0, 1):
            raise ValueError("max_depth 0/1 renders no reflected light; use 2 (direct) or -1 (global)")
        return self


# -------------------------------------------------------------------------------------- scene
class SceneSpec(Model):
    """A validated scene: immutable, hashable by :meth:`content_hash`."""

    name: str = Field(pattern=r"^[A-Za-z0-9_.\-\[\]=,+ ]+$")
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

    @model_validator(mode="after")
    def _check(self):
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

    def shape_names(self) -> list[str]:
        return [s.name or f"shape{i}" for i, s in enumerate(self.shapes)]

    def canonical(self) -> dict:
        """JSON-ready dict of everything that affects the render (no paths, no sweep)."""
        d = self.model_dump(mode="json", exclude={"base_dir", "source", "sweep", "description", "reference", "tags"})
        return d

    def content_hash(self) -> str:
        """sha256 of the canonical JSON, plus the bytes of every file the scene reads."""
        h = hashlib.sha256(json.dumps(self.canonical(), sort_keys=True, separators=(",", ":")).encode())
        for p in self.referenced_files():
            with open(p, "rb") as f:
                h.update(f.read())
        return h.hexdigest()

    def referenced_files(self) -> list[str]:
        import os

        out = []
        mats = list(self.materials.values()) + [s.material for s in self.shapes if not isinstance(s.material, str)]
        for m in mats:
            if isinstance(m.albedo, ImageTexture):
                out.append(os.path.join(self.base_dir, m.albedo.path))
        for s in self.shapes:
            if isinstance(s, Heightfield) and s.path:
                out.append(os.path.join(self.base_dir, s.path))
        return out
