"""Hostile exports for ``pbrbench evaluate`` (tests/corpus/evaluate_faults.py): each damages one
prediction file, replicate prediction, ``manifest.json`` or ``job.json`` of a good export, and
the command must exit 1 with one stderr line naming the file, no traceback, nothing read outside
the export, and the good jobs still scored and stored (finite values only).  The command line
runs in this process (the task and ground truths are synthetic: no renderer)."""

from __future__ import annotations

import pytest

from tests.corpus.evaluate_faults import (
    build_base,
    cases,
    classify,
    evaluate,
    job_dirs,
    stored,
)

CASES = cases()


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """The good export every case copies (predictions for every job, not for the replicates)."""
    return build_base(tmp_path_factory.mktemp("evaluate-corpus") / "base")


def test_the_good_export_is_scored_and_exits_0(base, tmp_path):
    r = evaluate(base, tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "scored on 3 of 3" in r.stdout and "prediction failed" not in r.stderr and "Traceback" not in r.stderr
    scores = stored(tmp_path)
    assert {s["condition"] for s in scores if s["metric"] == "normal_mean_deg"} == {"local", "local+noise0.01", "global"}
    assert not [s for s in scores if s["metric"] == "failed" and s["value"] == 1.0]


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_a_hostile_export_is_one_line_and_keeps_the_good_jobs(case, base):
    outcome, msg = classify(case, base)
    assert outcome == "clean", f"{case.kind} {case.name}: {outcome}: {msg}"


def test_two_bad_jobs_are_two_lines_and_the_third_is_scored(base, tmp_path):
    import shutil

    import numpy as np

    exp = tmp_path / "export"
    shutil.copytree(base, exp, symlinks=True)
    d = job_dirs(exp)
    (d[0] / "normals.npy").write_bytes(b"")
    np.save(d[2] / "valid.npy", np.full((40, 40), np.nan))
    r = evaluate(exp, tmp_path)
    lines = [ln for ln in r.stderr.splitlines() if "prediction failed" in ln]
    assert r.returncode == 1 and len(lines) == 2, r.stderr[-2000:]
    assert str(d[0] / "normals.npy") in lines[0] and str(d[2] / "valid.npy") in lines[1]
    assert "scored on 1 of 3" in r.stdout
    assert {s["condition"] for s in stored(tmp_path) if s["metric"] == "normal_mean_deg"} == {"local+noise0.01"}


def test_predictions_elsewhere_must_not_link_out_of_their_folder(base, tmp_path):
    """--predictions PDIR: a job folder of PDIR that is a link to another place is refused before
    anything is scored; the same tree as real folders is scored."""
    import shutil

    exp, pdir = tmp_path / "export", tmp_path / "preds"
    shutil.copytree(base, exp, symlinks=True)
    rel = [p.relative_to(exp) for p in job_dirs(exp)]
    for r_ in rel:
        (pdir / r_).mkdir(parents=True)
        for f in ("normals.npy", "albedo.npy", "valid.npy"):
            shutil.copy(exp / r_ / f, pdir / r_ / f)
    ok = evaluate(exp, tmp_path / "a", ["--predictions", str(pdir)])
    assert ok.returncode == 0 and "scored on 3 of 3" in ok.stdout, ok.stderr[-2000:]
    shutil.rmtree(pdir / rel[0])
    (pdir / rel[0]).symlink_to(exp / rel[0])      # the export's own folder, but outside PDIR
    bad = evaluate(exp, tmp_path / "b", ["--predictions", str(pdir)])
    lines = [ln for ln in bad.stderr.splitlines() if ln.strip() and "%" not in ln and "done" not in ln]
    assert bad.returncode == 1 and len(lines) == 1 and "outside" in lines[0] and "Traceback" not in bad.stderr, bad.stderr
    assert not stored(tmp_path / "b")


def test_there_are_enough_cases():
    kinds = [c.kind for c in CASES]
    assert kinds.count("prediction") >= 40 and kinds.count("export") >= 40 and "replicate" in kinds
