"""The algorithm registry: entries, versions that follow the source, quality budgets, pickling,
and the promise that a new method is one module plus one line in its methods table."""

from __future__ import annotations

import pickle
import sys
import textwrap

import numpy as np
import pytest

from pbrbench.quality import get_quality
from pbrbench.registry import Algorithm, Registry, builtin_registry, source_hash
from pbrbench.tasks import get_tasks
from pbrbench.tasks.photometric_stereo import PhotometricStereoTask
from tests.fakes import FakeSource, ps_gt, ps_job, settings_for


def _module(tmp_path, name, body):
    (tmp_path / f"{name}.py").write_text(textwrap.dedent(body))
    sys.path.insert(0, str(tmp_path))
    try:
        __import__(name)
    finally:
        sys.path.remove(str(tmp_path))
    return sys.modules[name]


def test_builtins_come_from_the_methods_tables_and_every_entry_has_a_version():
    from pbrbench.infer.photometric_stereo import METHODS
    from pbrbench.infer.sfs import METHODS as SFS
    from pbrbench.inverse import METHODS as INVERSE

    reg = builtin_registry(get_tasks())
    ps = [a.name for a in reg.for_task("photometric_stereo", kinds=["method"]) if a.name in METHODS]
    assert ps == list(METHODS)          # every table entry, in table order (some with their own interface)
    inv = [a.name for a in reg.for_task("photometric_stereo", kinds=["method"]) if a.interface == "scene"]
    assert inv == [f"inverse:{n}" for n in INVERSE]
    assert [a.name for a in reg.for_task("sfs") if a.kind == "method" and not a.interface][:len(SFS)] == list(SFS)
    for a in reg:
        v = a.full_version
        assert v.count("+") == 1 and len(v.split("+")[1]) == 10, (a.name, v)
    kinds = {a.kind for a in reg}
    assert {"method", "baseline", "floor"} <= kinds


def test_version_hash_changes_when_the_source_changes(tmp_path):
    m1 = _module(tmp_path, "pb_reg_v1", "def fn(x):\n    return x\n")
    m2 = _module(tmp_path, "pb_reg_v2", "def fn(x):\n    return x + 1\n")
    m3 = _module(tmp_path, "pb_reg_v3", "VERSION = '2.1'\ndef fn(x):\n    return x\n")
    a1, a2, a3 = (Algorithm("m", "t", m.fn) for m in (m1, m2, m3))
    assert source_hash(m1.fn) != source_hash(m2.fn)
    assert a1.full_version.startswith("1+") and a3.full_version.startswith("2.1+")
    assert a1.full_version.split("+")[1] == a3.full_version.split("+")[1] or m1 is not m3
    assert Algorithm("m", "t", m1.fn, version="7").full_version.startswith("7+")


def test_a_wrapper_s_version_follows_the_method_it_binds(tmp_path):
    # functools.partial(with_estimated_light, method=kimmel2001) ran kimmel2001's code under the
    # wrapper's version alone: its scores changed with kimmel2001 and its version did not
    import functools

    w = _module(tmp_path, "pb_reg_wrap", "def wrap(x, *, method):\n    return method(x)\n")
    m1 = _module(tmp_path, "pb_reg_bound1", "def fn(x):\n    return x\n")
    m2 = _module(tmp_path, "pb_reg_bound2", "def fn(x):\n    return x + 1\n")
    v1, v2 = (source_hash(functools.partial(w.wrap, method=m.fn)) for m in (m1, m2))
    assert v1 != v2 and source_hash(w.wrap) not in (v1, v2)
    assert source_hash(functools.partial(w.wrap, method=m1.fn)) == v1      # stable
    assert source_hash(functools.partial(w.wrap, scale=2)) == source_hash(w.wrap)   # values: as before
    reg = builtin_registry(get_tasks(["sfs"]))
    est = reg.get("sfs", "kimmel2001+estimated_light").full_version
    assert est != reg.get("sfs", "horn1989+estimated_light").full_version


def test_a_method_s_version_follows_the_helper_modules_and_methods_it_imports(tmp_path, monkeypatch):
    # photometric stereo's shared solvers (_common), the Poisson integrator, the method another
    # calls (zheng_chellappa1991's horn1989, inverse rendering's starts): a change to any of them
    # changes the results of the methods that run it, and so must their version
    from pbrbench import registry

    monkeypatch.setattr(registry, "HELPER_PACKAGES", registry.HELPER_PACKAGES + ("pb_hlp",))
    hashes = []
    for body in ("def step(x):\n    return x\n", "def step(x):\n    return x + 1\n"):
        for name in [n for n in sys.modules if n.startswith("pb_hlp")]:
            monkeypatch.delitem(sys.modules, name)
        registry._SOURCE_HASHES.clear()
        pkg = tmp_path / f"v{len(hashes)}" / "pb_hlp"
        pkg.mkdir(parents=True)
        (pkg / "__init__.py").write_text("")
        (pkg / "_common.py").write_text(body)
        (pkg / "method.py").write_text("from pb_hlp._common import step\n\ndef solve(x):\n    return step(x)\n")
        (pkg / "other.py").write_text("from pb_hlp import method\n\ndef solve(x):\n    return method.solve(x)\n")
        monkeypatch.syspath_prepend(str(pkg.parent))
        import importlib

        method, other = (importlib.import_module(f"pb_hlp.{m}") for m in ("method", "other"))
        assert registry.helper_modules("pb_hlp.method") == ["pb_hlp._common"]
        assert registry.helper_modules("pb_hlp.other") == ["pb_hlp._common", "pb_hlp.method"]   # through a method
        hashes.append((source_hash(method.solve), source_hash(other.solve)))
    assert hashes[0][0] != hashes[1][0] and hashes[0][1] != hashes[1][1]
    registry._SOURCE_HASHES.clear()
    from pbrbench.infer.sfs import horn1989, zheng_chellappa1991
    from pbrbench.inverse import nicolet2021

    assert "pbrbench.infer.sfs.horn1989" in registry.helper_modules(zheng_chellappa1991.__name__)
    assert "pbrbench.infer.sfs._common" in registry.helper_modules(horn1989.__name__)
    starts = registry.helper_modules(nicolet2021.__name__)
    assert {f"pbrbench.infer.photometric_stereo.{s}" for s in nicolet2021.STARTS} <= set(starts)
    # the other photometric-stereo methods are no part of inverse rendering's version (its noise scales
    # are keyed by it), nor documentation
    assert "pbrbench.infer.photometric_stereo.wu2010" not in starts and "pbrbench.infer._docstring" not in starts


def test_quality_budgets_are_merged_and_entries_pickle():
    reg = builtin_registry(get_tasks(["sfs", "hdr"]))
    horn = reg.get("sfs", "horn1989")
    assert horn.options_for(get_quality("draft")) == {"max_iter": 50}
    assert horn.options_for(get_quality("standard")) == {}
    assert reg.get("hdr", "mitsunaga1999").options_for(get_quality("draft")) == {"degree": 5}
    back = pickle.loads(pickle.dumps(horn))
    assert back.name == horn.name and back.full_version == horn.full_version
    assert back.options_for(get_quality("draft")) == {"max_iter": 50} and back.cost_note == horn.cost_note
    assert reg.get("sfs", "horn1989+estimated_light").variant_of == "horn1989"


def test_entry_metadata_is_validated_when_the_registry_is_built():
    from pbrbench.quality import PRESETS

    def fn(images, lights, *, mask=None, max_iter=10):
        return images

    Algorithm("a", "t", fn, budgets={"draft": {"max_iter": 5}}).check(PRESETS)
    with pytest.raises(ValueError, match="unknown quality profile"):
        Algorithm("a", "t", fn, budgets={"drafty": {"max_iter": 5}}).check(PRESETS)
    with pytest.raises(ValueError, match="max_iters is not a parameter"):
        Algorithm("a", "t", fn, budgets={"draft": {"max_iters": 5}}).check(PRESETS)
    with pytest.raises(ValueError, match="options tol"):
        Algorithm("a", "t", fn, options={"tol": 1}).check(PRESETS)
    assert pickle.loads(pickle.dumps(get_quality("draft"))) is get_quality("draft")


def test_registry_refuses_duplicates_bad_kinds_and_unknown_names():
    reg = Registry([Algorithm("a", "t", len)])
    with pytest.raises(ValueError, match="registered twice"):
        reg.add(Algorithm("a", "t", len))
    reg.add(Algorithm("a", "t", abs), replace=True)
    assert reg.get("t", "a").fn is abs
    with pytest.raises(ValueError, match="kind"):
        Algorithm("b", "t", len, kind="magic")
    with pytest.raises(ValueError, match="name"):
        Algorithm("a|b", "t", len)
    with pytest.raises(KeyError, match="has no algorithm 'zz'"):
        reg.get("t", "zz")


class TinyPS(PhotometricStereoTask):
    """The photometric-stereo task on one synthetic sphere (no renderer)."""

    def jobs(self, quality):
        return [ps_job("local", scene="s")]


class SyntheticSource(FakeSource):
    def load(self, spec):
        gt, _ = ps_gt()
        gt.meta["scene_hash"] = spec.content_hash()
        return gt


def test_a_new_method_is_one_module_plus_one_line_in_its_table(tmp_path, monkeypatch):
    from pbrbench.bench.run import RunConfig, run_benchmark
    from pbrbench.infer.photometric_stereo import METHODS

    mod = _module(tmp_path, "pb_ps_mymethod", '''
        """A test method: Woodham's least squares with the normals rounded to 1e-3."""
        import numpy as np
        from pbrbench.infer.photometric_stereo import photometric_stereo_woodham1980

        def photometric_stereo_rounded2026(images, lights, *, mask=None):
            r = photometric_stereo_woodham1980(images, lights, mask=mask)
            n = np.round(r.normals, 3)
            return {"normals": n, "albedo": r.albedo, "valid": r.valid}
        ''')
    monkeypatch.setitem(METHODS, "rounded2026", mod.photometric_stereo_rounded2026)   # the one line
    o = run_benchmark(RunConfig(quality="draft"), settings=settings_for(tmp_path), tasks={"photometric_stereo": TinyPS()},
                      source=SyntheticSource(tmp_path / "cache"), log=lambda m: None)
    assert not o.errors
    mine = {s["metric"]: s["value"] for s in o.scores if s["algorithm"] == "rounded2026"}
    assert 0 < mine["normal_mean_deg"] < 0.1 and mine["coverage"] == 1.0
    assert {s["algorithm_version"] for s in o.scores if s["algorithm"] == "rounded2026"} == \
        {Algorithm("x", "t", mod.photometric_stereo_rounded2026).full_version}
    assert 'data-algorithm="rounded2026"' in o.report.read_text()
    assert "normals: rounded2026" in (o.report.parent / "task-photometric_stereo.html").read_text()


def test_a_failing_or_malformed_algorithm_is_scored_as_failed_and_the_job_goes_on(tmp_path):
    from pbrbench.bench.run import RunConfig, run_benchmark

    def raises(images, lights, *, mask=None):
        raise RuntimeError("my bug")

    def nan_normals(images, lights, *, mask=None):
        k, h, w = images.shape
        return np.full((h, w, 3), np.nan), np.ones((h, w))

    def wrong_shape(images, lights, *, mask=None):
        return np.zeros((3, 3, 3)), np.zeros((3, 3))

    task = TinyPS()
    reg = builtin_registry({task.name: task})
    for fn in (raises, nan_normals, wrong_shape):
        reg.add(Algorithm(fn.__name__, task.name, fn, kind="plugin"))
    o = run_benchmark(RunConfig(quality="draft"), settings=settings_for(tmp_path), tasks={task.name: task},
                      source=SyntheticSource(tmp_path / "cache"), registry=reg, log=lambda m: None)
    assert not o.errors
    sc = {(s["algorithm"], s["metric"]): s["value"] for s in o.scores}
    for name in ("raises", "nan_normals", "wrong_shape"):
        assert sc[(name, "failed")] == 1.0 and (name, "normal_mean_deg") not in sc
    assert sc[("woodham1980", "normal_mean_deg")] < 0.01
    html = o.report.read_text()
    assert "RuntimeError: my bug" in html and "non-finite" in html and "shape" in html
