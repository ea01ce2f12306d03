"""docs/relief-error-vs-time.png (mean dLuv against interleaved wall time / displaced@2, from out/m/timing2-*.log
and the runs' report.json) and docs/relief-torus-bricks.png (frame 0: reference, relief@32, heat maps)."""
import json, re
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
from PIL import Image

scenes = ["torus-bricks", "vase-bricks", "torus-gravel", "vase-gravel"]
fig, axes = plt.subplots(1, 4, figsize=(16, 4))
for ax, s in zip(axes, scenes):
    rows = {r["label"]: r for r in json.load(open(f"out/m/r-{s}/report.json"))["rows"]}
    ratio = {}
    for line in open(f"out/m/timing2-{s}.log"):
        m = re.match(r"(\S+)\s+wall median\s+[\d.]+ ms ratio ([\d.]+)", line)
        if m:
            ratio[m.group(1)] = float(m.group(2))
    for tech, style in (("relief", "o-"), ("pom", "s-"), ("displaced", "^-")):
        labels = [k for k in rows if k.startswith(tech + "@")]
        labels.sort(key=lambda k: ratio[k])
        ax.plot([ratio[k] for k in labels], [rows[k]["mean_dluv"] for k in labels], style, label=tech)
        for k in labels:
            ax.annotate(k.split("@")[1], (ratio[k], rows[k]["mean_dluv"]), fontsize=7)
    ax.axvline(0.4, color="grey", lw=0.5, ls=":")
    ax.axhline(rows["displaced@2"]["mean_dluv"], color="grey", lw=0.5, ls=":")
    ax.set_title(s); ax.set_xlabel("wall time / displaced@2 (interleaved)"); ax.set_ylabel("mean dLuv")
    ax.legend(fontsize=8)
fig.suptitle("relief (iterations), pom (steps), displaced (levels), 512x512, llvmpipe, 2 orbit frames")
fig.tight_layout()
fig.savefig("docs/relief-error-vs-time.png", dpi=80)

run = "out/m/r-torus-bricks"
keys = [("reference/torus-bricks", "reference"), ("frames/torus-bricks/relief@32", "relief@32"),
        ("heatmaps/torus-bricks/relief@32", "relief@32 error"), ("heatmaps/torus-bricks/pom@16", "pom@16 error"),
        ("heatmaps/torus-bricks/displaced@2", "displaced@2 error")]
ims = [Image.open(f"{run}/{k}/000.png").convert("RGB").crop((0, 90, 512, 422)).resize((384, 249)) for k, _ in keys]
out = Image.new("RGB", (384 * len(ims), 249))
for i, im in enumerate(ims):
    out.paste(im, (384 * i, 0))
out.save("docs/relief-torus-bricks.png")
