"""Where is the error? Per variant: mean dLuv over the union of coverage masks, split into the silhouette
band (pixels within 2 px of the coverage boundary of the reference or of the frame) and the interior."""
import sys, glob, os, numpy as np
from PIL import Image
from scipy import ndimage
from vdmrender.comparing.metrics import delta_luv

def split(run, obj):
    refs = sorted(glob.glob(f"{run}/reference/{obj}/*.png"))
    variants = sorted(os.listdir(f"{run}/frames/{obj}"))
    bg = np.asarray(Image.open(refs[0]).convert("RGB"))[0, 0]
    rows = {}
    for v in variants:
        tot = band_sum = 0.0; n = nb = 0
        for rp in refs:
            ref = np.asarray(Image.open(rp).convert("RGB"))
            fr = np.asarray(Image.open(f"{run}/frames/{obj}/{v}/{os.path.basename(rp)}").convert("RGB"))
            mr, mf = (ref != bg).any(-1), (fr != bg).any(-1)
            union = mr | mf
            edge = lambda m: m ^ ndimage.binary_erosion(m)
            band = ndimage.binary_dilation(edge(mr) | edge(mf) | (mr ^ mf), iterations=2) & union
            d = delta_luv(fr, ref)
            tot += d[union].sum(); n += union.sum(); band_sum += d[band].sum(); nb += band.sum()
        rows[v] = (tot / n, band_sum / n, (tot - band_sum) / n, nb / n)
    return rows

if __name__ == "__main__":
    run, obj = sys.argv[1], sys.argv[2]
    print(f"{'variant':14s} {'mean':>7s} {'band':>7s} {'inner':>7s}  band share of pixels")
    for v, (m, b, i, f) in split(run, obj).items():
        print(f"{v:14s} {m:7.3f} {b:7.3f} {i:7.3f}  {f:.3f}")
