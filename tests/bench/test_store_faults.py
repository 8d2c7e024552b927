"""The results store under faults, in process: read-only opening (archived databases), files that
are not pbrbench databases, writes that fail (full disk) are one-line errors and change nothing,
and databases of an older schema can still be read read-only."""

from __future__ import annotations

import sqlite3

import pytest

from pbrbench.bench.store import MIGRATIONS, Store
from pbrbench.errors import DiskError, UserError
from tests.corpus.faults import Fault, _FullConnection


def _store_with_a_run(path):
    with Store(path) as s:
        rid = s.create_run(quality_name="draft", env={})
        s.add_job_result(rid, "job1", "t", [{"task": "t", "scene": "a", "algorithm": "x", "metric": "m", "value": 1.0}])
        s.set_status(rid, "complete")
    return rid


def test_read_only_store_reads_and_refuses_writes_in_one_line(tmp_path):
    p = tmp_path / "h.sqlite"
    rid = _store_with_a_run(p)
    before = p.read_bytes()
    with Store(p, readonly=True) as s:
        assert s.readonly and [r["id"] for r in s.runs()] == [rid] and len(s.scores(rid)) == 1
        with pytest.raises(DiskError, match="opened read-only") as e:
            s.create_run(quality_name="draft", env={})
        assert "\n" not in str(e.value)
    assert p.read_bytes() == before


@pytest.mark.parametrize("what, words", [("text", "not a readable pbrbench results database"),
                                         ("foreign", "not a pbrbench results database"),
                                         ("directory", "is a directory")])
def test_files_that_are_not_a_results_store(tmp_path, what, words):
    p = tmp_path / "h.sqlite"
    if what == "text":
        p.write_text("hello\n" * 100)
    elif what == "foreign":
        con = sqlite3.connect(p)
        con.execute("CREATE TABLE people (name TEXT)")
        con.commit()
        con.close()
    else:
        p.mkdir()
    for ro in (False, None, True):
        with pytest.raises(UserError, match=words):
            Store(p, readonly=ro)
    if what == "foreign":  # nothing of pbrbench was added to someone else's database
        con = sqlite3.connect(p)
        assert [r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type = 'table'")] == ["people"]
        con.close()


def test_a_full_disk_is_one_line_and_rolls_back(tmp_path):
    p = tmp_path / "h.sqlite"
    rid = _store_with_a_run(p)
    s = Store(p)
    s.conn = _FullConnection(s.conn, Fault("full", str(tmp_path), 0))
    with pytest.raises(DiskError, match=r"cannot write \(database or disk is full\); the disk is full") as e:
        s.add_job_result(rid, "job2", "t", [{"task": "t", "scene": "b", "algorithm": "x", "metric": "m", "value": 2.0}])
    assert "\n" not in str(e.value)
    s.close()
    with Store(p) as s2:
        assert s2.done_jobs(rid) == {"job1"} and len(s2.scores(rid)) == 1 and s2.integrity_ok()


def test_an_older_schema_reads_read_only(tmp_path):
    p = tmp_path / "old.sqlite"
    con = sqlite3.connect(p, isolation_level=None)
    con.execute("CREATE TABLE schema_migrations (version INTEGER PRIMARY KEY, description TEXT NOT NULL, "
                "applied TEXT NOT NULL)")
    for version, desc, sql in MIGRATIONS[:2]:
        for stmt in sql.split(";"):
            if stmt.strip():
                con.execute(stmt)
        con.execute("INSERT INTO schema_migrations VALUES (?, ?, '2025-01-01')", (version, desc))
    con.execute("INSERT INTO runs (id, time, status, config) VALUES ('r1', '2025-01-01T00:00:00+00:00', 'running', '{}')")
    con.close()
    with Store(p, readonly=True) as s:
        (run,) = s.runs()
        # recorded by a pbrbench that kept no process: a 'running' run from long ago is interrupted
        assert run["stored_status"] == "running" and run["status"] == "interrupted"
    with Store(p) as s:  # opened for writing, it is migrated
        assert s.schema_version() == MIGRATIONS[-1][0]


def test_store_in_an_unwritable_place(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(DiskError, match=r"results database .*file/h\.sqlite.*a file stands where a directory"):
        Store(blocker / "h.sqlite")


def test_a_full_out_while_the_report_is_written_names_the_file_and_leaves_no_temporary(tmp_path, monkeypatch):
    """The report's pages and images are written atomically: ENOSPC is one line naming the file and
    --out, and no temporary file stays beside it."""
    import errno

    import pbrbench.io as pio
    from pbrbench.errors import DiskError
    from pbrbench.report.html import write_compare

    def full(fd):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(pio.os, "fsync", full)
    out = tmp_path / "cmp"
    with pytest.raises(DiskError) as err:
        write_compare(out / "index.html", ({"id": "a"}, {"id": "b"}), [], {})
    msg = str(err.value)
    assert "\n" not in msg and str(out / "style.css") in msg and "--out" in msg and "disk is full" in msg, msg
    assert sorted(p.name for p in out.iterdir()) == [], list(out.iterdir())


def test_a_write_that_names_no_file_names_the_places_of_the_command(tmp_path, monkeypatch, capsys):
    """ENOSPC from write() carries no file name: the one line names --out / --store and the fix."""
    import errno

    import pbrbench.cli.history as hist
    from pbrbench.cli.main import main

    def full(args):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(hist, "run", full)
    assert main(["history", "--store", str(tmp_path / "h.sqlite")]) == 1
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and f"--store {tmp_path / 'h.sqlite'}" in err and "free some space" in err, err
