"""``pbrbench evaluate TASK DIR``: score predictions written by any program.

DIR is either a ``pbrbench export`` folder (the predictions sit in its job folders, or in the
same tree under ``--predictions``; stored as a run: report, history, compare) or a real data set
on disk: a DiLiGenT-layout folder for photometric stereo (mean / median angular error per
object) or an MIT-Intrinsic-layout folder for lightness (Grosse et al. 2009 LMSE).

An export is checked before it is read (its JSON files, its folders, every prediction file's
header: :mod:`pbrbench.bench.external`); every refused prediction is one line on stderr naming
the file and the fix, the good ones are still scored and stored, and the exit status is 1 when
any prediction failed."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from pbrbench.cli.common import add_cache, add_store, add_variant, settings
from pbrbench.errors import UserError, printable


def register(sub):
    from pbrbench.quality import PRESETS

    p = sub.add_parser("evaluate", help="score an external program's predictions (an export, DiLiGenT or MIT data)",
                       description=__doc__.split("\n", 2)[2].strip())
    p.add_argument("task", metavar="TASK", help="photometric_stereo, sfs, lightness, hdr or specular")
    p.add_argument("dir", metavar="DIR", help="an export folder, or a DiLiGenT / MIT Intrinsic Images folder")
    p.add_argument("--predictions", default=None, metavar="PDIR",
                   help="where the predictions are (default: DIR itself); same sub-folders as DIR")
    p.add_argument("--name", default="external", help="the algorithm name the scores carry (default: external)")
    p.add_argument("--version", default="1", help="its declared version (the files' hash is appended)")
    p.add_argument("--with-builtins", action="store_true", help="score the built-in algorithms in the same run")
    p.add_argument("--quality", choices=list(PRESETS), default=None,
                   help="must match the export's quality (default: the export's)")
    p.add_argument("--no-report", action="store_true", help="store the scores but write no HTML report")
    p.add_argument("--method", action="append", default=[], metavar="NAME",
                   help="real data: a built-in method to run and score (repeatable; default: all of the task's)")
    p.add_argument("--algorithm", action="append", default=[], metavar="TASK=MODULE:FUNCTION[:NAME]",
                   help="real data: also run your own algorithm (as for `pbrbench run --algorithm`)")
    p.add_argument("--json", default=None, metavar="FILE", help="real data: write the scores here as JSON")
    add_store(p)
    add_variant(p)
    add_cache(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from pbrbench.tasks import task_names

    name = args.task.replace("-", "_")
    if name not in task_names():
        raise UserError(f"TASK {args.task!r}: unknown task; choose from {', '.join(task_names())}")
    d = Path(args.dir)
    if not d.exists():
        raise UserError(f"{d}: no such folder")
    if (d / "manifest.json").is_file():
        return _export(args, name, d)
    from pbrbench.bench.realdata import evaluate_folder

    result = evaluate_folder(name, d, methods=args.method, specs=args.algorithm, predictions=args.predictions,
                             name=args.name, settings=settings(args), report=not args.no_report,
                             log=lambda m: print(f"pbrbench: {m}", file=sys.stderr))
    for line in result.lines():
        print(line)
    if args.json:
        Path(args.json).write_text(json.dumps(result.as_dict(), indent=1))
        print(f"scores: {Path(args.json).resolve()}")
    return 1 if result.failures else 0


def _export(args, name: str, d: Path) -> int:
    from pbrbench.bench.external import evaluate_export, read_manifest
    from pbrbench.bench.source import GroundTruthSource
    from pbrbench.cli.run import summary_lines
    from pbrbench.quality import get_quality
    from pbrbench.render.cache import RenderCache
    from pbrbench.scene.load import SceneLibrary
    from pbrbench.tasks import get_tasks

    st = settings(args)
    m = read_manifest(d)
    if args.quality and args.quality != m["quality"]:
        raise UserError(f"--quality {args.quality}: {d} was exported at {m['quality']}; drop --quality or export again")
    task = get_tasks([name], library=SceneLibrary.from_settings(st))[name]
    source = GroundTruthSource(get_quality(m["quality"]), cache=RenderCache(st.cache), variant=st.variant,
                               library=SceneLibrary.from_settings(st))
    o, reader = evaluate_export(task, d, predictions_dir=args.predictions, name=args.name, version=args.version,
                                with_builtins=args.with_builtins, settings=st, source=source,
                                report=not args.no_report, log=lambda msg: print(f"pbrbench: {msg}", file=sys.stderr))
    failed = dict(reader.errors)
    for key, tb in o.errors.items():      # a job that crashed: named too, never silent
        last = [ln for ln in str(tb).splitlines() if ln.strip()]
        failed.setdefault(key, f"job {key}: not scored ({last[-1].strip() if last else 'unknown error'})")
    n_ok = len(m["jobs"]) - len(failed)
    print(f"run {o.run_id}: {args.name} scored on {n_ok} of {len(m['jobs'])} job(s) of {task.name} ({m['quality']})")
    for line in summary_lines(o):
        print(line)
    for msg in failed.values():
        print(printable(f"pbrbench: prediction failed: {msg}"), file=sys.stderr)
    for key, msg in reader.replicate_errors.items():
        if key not in failed:
            print(printable(f"pbrbench: replicate prediction refused (that score has no ± standard error): {msg}"),
                  file=sys.stderr)
    if not m.get("replicates"):
        print("note: the export has no replicate inputs (exported with --no-replicates): the scores carry no ± "
              "standard error")
    elif reader.missing_replicates - set(reader.replicate_errors):
        print(f"note: {len(reader.missing_replicates - set(reader.replicate_errors))} of {len(m['jobs'])} job(s) have no predictions in their "
              "replicates/ folders: those scores carry no ± standard error; run your program on every "
              "jobs/*/replicates/*/ folder too (same inputs, same outputs) to get it")
    elif not reader.replicate_errors:
        print("standard errors: from the predictions on every job's replicate inputs (delete-one-group jackknife)")
    if m.get("replicates") and reader.missing_perturbed:
        print(f"note: {len(reader.missing_perturbed)} of {len(m['jobs'])} job(s) have no predictions in "
              "replicates/perturbed/: their ± is the jackknife's, not tested for an output that jumps with a change "
              "far below the render noise; run your program there too to test it")
    if o.report:
        print(f"report: {o.report.resolve()}")
    return 1 if failed or reader.replicate_errors else 0
