"""The results store: every benchmark run and every score, in one SQLite file.

Location: the ``store`` setting (:class:`pbrbench.settings.Settings`: ``--store``, ``PBRBENCH_STORE``,
else ``<out>/history.sqlite``).

Schema (version :data:`SCHEMA_VERSION`, created and upgraded by the explicit, numbered
:data:`MIGRATIONS`; the table ``schema_migrations`` records which have been applied):

* ``runs``: id, time (UTC ISO 8601), git revision, package / mitsuba / drjit / numpy versions,
  variant, machine, quality, config (JSON), status (running | complete | interrupted | failed),
  comparison (JSON: the regression comparison with the baselines, made once by the run);
* ``scores``: run, task, scene, scene_hash, condition, algorithm, algorithm_version, metric,
  value, uncertainty (one standard error, NULL when none was estimated) and the replicate values
  behind it (replicates: the delete-one-group values as JSON; noise_reps: the values at the
  other seeds of a seed-dependent job as JSON, and rep_noise the first of them, the only one
  before schema 6; rep_a, rep_b: the two half-sample values of runs stored before schema 5),
  dof, bias, unstable, perturbed (the value on the perturbed ground truth, where it was scored),
  chaotic (its SE then from independent draws), seconds,
  better (lower | higher), unit, job (the job key, for resuming);
* ``jobs``: which jobs of a run are complete (a job may produce no score; resume skips it);
* ``ground_truths``: per run and scene, the ground truth used (hash, quality, spp, resolution,
  Monte Carlo noise floor, render time) and the scene file's spp: the report shows its noise
  without re-reading renders.

Concurrency: WAL journal and a busy timeout, and every write is one short ``BEGIN IMMEDIATE``
transaction, so two runs writing at once wait for each other instead of failing or corrupting
the file (see ``tests/test_store.py``).

Faults: a database that cannot be written (a read-only file, directory or file system; an
archived copy) is opened read-only by the readers (``Store(path, readonly=None)``: history,
report, compare) without changing its journal mode or migrating it; a write that fails (full
disk, read-only) raises a one-line :class:`~pbrbench.errors.DiskError` naming the file, and
SQLite's transaction keeps the file as it was.  A file that is not a SQLite database is refused
with a one-line error.

Liveness: a run records its process (host, pid, the process's start time) and a heartbeat
(:mod:`pbrbench.bench.liveness`); a ``running`` run whose process is gone reads as
``interrupted`` (:meth:`Store.runs`, :meth:`Store.get_run`), and can be resumed.
"""

from __future__ import annotations

import json
import math
import os
import platform
import secrets
import sqlite3
import subprocess
import time
from collections.abc import Iterable
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path

from pbrbench.errors import DiskError, UserError, disk_error
from pbrbench.uncertainty import noise_values, replicates_of

BUSY_TIMEOUT_MS = 60_000

# (version, description, SQL). Never edit an applied migration: append a new one.
MIGRATIONS: list[tuple[int, str, str]] = [
    (1, "runs, scores, jobs, ground_truths", """
CREATE TABLE runs (
    id TEXT PRIMARY KEY,
    time TEXT NOT NULL,
    git_revision TEXT,
    pbrbench_version TEXT,
    mitsuba_version TEXT,
    drjit_version TEXT,
    numpy_version TEXT,
    variant TEXT,
    machine TEXT,
    quality TEXT,
    config TEXT NOT NULL DEFAULT '{}',
    status TEXT NOT NULL DEFAULT 'running',
    finished TEXT
);
CREATE TABLE scores (
    run TEXT NOT NULL REFERENCES runs(id) ON DELETE CASCADE,
    task TEXT NOT NULL,
    scene TEXT NOT NULL,
    scene_hash TEXT NOT NULL DEFAULT '',
    condition TEXT NOT NULL DEFAULT '',
    algorithm TEXT NOT NULL,
    algorithm_version TEXT NOT NULL DEFAULT '',
    metric TEXT NOT NULL,
    value REAL,
    seconds REAL,
    better TEXT NOT NULL DEFAULT 'lower',
    unit TEXT NOT NULL DEFAULT '',
    job TEXT NOT NULL DEFAULT ''
);
CREATE INDEX scores_run ON scores(run, task);
CREATE INDEX scores_metric ON scores(task, metric, algorithm);
CREATE TABLE jobs (
    run TEXT NOT NULL REFERENCES runs(id) ON DELETE CASCADE,
    job TEXT NOT NULL,
    task TEXT NOT NULL,
    seconds REAL,
    finished TEXT,
    error TEXT,
    PRIMARY KEY (run, job)
);
CREATE TABLE ground_truths (
    run TEXT NOT NULL REFERENCES runs(id) ON DELETE CASCADE,
    scene TEXT NOT NULL,
    scene_hash TEXT,
    quality TEXT,
    spp INTEGER,
    resolution TEXT,
    noise TEXT,
    render_seconds REAL,
    from_cache INTEGER,
    PRIMARY KEY (run, scene)
);
"""),
    (2, "per-score uncertainty; the regression comparison stored with its run", """
ALTER TABLE scores ADD COLUMN uncertainty REAL;
ALTER TABLE runs ADD COLUMN comparison TEXT
"""),
    (3, "the replicate values behind each uncertainty (two half-sample renders, a second seed)", """
ALTER TABLE scores ADD COLUMN rep_a REAL;
ALTER TABLE scores ADD COLUMN rep_b REAL;
ALTER TABLE scores ADD COLUMN rep_noise REAL;
ALTER TABLE ground_truths ADD COLUMN tags TEXT
"""),
    (4, "the process of a run (host, pid, start) and its heartbeat, to tell a dead run from a live one", """
ALTER TABLE runs ADD COLUMN host TEXT;
ALTER TABLE runs ADD COLUMN pid INTEGER;
ALTER TABLE runs ADD COLUMN pid_start TEXT;
ALTER TABLE runs ADD COLUMN heartbeat TEXT
"""),
    (5, "jackknife replicates (delete-one-group, JSON), degrees of freedom, Monte Carlo bias, bimodal flag", """
ALTER TABLE scores ADD COLUMN replicates TEXT;
ALTER TABLE scores ADD COLUMN dof REAL;
ALTER TABLE scores ADD COLUMN bias REAL;
ALTER TABLE scores ADD COLUMN unstable INTEGER
"""),
    (6, "the values of a seed-dependent score at its other seeds (JSON; rep_noise keeps the first)", """
ALTER TABLE scores ADD COLUMN noise_reps TEXT
"""),
    (7, "the scene file's samples per pixel beside the ground truth's (what more samples would change)", """
ALTER TABLE ground_truths ADD COLUMN spp_file INTEGER
"""),
    (8, "a seed-dependent score's value is the mean over its seeds (1; NULL: the job's own seed's draw)", """
ALTER TABLE scores ADD COLUMN noise_mean INTEGER
"""),
    (9, "CPU seconds beside wall seconds, of each job (its process, all threads) and of each render", """
ALTER TABLE jobs ADD COLUMN cpu_seconds REAL;
ALTER TABLE ground_truths ADD COLUMN render_cpu_seconds REAL
"""),
    (10, "the value on the perturbed ground truth and whether the score is chaotic in its input (its SE from draws)", """
ALTER TABLE scores ADD COLUMN perturbed REAL;
ALTER TABLE scores ADD COLUMN chaotic INTEGER
"""),
]
SCHEMA_VERSION = MIGRATIONS[-1][0]

RUN_FIELDS = ("id", "time", "git_revision", "pbrbench_version", "mitsuba_version", "drjit_version",
              "numpy_version", "variant", "machine", "quality", "config", "status", "finished")
SCORE_FIELDS = ("run", "task", "scene", "scene_hash", "condition", "algorithm", "algorithm_version",
                "metric", "value", "seconds", "better", "unit", "job", "uncertainty", "rep_noise", "replicates", "dof",
                "bias", "unstable", "noise_reps", "noise_mean", "perturbed", "chaotic")


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="microseconds")


def new_run_id() -> str:
    """Sortable and unique: UTC time plus 4 random hex digits, e.g. ``20260105-142501-3fa2``."""
    return datetime.now(UTC).strftime("%Y%m%d-%H%M%S") + "-" + secrets.token_hex(2)


def git_revision(cwd: str | os.PathLike | None = None) -> str | None:
    """``git describe``-like revision of the source tree (``+dirty`` when modified), or None."""
    cwd = cwd or Path(__file__).resolve().parents[2]
    try:
        rev = subprocess.run(["git", "rev-parse", "--short=12", "HEAD"], cwd=cwd, capture_output=True,
                             text=True, timeout=10)
        if rev.returncode != 0:
            return None
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=cwd,
                               capture_output=True, text=True, timeout=10)
        return rev.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")
    except (OSError, subprocess.SubprocessError):
        return None


def environment() -> dict:
    """Versions and machine description recorded with each run (imports no renderer)."""
    from pbrbench.versions import version as v

    return {
        "git_revision": git_revision(),
        "pbrbench_version": v("pbrbench"),
        "mitsuba_version": v("mitsuba"),
        "drjit_version": v("drjit"),
        "numpy_version": v("numpy"),
        "machine": f"{platform.node()} {platform.machine()} {os.cpu_count()} cpu, {platform.system()} {platform.release()}, Python {platform.python_version()}",
    }


def _with_liveness(run: dict) -> dict:
    """``status`` as it is (a ``running`` run whose process is gone reads ``interrupted``);
    ``stored_status`` keeps what the database says."""
    from pbrbench.bench.liveness import effective_status

    run["stored_status"] = run.get("status")
    run["status"] = effective_status(run)
    return run


def _json_default(x):
    f = float(x)
    return f if math.isfinite(f) else None


def _num(x):
    """A float for SQLite (NaN and inf are stored as NULL / as themselves respectively)."""
    if x is None:
        return None
    x = float(x)
    return None if math.isnan(x) else x


def _first(xs):
    return xs[0] if xs else None


def _reps(r) -> str | None:
    """Replicate values as JSON text (NaN as null), or None."""
    if r is None:
        return None
    return json.dumps([None if not (isinstance(v, (int, float)) and math.isfinite(v)) else float(v) for v in r])


_READONLY_HINTS = ("readonly", "read-only", "unable to open", "attempt to write", "disk i/o error", "cannot open")


def _is_readonly_error(exc: sqlite3.Error) -> bool:
    return any(h in str(exc).lower() for h in _READONLY_HINTS)


class Store:
    """A connection to the results database (created and migrated on open).

    ``readonly``: False (the default) opens it for writing, creating and migrating it; True opens
    an existing database read-only; None opens it for writing when possible, else read-only (the
    readers: history, report, compare).  :attr:`readonly` says which it got.
    """

    def __init__(self, path: str | os.PathLike, *, readonly: bool | None = False):
        self.path = Path(path)
        self.readonly = False
        self.conn = None
        if self.path.is_dir():
            raise UserError(f"--store {self.path}: is a directory; give the path of a results database file")
        if readonly:
            self._open_readonly()
            return
        try:
            self._open_writable()
        except (UserError, sqlite3.Error, OSError) as exc:
            if readonly is None and self.path.is_file() and (
                    isinstance(exc, OSError) or isinstance(exc, DiskError) or
                    (isinstance(exc, sqlite3.Error) and _is_readonly_error(exc))):
                self._close_quietly()
                self._open_readonly()
                return
            self._close_quietly()
            if isinstance(exc, UserError):
                raise
            raise self._error(exc, "open") from None

    def _open_writable(self):
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise disk_error(exc, f"results database {self.path}", option="--store or PBRBENCH_STORE") from None
        self.conn = sqlite3.connect(str(self.path), timeout=BUSY_TIMEOUT_MS / 1000, isolation_level=None)
        self.conn.row_factory = sqlite3.Row
        self.conn.execute(f"PRAGMA busy_timeout = {BUSY_TIMEOUT_MS}")
        self._retry(lambda: self.conn.execute("PRAGMA journal_mode = WAL"))
        self.conn.execute("PRAGMA foreign_keys = ON")
        self.conn.execute("PRAGMA synchronous = NORMAL")
        self.migrate()

    def _open_readonly(self):
        """Read an existing database without writing a byte (no journal mode, no migration);
        ``immutable`` when even SQLite's shared-memory file cannot be created beside it."""
        if not self.path.is_file():
            raise UserError(f"--store {self.path}: no results database there; run `pbrbench run` first or pass --store")
        from urllib.parse import quote

        uri = "file:" + quote(str(self.path.resolve()))
        last = None
        for extra in ("?mode=ro", "?mode=ro&immutable=1"):
            try:
                conn = sqlite3.connect(uri + extra, uri=True, timeout=BUSY_TIMEOUT_MS / 1000, isolation_level=None)
                conn.row_factory = sqlite3.Row
                conn.execute(f"PRAGMA busy_timeout = {BUSY_TIMEOUT_MS}")
                conn.execute("SELECT count(*) FROM sqlite_master").fetchone()
            except sqlite3.Error as exc:
                last = exc
                continue
            self.conn, self.readonly = conn, True
            break
        else:
            raise self._error(last, "open")
        try:
            tables = {r[0] for r in self.conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
            if "schema_migrations" not in tables:
                raise UserError(f"--store {self.path}: not a pbrbench results database (no schema_migrations table); "
                                "pass another --store")
            v = self.schema_version()
        except sqlite3.Error as exc:
            raise self._error(exc, "read") from None
        if v > SCHEMA_VERSION:
            raise UserError(f"{self.path}: results store has schema version {v}, newer than this pbrbench "
                            f"({SCHEMA_VERSION}); upgrade pbrbench or use another --store")

    def _close_quietly(self):
        if self.conn is not None:
            try:
                self.conn.close()
            except sqlite3.Error:
                pass
            self.conn = None

    def _error(self, exc: BaseException, doing: str) -> UserError:
        """A one-line error for a failed ``doing`` (open / read / write) of the database."""
        msg = str(exc)
        low = msg.lower()
        if "not a database" in low or "malformed" in low or "file is encrypted" in low:
            return UserError(f"--store {self.path}: not a readable pbrbench results database ({msg}); pass another "
                             "--store, or move the file away to start a new one")
        if "full" in low:
            return DiskError(f"results database {self.path}: cannot {doing} ({msg}); the disk is full: free some space "
                             "or choose another place (with --store or PBRBENCH_STORE)")
        if _is_readonly_error(exc):
            return DiskError(f"results database {self.path}: cannot {doing} ({msg}); the file or its directory is not "
                             "writable: fix the permissions or choose another place (with --store or PBRBENCH_STORE)")
        if isinstance(exc, OSError):
            return disk_error(exc, f"results database {self.path}", option="--store or PBRBENCH_STORE")
        return UserError(f"results database {self.path}: cannot {doing} ({type(exc).__name__}: {msg})")

    # ------------------------------------------------------------------ plumbing
    def close(self):
        self._close_quietly()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    @staticmethod
    def _retry(fn, tries: int = 50):
        for i in range(tries):
            try:
                return fn()
            except sqlite3.OperationalError as e:
                if "locked" not in str(e) and "busy" not in str(e) or i == tries - 1:
                    raise
                time.sleep(0.05 * (1 + i % 5))

    @contextmanager
    def transaction(self):
        """One ``BEGIN IMMEDIATE`` transaction (takes the write lock up front: no deadlock).  A
        failed write (full disk, read-only file) is rolled back and raised as a one-line error."""
        if self.readonly:
            raise DiskError(f"results database {self.path}: opened read-only (the file or its directory is not "
                            "writable); this command needs to write it: fix the permissions or pass another --store")
        try:
            self._retry(lambda: self.conn.execute("BEGIN IMMEDIATE"))
        except sqlite3.Error as exc:
            raise self._error(exc, "write") from None
        try:
            yield self.conn
        except BaseException as exc:
            try:
                self.conn.execute("ROLLBACK")
            except sqlite3.Error:
                pass
            if isinstance(exc, sqlite3.Error):
                raise self._error(exc, "write") from None
            raise
        else:
            try:
                self._retry(lambda: self.conn.execute("COMMIT"))
            except sqlite3.Error as exc:
                try:
                    self.conn.execute("ROLLBACK")
                except sqlite3.Error:
                    pass
                raise self._error(exc, "write") from None

    def schema_version(self) -> int:
        row = self.conn.execute("SELECT max(version) FROM schema_migrations").fetchone()
        return int(row[0] or 0)

    def migrate(self) -> list[int]:
        """Apply the migrations not yet applied, in order; returns their versions."""
        with self.transaction() as c:
            tables = {r[0] for r in c.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
            if tables and "schema_migrations" not in tables:
                raise UserError(f"--store {self.path}: a SQLite database of something else (tables "
                                f"{', '.join(sorted(tables)[:5])}), not a pbrbench results database; pass another --store")
            c.execute("CREATE TABLE IF NOT EXISTS schema_migrations (version INTEGER PRIMARY KEY, "
                      "description TEXT NOT NULL, applied TEXT NOT NULL)")
            done = {r[0] for r in c.execute("SELECT version FROM schema_migrations")}
            if done and max(done) > SCHEMA_VERSION:
                raise UserError(f"{self.path}: results store has schema version {max(done)}, newer than this "
                                f"pbrbench ({SCHEMA_VERSION}); upgrade pbrbench or use another --store")
            applied = []
            for version, desc, sql in MIGRATIONS:
                if version in done:
                    continue
                for stmt in sql.split(";"):
                    if stmt.strip():
                        c.execute(stmt)
                c.execute("INSERT INTO schema_migrations VALUES (?, ?, ?)", (version, desc, _now()))
                applied.append(version)
        return applied

    # ------------------------------------------------------------------ runs
    def create_run(self, *, quality_name: str, config: dict | None = None, variant: str | None = None,
                   run_id: str | None = None, env: dict | None = None) -> str:
        run_id = run_id or new_run_id()
        env = environment() if env is None else env
        row = dict(id=run_id, time=_now(), variant=variant, quality=quality_name,
                   config=json.dumps(config or {}, sort_keys=True, default=str), status="running")
        row.update({k: env.get(k) for k in ("git_revision", "pbrbench_version", "mitsuba_version",
                                              "drjit_version", "numpy_version", "machine")})
        cols = ", ".join(row)
        with self.transaction() as c:
            c.execute(f"INSERT INTO runs ({cols}) VALUES ({', '.join('?' * len(row))})", tuple(row.values()))
        return run_id

    def set_status(self, run_id: str, status: str, *, variant: str | None = None):
        with self.transaction() as c:
            fin = _now() if status != "running" else None
            c.execute("UPDATE runs SET status = ?, finished = ? WHERE id = ?", (status, fin, run_id))
            if variant:
                c.execute("UPDATE runs SET variant = ? WHERE id = ?", (variant, run_id))

    def get_run(self, run_id: str) -> dict | None:
        row = self.conn.execute("SELECT * FROM runs WHERE id = ?", (run_id,)).fetchone()
        if row is None:
            return None
        d = dict(row)
        d["config"] = json.loads(d["config"] or "{}")
        d["comparison"] = json.loads(d["comparison"]) if d.get("comparison") else None
        return _with_liveness(d)

    def set_comparison(self, run_id: str, comparison: dict):
        """Store the run's regression comparison (computed once, by the run; the report reads it)."""
        with self.transaction() as c:
            c.execute("UPDATE runs SET comparison = ? WHERE id = ?",
                      (json.dumps(comparison, sort_keys=True, default=_json_default), run_id))

    def get_comparison(self, run_id: str) -> dict | None:
        run = self.get_run(run_id)
        return None if run is None else run["comparison"]

    def resolve_run(self, ref: str | None) -> str:
        """A run id from a reference: an id, a unique prefix, ``latest`` / None, or ``-N``."""
        ids = [r[0] for r in self.conn.execute("SELECT id FROM runs ORDER BY time, rowid")]
        if not ids:
            raise UserError(f"{self.path}: no runs stored yet; run `pbrbench run` first")
        if ref in (None, "", "latest"):
            return ids[-1]
        if ref.startswith("-") and ref[1:].isdigit() and 0 < int(ref[1:]) <= len(ids):
            return ids[-int(ref[1:])]
        if ref in ids:
            return ref
        match = [i for i in ids if i.startswith(ref)]
        if len(match) == 1:
            return match[0]
        if not match:
            raise UserError(f"run {ref!r}: not in {self.path}; `pbrbench history` lists the runs")
        raise UserError(f"run {ref!r} is ambiguous ({', '.join(match[:5])}); give more of the id")

    def runs(self, *, task: str | None = None, quality_name: str | None = None, limit: int | None = None) -> list[dict]:
        """Runs, oldest first, with their number of scores (``task``: only runs that scored it)."""
        q = ("SELECT r.*, (SELECT count(*) FROM scores s WHERE s.run = r.id) AS n_scores, "
             "(SELECT group_concat(DISTINCT task) FROM scores s WHERE s.run = r.id) AS tasks FROM runs r")
        where, args = [], []
        if task:
            where.append("EXISTS (SELECT 1 FROM scores s WHERE s.run = r.id AND s.task = ?)")
            args.append(task)
        if quality_name:
            where.append("r.quality = ?")
            args.append(quality_name)
        if where:
            q += " WHERE " + " AND ".join(where)
        q += " ORDER BY r.time, r.rowid"
        rows = [dict(r) for r in self.conn.execute(q, args)]
        for r in rows:
            r["config"] = json.loads(r["config"] or "{}")
            r["comparison"] = json.loads(r["comparison"]) if r.get("comparison") else None
            _with_liveness(r)
        return rows[-limit:] if limit else rows

    # ------------------------------------------------------------------ liveness
    def set_process(self, run_id: str, *, host: str, pid: int, pid_start: str | None):
        """Record the process that runs ``run_id`` (and a first heartbeat)."""
        with self.transaction() as c:
            c.execute("UPDATE runs SET host = ?, pid = ?, pid_start = ?, heartbeat = ? WHERE id = ?",
                      (host, pid, pid_start, _now(), run_id))

    def beat(self, run_id: str):
        """Refresh the heartbeat of a running run."""
        with self.transaction() as c:
            c.execute("UPDATE runs SET heartbeat = ? WHERE id = ? AND status = 'running'", (_now(), run_id))

    # ------------------------------------------------------------------ scores and jobs
    def add_job_result(self, run_id: str, job_key: str, task: str, scores: Iterable, *,
                       seconds: float | None = None, error: str | None = None, cpu_seconds: float | None = None):
        """Store a finished job's scores and mark the job complete, in one transaction; ``seconds``
        its wall time, ``cpu_seconds`` the CPU time of its process (every thread)."""
        rows = []
        for s in scores:
            d = s if isinstance(s, dict) else s.as_dict()
            rows.append((run_id, d["task"], d["scene"], d.get("scene_hash", "") or "", d.get("condition", "") or "",
                         d["algorithm"], d.get("algorithm_version", "") or "", d["metric"], _num(d["value"]),
                         _num(d.get("seconds")), d.get("better", "lower") or "lower", d.get("unit", "") or "", job_key,
                         _num(d.get("uncertainty")), _num(_first(noise_values(d.get("rep_noise")))),
                         _reps(d.get("replicates")), _num(d.get("dof")), _num(d.get("bias")),
                         None if d.get("unstable") is None else int(bool(d["unstable"])),
                         _reps(noise_values(d.get("rep_noise")) or None), 1 if d.get("noise_mean") else None,
                         _num(d.get("perturbed")), None if d.get("chaotic") is None else int(bool(d["chaotic"]))))
        with self.transaction() as c:
            c.execute("DELETE FROM scores WHERE run = ? AND job = ?", (run_id, job_key))
            c.executemany(f"INSERT INTO scores ({', '.join(SCORE_FIELDS)}) VALUES ({', '.join('?' * len(SCORE_FIELDS))})", rows)
            c.execute("INSERT OR REPLACE INTO jobs (run, job, task, seconds, finished, error, cpu_seconds) "
                      "VALUES (?, ?, ?, ?, ?, ?, ?)", (run_id, job_key, task, seconds, _now(), error, _num(cpu_seconds)))

    def done_jobs(self, run_id: str) -> set[str]:
        """Keys of the jobs of ``run_id`` that completed (without error)."""
        return {r[0] for r in self.conn.execute("SELECT job FROM jobs WHERE run = ? AND error IS NULL", (run_id,))}

    def job_errors(self, run_id: str) -> dict[str, str]:
        return {r[0]: r[1] for r in self.conn.execute("SELECT job, error FROM jobs WHERE run = ? AND error IS NOT NULL", (run_id,))}

    def scores(self, run_id: str, *, task: str | None = None) -> list[dict]:
        q, args = "SELECT * FROM scores WHERE run = ?", [run_id]
        if task:
            q += " AND task = ?"
            args.append(task)
        q += " ORDER BY task, scene, condition, algorithm, metric"
        out = []
        for r in self.conn.execute(q, args):
            d = dict(r)
            if d["value"] is None:
                d["value"] = float("nan")
            if d.get("uncertainty") is None:
                d["uncertainty"] = float("nan")
            d["replicates"] = replicates_of(d)   # older rows: the two half-sample values
            nr = d.pop("noise_reps", None)      # older rows: one other seed, in rep_noise
            d["rep_noise"] = noise_values(nr if nr is not None else d.get("rep_noise")) or None
            if d.get("dof") is None:
                d["dof"] = float(len(d["replicates"]) - 1) if d["replicates"] else 0.0
            if d.get("bias") is None:
                d["bias"] = float("nan")
            if d.get("unstable") is not None:
                d["unstable"] = bool(d["unstable"])
            if d.get("chaotic") is not None:
                d["chaotic"] = bool(d["chaotic"])
            d["noise_mean"] = bool(d.get("noise_mean"))   # older rows: the own seed's draw
            out.append(d)
        return out

    def add_ground_truth(self, run_id: str, scene: str, meta: dict, *, from_cache: bool, spp_file: int | None = None):
        """Record the ground truth ``meta`` of ``scene`` used by the run; ``spp_file``: the samples
        per pixel its scene file asks for (what the standard quality renders at least)."""
        with self.transaction() as c:
            c.execute("INSERT OR REPLACE INTO ground_truths (run, scene, scene_hash, quality, spp, resolution, noise, "
                      "render_seconds, from_cache, tags, spp_file, render_cpu_seconds) "
                      "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                      (run_id, scene, meta.get("scene_hash"), meta.get("quality"), meta.get("spp"),
                       json.dumps(meta.get("resolution")), json.dumps(meta.get("noise", {})),
                       meta.get("wall_s"), int(bool(from_cache)), json.dumps(list(meta.get("tags", []))),
                       None if spp_file is None else int(spp_file), _num(meta.get("cpu_s"))))

    def ground_truths(self, run_id: str) -> list[dict]:
        out = []
        for r in self.conn.execute("SELECT * FROM ground_truths WHERE run = ? ORDER BY scene", (run_id,)):
            d = dict(r)
            d["noise"] = json.loads(d["noise"] or "{}")
            d["resolution"] = json.loads(d["resolution"] or "null")
            d["tags"] = json.loads(d.get("tags") or "[]")
            out.append(d)
        return out

    def metric_history(self, task: str, metric: str, *, quality_name: str | None = None) -> list[dict]:
        """Per run (oldest first) and algorithm: the mean of ``metric`` over scenes and conditions."""
        q = ("SELECT r.id AS run, r.time AS time, s.algorithm AS algorithm, s.condition AS condition, "
             "avg(s.value) AS value, count(s.value) AS n FROM scores s JOIN runs r ON r.id = s.run "
             "WHERE s.task = ? AND s.metric = ?")
        args = [task, metric]
        if quality_name:
            q += " AND r.quality = ?"
            args.append(quality_name)
        q += " GROUP BY r.id, s.algorithm, s.condition ORDER BY r.time, r.rowid"
        return [dict(r) for r in self.conn.execute(q, args)]

    # ------------------------------------------------------------------ export
    def export_run(self, run_id: str, *, status: str | None = None) -> dict:
        """The run, its scores, ground truths and job errors (``status``: the status to show, when
        the run is about to take it)."""
        run = self.get_run(run_id)
        if run is None:
            raise KeyError(run_id)
        if status is not None:
            run["status"] = status
        return {"schema_version": SCHEMA_VERSION, "run": run, "scores": self.scores(run_id),
                "ground_truths": self.ground_truths(run_id), "job_errors": self.job_errors(run_id)}

    def export_json(self, run_id: str, path: str | os.PathLike, *, status: str | None = None) -> Path:
        """Write the run and its scores as JSON (NaN written as null)."""
        data = self.export_run(run_id, status=status)
        for s in data["scores"]:
            for k in ("value", "uncertainty", "bias", "dof"):
                if isinstance(s.get(k), float) and not math.isfinite(s[k]):
                    s[k] = None
        p = Path(path)
        p.parent.mkdir(parents=True, exist_ok=True)
        tmp = p.with_suffix(p.suffix + ".tmp")
        tmp.write_text(json.dumps(data, indent=1, sort_keys=True))
        os.replace(tmp, p)
        return p

    def integrity_ok(self) -> bool:
        return self.conn.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
