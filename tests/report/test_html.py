"""The HTML report: a small offline site (index, one page per task, history) whose every image
decodes and every link resolves, with the expected headline rows and every user-supplied string
escaped; checked by parsing and, where Chromium is installed (Debian package `chromium`), in a
headless browser, which also saves a screenshot of the index."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import pytest
from PIL import Image

from pbrbench.bench import regress
from pbrbench.bench.run import comparison_record
from pbrbench.bench.store import Store
from pbrbench.report.html import headline_tables, write_report
from tests.fakes import EVIL, FakeTask, fake_run

CHROMIUM = "/usr/bin/chromium"
ARTIFACTS = Path(__file__).resolve().parents[2] / "reports" / "artifacts"


class EvilTask(FakeTask):
    scenes = ("scene_a", f"scene {EVIL}")


class Parsed(HTMLParser):
    def __init__(self):
        super().__init__()
        self.imgs, self.links, self.anchors, self.ids, self.scripts, self.headline_rows = [], [], [], set(), 0, []
        self._table = None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if "id" in a:
            self.ids.add(a["id"])
        if tag == "img":
            self.imgs.append(a)
        elif tag == "a" and "href" in a:
            self.anchors.append(a["href"])
        elif tag in ("link", "iframe", "object", "embed"):
            self.links.append(a)
        elif tag == "script":
            self.scripts += 1
        elif tag == "table" and "headline" in (a.get("class") or ""):
            self._table = a.get("data-task")
        elif tag == "tr" and self._table and "data-algorithm" in a:
            self.headline_rows.append((self._table, a["data-algorithm"]))

    def handle_endtag(self, tag):
        if tag == "table":
            self._table = None


def parse(path: Path) -> Parsed:
    p = Parsed()
    p.feed(path.read_text())
    return p


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    """The report of the second of two runs into one store (the first has no history to plot)."""
    tmp = tmp_path_factory.mktemp("report")
    first = fake_run(tmp, task=EvilTask())
    o = fake_run(tmp, task=EvilTask())
    assert o.run_id != first.run_id
    return tmp, o


def test_a_first_run_draws_no_history_and_says_when_it_will(tmp_path):
    o = fake_run(tmp_path, task=EvilTask())
    site = o.report.parent
    hist = site / "history.html"
    assert parse(hist).imgs == [] and "the plots appear once the store holds two runs" in hist.read_text()
    assert len(parse(site / "task-fake.html").imgs) == 4 * 6   # the job figures, no history plot
    assert not list((site / "history").glob("*.png"))
    # the second run into the same store plots both runs
    o2 = fake_run(tmp_path, task=EvilTask())
    h2 = parse(o2.report.parent / "history.html")
    assert h2.imgs and "over 2 run(s)" in (o2.report.parent / "history.html").read_text()


def test_the_site_is_offline_every_image_decodes_and_every_link_resolves(report):
    _, o = report
    site = o.report.parent
    pages = sorted(site.glob("*.html"))
    assert {p.name for p in pages} == {"index.html", "task-fake.html", "history.html"}
    assert o.report.stat().st_size < 3e6
    n_img = 0
    for page in pages:
        html = page.read_text()
        p = parse(page)
        assert p.scripts == 0 and "http://" not in html and "https://" not in html
        assert p.links == [{"rel": "stylesheet", "href": "style.css"}] and (site / "style.css").is_file()
        for img in p.imgs:
            assert not img["src"].startswith(("data:", "/", "http")), img["src"]
            with Image.open(site / img["src"]) as im:
                im.load()
                assert im.format == "PNG" and im.width > 0 and im.height > 0
            n_img += 1
        for href in p.anchors:
            target, _, frag = href.partition("#")
            doc = site / target if target else page
            assert doc.is_file(), (page.name, href)
            if frag:
                assert frag in parse(doc).ids, (page.name, href)
    # 4 jobs x (3 images + 2 error maps + 1 plot) on the task page, plus the history plots
    task = parse(site / "task-fake.html")
    assert len(task.imgs) == 4 * 6 + 1
    assert n_img >= 4 * 6 + 2


def test_headline_rows_and_regression_markers(report):
    tmp, o = report
    assert parse(o.report).headline_rows == [("fake", "good"), ("fake", "baseline:zero")]
    # a baseline that the run beats for "good" and misses for "baseline:zero"
    entries = {}
    for s in o.scores:
        if s["metric"] != "height_rmse":
            continue
        e = {k: s[k] for k in regress.KEY_FIELDS}
        old = s["value"] * (0.5 if s["algorithm"] == "baseline:zero" else 2.0)
        e.update(value=old, better="lower", tolerance=1e-6)
        entries[regress.score_key(s)] = e
    base = {"format": regress.FORMAT, "quality": "draft", "entries": entries}
    comp = regress.compare(o.scores, base)
    with Store(tmp / "h.sqlite") as st:
        st.set_comparison(o.run_id, dict(comparison_record(comp), baseline_quality="draft"))
        path = write_report(st, o.run_id, out_dir=tmp / "again")
    html = path.read_text()
    assert html.count('class="mark-regression" title') == 2   # baseline:zero x (local, global - local)
    assert html.count('class="mark-improvement" title') == 2  # good x (local, global - local)
    assert "Regression check" in html


def test_user_strings_are_escaped(report):
    _, o = report
    for page in o.report.parent.glob("*.html"):
        html = page.read_text()
        assert EVIL not in html, page.name
    assert "&lt;script&gt;alert(" in (o.report.parent / "task-fake.html").read_text()


def test_headline_is_the_reference_and_the_cost_of_each_effect_on_matched_scenes():
    scores = [{"task": "t", "scene": s, "condition": c, "algorithm": a, "metric": "m", "value": v, "better": "lower",
               "uncertainty": 0.1, "scene_hash": s}
              for a, s, c, v in (("a", "x", "local", 1.0), ("a", "y", "local", 3.0), ("a", "x", "global", 5.0),
                                 ("b", "x", "local", 2.0), ("b", "y", "local", 1.0), ("b", "x", "global", 2.1))]
    (h,) = headline_tables(scores, {"t": {"headline_metric": "m", "conditions": ["local", "area", "global"],
                                          "reference_condition": "local"}})
    assert h["conditions"] == ["local", "global − local"]
    (ra, rb) = h["rows"]
    assert [c["value"] for c in ra["cells"]] == [2.0, 4.0] and [c["n"] for c in ra["cells"]] == [2, 1]
    assert ra["cells"][1]["cls"] == "cost" and rb["cells"][1]["cls"] == "ns"  # 0.1 is within 2 SE
    assert ra["cells"][0]["text"].startswith("2 ±") and rb["cells"][1]["text"].startswith("+0.1")
    assert rb["cells"][0]["colour"].startswith("hsl(120") and ra["cells"][0]["colour"].startswith("hsl(0,")


def test_report_cli_rerenders_from_store_only(report, tmp_path):
    tmp, o = report
    out = tmp_path / "copy"
    shutil.copytree(tmp / "reports" / o.run_id / "figures", out / o.run_id / "figures")
    from pbrbench.cli.main import main

    assert main(["report", o.run_id, "--out", str(out), "--store", str(tmp / "h.sqlite")]) == 0
    p1, p2 = parse(o.report), parse(out / o.run_id / "index.html")
    assert p2.headline_rows == p1.headline_rows
    assert len(parse(out / o.run_id / "task-fake.html").imgs) == len(parse(o.report.parent / "task-fake.html").imgs)
    assert json.loads((out / o.run_id / "scores.json").read_text())["run"]["id"] == o.run_id


CHECK_JS = """<script>
window.addEventListener('error', e => { (window.__errs = window.__errs || []).push(String(e.message || e.type)); }, true);
window.addEventListener('load', () => {
  const imgs = Array.from(document.images);
  imgs.forEach(im => { im.loading = 'eager'; });
  setTimeout(() => {
    const bad = [];
    imgs.forEach((im, i) => { if (!im.complete || !im.naturalWidth || !im.naturalHeight) bad.push(im.getAttribute('src')); });
    const links = Array.from(document.querySelectorAll('a[href^="#"]')).map(a => a.getAttribute('href').slice(1))
      .filter(id => !document.getElementById(id));
    const rows = Array.from(document.querySelectorAll('table.headline tr[data-algorithm]'))
      .map(r => r.closest('table').dataset.task + '/' + r.dataset.algorithm);
    document.body.setAttribute('data-check', JSON.stringify({n: imgs.length, bad: bad, links: links, rows: rows,
                                                             errors: window.__errs || []}));
  }, 500);
});
</script>"""

FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync"]


@pytest.mark.slow   # 2.5 s or more (the fast loop leaves it to make test)
@pytest.mark.skipif(not Path(CHROMIUM).exists(), reason=f"{CHROMIUM} not installed (Debian package `chromium`)")
def test_headless_chromium_every_page_loads_clean(report, tmp_path):
    _, o = report
    site = tmp_path / "site"
    shutil.copytree(o.report.parent, site)
    for page in sorted(site.glob("*.html")):
        # the checker goes first in <head>, so it sees every error of the page's own content
        page.write_text(page.read_text().replace("<head>", "<head>" + CHECK_JS, 1))
        p = subprocess.run([CHROMIUM, *FLAGS, f"--user-data-dir={tmp_path / 'profile'}", "--enable-logging=stderr",
                            "--v=0", "--virtual-time-budget=10000", "--dump-dom", page.as_uri()],
                           capture_output=True, text=True, timeout=120)
        assert p.returncode == 0, p.stderr[-2000:]
        marker = 'data-check="'
        assert marker in p.stdout, f"{page.name} did not finish loading"
        raw = p.stdout.split(marker, 1)[1].split('"', 1)[0]
        check = json.loads(raw.replace("&quot;", '"').replace("&amp;", "&"))
        assert check["bad"] == [] and check["links"] == [] and check["errors"] == [], (page.name, check)
        console = [ln for ln in p.stderr.splitlines() if "CONSOLE" in ln]
        assert console == [], (page.name, console)
        if page.name == "index.html":
            assert check["rows"] == ["fake/good", "fake/baseline:zero"]
        if page.name == "task-fake.html":
            assert check["n"] == 25
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    shot = ARTIFACTS / "report-index.png"
    p = subprocess.run([CHROMIUM, *FLAGS, f"--user-data-dir={tmp_path / 'profile2'}", "--window-size=1400,1800",
                        f"--screenshot={shot}", o.report.as_uri()], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0 and shot.is_file() and shot.stat().st_size > 10_000, p.stderr[-2000:]
    os.utime(shot)


def test_compare_html_page_lists_changes_beyond_the_noise(tmp_path, capsys):
    from pbrbench.cli.main import main

    a = fake_run(tmp_path, seed=0)
    b = fake_run(tmp_path, seed=1)
    out = tmp_path / "cmp" / "index.html"
    assert main(["compare", a.run_id, b.run_id, "--store", str(tmp_path / "h.sqlite"), "--html", str(out)]) == 0
    text = capsys.readouterr().out
    assert f"comparison page: {out.resolve()}" in text
    p = parse(out)
    assert p.scripts == 0 and p.links == [{"rel": "stylesheet", "href": "style.css"}]
    html = out.read_text()
    # seed-dependent "good" changes; the zero baseline is identical in both runs
    assert "baseline:zero" in html and html.count(">same <") >= 4
    for href in p.anchors:
        target, _, frag = href.partition("#")
        assert (out.parent / target).is_file() if target else frag in p.ids, href


class Groups(HTMLParser):
    """The row groups of the headline table of one task: [(class, [(algorithm, [cell texts])])]."""

    def __init__(self, task):
        super().__init__()
        self.task, self.groups, self._in, self._row, self._cell = task, [], False, None, None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "table" and a.get("data-task") == self.task:
            self._in = True
        elif self._in and tag == "tr" and "group" in (a.get("class") or ""):
            self.groups.append((a["data-group"], []))
        elif self._in and tag == "tr" and "data-algorithm" in a:
            assert a.get("data-group") == self.groups[-1][0]
            self._row = (a["data-algorithm"], [])
            self.groups[-1][1].append(self._row)
        elif self._row is not None and tag == "td":
            self._cell = []

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)

    def handle_endtag(self, tag):
        if tag == "td" and self._cell is not None:
            self._row[1].append("".join(self._cell).strip())
            self._cell = None
        elif tag == "tr":
            self._row = None
        elif tag == "table":
            self._in = False


def test_interreflection_headline_has_a_row_group_per_scene_class_and_the_cost_sign_of_every_task(tmp_path):
    # a synthetic stored run of the interreflection task: the local model is right against the direct
    # light (local) and wrong against the full radiance (global) in proportion to how bright the scene is
    from pbrbench.bench.plan import task_info
    from pbrbench.registry import builtin_registry
    from pbrbench.tasks.interreflection import TASK

    err = {"room_white": 0.68, "room_black": 0.12, "groove_reflex_parallel[albedo=0.1]": 0.03,
           "groove_reflex_bisector[albedo=0.1]": 0.05, "groove_reflex_parallel[albedo=0.9]": 0.4,
           "groove_reflex_bisector[albedo=0.9]": 0.5, "ps_cap[albedo=0.9]": 0.3, "cylinder_bump": 0.05,
           "colour_bleeding": 0.12}
    scores = []
    for scene, e in err.items():
        for alg, loc, glo in (("local", 0.01, e), ("radiosity", 0.8 * e, 0.02)):
            for cond, v in (("local", loc), ("global", glo)):
                scores.append({"task": "interreflection", "scene": scene, "scene_hash": scene, "condition": cond,
                               "algorithm": alg, "metric": "radiosity_rel_error", "value": v, "better": "lower",
                               "uncertainty": 0.001, "dof": 1e9})
    reg = builtin_registry({"interreflection": TASK})
    with Store(tmp_path / "h.sqlite") as st:
        run = st.create_run(quality_name="draft", config={"task_info": task_info({"interreflection": TASK}, reg)}, env={})
        st.add_job_result(run, "all", "interreflection", scores)
        st.set_status(run, "complete")
        index = write_report(st, run, out_dir=tmp_path / "site")
    for page in (index, index.parent / "task-interreflection.html"):
        p = Groups("interreflection")
        p.feed(page.read_text())
        assert [g for g, _ in p.groups] == ["grooves, albedo 0.1", "grooves, albedo 0.9", "black room", "white room",
                                            "bump", "concave cap, albedo 0.9", "colour bleeding"], page.name
        rows = {(g, a): cells[1:] for g, rs in p.groups for a, cells in rs}   # cells[0]: the algorithm
        assert all(len(cells) == 3 for cells in rows.values())   # local, global − local, global
        # cost = condition − reference, positive = worse: the local model pays for ignoring interreflection
        assert rows[("white room", "local")][1].startswith("+0.67 ±")
        assert rows[("black room", "local")][1].startswith("+0.11 ±")
        assert rows[("white room", "radiosity")][1].startswith("-0.524 ±")
        assert rows[("grooves, albedo 0.9", "local")][1].startswith("+0.44 ±")   # mean of its two scenes
        assert rows[("white room", "local")][2].startswith("0.68 ±")
    html = (index.parent / "task-interreflection.html").read_text()
    assert 'class="cost"' in html and 'class="gain"' in html and "global − local" in html


def test_the_noise_limited_hint_uses_each_scenes_real_sample_fraction():
    # draft's floor of two samples per group gives 8 spp on scenes that ask for 48 or 240: the
    # run has 1/6 to 1/30 of the files' samples (not the profile's nominal 1/16)
    from pbrbench.report.html import noise_statement

    heads = [{"task": "t", "rows": [{"cells": [{"value": 1.0, "cls": "biased"}, {"value": 2.0, "cls": ""}]}]}]
    gts = [{"spp": 8, "spp_file": 48}, {"spp": 8, "spp_file": 240}, {"spp": 8, "spp_file": 8}]
    ns = noise_statement(heads, gts)
    assert (ns["cells"], ns["limited"]) == (2, 1)
    assert "1/6 to 1/30 of the scene files' samples" in ns["hint"]
    assert "standard error to about 0.41 to 0.18" in ns["hint"]
    # a run at the files' samples, or one stored before the files' counts were recorded: no claim
    assert noise_statement(heads, [{"spp": 48, "spp_file": 48}])["hint"] == ""
    assert noise_statement(heads, [{"spp": 8, "spp_file": None}])["hint"] == ""
    # nothing noise-limited: nothing to say
    assert noise_statement([{"task": "t", "rows": [{"cells": [{"value": 1.0, "cls": ""}]}]}], gts)["hint"] == ""
