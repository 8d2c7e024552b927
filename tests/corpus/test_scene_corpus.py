"""The corpus of malformed scene files (tests/corpus/scenes, written by make_scenes.py): every
file is refused with one line that names the file, the key and the reason (the ``# expect:``
lines of the file); the ones only a render can judge are refused by the render (marked
``render``) and never cached.  A sample goes through the command line (``main`` in this process;
one of them also as a subprocess, ``python -m pbrbench``): exit 1, one line on stderr, no
traceback."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest

from pbrbench.errors import SceneError, UserError
from pbrbench.quality import DRAFT
from pbrbench.scene.load import load_scene_file
from tests.corpus.measure import expectations, run_cli, run_in_process

SCENES = Path(__file__).resolve().parent / "scenes"
FILES = sorted(SCENES.glob("*.toml"))
LOAD = [f for f in FILES if expectations(f)["stage"] == "load"]
RENDER = [f for f in FILES if expectations(f)["stage"] == "render"]


def test_corpus_size_and_classes():
    classes = {expectations(f)["class"] for f in FILES}
    assert len(FILES) >= 100
    assert {"nonfinite", "degenerate", "params", "datafile", "name", "render", "expansion", "structure",
            "types", "black"} <= classes
    for f in FILES:
        assert expectations(f)["expect"], f"{f.name}: no '# expect:' line"


@pytest.mark.parametrize("path", LOAD, ids=[f.stem for f in LOAD])
def test_malformed_file_is_refused_in_one_line(path):
    with pytest.raises(SceneError) as e:
        load_scene_file(path)
    msg = str(e.value)
    assert "\n" not in msg and "\r" not in msg, msg
    assert msg.startswith(str(path)), f"the message does not start with the file: {msg}"
    for want in expectations(path)["expect"]:
        assert want in msg, f"{path.name}: {want!r} not in {msg!r}"


@pytest.mark.render
@pytest.mark.parametrize("path", RENDER, ids=[f.stem for f in RENDER])
def test_black_ground_truth_is_refused_and_not_cached(path, tmp_path):
    from pbrbench.render.cache import RenderCache, ground_truth

    (spec,) = load_scene_file(path)
    cache = RenderCache(tmp_path)
    with pytest.raises(UserError) as e:
        ground_truth(spec, DRAFT, cache=cache)
    msg = str(e.value)
    assert "\n" not in msg and "not cached" in msg
    for want in expectations(path)["expect"]:
        assert want in msg, f"{path.name}: {want!r} not in {msg!r}"
    assert cache.info()["entries"] == 0


# one file per class, through the command line (in this process; the first also as a subprocess: a
# few seconds, Mitsuba's import included)
CLI_SAMPLE = ["nonfinite-sphere-radius-inf", "degenerate-cylinder-equal-ends", "params-params-misspelt",
              "datafile-npy-header-lies", "datafile-npy-absolute", "name-name-dotdot", "render-seed-64bit",
              "expansion-sweep-10000", "structure-not-utf8", "types-radius-bool"]


@pytest.mark.parametrize("stem,how", [(s, "main") for s in CLI_SAMPLE]
                         + [pytest.param(CLI_SAMPLE[0], "subprocess", marks=pytest.mark.slow)])
def test_cli_refuses_in_one_line_with_exit_1(stem, how, tmp_path):
    path = SCENES / f"{stem}.toml"
    args = ["render", str(path), "--quality", "draft", "--cache", str(tmp_path / "c"), "--out", str(tmp_path / "o")]
    r = run_cli(args) if how == "subprocess" else run_in_process(args)
    assert r is not None, "timed out"
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 1 and len(lines) == 1 and "Traceback" not in r.stderr, (r.returncode, r.stderr)
    assert lines[0].startswith(f"pbrbench: error: {path}")
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())


# ------------------------------------------------------------------ cases that need a live set-up
def _scene(tmp_path, body: str, name="live") -> Path:
    p = tmp_path / f"{name}.toml"
    p.write_text(f'name = "{name}"\ndescription = "x"\n[render]\nresolution = 16\nspp = 4\n{body}\n'
                 '[[lights]]\ntype = "directional"\ndirection = [0.0, 0.0, 1.0]\n')
    return p


def test_symlink_out_of_the_scene_directory_is_refused(tmp_path):
    outside = tmp_path / "outside"
    outside.mkdir()
    np.save(outside / "h.npy", np.zeros((8, 8)))
    scene_dir = tmp_path / "scenes"
    scene_dir.mkdir()
    os.symlink(outside / "h.npy", scene_dir / "h.npy")
    p = _scene(scene_dir, '[[shapes]]\ntype = "heightfield"\nresolution = 8\npath = "h.npy"\n')
    with pytest.raises(SceneError, match=r"shapes\[0\]\.path: h\.npy: lies outside the scene file's directory"):
        load_scene_file(p)


def test_data_dirs_setting_allows_another_directory(tmp_path, monkeypatch):
    outside = tmp_path / "data"
    outside.mkdir()
    np.save(outside / "h.npy", np.zeros((8, 8)))
    scene_dir = tmp_path / "scenes"
    scene_dir.mkdir()
    p = _scene(scene_dir, '[[shapes]]\ntype = "heightfield"\nresolution = 8\npath = "../data/h.npy"\n')
    with pytest.raises(SceneError, match="outside"):
        load_scene_file(p)
    (spec,) = load_scene_file(p, data_dirs=(str(outside),))
    assert spec.referenced_data() == [("shapes[0].path", "../data/h.npy", "height")]
    # the extra directory travels with the spec: its data files load where they are used (the render)
    from pbrbench.scene.data import load_data

    assert load_data(spec.data_root, "../data/h.npy", "height", where="h").shape == (8, 8)
    with pytest.raises(SceneError, match="outside"):
        load_data(spec.base_dir, "../data/h.npy", "height", where="h")
    # the settings reach the loader through the library object
    from pbrbench.scene.load import SceneLibrary
    from pbrbench.settings import Settings

    lib = SceneLibrary.from_settings(Settings.from_env({"PBRBENCH_DATA_DIRS": str(outside)}, cache=tmp_path / "c"))
    assert lib.load_file(p)[0].data_dirs == (str(outside),)


def test_size_limit_of_a_data_file(tmp_path, monkeypatch):
    from pbrbench.scene import data

    np.save(tmp_path / "h.npy", np.zeros((64, 64)))
    p = _scene(tmp_path, '[[shapes]]\ntype = "heightfield"\nresolution = 8\npath = "h.npy"\n')
    load_scene_file(p)
    monkeypatch.setattr(data, "MAX_DATA_BYTES", 1024)
    data._CHECKED.clear()
    with pytest.raises(SceneError, match=r"asks for 32\.00 KiB .* above the 1\.00 KiB limit"):
        load_scene_file(p)


def test_allow_large_lifts_the_limits(tmp_path, monkeypatch):
    p = SCENES / "expansion-sweep-1500.toml"
    with pytest.raises(SceneError, match="PBRBENCH_ALLOW_LARGE"):
        load_scene_file(p)
    assert len(load_scene_file(p, allow_large=True)) == 1500


def test_unreadable_scene_file_is_one_line(tmp_path, monkeypatch):
    import builtins

    p = _scene(tmp_path, '[[shapes]]\ntype = "sphere"\n')
    real_open = builtins.open

    def denied(file, *a, **k):
        if str(file) == str(p):
            raise PermissionError(13, "Permission denied", str(file))
        return real_open(file, *a, **k)

    monkeypatch.setattr(builtins, "open", denied)
    with pytest.raises(SceneError, match=r"cannot be read \(Permission denied\)"):
        load_scene_file(p)


def test_scene_directory_given_as_a_file(tmp_path):
    with pytest.raises(SceneError, match="is a directory"):
        load_scene_file(tmp_path)


def test_library_still_loads_and_names_are_safe():
    from pbrbench.scene.load import load_library
    from pbrbench.scene.spec import check_scene_name

    lib = load_library()
    assert len(lib) > 30
    for name in lib:
        assert check_scene_name(name) == name


def test_out_directory_name_never_escapes():
    from pbrbench.cli.render import _safe

    for bad in ("..", ".", "", "...", "a/../b"):
        s = _safe(bad)
        assert s not in ("", ".", "..") and "/" not in s


def test_heightfield_params_are_the_surface_signature():
    """Every keyword parameter of every named surface is accepted with its default value."""
    import inspect

    from pbrbench.scene.spec import SceneSpec
    from pbrbench.shading.surfaces import SURFACES

    for name, fn in SURFACES.items():
        params = {}
        for k, prm in inspect.signature(fn).parameters.items():
            if prm.kind is inspect.Parameter.KEYWORD_ONLY:
                d = prm.default
                params[k] = [list(x) for x in d] if isinstance(d, tuple) and d and isinstance(d[0], tuple) else (
                    list(d) if isinstance(d, tuple) else d)
        SceneSpec.model_validate({"name": "t", "description": "d", "lights": [{"type": "directional", "direction": [0, 0, 1]}],
                                  "shapes": [{"type": "heightfield", "surface": name, "params": params, "resolution": 16}]})


if __name__ == "__main__":  # pragma: no cover
    sys.exit(pytest.main([__file__]))
