"""report.html (vdmrender.html, issue 35): the page of a small real render with a sweep and an LOD chain, of a
--baseline run with a regression, and of a many-bundle run; self-contained (no network address loaded), every
image it names on disk, a table row per report row; and the page in a real browser (Debian's headless Chromium,
`make sysdeps`): its script runs without an error, images load, the table and plots are in the DOM, a screenshot
shows them, images have alt text and the heat-map legend's text is readable (contrast >= 4.5:1)."""
from __future__ import annotations

import json
import re
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from scenes import TINY_HEAD, bake_and_render
from vdmrender import measure
from vdmrender.cli import main as render_main

pytestmark = pytest.mark.gl

SCENE = TINY_HEAD.replace("orbit = { count = 1 }", "orbit = { count = 2 }") + """
[render.sweep]
sizes = [32, 8]
[[render.sweep.lod]]
name = "loose"
mean_dluv = 50.0
pop_dluv = 10.0
[[objects]]
name = "ball"
primitive = "sphere"
techniques = { mesh = {}, coarse = { ratios = [0.3, 0.05] } }
"""


class Page(HTMLParser):
    """What a test needs of the page: every src and href, every img's alt, the table's body rows, the SVGs."""

    def __init__(self, text: str):
        super().__init__()
        self.refs, self.alts, self.rows, self.svgs, self._body = [], [], 0, 0, None
        self.scripts, self._script = [], False
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.refs += [a[k] for k in ("src", "href") if a.get(k)]
        if tag == "img":
            self.alts.append(a.get("alt"))
        if tag == "table":
            self._body = a.get("id")
        if tag == "tr" and self._body == "rows" and "data-object" in a:
            self.rows += 1
        self.svgs += tag == "svg"
        self._script = tag == "script"

    def handle_data(self, data):
        if self._script:
            self.scripts.append(data)

    def handle_endtag(self, tag):
        self._script = False


@pytest.fixture(scope="module")
def swept(tmp_path_factory):
    """A render with a sweep and an LOD chain (two cameras, two sizes), and its report."""
    tmp = tmp_path_factory.mktemp("swept")
    r, out = bake_and_render(tmp, SCENE, "--no-flip")
    assert r.exit_code == 0, r.output
    return tmp, out, json.loads((out / "report.json").read_text())


def frame_urls(text: str) -> list[str]:
    """The image URLs the viewer's data (the JSON script) names."""
    data = json.loads(re.search(r"<script type='application/json' id='frames'>(.*?)</script>", text, re.S)[1])
    return [u for obj in data.values() for u in
            obj["ref"] + [x for v in obj["variants"].values() for x in v["frame"] + v["heat"]]]


def check_self_contained(folder: Path) -> Page:
    """No address on the network loaded, every file the page names there, scripts and style inline."""
    text = (folder / "report.html").read_text()
    page = Page(text)
    assert not re.search(r"""<(script|link|img)[^>]*(src|href)=['"]?(https?:)?//""", text)
    assert not re.search(r"url\(\s*['\"]?(https?:)?//", text) and "@import" not in text
    for ref in page.refs + frame_urls(text):
        assert not re.match(r"[a-z]+:", ref), ref
        assert (folder / unquote(ref)).exists(), ref
    assert all(page.alts), "an image without alt text"
    return page


def test_the_page_holds_the_render(swept):
    _, out, report = swept
    page = check_self_contained(out)
    assert page.rows == len(report["rows"]) == 3
    text = (out / "report.html").read_text()
    # per object: the error-against-time plot, change, error and cost against size, the chain's bands
    assert page.svgs == 5 and text.count("class='pt'") == 3 + 3 * len(report["sweep"]["rows"])
    assert "the floor: what no variant changes" in text
    assert "chain loose" in text and "Pareto front" in text
    for raw in ("report.json", "report.csv", "sweep.csv", "lod.json", "lod.md"):
        assert f"href='{raw}'" in text
    assert report["device"] in text and "reference 1 spp" in text
    assert len((out / "report.html").read_bytes()) < 200_000   # the frames are referenced, not inlined


def test_a_regression_comes_first_with_frames_before_and_after(swept, monkeypatch):
    """A baseline whose coarse@0.05 error was lower, and this run's frame pass doubled: the row over the error
    threshold first, coloured, with its frames of both runs; the rows whose counters changed follow."""
    tmp, out, report = swept
    old = json.loads((out / "report.json").read_text())
    for r in old["rows"]:
        if r["label"] == "coarse@0.05":
            r["mean_dluv"] = 0.0   # its error here is about 0.5-0.8
    (out / "old.json").write_text(json.dumps(old))
    monkeypatch.setenv(measure.DOUBLE_PASS, "frame")
    new = tmp / "new"
    r = CliRunner().invoke(render_main, [str(tmp / "b.bundle"), "-o", str(new), "--no-flip", "--baseline",
                                         str(out / "old.json"), "--max-error-increase", "0.2"])
    assert r.exit_code == 1, r.output
    check_self_contained(new)
    text = (new / "report.html").read_text()
    changes = re.search(r"<table id='changes'>.*?</table>", text, re.S)[0]
    first = re.search(r"<tr class='([^']*)' data-object='ball'><td>ball</td><td>([^<]*)<", changes)
    assert first[2] == "coarse@0.05" and "regression" in first[1]
    assert "../out/frames/ball/coarse%400.05/000.png" in text   # the baseline's own frames, relative
    assert "frame 0, before" in text and "frame 0, after" in text


def test_many_bundles_one_page(swept, tmp_path):
    """Two bundles in a folder: the combined page names each object as SCENE/OBJECT, one at a time past a few,
    links each run's own page, and its images lie in the runs' folders."""
    tmp, _, _ = swept
    bundles = tmp_path / "bundles"
    bundles.mkdir()
    for name in ("one", "two"):
        shutil.copytree(tmp / "b.bundle", bundles / f"{name}.bundle")
    r = CliRunner().invoke(render_main, [str(bundles), "-o", str(tmp_path / "all"), "--no-flip", "--sizes", "32"])
    assert r.exit_code == 0, r.output
    page = check_self_contained(tmp_path / "all")
    assert page.rows == 6
    text = (tmp_path / "all" / "report.html").read_text()
    assert "href='one/report.html'" in text and "<option value='two/ball'>" in text
    assert "one/frames/ball/mesh/000.png" in text


# --- in a real browser ----------------------------------------------------------------------------------------

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
needs_chromium = pytest.mark.skipif(CHROMIUM is None, reason="Debian's chromium is not installed (`make sysdeps` "
                                                              "installs it): the page is not checked in a browser")
WINDOW = (1280, 1600)

# Appended to a copy of the page (the page itself carries nothing for tests): where the first plot and the table
# lie, and the heat-map legend's colours as the browser computed them.
PROBE = """<script>(function () {
  const box = e => { const r = e.getBoundingClientRect(); return [r.left, r.top, r.width, r.height]; };
  const h = document.documentElement, l = getComputedStyle(document.querySelector('.legendbar'));
  h.dataset.plot = JSON.stringify(box(document.querySelector('svg.plot')));
  h.dataset.table = JSON.stringify(box(document.querySelector('#rows')));
  h.dataset.legend = JSON.stringify([l.color, l.backgroundColor]);
})();</script>"""


def chromium(page: Path, *args) -> subprocess.CompletedProcess:
    """Headless Chromium on the file, with no network: every host unresolvable, no proxy to reach."""
    return subprocess.run([CHROMIUM, "--headless", "--disable-gpu", "--no-sandbox", "--no-first-run",
                           "--disable-extensions", f"--user-data-dir={page.parent / '.chromium'}",
                           "--host-resolver-rules=MAP * ~NOTFOUND", "--proxy-server=127.0.0.1:9",
                           "--enable-logging=stderr", "--v=0", "--virtual-time-budget=5000", "--hide-scrollbars",
                           f"--window-size={WINDOW[0]},{WINDOW[1]}", *args, page.as_uri()],
                          capture_output=True, text=True, timeout=120)


def luminance(css: str) -> float:
    """WCAG's relative luminance of a computed CSS colour rgb(r, g, b)."""
    c = np.array([int(v) for v in re.findall(r"\d+", css)[:3]]) / 255
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return float(lin @ [0.2126, 0.7152, 0.0722])


@needs_chromium
def test_the_page_in_a_browser(swept):
    _, out, report = swept
    probe = out / "probe.html"
    probe.write_text((out / "report.html").read_text().replace("</body>", PROBE + "</body>"))
    run = chromium(probe, "--dump-dom")
    assert run.returncode == 0, run.stderr
    dom = run.stdout
    root = re.search(r"<html[^>]*>", dom)[0]
    assert 'data-ready="1"' in root and "data-errors" not in root, root   # the script ran; every image loaded
    assert not [line for line in run.stderr.splitlines() if ":CONSOLE(" in line], run.stderr
    assert dom.count("<svg class=\"plot\"") == 5 and len(re.findall(r"<tr data-object=", dom)) == len(report["rows"])
    # the viewer filled its frame list from the page's data: one option per camera
    assert len(re.findall(r"<option value=\"\d\">", dom)) >= 2
    page = Page(dom)
    assert page.alts and all(page.alts)
    fg, bg = json.loads(re.search(r"data-legend=\"([^\"]*)\"", dom)[1].replace("&quot;", '"'))
    light, dark = sorted((luminance(fg), luminance(bg)), reverse=True)
    assert (light + 0.05) / (dark + 0.05) >= 4.5

    shot = out / "shot.png"
    run = chromium(probe, f"--screenshot={shot}")
    assert run.returncode == 0, run.stderr
    img = np.asarray(Image.open(shot).convert("RGB"), float)
    assert img.shape[:2] == (WINDOW[1], WINDOW[0]) and img.std() > 10   # not blank
    for key in ("plot", "table"):
        x, y, w, h = (round(v) for v in json.loads(re.search(rf"data-{key}=\"([^\"]*)\"", dom)[1]))
        assert w > 200 and h > 50 and y + h <= WINDOW[1], (key, x, y, w, h)
        region = img[y:y + h, x:x + w]
        assert region.std() > 10 and len(np.unique(region.reshape(-1, 3), axis=0)) > 8, key   # drawn, not empty
