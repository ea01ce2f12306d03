"""Result tables of README.md and docs/*.md, written from the committed result files (`make docs`).

One rule: a table between `<!-- table:FILE:KEY -->` and `<!-- /table -->` is the rendering of table KEY of
docs/results/FILE.json, and nothing else. A result file is either

* a bench's own output, committed as the bench wrote it, rendered by the view named after the file in VIEWS
  (the figures formatted as the bench's own .md formats them: bench/tables.py, shared with the benches).
  A bench run with `--publish docs/results` writes it with its `provenance` (bench/publish.py: the command,
  commit, date, device, load average at start and end, wall time), which the key `provenance` renders as a
  sentence; or
* a transcription of a measurement's table (`"tables": {KEY: {"header", "align", "rows"}}`, every cell the
  string that was published, never re-rounded), beside `measured_by`, `when` and `device`: which command
  measured it, when and on what, and `transcribed`: why no bench writes it (a GPU session, code that no longer
  exists, a one-off experiment).

`python tools/make_docs.py` rewrites the tables in place; `--check` changes nothing and exits 1 naming every
table that differs from its result file (tests/test_docs.py runs it)."""
from __future__ import annotations

import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from bench import tables  # noqa: E402  (the standard library only: no package import)

RESULTS = ROOT / "docs" / "results"
BLOCK = re.compile(r"(<!-- table:([\w.-]+):([\w.-]+) -->\n)(.*?)(<!-- /table -->)", re.S)


def documents() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


markdown = tables.markdown


def _filtered(doc: dict, key: str) -> str:
    """bench.filtered's filtered.json: per object and variant, per size `aliased · none / msaa4 / ssaa2`."""
    sizes, modes = doc["sizes_px"], doc["modes"]
    rows = []
    for config in doc["rows"].values():
        by = {m: {(r["object"], r["label"], r["size_px"]): r for r in config[m]} for m in modes}
        keys = list(dict.fromkeys((o, v) for o, v, _ in by[modes[0]]))
        for obj, variant in keys:
            cells = []
            for px in sizes:
                rs = [by[m][(obj, variant, px)] for m in modes]
                cells.append(f"{rs[0]['aliased_mean_dluv']:.2f} · " + " / ".join(f"{r['mean_dluv']:.2f}" for r in rs))
            rows.append([obj, variant, *cells])
    return markdown(["object", "variant", *(f"{px} px" for px in sizes)], ["---"] * (2 + len(sizes)), rows)


def _demo(doc: dict, key: str) -> str:
    """tools/demo_results.py's demo.json: `default`, every variant at the orbit views; `chains`, each chain's bands."""
    num = lambda x, f: "-" if x is None else format(x, f)   # noqa: E731
    if key == "default":
        rows = [[r["object"], r["variant"],
                 "-" if r["faces"] is None else f"{r['faces']:,}" + (f" ({r['faces_of']})" if r["faces_of"] else ""),
                 num(r["median_ms"], ".1f"), num(r["ratio"], ".2f"), f"{r['fetches_px']:.1f} / {r['steps_px']:.1f}",
                 num(r["mean_dluv"], ".3f"), num(r["p95_dluv"], ".2f"), num(r["iou"], ".4f"), num(r["flip"], ".4f")]
                for r in doc["rows"]]
        return markdown(["object", "variant", "faces", "median GPU ms/frame", "time / first variant",
                         "fetches / steps per px", "mean ΔLuv", "p95 ΔLuv", "IoU", "FLIP"],
                        ["---", "---", "---:", "---:", "---:", "---", "---:", "---:", "---:", "---:"], rows)
    rows = [[c["object"], f"{c['chain']} ({', '.join(f'{k} ≤ {v:g}' for k, v in c['limits'].items())})",
             f"({c['min_px']}, {c['max_px']}]", c["variant"], "yes" if c["meets"] else "no (least change)",
             num(c["change_dluv"], ".2f"), num(c["mean_dluv"], ".2f"), num(c["floor_dluv"], ".2f"),
             num(c["median_ms"], ".1f")] for c in doc["chains"]]
    return markdown(["object", "chain", "band [px]", "ships", "within the limit", "change ΔLuv",
                     "error ΔLuv", "floor ΔLuv", "median GPU ms/frame"],
                    ["---", "---", "---", "---", "---", "---:", "---:", "---:", "---:"], rows)


def _composite(doc: dict, key: str) -> str:
    """tools/demo_results.py's composite.json: `sets`, each composite set; `objects`, each object's own rows."""
    if key == "sets":
        head, align = ["set", "variants"], ["---:", "---"]
        lead = [(str(c["set"]), ", ".join(f"{o} {v}" for o, v in c["variants"].items()), c) for c in doc["sets"]]
    else:
        head, align = ["object", "variant"], ["---", "---"]
        lead = [(r["object"], r["variant"], r) for r in doc["rows"]]
    rows = [[a, b, f"{r['median_ms']:.1f}", f"{r['mean_dluv']:.3f}", f"{r['p95_dluv']:.2f}", f"{r['iou']:.4f}"]
            for a, b, r in lead]
    return markdown(head + ["median ms/frame", "mean ΔLuv", "p95 ΔLuv", "IoU"], align + ["---:"] * 4, rows)


def _rooms(doc: dict, key: str) -> str:
    """tools/rooms.py's rooms.json: each room, its modules and the rooms it imports."""
    rows = [[f"`{name}`" if name != "(top)" else "the run (top level)", ", ".join(r["modules"]),
             ", ".join(r["imports"]) or "-"] for name, r in doc["rooms"].items()]
    rows.append(["all", f"{doc['modules']} modules", f"{doc['floors']} floors (highest: {', '.join(doc['highest'])})"])
    return markdown(["room", "modules", "imports rooms"], ["---", "---", "---"], rows)


def _provenance(doc: dict) -> str:
    """A published bench output's provenance, as one sentence."""
    p = doc["provenance"]
    when = p["date"].replace("T", " ").replace("+00:00", " UTC")
    dirty = " with uncommitted changes" if p["dirty"] else ""
    return (f"Measured by `{p['command']}` at commit {p['commit'][:9]}{dirty}, {when}, on {p['device']}; load average "
            f"(1 min) {p['load_start'][0]:.2f} at the start and {p['load_end'][0]:.2f} at the end; "
            f"{p['wall_s'] / 60:.1f} min wall.\n")


# a command's own output without bench/publish.py's provenance, and why
UNPUBLISHED = {"rooms": "tools/rooms.py reads it from the source (not a measurement; test_docs checks it is current)",
               "filtered": "bench.filtered's JSON as it wrote it, before the benches published their provenance",
               "demo": "tools/demo_results.py's summary of make demo, before the benches published their provenance",
               "composite": "tools/demo_results.py's summary of a run of configs/composite.toml",
               "reference": "bench.reference --docs writes it, its tables with its own command, date and load average",
               "reference-ab6be10": "bench.reference --docs at commit ab6be10, kept beside today's run"}


def _bench(views: dict):
    """A published bench's view: its keys, and `provenance`."""
    return lambda doc, key: _provenance(doc) if key == "provenance" else views[key](doc)


VIEWS = {"filtered": _filtered, "demo": _demo, "composite": _composite, "rooms": _rooms,
         "quadrics": _bench({"rows": tables.quadrics, "selected": tables.quadrics_selected}),
         "vdm-bench": _bench({"page": tables.vdm, "interleaved-cpu": tables.vdm_interleaved_cpu}),
         "billboards-bench": _bench({"page": tables.billboards, "models-800x600": tables.billboards_models,
                                     "bunny-interleaved": tables.billboards_interleaved}),
         "octahedral-bench": _bench({"page": tables.octahedral, "bunny-800x600": tables.octahedral_model,
                                     "bunny-categories-800x600": tables.octahedral_categories,
                                     "bunny-resolutions": tables.octahedral_resolutions,
                                     "primitives-800x600": tables.octahedral_primitives}),
         "instances": _bench({"fields": tables.instances_fields}),
         "cluster": _bench({"serial-vs-cluster": tables.cluster_runs, "faults": tables.cluster_faults}),
         "suite": _bench({"run": tables.suite, "subsets": tables.suite_subsets, "files": tables.suite_files,
                          "tests": tables.suite_tests})}
VIEWS["suite-62f9cd8"] = VIEWS["suite"]          # the suite of the day issue 45 was filed, run by bench.suite --at


def table(name: str, key: str) -> str:
    """The markdown between the markers (a blank line either side of the table)."""
    return "\n" + _table(name, key) + "\n"


def _table(name: str, key: str) -> str:
    path = RESULTS / f"{name}.json"
    doc = json.loads(path.read_text())
    if "tables" in doc:
        t = doc["tables"][key]
        return markdown(t["header"], t["align"], t["rows"])
    return VIEWS[name](doc, key)


def render(text: str) -> str:
    """`text` with every marked table written from its result file."""
    return BLOCK.sub(lambda m: m[1] + table(m[2], m[3]) + m[5], text)


def stale() -> list[str]:
    """Every marked table that differs from its result file, as `FILE: table NAME:KEY`."""
    out = []
    for path in documents():
        text = path.read_text()
        for m in BLOCK.finditer(text):
            if m[4] != table(m[2], m[3]):
                out.append(f"{path.relative_to(ROOT)}: table {m[2]}:{m[3]}")
    return out


def main(argv: list[str]) -> int:
    if "--check" in argv:
        wrong = stale()
        for w in wrong:
            print(f"{w} differs from docs/results/{w.split('table ')[1].split(':')[0]}.json "
                  "(run make docs, or fix the result file)", file=sys.stderr)
        return 1 if wrong else 0
    for path in documents():
        text = path.read_text()
        new = render(text)
        if new != text:
            path.write_text(new)
            print(f"rewrote {path.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
