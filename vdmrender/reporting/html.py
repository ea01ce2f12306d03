"""report.html (issues 35 and 44): one self-contained page per render folder, and in the combined folder of many
bundles, read at a glance at 1280 px: first the verdict per object (each LOD chain's bands: the variant shipped,
its cost and change, within the limit or not; without a chain, the Pareto front), then a sortable and searchable
table of the rows in column groups, per object the error-against-time plot (hover a point: variant, time, error,
counters; the Pareto front drawn), the sweep plots and LOD chains where present, and per variant and frame its
frame, reference, heat map and a swipe side by side; the run's header (device, GL, clocks, timing rule,
filtering, tool version) last. docs/report.md describes it.

Offline and self-contained: the style and script are inline and hand-written, the plots inline SVG built here, so
the page opens from the file system with no network. Images are referenced by relative path (they are in the
folder already), never inlined, so the page stays small."""
from __future__ import annotations

import html
import json
import math
import os
from pathlib import Path
from urllib.parse import quote

from vdmbake.bundle import staging
from vdmbake.scene import LIMIT_ON

from ..deciding.lod import CHANGE

# Files a render folder may hold, linked from the header where present (docs/guide.md lists what each is).
RAW = ("report.json", "report.csv", "error_vs_time.png", "sweep.csv", "error_vs_size.png", "cost_vs_size.png",
       "lod.json", "lod.md", "lod.png", "baseline.md", "baseline.csv", "composite.md", "runs.md", "overview")

# The table's columns, in groups a reader shows or hides (the first groups shown at first, so that the table fits a
# laptop's window): (key of the row as report.csv spells it, header with its unit, decimals (None: text), group).
GROUPS = {"variant": "", "time": "time", "change": "change against the full asset",
          "error": "error against the reference", "floor": "floor and noise", "aliased": "aliased (point-sampled)",
          "spread": "timing spread", "work": "work and memory"}
SHOWN = ("variant", "time", "change", "error")
COLUMNS = [("object", "object", None, "variant"), ("label", "variant", None, "variant"),
           ("median_ms", "GPU [ms]", 3, "time"), ("ratio_to_baseline", "relative [×]", 2, "time"),
           ("change_dluv", "ΔLuv", 3, "change"), ("change_iou", "IoU", 4, "change"),
           ("mean_dluv", "mean ΔLuv", 3, "error"), ("p95_dluv", "p95 ΔLuv", 2, "error"),
           ("max_dluv", "max ΔLuv", 2, "error"), ("iou", "IoU", 4, "error"), ("flip_mean", "FLIP", 4, "error"),
           ("floor_dluv", "floor ΔLuv", 3, "floor"), ("reference_noise_dluv", "noise ΔLuv", 3, "floor"),
           ("aliased_mean_dluv", "mean ΔLuv", 3, "aliased"), ("aliased_p95_dluv", "p95 ΔLuv", 2, "aliased"),
           ("aliased_iou", "IoU", 4, "aliased"),
           ("q1_ms", "q1 [ms]", 3, "spread"), ("q3_ms", "q3 [ms]", 3, "spread"),
           ("spread_ms", "spread [ms]", 3, "spread"), ("wall_ms", "wall [ms]", 3, "spread"),
           ("sm_clock", "SM clock [MHz]", None, "spread"),
           ("fragments_px", "fragments [/px]", 2, "work"), ("fetches_px", "fetches [/px]", 1, "work"),
           ("steps_px", "steps [/px]", 1, "work"), ("primitives", "primitives", 0, "work"),
           ("faces", "faces", 0, "work"), ("gpu_mib", "GPU memory [MiB]", 2, "work"),
           ("coverage", "coverage", 3, "work"), ("empty_frames", "empty frames", 0, "work")]

# Every abbreviation the page uses, said once in words (the legend under the table; <abbr> titles in the headers).
GLOSSARY = {
    "ΔLuv": "the colour difference of a pixel in CIE L*u*v* (ΔE*uv; about 1 is just noticeable side by side), "
            "averaged over the pixels the object covers in either image",
    "change": "a variant's frames against its object's full asset drawn the same way (what a viewer sees change "
              "when an engine switches to it); 0 for the full asset itself",
    "error": "a variant's frames against the reference, a ray-traced image of the same scene",
    "p95": "the 95th percentile of the per-pixel ΔLuv", "max": "the largest per-pixel ΔLuv",
    "IoU": "intersection over union of the covered pixels (1: the same silhouette)",
    "FLIP": "NVIDIA's ꟻLIP perceptual difference, 0 (none) to 1",
    "GPU [ms]": "median GPU time per frame from timer queries (see timing in the run's details)",
    "relative [×]": "the GPU time over that of the object's mesh variant (its first variant where it has none), "
                    "timed in the same run; not the --baseline run",
    "floor": "the full asset's own mean ΔLuv against the reference: what the pipeline costs whatever the "
             "representation",
    "noise": "the reference's own sampling noise in ΔLuv: no difference below it can be told from noise",
    "aliased": "the error of the frames drawn without anti-aliasing against a one-sample reference; shown only "
               "where it differs from the plain error",
    "q1, q3": "the quartiles of the GPU times", "wall": "the median wall-clock time per frame",
    "LOD": "level of detail: a chain of variants, each shipped over a band of sizes on screen",
    "/px": "per pixel the object covers", "pop": "the mean ΔLuv between two variants' frames at the size where "
                                                "a chain switches between them",
}

# Page colours: text on background, and the heat-map legend's text on its own background (contrast >= 4.5:1,
# checked by tests/test_report_html.py in the browser).
TEXT, BACKGROUND, MUTED = "#1a1a1a", "#ffffff", "#555555"
LEGEND_TEXT, LEGEND_BACKGROUND = "#1a1a1a", "#f4f4f4"
# matplotlib's tab10: the variants' colours in the plots, as in the PNG plots
PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22",
           "#17becf")
# inferno at 0, 1/4, 1/2, 3/4, 1: the heat maps' scale (vdmrender.common.images.heatmap)
INFERNO = ("#000004", "#57106e", "#bc3754", "#f98e09", "#fcffa4")
ALL_AT_ONCE = 6   # up to this many objects the page shows them all at first; more, one at a time

CSS = f"""
body {{ font: 14px/1.4 system-ui, sans-serif; color: {TEXT}; background: {BACKGROUND}; margin: 0 1.5em 3em;
  max-width: 1600px; }}
h1 {{ font-size: 1.4em; margin: .6em 0 .2em; }} h2 {{ font-size: 1.2em; margin: 1.4em 0 .4em; }}
h3 {{ font-size: 1.05em; margin: 1em 0 .3em; }} h4 {{ margin: .8em 0 .2em; }}
.muted {{ color: {MUTED}; }} dl {{ display: grid; grid-template-columns: max-content auto; gap: .1em 1em; }}
dt {{ font-weight: 600; }} dd {{ margin: 0; }} details {{ margin: .3em 0; }} summary {{ cursor: pointer; }}
nav.controls {{ position: sticky; top: 0; background: {BACKGROUND}; padding: .5em 0; border-bottom: 1px solid #ccc;
  z-index: 2; display: flex; gap: 1em; flex-wrap: wrap; align-items: center; }}
.plots {{ display: flex; flex-wrap: wrap; gap: 1em; }} svg.plot {{ width: 560px; max-width: 100%; height: auto; }}
svg text {{ font: 11px system-ui, sans-serif; fill: {TEXT}; }} svg .grid {{ stroke: #ddd; }}
svg .axis {{ stroke: #333; }} svg .pt {{ cursor: pointer; }} svg .pt:hover, svg .pt:focus {{ stroke: #000;
  stroke-width: 2; }} .legend span {{ margin-right: 1em; white-space: nowrap; display: inline-block; }}
.swatch {{ display: inline-block; width: .9em; height: .9em; vertical-align: middle; margin-right: .3em;
  border: 1px solid #0003; }}
#tip {{ position: fixed; pointer-events: none; background: #222; color: #fff; padding: .3em .5em; border-radius: 3px;
  font-size: 12px; white-space: pre; display: none; z-index: 5; }}
.tablewrap {{ max-height: 70vh; overflow: auto; border: 1px solid #ccc; max-width: 100%; }}
table {{ border-collapse: collapse; font-size: 12px; }} th, td {{ padding: 2px 6px; border-bottom: 1px solid #eee; }}
th {{ background: #eef; text-align: left; }} #rows thead tr:last-child th {{ position: sticky; top: 0;
  cursor: pointer; }} th.group {{ text-align: center; border-left: 2px solid #fff; font-weight: 600; }}
td.n {{ text-align: right; font-variant-numeric: tabular-nums; }} th[aria-sort=ascending]::after {{ content: " ▲"; }}
th[aria-sort=descending]::after {{ content: " ▼"; }}
#rows td:nth-child(-n+2) {{ white-space: nowrap; }} abbr {{ text-decoration: underline dotted; }}
.groups label {{ margin-right: .8em; white-space: nowrap; }}
{" ".join(f"#rows.hide-{g} .g-{g} {{ display: none; }}" for g in GROUPS if g != "variant")}
#verdict table {{ font-size: 13px; }} #verdict td, #verdict th {{ padding: 3px 8px; }}
#verdict tbody {{ border-top: 2px solid #889; }}
tr.over > td:not([rowspan]), .swatch.over {{ background: repeating-linear-gradient(135deg, #fff0, #fff0 3px, #0002 3px,
  #0002 5px); }}
.viewer .trio {{ display: flex; gap: .8em; align-items: flex-start; overflow: auto; }}
.viewer .trio figure {{ flex: 0 1 auto; min-width: 0; }} .viewer.fit img {{ max-width: 100%; height: auto; }}
.viewer figure, .pair figure {{ margin: 0; }} .viewer img, .pair img {{ display: block; }}
.viewer:not(.fit) img, .pair img {{ image-rendering: pixelated; image-rendering: crisp-edges; }}
.swipe {{ position: relative; display: inline-block; }}
.swipe img.top {{ position: absolute; left: 0; top: 0; width: 100%; }}
.legendbar {{ color: {LEGEND_TEXT}; background: {LEGEND_BACKGROUND}; padding: .3em .5em; display: inline-block;
  margin-top: .4em; }} .legendbar .bar {{ display: inline-block; width: 200px; height: .9em; vertical-align: middle;
  margin: 0 .4em; background: linear-gradient(to right, {", ".join(INFERNO)}); }}
.regression {{ background: #fde2e1; }} .worse {{ color: #8a3b00; }} .better {{ color: #1b6e20; }}
.pair {{ display: flex; gap: .5em; flex-wrap: wrap; }}
.obj {{ border-top: 2px solid #889; margin-top: 1.5em; }}
"""

# The page's script: the object chooser and search, the sortable table, the tooltips, the frame viewer. Errors
# (script or a missing image) are written into <html data-errors>, and data-ready set when it ran through, so that a
# test reading the DOM sees both.
JS = """
(function () {
  const $ = (s, e) => (e || document).querySelector(s), $$ = (s, e) => [...(e || document).querySelectorAll(s)];
  const frames = JSON.parse($('#frames').textContent);
  const tip = $('#tip');
  $$('.pt').forEach(p => {
    const show = ev => { tip.textContent = p.dataset.tip; tip.style.display = 'block';
      const r = p.getBoundingClientRect(); tip.style.left = (r.right + 8) + 'px'; tip.style.top = (r.top - 4) + 'px'; };
    p.addEventListener('mouseenter', show); p.addEventListener('focus', show);
    p.addEventListener('mouseleave', () => tip.style.display = 'none');
    p.addEventListener('blur', () => tip.style.display = 'none');
  });
  // sortable table: numbers by data-v, text otherwise; empty cells last
  const heads = $$('#rows thead tr:last-child th');
  heads.forEach((th, i) => th.addEventListener('click', () => {
    const up = th.getAttribute('aria-sort') !== 'ascending';
    heads.forEach(h => h.removeAttribute('aria-sort'));
    th.setAttribute('aria-sort', up ? 'ascending' : 'descending');
    const body = $('#rows tbody'), key = tr => tr.children[i].dataset.v;
    const rows = $$('tr', body).sort((a, b) => {
      const x = key(a), y = key(b);
      if (x === '' || y === '') return (x === '') - (y === '');
      const d = isNaN(x) || isNaN(y) ? x.localeCompare(y) : x - y;
      return up ? d : -d;
    });
    rows.forEach(r => body.appendChild(r));
  }));
  // the table's column groups, shown or hidden
  $$('.groups input').forEach(c => c.addEventListener('change', () =>
    $('#rows').classList.toggle('hide-' + c.value, !c.checked)));
  // one object at a time (or all), and a search over the table's rows
  const pick = $('#object'), search = $('#search');
  function filter() {
    const obj = pick.value, q = search.value.toLowerCase();
    $$('section.obj, #verdict tbody').forEach(s => s.hidden = obj !== '*' && s.dataset.object !== obj);
    let shown = 0;
    $$('#rows tbody tr').forEach(tr => {
      tr.hidden = (obj !== '*' && tr.dataset.object !== obj) || !tr.textContent.toLowerCase().includes(q);
      shown += !tr.hidden;
    });
    $$('option', pick).forEach(o => o.hidden = o.value !== '*' && !o.value.toLowerCase().includes(q)
      && !$$('#rows tbody tr').some(tr => tr.dataset.object === o.value && tr.textContent.toLowerCase().includes(q)));
    $('#shown').textContent = shown + ' of ' + $$('#rows tbody tr').length + ' rows';
  }
  pick.addEventListener('change', filter); search.addEventListener('input', filter); filter();
  // the frame viewer: variant, frame and zoom chosen; frame, reference and heat map side by side, and a swipe
  $$('.viewer').forEach(v => {
    const data = frames[v.dataset.object], vs = $('.v-variant', v), fs = $('.v-frame', v), zs = $('.v-zoom', v);
    const imgs = { frame: $$('.i-frame', v), ref: $$('.i-ref', v), heat: $$('.i-heat', v) };
    const cut = $('.v-cut', v), top = $('.swipe img.top', v);
    // fit: each image at most its share of the row and at most 1x; a zoom: that many screen pixels per pixel
    function size() { const z = +zs.value; v.classList.toggle('fit', !z);
      $$('img:not(.top)', v).forEach(i => { i.style.width = z && i.naturalWidth ? i.naturalWidth * z + 'px' : ''; }); }
    function show() {
      const d = data.variants[vs.value], k = +fs.value;
      imgs.frame.forEach(i => { i.src = d.frame[k]; i.alt = vs.value + ' frame ' + k; });
      imgs.heat.forEach(i => { i.src = d.heat[k]; i.alt = vs.value + ' heat map, frame ' + k; });
      imgs.ref.forEach(i => { i.src = data.ref[k]; i.alt = 'reference, frame ' + k; });
    }
    function options() {
      const d = data.variants[vs.value]; fs.innerHTML = '';
      d.frame.forEach((_, k) => fs.add(new Option(String(k).padStart(3, '0') + '  ΔLuv ' + d.error[k], k)));
      show();
    }
    vs.addEventListener('change', options); fs.addEventListener('change', show); zs.addEventListener('change', size);
    $$('img', v).forEach(i => i.addEventListener('load', size));
    size();
    cut.addEventListener('input', () => top.style.clipPath = 'inset(0 ' + (100 - cut.value) + '% 0 0)');
    $('.v-toggle', v).addEventListener('click', () => { cut.value = cut.value > 50 ? 0 : 100;
      cut.dispatchEvent(new Event('input')); });
    v.addEventListener('keydown', ev => { if (ev.key === 't') $('.v-toggle', v).click(); });
  });
  document.documentElement.dataset.ready = '1';
})();
"""
# Before any other script: errors of the page's script and images that fail to load, kept in the DOM.
CATCH = """
window.addEventListener('error', e => { const h = document.documentElement, t = e.target;
  const what = t && t !== window && t.src ? 'failed to load ' + t.getAttribute('src') : String(e.message);
  h.dataset.errors = (h.dataset.errors ? h.dataset.errors + ' | ' : '') + what; }, true);
"""


def write(folder: Path, report: dict) -> None:
    """folder/report.html for the report (report.finite()'s), its images referenced relative to the folder."""
    (folder / "report.html").write_text(page(folder, report))


def esc(x) -> str:
    return html.escape(str(x), quote=True)


def url(*parts: str) -> str:
    """A relative URL to a file in the folder (each part percent-encoded: labels hold @ and +)."""
    return "/".join(quote(p) for p in "/".join(parts).split("/") if p)


def num(v, digits) -> str:
    if v is None:
        return "–"
    return f"{v:,.0f}" if digits == 0 else f"{v:.{digits}f}"


def combined(report: dict) -> bool:
    """A many-bundle report (vdmrender.many): objects spelled SCENE/OBJECT, each run in its own sub-folder."""
    return "runs" in report


def where(report: dict, obj: str) -> tuple[str, str]:
    """(the sub-folder of the run that rendered the object, the object's own name)."""
    return (obj.split("/", 1)[0] + "/", obj.split("/", 1)[1]) if combined(report) else ("", obj)


def target(folder: Path) -> Path:
    """The folder the page will be read in: a render writes into a hidden staging sibling that is then swapped
    into place (vdmbake.bundle.staging)."""
    return staging.target(folder)


def page(folder: Path, report: dict) -> str:
    rows = report["rows"]
    objects = list(dict.fromkeys(r["object"] for r in rows))
    title = f"vdmrender report: {Path(report.get('bundle') or target(folder)).name}"
    body = [f"<h1>{esc(title)}</h1>", summary(folder, report), controls(objects), verdict(folder, report, objects),
            baseline_section(folder, report), table(rows)]
    if combined(report):
        body.append(runs_table(folder, report["runs"]))
    data = {obj: viewer_data(folder, report, obj) for obj in objects}
    body += [object_section(report, obj, data[obj]) for obj in objects]
    body.append(header(report))
    script = json.dumps(data, separators=(",", ":")).replace("</", "<\\/")
    return (f"<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
            f"<meta name='viewport' content='width=device-width, initial-scale=1'><title>{esc(title)}</title>"
            f"<script>{CATCH}</script><style>{CSS}</style></head><body>\n{HATCH}\n" + "\n".join(b for b in body if b)
            + f"\n<div id='tip' role='tooltip'></div><script type='application/json' id='frames'>{script}</script>"
            f"<script>{JS}</script></body></html>\n")


def summary(folder: Path, report: dict) -> str:
    """One line under the title: the device, the frame, what the error compares; and the raw files."""
    res, f = report.get("resolution"), report.get("filtering")
    what = [report.get("device") or "–"] + ([f"frame {res[0]} × {res[1]} px"] if res else [])
    if f:
        what.append(f"reference {f['reference_spp']} samples per pixel, frames anti-aliased {f['antialias']}")
    return (f"<p class='muted'>{esc(' · '.join(what))} (more under <a href='#run'>the run</a> at the end)</p>"
            f"<p>raw files: {links(folder)}</p>")


def header(report: dict) -> str:
    """The run: device, GL strings, clocks, timing rule, filtering, tool version, and the rules in words."""
    gl, nvml, f = report.get("gl") or {}, report.get("nvml"), report.get("filtering")
    items = [("device", report.get("device") or "–"), ("tool version", report.get("tool_version"))]
    if gl:
        items.append(("GL", f"{gl.get('vendor')} · {gl.get('renderer')} · {gl.get('version')}"))
    if nvml:
        items += [(f"GPU {g['index']}", f"{g['name']}: SM {g['sm_clock_mhz']} of {g['sm_clock_max_mhz']} MHz, "
                                        f"memory {g['mem_clock_mhz']} MHz, busy {g['util_pct']}%, clock reasons: "
                                        f"{', '.join(g['clock_reasons']) or 'none'} (driver {nvml['driver']})")
                  for g in nvml["gpus"]]
    elif gl:
        items.append(("clocks", "not read (no NVIDIA NVML on this device)"))
    res = report.get("resolution")
    if res:
        items.append(("frame", f"{res[0]} × {res[1]} px"))
    if report.get("budget"):
        items.append(("budget", ", ".join(f"{k} {v}" for k, v in report["budget"].items())))
    if f:
        items.append(("filtering", f"reference {f['reference_spp']} spp ({f['reference_filter']}), frames "
                                   f"anti-aliased {f['antialias']}; {f['aliased']}"))
    if report.get("bundle"):
        items.append(("bundle", report["bundle"]))
    dl = "".join(f"<dt>{esc(k)}</dt><dd>{esc(v)}</dd>" for k, v in items)
    notes = "".join(f"<details><summary>{esc(k)}</summary><p>{esc(report[k])}</p></details>"
                    for k in ("timing", "error", "flip", "how") if isinstance(report.get(k), str))
    return f"<h2 id='run'>The run</h2><dl>{dl}</dl>{notes}"


def abbr(word: str) -> str:
    """The word with the glossary's words for it on hover."""
    return f"<abbr title='{esc(GLOSSARY[word])}'>{esc(word)}</abbr>"


def glossary(keys) -> str:
    return ("<p class='glossary muted'>" + "; ".join(f"<b>{esc(k)}</b>: {esc(GLOSSARY[k])}" for k in keys)
            + ".</p>")


def verdict(folder: Path, report: dict, objects: list[str]) -> str:
    """What the run answers, per object: where the run chose LOD chains, each chain's bands of screen sizes with
    the variant shipped there, its cost and its change against the full asset there (each band judged at its
    largest size) and whether it is within the chain's limits; for an object without a chain, the variants no
    other beats on both time and error (its Pareto front), fastest first. A combined page links the runs' own pages
    for their chains."""
    lod = report.get("lod") or {}
    chained = [o for o in objects if any(o in c["objects"] for c in lod.get("chains", []))]
    out = ["<section id='verdict'><h2>Verdict</h2>"]
    if chained:
        out += [f"<p>What to ship at each size on screen (the object's bounding sphere, in px), per "
                f"{abbr('LOD')} chain: the cheapest variant whose change against the "
                "full asset is within the chain's limit there.</p>", chain_table(lod, chained),
                "<p class='legend muted'><span><i class='swatch over'></i>hatched: over the limit (no variant is "
                "within it at these sizes; the one of least change is shipped)</span> <span>GPU [ms] and change: "
                "at the band's largest size, where the chain judges it</span></p>",
                glossary(("change", "ΔLuv"))]
    rest = [o for o in objects if o not in chained]
    if rest:
        out += ["<p>" + ("Objects without a chain: the" if chained else "The") + " variants no other is both faster "
                "and closer to the reference than (the Pareto front), fastest first.</p>", front_table(report, rest)]
    runs = [r["scene"] for r in report.get("runs", []) if (folder / r["scene"] / "lod.json").is_file()]
    if runs:
        out.append("<p>Each run's LOD chains, what to ship at each size on screen, are on its own page: "
                   + ", ".join(f"<a href='{url(s, 'report.html')}'>{esc(s)}</a>" for s in runs) + ".</p>")
    if rest and not chained:
        out.append(glossary(("GPU [ms]", "change", "error", "ΔLuv")))
    return "".join(out) + "</section>"


def limits(c: dict) -> str:
    """A chain's limits in words: "change ΔLuv ≤ 1"."""
    name = {"mean_dluv": "ΔLuv", "p95_dluv": "p95 ΔLuv", "flip": "FLIP", "iou": "IoU"}
    words = {field: f"{'change' if on == 'change' else 'error'} {name[k]}" for on, keys in LIMIT_ON.items()
             for k, field in keys.items()}
    return ", ".join(f"{words.get(k, k)} {'≥' if k.endswith('iou') else '≤'} {v:g}" for k, v in c["limits"].items())


def chain_table(lod: dict, objects: list[str]) -> str:
    head = ("<thead><tr><th>object</th><th>chain: limit</th><th>size on screen [px]</th><th>ship</th>"
            f"<th>{abbr('GPU [ms]')}</th><th>{abbr('change')} {abbr('ΔLuv')}</th><th>within the limit</th>"
            "</tr></thead>")
    bodies = []
    for obj in objects:
        lines = []
        for c in lod["chains"]:
            ch = c["objects"].get(obj)
            if not ch:
                continue
            shown = LIMIT_ON[c.get("limit_on", "change")]["mean_dluv"]
            limit = limits(c)
            if "field" in ch:   # an object drawn as many copies: what the field ships (lod.priced_on_field)
                limit += f"; priced on the field of copies: {ch['field']['chosen']} ships"
            for k, e in enumerate(ch["entries"]):
                m = e["measured"][0]
                value = num(m.get(shown), 3) + ("" if shown == CHANGE else " (error)")
                cells = (f"<td class='n'>{e['min_px']}–{e['max_px']}</td><td>{esc(e['variant'])}</td>"
                         f"<td class='n'>{num(m.get('median_ms'), 3)}</td><td class='n'>{value}</td>"
                         f"<td>{'yes' if e['meets'] else 'no: least change taken'}</td>")
                first = "" if k else f"<td rowspan='{len(ch['entries'])}'>{esc(c['name'])}: {esc(limit)}</td>"
                lines.append([first, cells, e["meets"]])
        lines[0][0] = f"<td rowspan='{len(lines)}'><a href='#obj-{quote(obj)}'>{esc(obj)}</a></td>" + lines[0][0]
        bodies.append(f"<tbody data-object='{esc(obj)}'>" + "".join(f"<tr{'' if meets else ' class=over'}>{a}{b}</tr>"
                                          for a, b, meets in lines) + "</tbody>")
    return f"<table>{head}{''.join(bodies)}</table>"


def front_table(report: dict, objects: list[str]) -> str:
    head = (f"<thead><tr><th>object</th><th>variant</th><th>{abbr('GPU [ms]')}</th>"
            f"<th>{abbr('change')} {abbr('ΔLuv')}</th><th>{abbr('error')} {abbr('ΔLuv')}</th><th></th></tr></thead>")
    bodies = []
    for obj in objects:
        pts = [r for r in report["rows"] if r["object"] == obj and r["mean_dluv"] is not None and r["median_ms"]]
        front = pareto(pts)
        if not front:
            continue
        lines = []
        for k, r in enumerate(front):
            role = ", ".join(w for w, yes in (("fastest", k == 0), ("least error", k == len(front) - 1)) if yes)
            first = "" if k else f"<td rowspan='{len(front)}'><a href='#obj-{quote(obj)}'>{esc(obj)}</a></td>"
            lines.append(f"<tr>{first}<td>{esc(r['label'])}</td><td class='n'>{num(r['median_ms'], 3)}</td>"
                         f"<td class='n'>{num(r.get('change_dluv'), 3)}</td><td class='n'>{num(r['mean_dluv'], 3)}"
                         f"</td><td class='muted'>{role}</td></tr>")
        bodies.append(f"<tbody data-object='{esc(obj)}'>" + "".join(lines) + "</tbody>")
    return f"<table>{head}{''.join(bodies)}</table>"


def links(folder: Path) -> str:
    found = [name for name in RAW if (folder / name).exists()]
    return " · ".join(f"<a href='{url(n)}'>{esc(n)}</a>" for n in found)


def controls(objects: list[str]) -> str:
    """The object chooser (all, or one at a time) and the search box."""
    first = "*" if len(objects) <= ALL_AT_ONCE else objects[0]
    opts = [f"<option value='*'{' selected' if first == '*' else ''}>all {len(objects)} objects</option>"]
    opts += [f"<option value='{esc(o)}'{' selected' if o == first else ''}>{esc(o)}</option>" for o in objects]
    return (f"<nav class='controls'><label>object <select id='object'>{''.join(opts)}</select></label>"
            "<label>search <input id='search' type='search' placeholder='object, variant, technique…'></label>"
            "<span id='shown' class='muted'></span></nav>")


def cell_value(row: dict, key: str):
    """A row's value for a table column, as report.csv has it (counters per pixel, GPU bytes in MiB)."""
    px, c = row.get("per_pixel") or {}, row.get("counters") or {}
    if key.endswith("_px") and key[:-3] in ("fragments", "fetches", "steps"):
        return px.get(key[:-3])
    if key == "primitives":
        return c.get("primitives")
    if key == "gpu_mib":
        return None if c.get("bytes") is None else c["bytes"] / 2**20
    if key == "sm_clock":
        return "→".join(map(str, row["sm_clock_mhz"])) if row.get("sm_clock_mhz") else None
    return row.get(key)


def differs(rows: list[dict], key: str) -> bool:
    """Whether an aliased column says anything its plain twin does not (without anti-aliasing they are equal)."""
    plain = key.removeprefix("aliased_")
    return any(r.get(key) is not None and r.get(key) != r.get(plain) for r in rows)


def table(rows: list[dict]) -> str:
    """Every row, sortable by any column (click its header); the columns in groups, the first few shown (a checkbox
    per group shows the rest); units in the headers, the abbreviations said in words under it."""
    cols = [c for c in COLUMNS if (any(cell_value(r, c[0]) is not None for r in rows) or c[0] == "mean_dluv")
            and (c[3] != "aliased" or differs(rows, c[0]))]
    groups = list(dict.fromkeys(g for *_, g in cols))
    spans = "".join(f"<th class='group g-{g}' colspan='{sum(c[3] == g for c in cols)}' scope='colgroup'>"
                    f"{esc(GROUPS[g])}</th>" for g in groups)
    head = "".join(f"<th scope='col' class='g-{g}'>{header_text(h)}</th>" for _, h, _, g in cols)
    body = []
    for r in rows:
        cells = []
        for key, _, digits, g in cols:
            v = cell_value(r, key)
            if digits is None:
                cells.append(f"<td class='g-{g}' data-v='{esc(v or '')}'>{esc(v or '–')}</td>")
            else:
                hint = f" title='÷ {esc(r['baseline'])}'" if key == "ratio_to_baseline" and r.get("baseline") else ""
                cells.append(f"<td class='n g-{g}' data-v='{'' if v is None else v}'{hint}>{num(v, digits)}</td>")
        body.append(f"<tr data-object='{esc(r['object'])}'>{''.join(cells)}</tr>")
    hidden = " ".join(f"hide-{g}" for g in groups if g not in SHOWN)
    boxes = "".join(f"<label><input type='checkbox' value='{g}'{' checked' if g in SHOWN else ''}> {esc(GROUPS[g])}"
                    "</label>" for g in groups if g != "variant")
    words = [k for k in GLOSSARY if k not in ("pop", "LOD", "error") and (k != "aliased" or "aliased" in groups)
             and (k not in ("floor", "noise") or "floor" in groups) and (k != "FLIP" or any(c[0] == "flip_mean"
                                                                                          for c in cols))]
    return (f"<h2>Rows</h2><p class='muted'>One per object and variant; click a header to sort.</p>"
            f"<p class='groups'>columns: {boxes}</p><div class='tablewrap'><table id='rows' class='{hidden}'>"
            f"<thead><tr>{spans}</tr><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table></div>"
            + glossary(words))


def header_text(h: str) -> str:
    """A column's header, its abbreviation explained on hover."""
    for k in sorted(GLOSSARY, key=len, reverse=True):
        if k in h and k not in ("change", "error"):
            return esc(h).replace(esc(k), abbr(k), 1)
    return esc(h)


def runs_table(folder: Path, runs: list[dict]) -> str:
    """A many-bundle run's bundles: status, rows, seconds, why one failed, and a link to each run's own page."""
    lines = []
    for r in runs:
        page_ = folder / r["scene"] / "report.html"
        link = f"<a href='{url(r['scene'], 'report.html')}'>{esc(r['scene'])}</a>" if page_.is_file() else esc(r["scene"])
        cls = " class='regression'" if r["status"] == "failed" else ""
        lines.append(f"<tr{cls}><td>{link}</td><td>{esc(r['status'])}</td><td class='n'>{r['rows']}</td>"
                     f"<td class='n'>{r['seconds']:.1f}</td><td>{esc(r['reason'])}</td></tr>")
    shut = len(runs) > 10 and all(r["status"] == "rendered" for r in runs)   # a long list of successes: folded
    return (f"<h2>Runs</h2><details{'' if shut else ' open'}><summary>{len(runs)} bundles, each rendered into its own "
            "folder (its report.html holds its sweep and LOD chains)</summary><div class='tablewrap'><table><thead><tr><th>scene</th><th>status</th><th>rows</th>"
            f"<th>seconds</th><th>reason</th></tr></thead><tbody>{''.join(lines)}</tbody></table></div></details>")


# --- plots ---------------------------------------------------------------------------------------------------------

W, H, LEFT, RIGHT, TOP, BOTTOM = 560, 330, 62, 14, 14, 42


class Scale:
    """A value to a pixel coordinate along one axis, linear or log, with tick values people read."""

    def __init__(self, lo: float, hi: float, a: float, b: float, log: bool):
        if log:
            lo, hi = math.log10(lo), math.log10(hi)
        if hi - lo < 1e-9:
            lo, hi = lo - (0.5 if log else max(abs(lo) * 0.1, 0.5)), hi + (0.5 if log else max(abs(hi) * 0.1, 0.5))
        pad = 0.06 * (hi - lo)
        self.lo, self.hi, self.a, self.b, self.log = lo - pad, hi + pad, a, b, log
        if not log:
            self.lo = max(self.lo, 0.0) if lo >= 0 else self.lo

    def __call__(self, v: float) -> float:
        x = math.log10(v) if self.log else v
        return self.a + (x - self.lo) / (self.hi - self.lo) * (self.b - self.a)

    def ticks(self) -> list[float]:
        if self.log:   # 1, 2, 5 per decade; only the decades where that is too many
            lo, hi = math.floor(self.lo), math.ceil(self.hi)
            for steps in ((1,), (1, 2, 5), range(1, 10)):   # the fewest that give at least three ticks
                out = [t for t in (m * 10.0 ** e for e in range(lo, hi + 1) for m in steps)
                       if self.lo <= math.log10(t) <= self.hi]
                if len(out) >= 3:
                    return out
            span = self.hi - self.lo   # a narrow range: two more, near its ends, at two significant digits
            ends = (float(f"{10 ** (self.lo + f * span):.2g}") for f in (0.15, 0.85))
            return sorted(set(out) | {t for t in ends if self.lo <= math.log10(t) <= self.hi})
        raw = (self.hi - self.lo) / 5
        step = min((m * 10 ** math.floor(math.log10(raw)) for m in (1, 2, 5, 10)), key=lambda s: abs(s - raw))
        return [k * step for k in range(math.ceil(self.lo / step), math.floor(self.hi / step) + 1)]


def tick_text(v: float) -> str:
    return f"{v:g}" if 1e-3 <= abs(v) < 1e5 or v == 0 else f"{v:.0e}"


# The plots' text is 11 px (CSS above); its width estimated from DejaVu Sans's advances (the widest of the usual
# fonts), erring wide, so that labels placed apart here stay apart in the browser.
FONT, ASCENT, DESCENT = 11, 10.5, 3.0
NARROW, WIDE = set("ijlIJ .,·:;/f-()[]tr'|!"), set("mwMW@%+×≤≥#")


def text_width(s: str) -> float:
    return FONT * sum(0.42 if c in NARROW else 1.02 if c in WIDE else 0.72 for c in s)


def text_box(x: float, y: float, s: str, anchor: str = "start") -> tuple[float, float, float, float]:
    """(left, top, right, bottom) of an SVG text at baseline (x, y)."""
    w = text_width(s)
    x0 = x - {"start": 0, "middle": w / 2, "end": w}[anchor]
    return x0, y - ASCENT, x0 + w, y + DESCENT


def apart(box, boxes, gap: float = 2.0) -> bool:
    return all(box[2] + gap <= b[0] or b[2] + gap <= box[0] or box[3] + gap <= b[1] or b[3] + gap <= box[1]
               for b in boxes)


def text(x: float, y: float, s: str, anchor: str = "middle") -> str:
    return f"<text x='{x:.1f}' y='{y:.1f}' text-anchor='{anchor}'>{esc(s)}</text>"


def frame(x: Scale, y: Scale, xlabel: str, ylabel: str, xticks=None) -> tuple[list[str], list]:
    """Grid, axes, ticks and labels of a plot, and the boxes their text takes; a tick label that would touch the
    one before it is left out (its grid line stays)."""
    out, boxes = [], []
    for t in xticks or x.ticks():
        px, s = x(t), tick_text(t)
        out.append(f"<line class='grid' x1='{px:.1f}' x2='{px:.1f}' y1='{TOP}' y2='{H - BOTTOM}'/>")
        box = text_box(px, H - BOTTOM + 14, s, "middle")
        if apart(box, boxes, 6):
            boxes.append(box)
            out.append(text(px, H - BOTTOM + 14, s))
    for t in y.ticks():
        py, s = y(t), tick_text(t)
        out.append(f"<line class='grid' x1='{LEFT}' x2='{W - RIGHT}' y1='{py:.1f}' y2='{py:.1f}'/>")
        box = text_box(LEFT - 5, py + 4, s, "end")
        if apart(box, boxes):
            boxes.append(box)
            out.append(text(LEFT - 5, py + 4, s, "end"))
    mid = (TOP + H - BOTTOM) / 2
    out.append(f"<path class='axis' fill='none' d='M{LEFT},{TOP}V{H - BOTTOM}H{W - RIGHT}'/>"
               + text((LEFT + W - RIGHT) / 2, H - 6, xlabel)
               + f"<text transform='translate(13,{mid}) rotate(-90)' text-anchor='middle'>{esc(ylabel)}</text>")
    boxes += [text_box((LEFT + W - RIGHT) / 2, H - 6, xlabel),
              (13 - ASCENT, mid - text_width(ylabel) / 2, 13 + DESCENT, mid + text_width(ylabel) / 2)]
    return out, boxes


def place(px: float, py: float, s: str, taken: list) -> str:
    """A point's label beside it where it touches no text or point placed so far (taken, which it joins), on the
    side towards the plot's middle first; none where every place is taken (the point's tooltip names it)."""
    towards = "start" if px < (LEFT + W - RIGHT) / 2 else "end"
    away = "end" if towards == "start" else "start"
    for anchor, dx, dy in ((towards, 7, -6), (towards, 7, 13), (away, 7, -6), (away, 7, 13), ("middle", 0, -9),
                           ("middle", 0, 17), (towards, 7, -16), (towards, 7, 23)):
        x = px + (dx if anchor == "start" else -dx)
        box = text_box(x, py + dy, s, anchor)
        if LEFT <= box[0] and box[2] <= W - RIGHT and TOP <= box[1] and box[3] <= H - BOTTOM and apart(box, taken):
            taken.append(box)
            return text(x, py + dy, s, anchor)
    return ""


def svg(parts: list[str], label: str) -> str:
    return (f"<svg class='plot' viewBox='0 0 {W} {H}' role='img' aria-label='{esc(label)}'>"
            f"<title>{esc(label)}</title>{''.join(parts)}</svg>")


def colours(keys) -> dict:
    return {k: PALETTE[i % len(PALETTE)] for i, k in enumerate(dict.fromkeys(keys))}


def legend(colour: dict) -> str:
    return "<p class='legend'>" + "".join(f"<span><i class='swatch' style='background:{c}'></i>{esc(k)}</span>"
                                          for k, c in colour.items()) + "</p>"


def tip(r: dict) -> str:
    """A point's tooltip: its variant, time, error (against what a viewer sees, and point-sampled where that
    differs), counters."""
    px = r.get("per_pixel") or {}
    aliased = r.get("aliased_mean_dluv")
    lines = [r["label"] + (f" @ {r['size_px']} px" if "size_px" in r else ""),
             f"median {num(r['median_ms'], 3)} ms (q1 {num(r.get('q1_ms'), 3)}, q3 {num(r.get('q3_ms'), 3)})",
             f"mean ΔLuv {num(r['mean_dluv'], 3)}"
             + (f", aliased {num(aliased, 3)}" if aliased is not None and aliased != r["mean_dluv"] else ""),
             f"p95 ΔLuv {num(r.get('p95_dluv'), 2)}, IoU {num(r.get('iou'), 4)}"]
    if px.get("fragments") is not None:
        lines.append(f"per px: {px['fragments']:.2f} fragments, {px['fetches']:.1f} fetches, {px['steps']:.1f} steps")
    return "\n".join(lines)


def pareto(points: list[dict]) -> list[dict]:
    """The points no other is both faster and more accurate than, fastest first."""
    front, best = [], math.inf
    for r in sorted(points, key=lambda r: (r["median_ms"], r["mean_dluv"])):
        if r["mean_dluv"] < best:
            front.append(r)
            best = r["mean_dluv"]
    return front


def point(x: float, y: float, colour: str, r: dict, ring: bool = False) -> str:
    edge = " stroke='#000' stroke-width='1.5'" if ring else ""
    return (f"<circle class='pt' tabindex='0' cx='{x:.1f}' cy='{y:.1f}' r='{5 if ring else 4}' fill='{colour}'"
            f"{edge} data-tip='{esc(tip(r))}'>"
            f"<title>{esc(tip(r))}</title></circle>")


def time_plot(obj: str, rows: list[dict]) -> str:
    """Mean ΔLuv against median GPU time (log), a technique's knob values joined, the Pareto front dashed."""
    pts = [r for r in rows if r["mean_dluv"] is not None and r["median_ms"]]
    if not pts:
        return "<p class='muted'>no row with both a time and an error to plot</p>"
    x = Scale(min(r["median_ms"] for r in pts), max(r["median_ms"] for r in pts), LEFT, W - RIGHT, True)
    y = Scale(0.0, max(r["mean_dluv"] for r in pts), H - BOTTOM, TOP, False)
    colour = colours(r["technique"] for r in pts)
    parts, taken = frame(x, y, "median GPU time per frame [ms] (log)", "mean ΔLuv against the reference")
    front = pareto(pts)
    steps = f"M{x(front[0]['median_ms']):.1f},{y(front[0]['mean_dluv']):.1f}" + "".join(
        f"H{x(r['median_ms']):.1f}V{y(r['mean_dluv']):.1f}" for r in front[1:])   # across to the next, then down
    parts.append(f"<path d='{steps}' fill='none' stroke='#000' stroke-dasharray='4 3' stroke-width='1'>"
                 "<title>Pareto front: no variant is both faster and more accurate</title></path>")
    for tech, c in colour.items():
        mine = [r for r in pts if r["technique"] == tech]
        if len(mine) > 1:
            d = "M" + "L".join(f"{x(r['median_ms']):.1f},{y(r['mean_dluv']):.1f}" for r in mine)
            parts.append(f"<path d='{d}' fill='none' stroke='{c}' stroke-width='1.5'/>")
    at = [(x(r["median_ms"]), y(r["mean_dluv"])) for r in pts]
    taken += [(px - 5, py - 5, px + 5, py + 5) for px, py in at]
    parts += [point(px, py, colour[r["technique"]], r, r in front) for r, (px, py) in zip(pts, at)]
    for i in sorted(range(len(pts)), key=lambda i: pts[i] not in front):   # the front's labels placed first
        parts.append(place(*at[i], pts[i]["label"], taken))
    return svg(parts, f"{obj}: mean ΔLuv against median GPU time") + legend(colour) + \
        ("<p class='muted'>ringed points and the dashed line: the Pareto front (no variant both faster and closer "
         "to the reference). Hover or focus a point for its numbers; a label that would overlap another is left "
         "out.</p>")


def size_plot(obj: str, rows: list[dict], field: str, ylabel: str, log_y: bool, colour: dict) -> str:
    """`field` against the object's size on screen (log 2), one line per variant; the point-sampled twin dashed."""
    pts = [r for r in rows if r.get(field) is not None and (r[field] > 0 or not log_y)]
    if not pts:
        return ""
    sizes = sorted({r["size_px"] for r in rows})
    x = Scale(min(sizes), max(sizes), LEFT, W - RIGHT, True)
    vals = [r[field] for r in pts] + [r[f"aliased_{field}"] for r in pts if r.get(f"aliased_{field}") is not None]
    y = Scale(min(vals) if log_y else 0.0, max(vals), H - BOTTOM, TOP, log_y)
    parts, _ = frame(x, y, "bounding sphere on screen [px] (log)", ylabel, sizes)
    for label, c in colour.items():
        mine = sorted((r for r in pts if r["label"] == label), key=lambda r: r["size_px"])
        if not mine:
            continue
        d = "M" + "L".join(f"{x(r['size_px']):.1f},{y(r[field]):.1f}" for r in mine)
        parts.append(f"<path d='{d}' fill='none' stroke='{c}' stroke-width='1.5'/>")
        twin = [r for r in mine if r.get(f"aliased_{field}") is not None]
        if twin and any(r[f"aliased_{field}"] != r[field] for r in twin):
            d = "M" + "L".join(f"{x(r['size_px']):.1f},{y(r[f'aliased_{field}']):.1f}" for r in twin)
            parts.append(f"<path d='{d}' fill='none' stroke='{c}' stroke-dasharray='4 3' stroke-width='1'/>")
        parts += [point(x(r["size_px"]), y(r[field]), c, r) for r in mine]
    shown = {r["label"] for r in pts}
    return svg(parts, f"{obj}: {ylabel} against screen size") + legend({k: c for k, c in colour.items() if k in shown})


def lod_section(obj: str, lod: dict, colour: dict) -> str:
    """The object's floor (its full asset against the reference, the reference's noise, per size); each chain of the
    object: its bands of screen sizes as coloured spans on a log size axis, each switch's hysteresis band hatched
    and its pop (ΔLuv between the two variants there) written at it; the field's pricing."""
    out = []
    floor = lod.get("floors", {}).get(obj)
    if floor:
        rows = "".join(f"<tr><td class='n'>{f['size_px']}</td><td>{esc(f['full_asset'])}</td>"
                       f"<td class='n'>{num(f['floor_dluv'], 3)}</td><td class='n'>{num(f.get('floor_iou'), 4)}</td>"
                       f"<td class='n'>{num(f['reference_noise_dluv'], 3)}"
                       f"</td><td class='n'>{f['ties']} of {f['pairs']}</td></tr>" for f in floor)
        out.append("<details><summary>the floor: what no variant changes</summary><p class='muted'>The full "
                   "asset's own error against the reference (what the pipeline, not the representation, costs) and the reference's sampling "
                   "noise (no difference below it can be told from noise); chains decide on the change against the "
                   "full asset unless a chain says limit_on = \"reference\".</p><table><thead><tr><th>size [px]</th>"
                   "<th>full asset</th><th>its mean ΔLuv</th><th>its IoU</th><th>reference noise ΔLuv</th><th>variant pairs within "
                   f"noise</th></tr></thead><tbody>{rows}</tbody></table></details>")
    for c in lod["chains"]:
        ch = c["objects"].get(obj)
        if not ch:
            continue
        out.append(f"<h4>chain {esc(c['name'])}: {esc(limits(c))}"
                   + (f", pop ≤ {c['pop_dluv']} ΔLuv" if c.get("pop_dluv") is not None else "") + "</h4>")
        out.append(bands(obj, c, ch["entries"], lod["sizes_px"], colour))
        if ch.get("unmet_px"):
            out.append(f"<p class='worse'>no variant within the limits at {', '.join(map(str, ch['unmet_px']))} px "
                       "(the least change against the full asset taken, hatched)</p>")
        if "field" in ch:
            f = ch["field"]
            chosen = {k["variant"]: " class='better'" if k["variant"] == f["chosen"] else "" for k in f["candidates"]}
            rows = "".join(f"<tr{chosen[k['variant']]}><td>{esc(k['variant'])}"
                           f"</td><td class='n'>{num(k['median_ms'], 3)}</td><td class='n'>{num(k['spread_ms'], 3)}</td>"
                           f"<td class='n'>{num(k.get('change_dluv'), 3)}</td><td class='n'>{num(k['mean_dluv'], 3)}"
                           f"</td><td>{'yes' if k['meets'] else 'no'}</td></tr>" for k in f["candidates"])
            out.append(f"<details open><summary>priced on the field of copies: {esc(f['chosen'])} ships</summary>"
                       f"<p class='muted'>{esc(f['how'])}</p><table><thead><tr><th>on the field</th><th>median GPU "
                       f"[ms]</th><th>spread [ms]</th><th>change ΔLuv</th><th>mean ΔLuv</th><th>within limits</th>"
                       "</tr></thead>"
                       f"<tbody>{rows}</tbody></table></details>")
    return "".join(out) + (BANDS_LEGEND if any(obj in c["objects"] for c in lod["chains"]) else "")


LANE, BAR, SPAN = 22, 16, 360   # the LOD bars: one lane per band, its bar this tall, the size axis this long


def bands(obj: str, c: dict, entries: list[dict], sizes: list[int], colour: dict) -> str:
    """A chain's bands of screen sizes, one lane each, on a log size axis, as a Gantt chart: left of each lane the
    variant shipped over the band, right of it its cost and change (or error) at the band's largest size and the pop
    where the chain switches to it; hatched where over the limits; each switch's hysteresis band shaded across the
    two lanes. The text columns are as wide as their longest text, so no label meets another or a bar."""
    shown = LIMIT_ON[c.get("limit_on", "change")]["mean_dluv"]
    facts = []
    for e in entries:
        m = e["measured"][0]
        facts.append(f"{num(m.get('median_ms'), 2)} ms · {'change' if shown == CHANGE else 'error'} "
                     f"{num(m.get(shown), 2)}"
                     + (f" · pop {m['pop_dluv']:.2f}" if m.get("pop_dluv") is not None else ""))
    a = 6 + max(text_width(e["variant"]) for e in entries) + 10
    b = a + SPAN
    width = b + 10 + max(map(text_width, facts)) + 6
    lo, hi = max(min(sizes) / 2, 0.5), max(sizes)
    x = Scale(lo, hi, a, b, True)
    at = lambda s: x(max(s, lo)) if s else a   # noqa: E731  (a band down to 0 px runs to the axis's start)
    base = 6 + LANE * len(entries)
    h = base + 34
    parts, boxes = [], []
    for s in sizes:
        parts.append(f"<line class='grid' x1='{x(s):.1f}' x2='{x(s):.1f}' y1='2' y2='{base}'/>")
        box = text_box(x(s), base + 12, str(s), "middle")
        if apart(box, boxes, 6):
            boxes.append(box)
            parts.append(text(x(s), base + 12, str(s)))
    for k, (e, fact) in enumerate(zip(entries, facts)):
        x0, x1, top = at(e["min_px"]), at(e["max_px"]), 6 + k * LANE
        m = e["measured"][0]
        what = (f"{e['variant']}: {e['min_px']}–{e['max_px']} px; at {m['size_px']} px change ΔLuv "
                f"{num(m.get('change_dluv'), 3)}, error ΔLuv {num(m.get('mean_dluv'), 3)}, "
                f"{num(m.get('median_ms'), 3)} ms" + ("" if e["meets"] else " (over the limits)"))
        bar = f"x='{x0:.1f}' y='{top}' width='{max(x1 - x0, 1):.1f}' height='{BAR}'"
        parts.append(f"<rect {bar} fill='{colour.get(e['variant'], PALETTE[-1])}' fill-opacity='0.75'>"
                     f"<title>{esc(what)}</title></rect>")
        if not e["meets"]:
            parts.append(f"<rect {bar} fill='url(#hatch)'><title>{esc(what)}</title></rect>")
        parts += [text(a - 8, top + BAR - 4, e["variant"], "end"), text(b + 10, top + BAR - 4, fact, "start")]
        if "switch_px" in e:   # the switch to the next coarser entry, at its hysteresis band
            lo_, hi_ = e["switch_px"]
            parts.append(f"<rect x='{at(lo_):.1f}' y='{top}' width='{max(at(hi_) - at(lo_), 2):.1f}' "
                         f"height='{LANE + BAR}' fill='#000' fill-opacity='0.3'><title>switch between {lo_} and "
                         f"{hi_} px (hysteresis)</title></rect>")
    parts.append(text((a + b) / 2, h - 4, "bounding sphere on screen [px] (log)"))
    return (f"<svg class='plot' viewBox='0 0 {width:.0f} {h}' style='width: {width:.0f}px' role='img' "
            f"aria-label='{esc(obj)}: LOD chain {esc(c['name'])}'><title>{esc(obj)}: LOD chain {esc(c['name'])}, "
            f"screen size in px (log)</title>{''.join(parts)}</svg>")


# The LOD bars' hatch (over the limits), defined once at the top of the page: a pattern inside a section that is
# hidden (one object at a time) would not paint elsewhere.
HATCH = ("<svg width='0' height='0' style='position:absolute' aria-hidden='true'><defs><pattern id='hatch' "
         "width='6' height='6' patternUnits='userSpaceOnUse' patternTransform='rotate(45)'><line x1='0' y1='0' "
         "x2='0' y2='6' stroke='#000' stroke-width='1.5' stroke-opacity='0.55'/></pattern></defs></svg>")
BANDS_LEGEND = ("<p class='legend muted'><span><i class='swatch over'></i>hatched: over the limit (no variant within "
                "it there; the least change shipped)</span><span><i class='swatch' style='background:#0004'></i>"
                "shaded: a switch's hysteresis (switch below its smaller size, back above its larger)</span></p>"
                "<p class='muted'>Each lane: the variant shipped over a band of sizes (left), and at the band's "
                "largest size its median GPU time · its mean change ΔLuv against the full asset (error: against "
                "the reference, where the chain limits that) · pop: the ΔLuv between its frames and the previous "
                "band's at the switch (right)"
                ".</p>")


# --- frames --------------------------------------------------------------------------------------------------------

def viewer_data(folder: Path, report: dict, obj: str) -> dict:
    """The object's images as the viewer loads them: per variant its frames, heat maps and per-frame error, and the
    reference, as URLs relative to the page (only the frames that exist: a failed variant has none)."""
    sub, name = where(report, obj)
    mine = [r for r in report["rows"] if r["object"] == obj]
    frames = max((r["frames"] for r in mine), default=0)
    ref = [url(sub, "reference", name, f"{k:03d}.png") for k in range(frames)]
    variants = {}
    for r in mine:
        fr = [url(sub, "frames", name, r["label"], f"{k:03d}.png") for k in range(r["frames"])]
        if fr and (folder / sub / "frames" / name / r["label"] / "000.png").is_file():
            variants[r["label"]] = {"frame": fr, "heat": [url(sub, "heatmaps", name, r["label"], f"{k:03d}.png")
                                                           for k in range(r["frames"])],
                                    "error": [num(f.get("mean_dluv"), 3) for f in r.get("per_frame") or []]
                                    or ["–"] * r["frames"]}
    return {"ref": ref, "variants": variants}


def viewer(report: dict, obj: str, data: dict) -> str:
    """Frame, reference, heat map and the frame swiped over the reference (the slider, or t to toggle) side by side,
    each at most 1x and its share of the row at first; zoom 1-8x on demand (no smoothing, the row then scrolls)."""
    if not data["variants"]:
        return "<p class='muted'>no frames written for this object</p>"
    first = next(iter(data["variants"]))
    d = data["variants"][first]
    opts = "".join(f"<option>{esc(v)}</option>" for v in data["variants"])
    frame_opts = "".join(f"<option value='{k}'>{k:03d}  ΔLuv {e}</option>" for k, e in enumerate(d["error"]))
    heat = report.get("heatmap_max_dluv", 10.0)
    zoom = "".join(f"<option value='{z}'>{z}×</option>" for z in (1, 2, 4, 8))

    def fig(cls, src, alt, caption):
        return f"<figure><img class='{cls}' src='{src}' alt='{esc(alt)}'><figcaption>{caption}</figcaption></figure>"

    return (f"<div class='viewer fit' data-object='{esc(obj)}'><p><label>variant <select class='v-variant'>{opts}"
            f"</select></label> <label>frame <select class='v-frame'>{frame_opts}</select></label> <label>zoom "
            f"<select class='v-zoom'><option value='0' selected>fit (at most 1×)</option>{zoom}</select></label></p>"
            "<div class='trio'>"
            + fig("i-frame", d["frame"][0], f"{first} frame 0", "frame")
            + fig("i-ref", data["ref"][0], "reference, frame 0", "reference")
            + fig("i-heat", d["heat"][0], f"{first} heat map, frame 0", "heat map (ΔLuv)")
            + f"<figure><div class='swipe'><img class='i-ref' src='{data['ref'][0]}' alt='reference, frame 0'>"
            f"<img class='i-frame top' src='{d['frame'][0]}' alt='{esc(first)} frame 0' "
            "style='clip-path: inset(0 50% 0 0)'></div><figcaption>swipe: frame left of the line, reference right"
            "</figcaption></figure></div>"
            f"<p><span class='legendbar'>0 ΔLuv<span class='bar' role='img' aria-label='inferno colour scale'></span>"
            f"{heat:g} ΔLuv and above</span> <label>swipe <input class='v-cut' type='range' min='0' max='100' "
            "value='50'></label> <button class='v-toggle' type='button'>toggle frame / reference (t)</button></p>"
            "</div>")


def object_section(report: dict, obj: str, frames: dict) -> str:
    rows = [r for r in report["rows"] if r["object"] == obj]
    parts = [f"<section class='obj' id='obj-{esc(obj)}' data-object='{esc(obj)}'><h2>{esc(obj)}</h2>"
             "<h3>error against time</h3>",
             time_plot(obj, rows)]
    sweep = [r for r in (report.get("sweep") or {}).get("rows", []) if r["object"] == obj]
    colour = colours(r["label"] for r in rows + sweep)   # a variant's colour the same in the size plots and bands
    if sweep:
        parts += ["<h3>against screen size</h3><div class='plots'><div>",
                  size_plot(obj, sweep, "change_dluv", "change ΔLuv against the full asset", False, colour),
                  "</div><div>",
                  size_plot(obj, sweep, "mean_dluv", "error ΔLuv against the reference", False, colour), "</div><div>",
                  size_plot(obj, sweep, "median_ms", "median GPU time [ms] (log)", True, colour), "</div></div>",
                  "<p class='muted'>dashed: the point-sampled (aliased) error, where it differs.</p>"]
    if report.get("lod"):
        parts += ["<h3>LOD chains</h3>", lod_section(obj, report["lod"], colour)]
    parts += ["<h3>frames</h3>", viewer(report, obj, frames), "</section>"]
    return "".join(parts)


# --- baseline ------------------------------------------------------------------------------------------------------

def baseline_section(folder: Path, report: dict) -> str:
    """The change against the baseline, regressions (over a threshold) first, then by error increase; coloured;
    before and after frames where both folders still hold them."""
    block = report.get("baseline")
    if not block:
        return ""
    old = Path(block["report"]).parent
    here = target(folder)
    # the old frames, unless the new run replaces the very folder they are in
    before = None if old.resolve() == here.resolve() else Path(os.path.relpath(old, here))
    order = sorted(block["rows"], key=lambda c: (not c["exceeds"], -(c["d_mean_dluv"] or 0)))
    t = block["thresholds"]
    lines = []
    for c in order:
        cls = "regression" if c["exceeds"] else ""
        tone = "worse" if (c["d_mean_dluv"] or 0) > 0 or (c["time_ratio"] or 1) > 1.05 else \
            "better" if (c["d_mean_dluv"] or 0) < 0 else ""
        counters = ", ".join(f"{k} {a}→{b}" for k, (a, b) in c["counters_changed"].items())
        lines.append(f"<tr class='{cls} {tone}' data-object='{esc(c['object'])}'><td>{esc(c['object'])}</td>"
                     f"<td>{esc(c['label'])}</td><td>{esc(', '.join(c['exceeds']) or c['status'])}</td>"
                     f"<td class='n'>{num(c['old_mean_dluv'], 3)} → {num(c['new_mean_dluv'], 3)}</td>"
                     f"<td class='n'>{num(c['d_mean_dluv'], 3)}</td><td class='n'>{num(c['old_ms'], 3)} → "
                     f"{num(c['new_ms'], 3)}</td><td class='n'>{num(c['time_ratio'], 2)}</td>"
                     f"<td>{esc(counters)}</td></tr>")
    notes = "".join(f"<li>{esc(n)}</li>" for n in block["notes"])
    pairs = "".join(before_after(folder, report, before, c) for c in order if c["status"] == "compared"
                    and (c["exceeds"] or (c["d_mean_dluv"] or 0) > 0 or c["counters_changed"]))
    return (f"<h2>Change against the baseline</h2><p>baseline <a href='{url(str(before or old), 'report.json')}'>"
            f"{esc(block['report'])}</a>; thresholds: error increase {t['max_error_increase']}, slowdown "
            f"{t['max_slowdown']}; <strong>{len(block['failed'])} over a threshold</strong></p><ul>{notes}</ul>"
            "<div class='tablewrap'><table id='changes'><thead><tr><th>object</th><th>variant</th><th>status</th>"
            "<th>mean ΔLuv old → new</th><th>Δ mean ΔLuv</th><th>GPU ms old → new</th><th>time ratio [×]</th>"
            f"<th>counters changed</th></tr></thead><tbody>{''.join(lines)}</tbody></table></div>{pairs}")


def before_after(folder: Path, report: dict, before: Path | None, c: dict) -> str:
    """A changed variant's frames before and after (and its heat maps), where both exist."""
    if before is None:
        return ""
    sub, name = where(report, c["object"])
    old_dir = (target(folder) / before).resolve()
    figs = []
    for k in range(max((r["frames"] for r in report["rows"] if r["object"] == c["object"]), default=0)):
        rel, heat = (f"{sub}{kind}/{name}/{c['label']}/{k:03d}.png" for kind in ("frames", "heatmaps"))
        if not ((old_dir / rel).is_file() and (folder / rel).is_file()):
            continue
        figs.append(f"<figure><img src='{url(str(before), rel)}' alt='{esc(c['label'])} frame {k}, before' "
                    f"width='128'><figcaption>{k:03d} before</figcaption></figure><figure><img src='{url(rel)}' "
                    f"alt='{esc(c['label'])} frame {k}, after' width='128'><figcaption>{k:03d} after</figcaption>"
                    f"</figure><figure><img src='{url(heat)}' "
                    f"alt='{esc(c['label'])} heat map {k}, after' width='128'><figcaption>heat map after"
                    "</figcaption></figure>")
    if not figs:
        return ""
    return f"<h4>{esc(c['object'])}: {esc(c['label'])}</h4><div class='pair'>{''.join(figs)}</div>"
