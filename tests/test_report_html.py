"""report.html (vdmrender.reporting.html, issues 35 and 44): the page of a small real render with a sweep and an LOD chain,
of one without, of a --baseline run with a regression, and of a many-bundle run; self-contained (no network
address loaded), every image it names on disk, a table row per report row, the verdict first; and the page in a
real browser (Debian's headless Chromium, `make sysdeps`): its script runs without an error, images load, the
table and plots are in the DOM, a screenshot shows them, images have alt text and the heat-map legend's text is
readable (contrast >= 4.5:1); at 1400 and 1280 px no two text boxes of a plot intersect, the page does not scroll
sideways and the frame viewer is one row."""
from __future__ import annotations

import html
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

from helpers import doubling
from scenes import TINY_HEAD, bake_and_render
from vdmrender.reporting import html as vhtml
from vdmrender import render
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
        self.refs, self.alts, self.rows, self.svgs, self._body, self.ids = [], [], 0, 0, None, set()
        self.scripts, self._script = [], False
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.refs += [a[k] for k in ("src", "href") if a.get(k)]
        self.ids |= {a["id"]} if a.get("id") else set()
        if tag == "img":
            self.alts.append(a.get("alt"))
        if tag == "table":
            self._body = a.get("id")
        if tag == "tr" and self._body == "rows" and "data-object" in a:
            self.rows += 1
        self.svgs += tag == "svg" and "plot" in (a.get("class") or "")
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


# No sweep, so no chain; anti-aliased against a 4-sample reference, so the aliased columns differ from the plain ones.
PLAIN = TINY_HEAD.replace("[render]\n", "[render]\nreference_spp = 4\nantialias = \"msaa4\"\n") + """
[[objects]]
name = "ball"
primitive = "sphere"
techniques = { mesh = {}, coarse = { ratios = [0.3, 0.05] } }
[[objects]]
name = "ring"
primitive = "torus"
techniques = { mesh = {}, coarse = { ratios = [0.2] } }
"""


@pytest.fixture(scope="module")
def plain(tmp_path_factory):
    """A render without a sweep (two objects), and its report."""
    tmp = tmp_path_factory.mktemp("plain")
    r, out = bake_and_render(tmp, PLAIN, "--no-flip")
    assert r.exit_code == 0, r.output
    return tmp, out, json.loads((out / "report.json").read_text())


def verdict_rows(text: str) -> list[list[str]]:
    """The verdict table's rows as their cells' text (a cell spanning rows counted in its first row only)."""
    section = re.search(r"<section id='verdict'>(.*?)</section>", text, re.S)[1]
    body = re.search(r"<table>.*?</table>", section, re.S)[0]
    return [[re.sub(r"<[^>]+>", "", c) for c in re.findall(r"<td[^>]*>(.*?)</td>", tr, re.S)]
            for tr in re.findall(r"<tr[^>]*>(.*?)</tr>", body.split("</thead>")[1], re.S)]


def test_the_page_opens_with_each_chains_bands(swept):
    """Before anything else, per object and chain: each band's sizes, the variant shipped, its time and change at
    the band's largest size, and whether it is within the limit, as lod.json has them."""
    _, out, report = swept
    text = (out / "report.html").read_text()
    assert re.findall(r"<h2[^>]*>([^<]*)</h2>", text)[0] == "Verdict"
    expect = []
    for obj in dict.fromkeys(r["object"] for r in report["rows"]):
        first = True
        for c in report["lod"]["chains"]:
            for k, e in enumerate(c["objects"][obj]["entries"]):
                m = e["measured"][0]
                expect.append(([obj] if first else [])
                              + ([f"{c['name']}: change ΔLuv ≤ {c['limits']['change_dluv']:g}"] if k == 0 else [])
                              + [f"{e['min_px']}–{e['max_px']}", e["variant"], f"{m['median_ms']:.3f}",
                                 f"{m['change_dluv']:.3f}", "yes" if e["meets"] else "no: least change taken"])
                first = False
    assert verdict_rows(text) == expect


def test_a_run_without_a_chain_opens_with_each_objects_front(plain):
    """No sweep: per object the variants no other is both faster and closer to the reference than, fastest
    first; and the aliased columns shown, since anti-aliased frames differ from point-sampled ones."""
    _, out, report = plain
    check_self_contained(out)
    text = (out / "report.html").read_text()
    assert re.findall(r"<h2[^>]*>([^<]*)</h2>", text)[0] == "Verdict"
    listed = [row[-5] for row in verdict_rows(text)]
    expect = []
    for obj in ("ball", "ring"):
        mine = [r for r in report["rows"] if r["object"] == obj]
        front = [r for r in mine if not any(o["median_ms"] <= r["median_ms"] and o["mean_dluv"] <= r["mean_dluv"]
                                            and o is not r for o in mine)]
        expect += [r["label"] for r in sorted(front, key=lambda r: r["median_ms"])]
    assert listed == expect and len(expect) >= 2
    verdict = re.search(r"<section id='verdict'>(.*?)</section>", text, re.S)[1]
    assert re.search(r"<b>error</b>: a variant(&#x27;|')s frames against the reference", verdict)   # said under it
    assert "aliased (point-sampled)" in text


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
        if ref.startswith("#"):   # a link within the page
            assert unquote(ref[1:]) in page.ids, ref
        else:
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
    assert "aliased (point-sampled)" not in text   # no anti-aliasing: the aliased columns would repeat the plain
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
    monkeypatch.setattr(render, "variants", doubling("frame"))
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
    assert (tmp_path / "all" / "one" / "lod.json").is_file()   # each run chose its chain: the verdict says where
    assert re.search(r"Each run's LOD chains[^<]*<a href='one/report.html'>one</a>, <a href='two/report.html'>", text)
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


def chromium(page: Path, *args, window=WINDOW) -> subprocess.CompletedProcess:
    """Headless Chromium on the file, with no network: every host unresolvable, no proxy to reach."""
    return subprocess.run([CHROMIUM, "--headless", "--disable-gpu", "--no-sandbox", "--no-first-run",
                           "--disable-extensions", f"--user-data-dir={page.parent / '.chromium'}",
                           "--host-resolver-rules=MAP * ~NOTFOUND", "--proxy-server=127.0.0.1:9",
                           "--enable-logging=stderr", "--v=0", "--virtual-time-budget=5000", "--hide-scrollbars",
                           f"--window-size={window[0]},{window[1]}", *args, page.as_uri()],
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


# Once the page and its images have loaded: every pair of text boxes within one plot that intersect and every text
# that runs past its plot's edge (the boxes the browser laid out, with its fonts); the widths of the window, the page,
# the rows table and its frame; per frame viewer its row's widths and how many rows its pictures take. A control plot
# with two overlapping labels, one past the edge, goes first: the probe must find them.
GLANCE = """<svg class='plot' aria-label='control' viewBox='0 0 100 40' width='100'><text x='5' y='20'>overlap</text>
<text x='12' y='24'>here</text><text x='70' y='30'>outside</text></svg><script>addEventListener('load', () => {
  const h = document.documentElement, hit = [], out = [], size = e => [e.scrollWidth, e.clientWidth];
  const $$ = (s, e) => [...(e || document).querySelectorAll(s)];
  $$('svg.plot').forEach(s => {
    const label = s.getAttribute('aria-label'), edge = s.getBoundingClientRect();
    const boxes = $$('text', s).map(t => [t.textContent, t.getBoundingClientRect()])
      .filter(([, r]) => r.width > 0 && r.height > 0);
    boxes.forEach(([a, p], i) => {
      if (p.left < edge.left - .5 || p.right > edge.right + .5 || p.top < edge.top - .5 || p.bottom > edge.bottom + .5)
        out.push([label, a]);
      boxes.slice(i + 1).forEach(([b, q]) => {
        if (p.left < q.right && q.left < p.right && p.top < q.bottom && q.top < p.bottom) hit.push([label, a, b]); });
    });
  });
  const rows = document.querySelector('#rows'), verdict = document.querySelector('#verdict');
  h.dataset.glance = JSON.stringify({overlaps: hit, outside: out, window: innerWidth, page: h.scrollWidth,
    table: rows && size(rows.parentElement), plots: $$('svg.plot').length,
    viewers: $$('.trio').map(t => [...size(t), new Set($$('figure', t).map(f => f.offsetTop)).size]),
    verdict: verdict && verdict.getBoundingClientRect().top});
});</script>"""


def glance(page: Path, text: str, width: int) -> dict:
    """The page's text with GLANCE appended, in Chromium at this width: GLANCE's findings, the control's taken out
    (and checked)."""
    probe = page.parent / "glance.html"
    probe.write_text(text.replace("</body>", GLANCE + "</body>"))
    run = chromium(probe, "--dump-dom", window=(width, 900))
    assert run.returncode == 0, run.stderr
    root = re.search(r"<html[^>]*>", run.stdout)[0]
    assert 'data-ready="1"' in root and "data-errors" not in root, root
    g = json.loads(html.unescape(re.search(r'data-glance="([^"]*)"', root)[1]))
    assert [o for o in g["overlaps"] if o[0] == "control"] == [["control", "overlap", "here"]]
    assert [o for o in g["outside"] if o[0] == "control"] == [["control", "outside"]]
    g["overlaps"] = [o for o in g["overlaps"] if o[0] != "control"]
    g["outside"] = [o for o in g["outside"] if o[0] != "control"]
    g["plots"] -= 1
    assert g["window"] == width
    return g


@needs_chromium
@pytest.mark.parametrize("width", [1400, 1280])
@pytest.mark.parametrize("run", ["swept", "plain"])
def test_the_page_at_a_glance(run, width, request, tmp_path):
    """At 1400 px and a laptop's 1280: the verdict on the first screen, no horizontal scrolling of the page, the rows
    table as first shown within its frame, frame, reference, heat map and swipe in one row at fit (the frames
    scaled up to 512 px here, as the demo's are), and no two labels of any plot on top of each other."""
    _, out, _ = request.getfixturevalue(run)
    folder = tmp_path / "page"
    shutil.copytree(out, folder, ignore=shutil.ignore_patterns("sizes", "overview", ".chromium"))
    for png in [p for kind in ("frames", "reference", "heatmaps") for p in (folder / kind).rglob("*.png")]:
        Image.open(png).resize((512, 512), Image.NEAREST).save(png)
    g = glance(folder / "report.html", (out / "report.html").read_text(), width)
    assert g["plots"] >= 2 and g["overlaps"] == [] and g["outside"] == [], g
    assert g["page"] <= width, g
    assert g["table"][0] <= g["table"][1], g
    assert g["viewers"] and all(scroll <= shown and rows == 1 for scroll, shown, rows in g["viewers"]), g
    assert g["verdict"] < 300, g


def crowded() -> str:
    """A page of the plots where labels crowd: a chain of six one-octave bands with long names, a pop at each
    switch, over the limits at the smallest (as lod-villin's), and twelve points of error against time within a
    few percent of each other in time (as the torus's)."""
    names = ["mesh", "tessellated@2", "impostor@direct", "billboards@greedy-hier+coarse", "coarse@0.01", "bump"]
    sizes = [512, 256, 128, 64, 32, 16, 8]
    entries = [{"variant": v, "min_px": sizes[k + 1] if k < 5 else 0, "max_px": sizes[k], "meets": k < 5,
                "measured": [{"size_px": sizes[k], "median_ms": 1.0 + k / 7, "change_dluv": 0.4 * k,
                              "mean_dluv": 2.0 + k, **({"pop_dluv": 1.77 + k / 10} if k else {})}],
                **({"switch_px": [sizes[k + 1] * 0.9, sizes[k + 1] * 1.1]} if k < 5 else {})}
               for k, v in enumerate(names)]
    chain = {"name": "tight", "limits": {"change_dluv": 1.5}}
    colour = vhtml.colours(names)
    rows = [{"object": "torus", "technique": n.split("@")[0], "label": f"{n}#{k}", "median_ms": 210 + k,
             "mean_dluv": 1.0 + (k % 4) * 0.05} for k, n in enumerate(names * 2)]
    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><style>{vhtml.CSS}</style></head><body>"
            f"{vhtml.HATCH}{vhtml.bands('villin', chain, entries, sizes, colour)}{vhtml.time_plot('torus', rows)}"
            f"<script>document.documentElement.dataset.ready = '1';</script></body></html>")


@needs_chromium
@pytest.mark.parametrize("width", [1400, 1280])
def test_crowded_plots_keep_their_labels_apart(tmp_path, width):
    """Every band of a chain named with its variant, cost and pop, and no label on another or past the plot's edge;
    the crowded points' labels left out where they would overlap, but not all of them."""
    text = crowded()
    for name in (">tessellated@2<", ">billboards@greedy-hier+coarse<", "1.14 ms · change 0.40 · pop 1.87<"):
        assert name in text, name
    g = glance(tmp_path / "crowded.html", text, width)
    assert g["plots"] == 2 and g["overlaps"] == [] and g["outside"] == [], g
    labels = re.findall(r"<text[^>]*>([^<]*#\d+)</text>", text)
    assert 2 <= len(labels) < 12, labels


@needs_chromium
def test_choosing_an_object_narrows_the_verdict_and_sections(plain, tmp_path):
    """The object chooser shows the chosen object's verdict, table rows and section only."""
    _, out, _ = plain
    probe = out / "choose.html"
    probe.write_text((out / "report.html").read_text().replace("</body>", """<script>
addEventListener('load', () => { const pick = document.querySelector('#object'), shown = s =>
  [...document.querySelectorAll(s)].filter(e => !e.hidden).map(e => e.dataset.object);
  pick.value = 'ring'; pick.dispatchEvent(new Event('change'));
  document.documentElement.dataset.shown = JSON.stringify([shown('#verdict tbody'), shown('section.obj'),
                                                           shown('#rows tbody tr')]); });</script></body>"""))
    run = chromium(probe, "--dump-dom")
    assert run.returncode == 0, run.stderr
    verdict, sections, rows = json.loads(html.unescape(re.search(r'data-shown="([^"]*)"', run.stdout)[1]))
    assert verdict == ["ring"] and sections == ["ring"] and rows == ["ring", "ring"]


def test_the_verdict_names_what_a_field_of_copies_ships():
    """An object drawn as many copies: its chain's cell says which variant the field's pricing ships."""
    entry = {"variant": "coarse@0.1", "min_px": 0, "max_px": 64, "meets": True,
             "measured": [{"size_px": 64, "median_ms": 1.5, "change_dluv": 0.4}]}
    lod = {"chains": [{"name": "c", "limit_on": "change", "limits": {"change_dluv": 1.0},
                       "objects": {"field": {"entries": [entry], "field": {"chosen": "lod@c"}}}}]}
    text = vhtml.chain_table(lod, ["field"])
    assert "c: change ΔLuv ≤ 1; priced on the field of copies: lod@c ships" in text and "coarse@0.1" in text
