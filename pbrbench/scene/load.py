"""Load scene files: TOML -> sweep expansion -> :class:`SceneSpec`, with one-line errors.

A bad file raises :class:`~pbrbench.errors.SceneError` whose message names the file, the key
path and the reason, with a hint where one helps, e.g.
``x.toml: lights[1].drection: unknown key (did you mean 'direction'?)``.

Loading also reads and checks every data file the scene names (:mod:`pbrbench.scene.data`), and
refuses files whose renders would be far larger than any scene of the library (a sweep of
thousands of values, thousands of lights, the largest resolution with the most samples): see
:data:`LIMITS`.  Setting ``PBRBENCH_ALLOW_LARGE=1`` (the ``allow_large`` setting) lifts them.
"""

from __future__ import annotations

import copy
import difflib
import itertools
import os
import re
import tomllib
import typing
from dataclasses import dataclass, field
from pathlib import Path

from pydantic import BaseModel, ValidationError

from pbrbench.errors import SceneError
from pbrbench.memo import Memo
from pbrbench.scene import spec as S

# Far above the library (at most 12 scenes per file, 12 lights, 4e7 samples per scene, 9e7 per
# file): a file beyond one of these is almost surely a mistake, and would run for hours.
LIMITS = {
    "scenes_per_file": 1000,        # scenes a sweep expands into
    "lights_per_scene": 1000,       # entries of lights + light_set
    "samples_per_scene": 2e10,      # width x height x spp x passes, at the file's own settings
    "samples_per_file": 1e11,       # the same summed over a sweep
}
_OVERRIDE = "set PBRBENCH_ALLOW_LARGE=1 to render it anyway (SceneLibrary(allow_large=True) from Python)"
MAX_SCENE_FILE_BYTES = 16 * 2**20


def scenes_dir(directory: str | os.PathLike | None = None) -> Path:
    """Directory of a scene library: ``directory``, else the library shipped with the package
    (:data:`pbrbench.settings.LIBRARY_DIR`)."""
    if directory is not None:
        return Path(directory)
    from pbrbench.settings import LIBRARY_DIR

    return Path(LIBRARY_DIR)


# ------------------------------------------------------------------- error formatting
_TAGS = {
    "checker", "mondrian", "image", "diffuse", "plastic", "roughplastic", "sphere", "rectangle",
    "box", "cylinder", "disk", "heightfield", "directional", "point", "area", "ambient",
}


def _models_in(annotation) -> list[type[BaseModel]]:
    """All pydantic models reachable from a type annotation (through unions, tuples, dicts)."""
    out = []
    origin = typing.get_origin(annotation)
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    if origin is typing.Annotated:
        return _models_in(typing.get_args(annotation)[0])
    for a in typing.get_args(annotation):
        out += _models_in(a)
    return out


def _fields_at(loc: tuple) -> set[str]:
    """Field names of the model(s) at a location, to suggest close matches for a typo."""
    models: list[type[BaseModel]] = [S.SceneSpec]
    tag = None
    for part in loc:
        if isinstance(part, int):
            continue
        if part in _TAGS and tag is None and not any(part in m.model_fields for m in models):
            tag = part
            models = [m for m in models if _tag_of(m) == part] or models
            continue
        nxt = []
        for m in models:
            f = m.model_fields.get(part)
            if f is not None:
                nxt += _models_in(f.annotation)
        if not nxt:
            # a key of a dict (e.g. a material name): keep the value models
            nxt = models
        models, tag = nxt, None
    names: set[str] = set()
    for m in models:
        names |= set(m.model_fields)
    return names


def _tags_for(loc: tuple) -> str:
    """The ``type`` values valid at a location (for a table that lacks its ``type`` key)."""
    unions = {"lights": S.Light, "light_set": S.Light, "shapes": S.Shape, "materials": S.Material, "albedo": S.Texture}
    key = next((p for p in reversed(loc) if isinstance(p, str) and p in unions), None)
    if key is None:
        return "the documented types (scenes/README.md)"
    return ", ".join(repr(_tag_of(m)) for m in _models_in(unions[key]))


def _tag_of(model: type[BaseModel]) -> str | None:
    f = model.model_fields.get("type")
    if f is None:
        return None
    args = typing.get_args(f.annotation)
    return args[0] if len(args) == 1 else None


_JUNK = ("tagged-union[", "function-", "tuple[", "dict[", "union[", "list[")


def _clean_loc(loc: tuple) -> tuple:
    """Drop pydantic's internal location parts (union branches, discriminator tags)."""
    parts = [p for p in loc if not (isinstance(p, str) and p.startswith(_JUNK))]
    out: list = []
    for p in parts:
        if isinstance(p, str) and p in _TAGS and out and _tag_follows(out):
            continue
        out.append(p)
    return tuple(out)


def _tag_follows(prev: list) -> bool:
    last = prev[-1]
    return isinstance(last, int) or last in ("material", "albedo") or (len(prev) >= 2 and prev[-2] == "materials")


def _loc_str(loc: tuple) -> str:
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else ("." if out else "") + str(part)
    return out or "(top level)"


def format_validation_error(path: str, err: ValidationError) -> str:
    """One line for the first (most useful) error of a pydantic ValidationError."""
    errors = err.errors(include_url=False)
    # Prefer errors that are not union-branch noise (e.g. "input should be a valid tuple").
    order = ("extra_forbidden", "union_tag_invalid", "value_error", "missing")

    def rank(e):
        t = e["type"]
        return (order.index(t) if t in order else len(order), -len(e["loc"]))

    e = sorted(errors, key=rank)[0]
    loc = _clean_loc(tuple(e["loc"]))
    sub = e.get("ctx", {}).get("error")
    if isinstance(sub, S.At):
        loc = loc + sub.sub
    where = _loc_str(loc)
    t = e["type"]
    if t == "extra_forbidden":
        key = loc[-1]
        parent = loc[:-1]
        close = difflib.get_close_matches(str(key), sorted(_fields_at(parent)), n=1, cutoff=0.6)
        hint = f" (did you mean {close[0]!r}?)" if close else f" (valid keys: {', '.join(sorted(_fields_at(parent)))})"
        return f"{path}: {where}: unknown key{hint}"
    if t == "missing":
        if loc and isinstance(loc[-1], int):
            return f"{path}: {_loc_str(loc[:-1])}: too few values (item {loc[-1]} is missing)"
        return f"{path}: {where}: required key is missing"
    if t == "union_tag_invalid":
        ctx = e.get("ctx", {})
        return f"{path}: {where}.type: unknown type {ctx.get('tag')!r}; choose one of {ctx.get('expected_tags')}"
    if t == "union_tag_not_found":
        return f"{path}: {where}: missing key 'type'; choose one of {_tags_for(loc)}"
    msg = re.sub(r"^Value error, ", "", e["msg"])
    if not loc:
        return f"{path}: {msg}"
    got = e.get("input")
    got_s = "" if isinstance(got, (dict, list)) or got is None or "got" in msg else f" (got {_short_repr(got)})"
    return f"{path}: {where}: {msg}{got_s}"


def _short_repr(v) -> str:
    r = repr(v)
    return r if len(r) <= 80 else r[:77] + "..."


# ------------------------------------------------------------------------- sweeps
_PATH_RE = re.compile(r"([^.\[\]]+)|\[(\d+)\]")


def _parse_key_path(key: str) -> list:
    parts = []
    pos = 0
    for m in _PATH_RE.finditer(key):
        if m.start() != pos and key[pos:m.start()] != ".":
            raise ValueError(key)
        parts.append(m.group(1) if m.group(1) is not None else int(m.group(2)))
        pos = m.end()
    if pos != len(key) or not parts:
        raise ValueError(key)
    return parts


def _set_path(doc, parts, value, path, key):
    cur = doc
    for k, p in enumerate(parts[:-1]):
        try:
            cur = cur[p]
        except (KeyError, IndexError, TypeError):
            raise SceneError(
                f"{path}: sweep.{key}: key path does not exist in the file at {'.'.join(map(str, parts[:k + 1]))!r}; "
                "a sweep key must name an existing value, e.g. 'materials.paper.albedo' or 'lights[0].irradiance'"
            ) from None
    last = parts[-1]
    try:
        cur[last]  # must exist so typos are caught
    except (KeyError, IndexError, TypeError):
        raise SceneError(f"{path}: sweep.{key}: key path does not exist in the file; set a default value there first") from None
    cur[last] = value


_UNSAFE = re.compile(r"[^A-Za-z0-9_.\-=+ ]")


def _fmt_value(v) -> str:
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, list):
        return "_".join(_fmt_value(x) for x in v)  # "/" is a path separator and not allowed in names
    return _UNSAFE.sub("_", str(v))  # a label is part of a file name


def expand_sweep(doc: dict, path: str, *, allow_large: bool = False) -> list[dict]:
    """Expand a ``[sweep]`` table into the Cartesian product of documents."""
    sweep = doc.get("sweep") or {}
    if not isinstance(sweep, dict):
        raise SceneError(f"{path}: sweep: must be a table of key path = [values]")
    if not sweep:
        return [doc]
    keys = list(sweep)
    n = 1
    for k in keys:
        if not isinstance(sweep[k], list) or not sweep[k]:
            raise SceneError(f"{path}: sweep.{k}: must be a non-empty list of values, e.g. [0.1, 0.5, 0.9]")
        try:
            _parse_key_path(k)
        except ValueError:
            raise SceneError(f"{path}: sweep.{k}: not a key path; write e.g. 'materials.paper.albedo' or 'lights[0].irradiance'") from None
        seen = set()
        for v in sweep[k]:
            r = repr(v)
            if r in seen:
                raise SceneError(f"{path}: sweep.{k}: the value {_short_repr(v)} appears twice; give each value once "
                                 "(the scenes would repeat)")
            seen.add(r)
        n *= len(sweep[k])
    if n > LIMITS["scenes_per_file"] and not allow_large:
        sizes = " x ".join(str(len(sweep[k])) for k in keys)
        raise SceneError(f"{path}: sweep: expands into {n} scenes ({sizes} values), more than the limit of "
                         f"{LIMITS['scenes_per_file']} per file; sweep fewer values, or {_OVERRIDE}")
    out = []
    for combo in itertools.product(*(sweep[k] for k in keys)):
        d = copy.deepcopy(doc)
        d.pop("sweep")
        for k, v in zip(keys, combo, strict=True):
            _set_path(d, _parse_key_path(k), v, path, k)
        label = ",".join(f"{_short(k)}={_fmt_value(v)}" for k, v in zip(keys, combo, strict=True))
        d["name"] = f"{doc.get('name', '?')}[{label}]"
        out.append(d)
    return out


def _short(key: str) -> str:
    return _parse_key_path(key)[-1] if isinstance(_parse_key_path(key)[-1], str) else key


# ------------------------------------------------------------------------- loading
def parse_file(path: str | Path) -> dict:
    """Read a TOML file, raising SceneError with line/column on a syntax error."""
    p = Path(path)
    if p.is_dir():
        raise SceneError(f"{path}: is a directory; give a .toml scene file or a name from `pbrbench scenes`")
    if not p.is_file():
        raise SceneError(f"{path}: no such scene file; give a name from `pbrbench scenes` or a path to a .toml file")
    try:
        size = p.stat().st_size
    except OSError as exc:
        raise SceneError(f"{path}: cannot be read ({exc.strerror or exc}); check the file's permissions") from None
    if size > MAX_SCENE_FILE_BYTES:
        raise SceneError(f"{path}: {size / 2**20:.1f} MiB, larger than any scene file should be (limit "
                         f"{MAX_SCENE_FILE_BYTES // 2**20} MiB); put large data in .npy files the scene names")
    try:
        with open(p, "rb") as f:
            return tomllib.load(f)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{path}: TOML syntax error: {exc}; fix the file (see scenes/README.md)") from None
    except UnicodeDecodeError:
        raise SceneError(f"{path}: not a UTF-8 text file; scene files are TOML") from None
    except OSError as exc:
        raise SceneError(f"{path}: cannot be read ({exc.strerror or exc}); check the file's permissions") from None
    except RecursionError:
        raise SceneError(f"{path}: nested too deeply to be a scene file") from None


def validate_doc(doc: dict, path: str, base_dir: str, *, member: str | None = None,
                 data_dirs: tuple[str, ...] = ()) -> S.SceneSpec:
    """One document (a file, or one scene of its sweep: ``member``) -> SceneSpec, with its data
    files read and checked (in ``base_dir`` or one of ``data_dirs``, which the spec keeps)."""
    where = f"{path} (scene {member!r} of the sweep)" if member else str(path)
    name = doc.get("name", "")
    if not isinstance(name, str):
        raise SceneError(f"{where}: name: must be a string, got {_short_repr(name)}")
    try:
        spec = S.SceneSpec.model_validate({**doc, "base_dir": base_dir, "source": str(path),
                                           "data_dirs": tuple(str(d) for d in data_dirs)})
    except ValidationError as exc:
        raise SceneError(format_validation_error(where, exc)) from None
    from pbrbench.scene.data import MAX_HEIGHT, check_data_file

    for key, rel, kind in spec.referenced_data():
        peak = check_data_file(spec.data_root, rel, kind, where=f"{where}: {key}")
        if kind == "height":
            i = int(key.split("[")[1].split("]")[0])
            zs = abs(spec.shapes[i].z_scale)
            if peak * zs > MAX_HEIGHT:
                raise SceneError(f"{where}: shapes[{i}].z_scale: heights times z_scale reach {peak * zs:.3g}, above "
                                 f"{MAX_HEIGHT:g}; lower z_scale or the heights")
    return spec


def _check_lights(doc: dict, path: str, allow_large: bool) -> None:
    n = sum(len(doc[k]) for k in ("lights", "light_set") if isinstance(doc.get(k), list))
    if n > LIMITS["lights_per_scene"] and not allow_large:
        parts = ", ".join(f"{len(doc[k])} in {k}" for k in ("lights", "light_set") if isinstance(doc.get(k), list) and doc[k])
        raise SceneError(f"{path}: lights/light_set: {n} lights ({parts}), more than the limit of "
                         f"{LIMITS['lights_per_scene']} per scene; use fewer lights, or {_OVERRIDE}")


def _check_work(specs: list[S.SceneSpec], path: str, allow_large: bool) -> None:
    """Refuse renders far beyond the library's (samples = width x height x spp x passes)."""
    if allow_large:
        return
    total = 0.0
    for s in specs:
        w, h = s.render.resolution
        passes = s.n_passes
        n = float(w) * h * s.render.spp * passes
        total += n
        if n > LIMITS["samples_per_scene"]:
            raise SceneError(
                f"{path}: render: scene {s.name!r} needs {n:.3g} samples ({w} x {h} px x {s.render.spp} spp x {passes} "
                f"passes), more than the limit of {LIMITS['samples_per_scene']:.3g} per scene; lower render.resolution, "
                f"render.spp or the number of lights, or {_OVERRIDE}")
    if total > LIMITS["samples_per_file"]:
        raise SceneError(f"{path}: render: the {len(specs)} scenes of the file need {total:.3g} samples together, more than "
                         f"the limit of {LIMITS['samples_per_file']:.3g} per file; sweep fewer values or lower "
                         f"render.resolution / render.spp, or {_OVERRIDE}")


def load_scene_file(path: str | Path, *, data_dirs: tuple[str, ...] = (), allow_large: bool = False) -> list[S.SceneSpec]:
    """Load one scene file; a file with a ``[sweep]`` returns several specs.  ``data_dirs``: other
    directories its data files may lie in; ``allow_large``: accept renders beyond :data:`LIMITS`."""
    doc = parse_file(path)
    _check_lights(doc, str(path), allow_large)
    if "sweep" in doc:
        docs = expand_sweep(doc, str(path), allow_large=allow_large)
        sweep = doc["sweep"]
        base = str(Path(path).parent)
        specs = [validate_doc({**d, "sweep": {}}, str(path), base, member=d["name"] if len(docs) > 1 else None,
                              data_dirs=data_dirs)
                 for d in docs]
        _check_work(specs, str(path), allow_large)
        # keep the sweep table on the specs for the record (it does not enter the hash)
        return [s.model_copy(update={"sweep": sweep}) for s in specs]
    specs = [validate_doc(doc, str(path), str(Path(path).parent), data_dirs=data_dirs)]
    _check_work(specs, str(path), allow_large)
    return specs


def library_files(directory: str | os.PathLike | None = None) -> list[Path]:
    return sorted(scenes_dir(directory).glob("*.toml"))


def load_library(directory: str | os.PathLike | None = None, *, data_dirs: tuple[str, ...] = (),
                 allow_large: bool = False) -> dict[str, S.SceneSpec]:
    """Every scene of the library by name (sweeps expanded)."""
    out: dict[str, S.SceneSpec] = {}
    for f in library_files(directory):
        for s in load_scene_file(f, data_dirs=data_dirs, allow_large=allow_large):
            if s.name in out:
                raise SceneError(f"{f}: name: {s.name!r} is also used by {out[s.name].source}; scene names must be unique")
            out[s.name] = s
    return out


def resolve(names_or_paths: list[str], directory: str | os.PathLike | None = None, *,
            data_dirs: tuple[str, ...] = (), allow_large: bool = False) -> list[S.SceneSpec]:
    """Scene names, family names (a file stem, expanding its sweep) or paths -> specs."""
    out: list[S.SceneSpec] = []
    lib = None
    kw = {"data_dirs": data_dirs, "allow_large": allow_large}
    for item in names_or_paths:
        if item.endswith(".toml") or os.sep in item:
            out += load_scene_file(item, **kw)
            continue
        stem_file = scenes_dir(directory) / f"{item}.toml"
        if stem_file.is_file():
            out += load_scene_file(stem_file, **kw)
            continue
        lib = lib if lib is not None else load_library(directory, **kw)
        if item in lib:
            out.append(lib[item])
            continue
        close = difflib.get_close_matches(item, list(lib), n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else "; run `pbrbench scenes` for the list"
        raise SceneError(f"{item}: no scene of that name{hint}")
    return out


@dataclass(frozen=True)
class SceneLibrary:
    """A scene library: a directory of scene files and how its scenes are loaded (the extra
    directories their data files may lie in, and whether renders beyond :data:`LIMITS` are
    accepted).  The command line builds one from the settings (:meth:`from_settings`) and hands it
    to the tasks; the default is the library shipped with the package, with the limits on."""

    root: Path = field(default_factory=lambda: scenes_dir())
    data_dirs: tuple[str, ...] = ()
    allow_large: bool = False

    @classmethod
    def from_settings(cls, settings) -> SceneLibrary:
        """The ``scenes``, ``data_dirs`` and ``allow_large`` settings (:class:`pbrbench.settings.Settings`)."""
        return cls(Path(settings.scenes), tuple(settings.data_dirs or ()), bool(settings.allow_large))

    def load_file(self, path: str | os.PathLike) -> list[S.SceneSpec]:
        """:func:`load_scene_file` with this library's data directories and limits."""
        return load_scene_file(path, data_dirs=self.data_dirs, allow_large=self.allow_large)

    def files(self) -> list[Path]:
        return library_files(self.root)

    def family(self, family: str) -> list[S.SceneSpec]:
        """The specs of a family (a file stem; its sweep expanded), [] when the library has no such
        file (a task lists every family it knows; those a library lacks contribute no jobs)."""
        path = Path(self.root) / f"{family}.toml"
        return self.load_file(path) if path.is_file() else []

    def spec(self, name: str) -> S.SceneSpec:
        """The spec of one scene by name (``family[key=value]``), loaded once per library."""
        key = (self, name)
        if key not in _SPECS:
            fam = name.split("[")[0]
            found = {s.name: s for s in self.family(fam)}
            if name not in found:
                raise ValueError(f"scene {name!r}: not in the library family {fam!r} ({self.root})")
            _SPECS.update({(self, n): s for n, s in found.items()})
        return _SPECS[key]

    def all(self) -> dict[str, S.SceneSpec]:
        """Every scene by name (:func:`load_library`)."""
        return load_library(self.root, data_dirs=self.data_dirs, allow_large=self.allow_large)

    def resolve(self, names_or_paths: list[str]) -> list[S.SceneSpec]:
        """:func:`resolve` in this library."""
        return resolve(names_or_paths, self.root, data_dirs=self.data_dirs, allow_large=self.allow_large)


_SPECS = Memo("scene specs by (library, name)", 4096)    # for SceneLibrary.spec
