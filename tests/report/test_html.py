"""The HTML report: one self-contained file whose images all decode, with the expected headline
rows and every user-supplied string escaped; checked by parsing and, where Chromium is
installed (Debian package `chromium`), in a headless browser."""

import base64
import io
import json
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


class EvilTask(FakeTask):
    scenes = ("scene_a", f"scene {EVIL}")


class Parsed(HTMLParser):
    def __init__(self):
        super().__init__()
        self.imgs, self.links, self.scripts, self.headline_rows, self.styles = [], [], 0, [], 0
        self._table = None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "img":
            self.imgs.append(a)
        elif tag in ("link", "iframe", "object", "embed"):
            self.links.append(a)
        elif tag == "script":
            self.scripts += 1
        elif tag == "style":
            self.styles += 1
        elif tag == "table" and "headline" in (a.get("class") or ""):
            self._table = a.get("data-task")
        elif tag == "tr" and self._table and "data-algorithm" in a:
            self.headline_rows.append((self._table, a["data-algorithm"]))

    def handle_endtag(self, tag):
        if tag == "table":
            self._table = None


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("report")
    o = fake_run(tmp, task=EvilTask())
    return tmp, o


def test_self_contained_and_images_decode(report):
    _, o = report
    html = o.report.read_text()
    p = Parsed()
    p.feed(html)
    assert p.scripts == 0 and p.links == [] and p.styles == 1  # CSS inline, nothing fetched
    assert "http://" not in html and "https://" not in html
    # 2 jobs per scene x 2 scenes: 3 images + 2 error maps + 1 plot each, plus 1 history plot
    assert len(p.imgs) == 4 * 6 + 1
    for img in p.imgs:
        src = img["src"]
        assert src.startswith("data:image/png;base64,"), src[:40]
        im = Image.open(io.BytesIO(base64.b64decode(src.split(",", 1)[1], validate=True)))
        im.load()
        assert im.format == "PNG" and im.width > 0 and im.height > 0


def test_headline_rows_and_regression_markers(report):
    tmp, o = report
    p = Parsed()
    p.feed(o.report.read_text())
    assert p.headline_rows == [("fake", "good"), ("fake", "baseline:zero")]
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
    assert html.count('class="mark-regression" title') == 2   # baseline:zero x (local, global)
    assert html.count('class="mark-improvement" title') == 2  # good x (local, global)
    assert "Regression check" in html


def test_user_strings_are_escaped(report):
    _, o = report
    html = o.report.read_text()
    assert EVIL not in html
    assert "&lt;script&gt;alert(" in html
    assert html.count("&lt;script&gt;") >= 3  # task description, scene names, image caption


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
    p1, p2 = Parsed(), Parsed()
    p1.feed(o.report.read_text())
    p2.feed((out / o.run_id / "index.html").read_text())
    assert p2.headline_rows == p1.headline_rows and len(p2.imgs) == len(p1.imgs)
    assert json.loads((out / o.run_id / "scores.json").read_text())["run"]["id"] == o.run_id


CHECK_JS = """<script>
window.addEventListener('error', e => { (window.__errs = window.__errs || []).push(String(e.message || e.type)); }, true);
window.addEventListener('load', () => {
  // the load event waits for every image: a broken one is complete with naturalWidth 0
  const imgs = Array.from(document.images), bad = [];
  imgs.forEach((im, i) => { if (!im.complete || !im.naturalWidth || !im.naturalHeight) bad.push(i); });
  const rows = Array.from(document.querySelectorAll('table.headline tr[data-algorithm]'))
    .map(r => r.closest('table').dataset.task + '/' + r.dataset.algorithm);
  document.body.setAttribute('data-check', JSON.stringify({n: imgs.length, bad: bad, rows: rows, errors: window.__errs || []}));
});
</script>"""


@pytest.mark.skipif(not Path(CHROMIUM).exists(), reason=f"{CHROMIUM} not installed (Debian package `chromium`)")
def test_headless_chromium(report, tmp_path):
    _, o = report
    html = o.report.read_text()
    page = tmp_path / "check.html"
    # the checker goes first in <head>, so it sees every error of the report's own content
    page.write_text(html.replace("<head>", "<head>" + CHECK_JS, 1))
    p = subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--enable-logging=stderr", "--v=0",
                        "--virtual-time-budget=10000", "--dump-dom", page.as_uri()],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr[-2000:]
    marker = 'data-check="'
    assert marker in p.stdout, "the page did not finish loading"
    raw = p.stdout.split(marker, 1)[1].split('"', 1)[0]
    check = json.loads(raw.replace("&quot;", '"').replace("&amp;", "&"))
    assert check["n"] == 25 and check["bad"] == []
    assert check["rows"] == ["fake/good", "fake/baseline:zero"]
    assert check["errors"] == []
    console = [ln for ln in p.stderr.splitlines() if "CONSOLE" in ln]
    assert console == [], console
