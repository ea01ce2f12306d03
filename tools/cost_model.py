"""How well the device-independent counters predict time on one device: a linear cost model fitted to the
rows of vdmrender reports made there.

Per frame, time = c0 + c_fragment * fragments + c_fetch * fetches + c_step * steps + c_primitive * primitives
+ c_light * light-pass fragments (vdmrender.measuring.counters; the light's pass apart, since it works at the shadow
map's size), with every coefficient >= 0, fitted by least squares on the relative error (so fast and slow
rows weigh alike). Reported: the fitted costs, Spearman's rank correlation of predicted and measured times,
and the median relative error both in the fit and leaving each row out (prediction, not description).

    python tools/cost_model.py out/a/report.json out/b/report.json -o out/cost-model
"""
from __future__ import annotations

import itertools
import json
from pathlib import Path

import click
import numpy as np

from vdmrender.measuring.measure import is_light_pass

FEATURES = ("fragments", "fetches", "steps", "primitives", "light fragments")


def features(row: dict) -> list[float]:
    """The row's counters per frame, camera passes and the light's pass apart (vdmrender.measuring.measure)."""
    frames = row["frames"]
    cam = {k: 0 for k in ("fragments", "fetches", "steps")}
    light = 0
    for name, p in row["counters_per_pass"].items():
        if is_light_pass(name):
            light += p["fragments"]
        else:
            for k in cam:
                cam[k] += p[k]
    return [cam["fragments"] / frames, cam["fetches"] / frames, cam["steps"] / frames,
            row["counters"]["primitives"] / frames, light / frames]


def nnls(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """argmin |a x - b| with x >= 0, exactly, by trying every support (a handful of columns)."""
    best, best_x = np.inf, np.zeros(a.shape[1])
    for k in range(a.shape[1] + 1):
        for cols in itertools.combinations(range(a.shape[1]), k):
            x = np.zeros(a.shape[1])
            if cols:
                x[list(cols)] = np.linalg.lstsq(a[:, cols], b, rcond=None)[0]
            if (x >= 0).all():
                r = float(np.sum((a @ x - b) ** 2))
                if r < best:
                    best, best_x = r, x
    return best_x


def fit(x: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Coefficients [c0, c per feature] minimising the squared relative error."""
    a = np.column_stack([np.ones(len(t)), x]) / t[:, None]
    return nnls(a, np.ones(len(t)))


def predict(c: np.ndarray, x: np.ndarray) -> np.ndarray:
    return c[0] + x @ c[1:]


def spearman(a, b) -> float:
    ra, rb = (np.argsort(np.argsort(v)) for v in (a, b))
    return float(np.corrcoef(ra, rb)[0, 1])


@click.command()
@click.argument("reports", nargs=-1, required=True, type=click.Path(exists=True, path_type=Path))
@click.option("-o", "--output", "out", required=True, type=click.Path(path_type=Path))
def main(reports, out):
    rows, devices = [], set()
    for p in reports:
        rep = json.loads(p.read_text())
        devices.add(rep["device"])
        rows += [{**r, "scene": p.parent.name} for r in rep["rows"] if r.get("counters_per_pass")]
    if len(devices) != 1:
        raise click.UsageError(f"reports from {len(devices)} devices: a cost model holds for one ({sorted(devices)})")
    x = np.array([features(r) for r in rows], float)
    t = np.array([r["median_ms"] for r in rows], float)
    c = fit(x, t)
    pred = predict(c, x)
    loo = np.array([predict(fit(np.delete(x, i, 0), np.delete(t, i)), x[i:i + 1])[0] for i in range(len(t))])
    rel, rel_loo = np.abs(pred / t - 1), np.abs(loo / t - 1)
    device = devices.pop()
    result = {"device": device, "rows": len(rows),
              "cost_ms": {"per frame": round(float(c[0]), 4),
                          **{f"per million {f}": round(float(v) * 1e6, 4) for f, v in zip(FEATURES, c[1:])}},
              "spearman": round(spearman(pred, t), 4), "spearman_leave_one_out": round(spearman(loo, t), 4),
              "median_rel_error": round(float(np.median(rel)), 4),
              "median_rel_error_leave_one_out": round(float(np.median(rel_loo)), 4),
              "table": [{"scene": r["scene"], "object": r["object"], "label": r["label"], "ms": r["median_ms"],
                         "predicted_ms": round(float(p), 3), "leave_one_out_ms": round(float(q), 3),
                         **{f: round(float(v)) for f, v in zip(FEATURES, xi)}}
                        for r, p, q, xi in zip(rows, pred, loo, x)]}
    out.mkdir(parents=True, exist_ok=True)
    (out / "cost_model.json").write_text(json.dumps(result, indent=1) + "\n")
    lines = [f"Cost model on {device}, {len(rows)} variants: time per frame = "
             + " + ".join([f"{result['cost_ms']['per frame']} ms"] +
                          [f"{v} ms per million {f}" for f, v in zip(FEATURES, [result['cost_ms'][f'per million {f}'] for f in FEATURES])]),
             "", f"Spearman rank correlation {result['spearman']} (leaving each row out: "
             f"{result['spearman_leave_one_out']}); median relative error {result['median_rel_error']:.1%} "
             f"(leaving each row out: {result['median_rel_error_leave_one_out']:.1%}).", "",
             "| scene | object | variant | ms | predicted | left out | " + " | ".join(FEATURES) + " |",
             "|---|---|---|---:|---:|---:|" + "---:|" * len(FEATURES)]
    lines += [f"| {r['scene']} | {r['object']} | {r['label']} | {r['ms']:.2f} | {r['predicted_ms']:.2f} | "
              f"{r['leave_one_out_ms']:.2f} | " + " | ".join(f"{r[f]:,}" for f in FEATURES) + " |" for r in result["table"]]
    (out / "cost_model.md").write_text("\n".join(lines) + "\n")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 5))
    for scene in dict.fromkeys(r["scene"] for r in rows):
        k = [i for i, r in enumerate(rows) if r["scene"] == scene]
        ax.scatter(t[k], loo[k], label=scene, s=18)
    lim = [min(t.min(), loo.min()) * 0.8, max(t.max(), loo.max()) * 1.25]
    ax.plot(lim, lim, "k:", lw=1)
    ax.set(xscale="log", yscale="log", xlim=lim, ylim=lim, xlabel="measured GPU ms per frame (timer queries)",
           ylabel="predicted from counters, row left out [ms]")
    ax.set_title(f"counters against time, {device}\nSpearman {result['spearman_leave_one_out']}", fontsize=8)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "cost_model.png", dpi=110)
    click.echo("\n".join(lines[:3]))


if __name__ == "__main__":
    main()
