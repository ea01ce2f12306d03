"""Golden-image regression tests: one small scene per technique family (tests/golden/*.toml: mesh and
coarse; impostor and tessellated; vdm, pom and bump; billboards), each variant's frame compared per
pixel with the image stored when the renderer was last known good (tests/golden/SCENE/...png,
8-bit sRGB with coverage as alpha; tests/golden/RENDERER.txt names the GL renderer they were made on).

The end-to-end tests elsewhere compare with a reference this repository computes; these catch any
change of the pictures themselves. The tolerance is statistical, as Mitsuba's render tests and
OpenImageIO's idiff use (a bound on the mean and on the fraction of pixels beyond a threshold):
over the union of both coverage masks,

* coverage: IoU >= 0.995 (at most 1 pixel in 200 covered by one image only),
* colour: mean ΔLuv <= 0.1, and at most 1% of the pixels with ΔLuv > 0.5.

On the renderer they were made on the frames reproduce exactly (0.0, IoU 1); the bounds leave room
for another driver's rounding and reject a one-pixel shift or a 3% darker light (tests below; the
margins are in docs/trust-notes.md).

Regenerate after an intended change of the pictures: VDM_REGEN_GOLDEN=1 pytest tests/test_golden.py
(then look at the images and commit them with tests/golden/RENDERER.txt).
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from vdmbake.bake import bake
from vdmbake.bundle import Bundle
from vdmbake.scene import parse_scene_dict
from vdmrender import gl, images
from vdmrender.camera import cameras_for
from vdmrender.metrics import compare
from vdmrender.techniques import variants

GOLDEN = Path(__file__).parent / "golden"
SCENES = sorted(p.stem for p in GOLDEN.glob("*.toml"))
REGEN = os.environ.get("VDM_REGEN_GOLDEN", "") not in ("", "0")
MIN_IOU, MAX_MEAN, PIXEL_DLUV, MAX_FRACTION = 0.995, 0.1, 0.5, 0.01


def render(tmp_path: Path, text: str) -> dict[str, np.ndarray]:
    """Bake and render the scene's first camera frame with every variant: {OBJECT/LABEL/NNN: RGBA8}."""
    (tmp_path / "s.toml").write_text(text)
    bake(tmp_path / "s.toml", tmp_path / "s.bundle")
    bundle = Bundle(tmp_path / "s.bundle")
    scene = parse_scene_dict(bundle.manifest["scene"], "golden")
    w, h = scene.render.resolution
    ctx = gl.create_context()
    target = gl.Target(ctx, w, h)
    out = {}
    try:
        for obj in scene.objects:
            entry = bundle.manifest["objects"][obj.name]
            for k, cam in enumerate(cameras_for(scene.camera, entry["centre"], entry["radius"], w, h)):
                for v in variants(obj, entry, bundle, scene):
                    r = v.build(ctx)
                    r.render(cam, target)
                    out[f"{obj.name}/{v.label}/{k:03d}"] = images.encode(target.read(), scene.render.background)
                    r.release()
    finally:
        target.release()
        ctx.release()
    return out


def difference(frame: np.ndarray, golden: np.ndarray) -> dict:
    """The statistics the tolerance bounds (RGBA8 images, alpha = coverage)."""
    c = compare(frame, golden)
    if c["empty"]:
        return {"iou": None, "mean": None, "above": None}
    return {"iou": c["iou"], "mean": c["mean"], "above": float((c["values"] > PIXEL_DLUV).mean())}


def within(d: dict) -> bool:
    return d["iou"] is not None and d["iou"] >= MIN_IOU and d["mean"] <= MAX_MEAN and d["above"] <= MAX_FRACTION


def stored(scene: str) -> dict[str, np.ndarray]:
    return {str(p.relative_to(GOLDEN / scene).with_suffix("")): np.asarray(Image.open(p))
            for p in sorted((GOLDEN / scene).rglob("*.png"))}


def regenerate(scene: str, frames: dict[str, np.ndarray]) -> None:
    for key, img in frames.items():
        p = GOLDEN / scene / f"{key}.png"
        p.parent.mkdir(parents=True, exist_ok=True)
        Image.fromarray(img, "RGBA").save(p)
    ctx = gl.create_context()
    (GOLDEN / "RENDERER.txt").write_text(
        "The golden images were rendered on:\n" + gl.renderer_name(ctx) + "\n"
        "Regenerate with VDM_REGEN_GOLDEN=1 pytest tests/test_golden.py on a known-good commit.\n")
    ctx.release()


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    """Each scene rendered once per test session."""
    cache = {}

    def get(scene: str) -> dict[str, np.ndarray]:
        if scene not in cache:
            cache[scene] = render(tmp_path_factory.mktemp(scene), (GOLDEN / f"{scene}.toml").read_text())
        return cache[scene]
    return get


@pytest.mark.parametrize("scene", SCENES)
def test_frames_match_the_golden_images(frames, scene):
    new = frames(scene)
    if REGEN:
        regenerate(scene, new)
        pytest.skip(f"regenerated tests/golden/{scene}/ ({len(new)} images)")
    old = stored(scene)
    assert set(new) == set(old), f"variants changed: rendered {sorted(new)}, stored {sorted(old)}; regenerate"
    for key in new:
        d = difference(new[key], old[key])
        assert within(d), f"{scene}/{key}: {d} outside IoU >= {MIN_IOU}, mean <= {MAX_MEAN}, " \
                          f"fraction above {PIXEL_DLUV} <= {MAX_FRACTION}"


def test_every_family_has_a_golden_scene():
    from vdmbake.scene import REGISTRY

    drawn = set()
    for scene in SCENES:
        s = parse_scene_dict(__import__("tomllib").loads((GOLDEN / f"{scene}.toml").read_text()), scene)
        drawn |= {t for o in s.objects for t in o.techniques}
    assert {"mesh", "coarse", "impostor", "tessellated", "vdm", "pom", "bump", "billboards"} <= drawn
    assert set(drawn) <= set(REGISTRY)


@pytest.mark.parametrize("scene", SCENES)
def test_a_one_pixel_shift_is_rejected(frames, scene):
    """The golden frame itself, moved one pixel right (the column shifted out refilled with the
    background): every variant's frame must fail the tolerance."""
    for key, img in stored(scene).items():
        shifted = np.concatenate([img[:, :1], img[:, :-1]], 1)
        shifted[:, 0] = img[0, 0]            # the background pixel of the corner
        d = difference(shifted, img)
        assert not within(d), (key, d)


@pytest.mark.parametrize("scene", SCENES)
def test_a_three_percent_darker_light_is_rejected(tmp_path, scene):
    """The scene rendered with its light's colour times 0.97 (the ambient term unchanged): every
    variant's frame must fail the tolerance."""
    text = (GOLDEN / f"{scene}.toml").read_text()
    assert "[light]" not in text
    darker = render(tmp_path, text.replace("[camera]", "[light]\ncolor = [0.97, 0.97, 0.97]\n[camera]", 1))
    old = stored(scene)
    for key, img in darker.items():
        d = difference(img, old[key])
        assert not within(d), (key, d)
