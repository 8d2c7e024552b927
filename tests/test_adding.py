"""docs/adding.md, proved: a photometric-stereo method is one module plus one line in
``METHODS``.  The module is written to a temporary folder (outside pbrbench), its function is
put into the table at run time, and with nothing else edited it is run by the benchmark task on a
synthetic draft job, scored, documented by the dispatcher and shown in the generated report."""

from __future__ import annotations

import importlib
import textwrap

import numpy as np

from pbrbench.bench.run import RunConfig, run_benchmark
from pbrbench.infer import photometric_stereo as ps
from pbrbench.tasks.photometric_stereo import PhotometricStereoTask
from tests.fakes import FakeSource, ps_gt, ps_job, settings_for

MODULE = '''
"""Photometric stereo by least squares on the brighter half of the lights (a test method)."""

from pbrbench.infer._docstring import docstring
from pbrbench.infer.photometric_stereo._common import DOCS, least_squares, prepare

VERSION = "7"


@docstring(DOCS)
def photometric_stereo_demo2099(images, lights, *, mask=None, intensities=None, shadow_threshold: float = 0.5,
                                saturation=None, min_lights: int = 3):
    r"""Least squares over the lights brighter than half the brightest (Woodham 1980).

    .. math:: g = \\arg\\min_g \\sum_{k: I_k > I_{max}/2} (V_k \\cdot g - I_k)^2

    Parameters
    ----------
    %(inputs)s
    %(options)s

    Returns
    -------
    %(result)s

    References
    ----------
    R. J. Woodham, "Photometric method for determining surface orientation from multiple
    images", Optical Engineering 19(1), 1980.
    """
    return least_squares(prepare(images, lights, mask, intensities, shadow_threshold, saturation, min_lights))
'''


class OneJob(PhotometricStereoTask):
    def jobs(self, quality):
        return [ps_job("local", scene="ps_a")]


class Synthetic(FakeSource):
    def load(self, spec):
        gt = ps_gt()[0]
        gt.meta["scene_hash"] = spec.content_hash()
        return gt


def test_a_new_method_is_one_module_and_one_table_line(tmp_path, monkeypatch):
    (tmp_path / "mods").mkdir()
    (tmp_path / "mods" / "demo2099.py").write_text(textwrap.dedent(MODULE))
    monkeypatch.syspath_prepend(str(tmp_path / "mods"))
    fn = importlib.import_module("demo2099").photometric_stereo_demo2099
    monkeypatch.setitem(ps.METHODS, "demo2099", fn)            # the one table line

    # the dispatcher and its option checking read the table; help() shows the shared parameters
    imgs, lights = np.stack([ps_gt()[0][f"light{k:02d}.direct"][..., 0] for k in range(5)]), ps_gt()[1]
    a = ps.solve_photometric_stereo(imgs, lights, method="demo2099")
    np.testing.assert_array_equal(a.normals, fn(imgs, lights).normals)
    assert "shadow_threshold : float" in fn.__doc__ and "%(" not in fn.__doc__

    task = OneJob()
    out = run_benchmark(RunConfig(quality="draft", seed=0, entry_points=False), settings=settings_for(tmp_path),
                        tasks={task.name: task}, source=Synthetic(tmp_path / "cache"), log=lambda m: None)
    assert not out.errors, out.errors
    mine = {s["metric"]: s for s in out.scores if s["algorithm"] == "demo2099"}
    assert {"normal_mean_deg", "coverage", "albedo_rel_err"} <= set(mine)
    assert 0 <= mine["normal_mean_deg"]["value"] < 45 and 0 < mine["coverage"]["value"] <= 1
    assert mine["normal_mean_deg"]["algorithm_version"].startswith("7+")
    others = {s["algorithm"] for s in out.scores}
    conds = {s["condition"] for s in out.scores}
    ran = {a.name for a in task.builtin_algorithms() if a.name in ps.METHODS and any(a.applies(c) for c in conds)}
    assert ran and ran <= others                                     # the built-in methods of its condition ran too
    html = out.report.read_text()
    assert 'data-algorithm="demo2099"' in html
