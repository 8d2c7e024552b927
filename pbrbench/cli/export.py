"""``pbrbench export TASK --out DIR``: every job's inputs in open formats, for a program in any
language (score its outputs with ``pbrbench evaluate TASK DIR``)."""

from __future__ import annotations

import sys

from pbrbench.cli.common import add_cache, add_quality, add_variant, settings
from pbrbench.errors import UserError


def register(sub):
    from pbrbench.tasks import task_names

    p = sub.add_parser("export", help="write every job's inputs (EXR, PNG, JSON, exact .npy) for an external program",
                       description="Write every scored job of TASK at the quality profile: images as float32 EXR "
                                   "(and the exact float64 inputs as .npy), light vectors and other numbers in "
                                   "job.json (camera frame, units stated), masks as PNG, and a manifest.json naming "
                                   "each job, its condition and the files a prediction must provide. Then run your "
                                   "program and `pbrbench evaluate TASK DIR`. Tasks: " + ", ".join(task_names()) + ".")
    p.add_argument("task", metavar="TASK", help="the task (e.g. photometric_stereo or photometric-stereo)")
    p.add_argument("--out", required=True, metavar="DIR", help="the export folder (new or empty)")
    add_quality(p)
    p.add_argument("--seed", type=int, default=0, help="the run seed of the noise conditions (default 0)")
    p.add_argument("--no-replicates", action="store_true",
                   help="write only each job's own inputs, not the replicate inputs (jobs/*/replicates/*/: the "
                        "delete-one-group ground truths and a second noise seed) that give evaluate its ± standard "
                        "errors")
    add_variant(p)
    add_cache(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from pbrbench.bench.external import export_task
    from pbrbench.bench.source import GroundTruthSource
    from pbrbench.quality import get_quality
    from pbrbench.render.cache import RenderCache
    from pbrbench.scene.load import SceneLibrary
    from pbrbench.tasks import get_tasks

    st = settings(args)
    from pbrbench.tasks import task_names

    name = args.task.replace("-", "_")
    if name not in task_names():
        raise UserError(f"TASK {args.task!r}: unknown task; choose from {', '.join(task_names())}")
    task = get_tasks([name], library=SceneLibrary.from_settings(st))[name]
    quality = get_quality(args.quality)
    source = GroundTruthSource(quality, cache=RenderCache(st.cache), variant=st.variant,
                               library=SceneLibrary.from_settings(st))
    m = export_task(task, args.out, quality=quality, seed=args.seed, source=source,
                    log=lambda msg: print(f"pbrbench: {msg}", file=sys.stderr), replicates=not args.no_replicates)
    need = ", ".join(f"{p['name']}{'' if p['required'] else ' (optional)'}" for p in m["predictions"])
    print(f"{len(m['jobs'])} job(s) of {task.name} ({m['quality']}, seed {m['seed']}) in {args.out}")
    print(f"write per job folder: {need}; see {args.out}/README.txt")
    print(f"then: pbrbench evaluate {task.name} {args.out}")
    return 0
