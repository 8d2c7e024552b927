"""Which scenes a task reads: a library family's specs, and the value a swept spec took.

Tasks resolve what they need from the scene specs when they *list* jobs (:meth:`Task.jobs`) and store
it in the job's ``params``, so that :meth:`Task.run_job` works from the job and the ground-truth arrays
alone (jobs run in worker processes; tests build jobs from synthetic ground truths).
"""

from __future__ import annotations


def family_scenes(family: str) -> list:
    """SceneSpecs of a library family (a file stem; its sweep expanded), [] if the file is absent.

    Tasks list every family of the naming contract; families the library does not have (yet)
    contribute no jobs instead of failing the whole task.
    """
    from pbrbench.scene.load import load_scene_file, scenes_dir

    path = scenes_dir() / f"{family}.toml"
    if not path.is_file():
        return []
    return load_scene_file(path)


def sweep_value(spec, key: str):
    """The value a swept spec took for ``key`` (the last part of a key path), parsed from its name
    ``family[key=value,...]``; None when the spec is not swept on it."""
    name = spec.name if not isinstance(spec, str) else spec
    if "[" not in name or not name.endswith("]"):
        return None
    for part in name[name.index("[") + 1:-1].split(","):
        k, _, v = part.partition("=")
        if k == key:
            try:
                return float(v)
            except ValueError:
                return v
    return None


_SPECS: dict = {}


def scene_spec(name: str):
    """The SceneSpec of a library scene by name (``family[key=value]``), cached per process."""
    if name not in _SPECS:
        fam = name.split("[")[0]
        found = {s.name: s for s in family_scenes(fam)}
        if name not in found:
            raise ValueError(f"scene {name!r}: not in the library family {fam!r}")
        _SPECS.update(found)
    return _SPECS[name]
