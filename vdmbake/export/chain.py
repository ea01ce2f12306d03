"""A bundle's objects exported by a measured LOD chain (vdmrender's lod.json): per chain and object, the
triangle-mesh levels as one glTF 2.0 file with MSFT_lod (vdmbake.export.gltf), and the impostors the chain
chose (octahedral atlases, enhanced billboards) as their bundle parts copied unchanged beside a JSON sidecar
that gives their layout and bands (docs/export.md)."""
from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import numpy as np

from ..bundle import parts
from ..bundle.directory import Bundle
from ..bundle.staging import StagedDir
from ..common.colour import to_srgb8
from ..errors import InputError, cut, escaped
from ..formats.safeio import read_regular
from ..scene import MAX_SIDE, TRIANGLE_MESHES
from ..schema import REQUIRED, Boolean, Integer, Invalid, Reader, Text, Type, Vector
from ..techniques import REGISTRY
from .gltf import Writer

SIDECAR = "vdm-impostors"


MAX_PX = 4 * MAX_SIDE                       # the largest screen size a sweep measures (scene.Sweep.sizes)
MAX_NUMBER = 1e300                          # what a measured value or a share may be, finite: copied into JSON


def _finite(value, depth: int = 0) -> bool:
    """Every number in `value` (a measured point: numbers, strings, None, nested lists and tables) finite and
    within MAX_NUMBER, nested no deeper than a few levels."""
    if depth > 8:
        return False
    if isinstance(value, dict):
        return all(_finite(v, depth + 1) for v in value.values())
    if isinstance(value, list):
        return all(_finite(v, depth + 1) for v in value)
    if isinstance(value, int) and not isinstance(value, bool):
        return abs(value) <= MAX_NUMBER          # compared exactly: math.isfinite(10**400) would overflow
    if isinstance(value, float):
        return math.isfinite(value) and abs(value) <= MAX_NUMBER
    return value is None or isinstance(value, (str, bool))


def check_identity(lod: dict, bundle: Bundle, lod_path: Path) -> None:
    """Refuse a lod.json rendered from another bundle than `bundle`: it records the sha256 of the manifest of the
    bundle it measured (bundle.manifest_sha256), which a re-bake of the same inputs keeps."""
    shown = escaped(str(lod_path))
    recorded = lod.get("bundle", {}).get("manifest_sha256") if isinstance(lod.get("bundle"), dict) else None
    if recorded is None:
        raise InputError(f"{shown} records no bundle identity (bundle.manifest_sha256): it was written by an older "
                         f"vdmrender; render {bundle.path} again with this one and export with its lod.json.")
    if recorded != bundle.identity:
        raise InputError(f"{shown} was rendered from another bundle (manifest sha256 {cut(str(recorded), 64)}"
                         f"), not {bundle.path} ({bundle.identity}); export with the bundle the chain was rendered "
                         "from, or render this bundle again.")


class String(Type):
    text = "a string"

    def parse(self, raw):
        if not isinstance(raw, str):
            raise Invalid
        return raw


class Measured(Type):
    """What lod.json measured, copied into the sidecar as it is."""
    text = f"a list of finite numbers within {MAX_NUMBER:g}, strings, true, false or null (nested lists and tables)"

    def parse(self, raw):
        if not isinstance(raw, list) or not _finite(raw):
            raise Invalid
        return raw


PX = Integer(0, MAX_PX)
# The keys of lod.json this export reads (schema.Reader, as vdmrender.deciding.baseline reads a report): (type, default).
TOP = {"device": (String(), REQUIRED), "resolution": (Vector(2, 1, MAX_SIDE, integer=True), REQUIRED),
       "band": (String(), "")}
CHAIN = {"name": (Text("1-64 characters from A-Z a-z 0-9 _ - (it becomes part of file names)", r"[A-Za-z0-9_-]{1,64}"),
                  REQUIRED)}
# screen_coverage: the band [max_px, min_px] over the frame's height (MSFT_screencoverage's unit), more than 1 where
# a sweep size overflows the frame (scene.Sweep.sizes); checked against the band by read_lod.
ENTRY = {"variant": (String(), REQUIRED), "technique": (String(), REQUIRED), "min_px": (PX, REQUIRED),
         "max_px": (PX, REQUIRED), "meets": (Boolean(), REQUIRED), "screen_coverage": (Vector(2, 0, MAX_PX), REQUIRED),
         "measured": (Measured(), REQUIRED)}


def read_lod(path: Path) -> dict:
    """lod.json as vdmrender wrote it, every key this export reads checked for its type (TOP, CHAIN, ENTRY) before
    anything is written: a damaged or hand-edited file ends the run with one message naming the key. Returns just
    those keys (and `bundle`, which check_identity reads)."""
    shown = escaped(str(path))
    try:
        lod = json.loads(read_regular(path, "lod.json", limit=64 << 20))
    except FileNotFoundError:
        raise InputError(f"{shown}: not found; vdmrender writes lod.json into its output folder for a scene with "
                         "[[render.sweep.lod]].") from None
    except (OSError, ValueError, RecursionError) as e:
        raise InputError(f"{shown}: not a lod.json written by vdmrender ({type(e).__name__}: "
                         f"{cut(str(e))}).") from None
    top = Reader(lod, "", f"{shown}: not a lod.json written by vdmrender, or edited (render again)")

    def entries(r: Reader, key: str) -> list[dict]:
        raw = r.data.get(key)
        if not isinstance(raw, list) or not raw:
            r.fail(key, raw, "a non-empty list of entries")
        out = []
        for k, e in enumerate(raw):
            er = Reader(e, f"{r.key(key)}[{k}]", r.origin)
            e = er.values(ENTRY)
            if e["min_px"] > e["max_px"]:
                er.fail("min_px", e["min_px"], f"at most max_px ({e['max_px']})")
            height = head["resolution"][1]   # read before the chains (below)
            band = [e["max_px"] / height, e["min_px"] / height]
            if max(abs(a - b) for a, b in zip(e["screen_coverage"], band)) > 1e-6:   # vdmrender rounds to 6 places
                er.fail("screen_coverage", list(e["screen_coverage"]), f"[max_px, min_px] over the frame's height "
                        f"{height}: [{band[0]:.6g}, {band[1]:.6g}]")
            out.append({**e, "screen_coverage": list(e["screen_coverage"])})
        return out

    def chain(r: Reader) -> dict:
        if not r.has("objects"):
            r.fail("objects", None, "a table of object names to their chains")
        objects, out = r.table("objects"), {}
        for name in objects.data:
            o = objects.table(name)
            out[name] = {"entries": entries(o, "entries")}
            if "meshes_only" in o.data:
                out[name]["meshes_only"] = {"entries": entries(o.table("meshes_only"), "entries")}
        return {**r.values(CHAIN), "objects": out}

    if not isinstance(top.data.get("chains"), list):
        top.fail("chains", top.data.get("chains"), "a list of chains")
    head = top.values(TOP)
    return {**head, "resolution": list(head["resolution"]), "bundle": lod.get("bundle"),
            "chains": [chain(Reader(c, f"chains[{i}]", top.origin)) for i, c in enumerate(lod["chains"])]}


def variant_value(obj, label: str):
    """The technique and value of the object's variant named `label` in reports."""
    for tech, options in obj.techniques.items():
        for v in REGISTRY[tech].values(options):
            if REGISTRY[tech].label(v) == label:
                return tech, v
    raise InputError(f"lod.json names variant {escaped(label)!r} of object {obj.name!r}, which the bundle's scene "
                     "does not have; export with the bundle the chain was rendered from.")


def export(bundle_path: Path, lod_path: Path, out_path: Path, only: str | None = None, log=lambda m: None) -> dict:
    bundle, lod = Bundle(bundle_path), read_lod(lod_path)
    check_identity(lod, bundle, lod_path)
    chains = [c for c in lod["chains"] if only in (None, c["name"])]
    if not lod["chains"]:
        raise InputError(f"{escaped(str(lod_path))} holds no chain; give the scene [[render.sweep.lod]] limits and "
                         "render it again.")
    if not chains:
        raise InputError(f"--chain {escaped(only)!r}: {escaped(str(lod_path))} has the chains "
                         f"{', '.join(repr(c['name']) for c in lod['chains'])}.")
    objects = {o.name: o for o in bundle.scene.objects}
    out = StagedDir(out_path, "export.json", "vdmexport output folder")
    summary = {"bundle": str(bundle.path), "lod": str(lod_path), "device": lod["device"], "files": [], "warnings": []}
    try:
        for c in chains:
            for name, ch in c["objects"].items():
                if name not in objects:
                    raise InputError(f"{escaped(str(lod_path))} names object {escaped(name)!r}, which bundle "
                                     f"{bundle.path} lacks; export with the bundle the chain was rendered from.")
                obj, entry, stem = objects[name], bundle.manifest["objects"][name], f"{name}-{c['name']}"
                for e in ch["entries"] + ch.get("meshes_only", {}).get("entries", []):
                    technique = variant_value(obj, e["variant"])[0]
                    if e["technique"] != technique:   # which parts are exported follows the technique
                        raise InputError(f"{escaped(str(lod_path))}: chain {c['name']!r} object {escaped(name)!r} "
                                         f"gives variant {escaped(e['variant'])!r} the technique "
                                         f"{escaped(e['technique'])!r}, where the bundle's scene makes it a "
                                         f"{technique!r} variant; render again, or export with the bundle the chain "
                                         "was rendered from.")
                if "meshes_only" in ch:
                    levels, note = _gltf(out, bundle, obj, entry, merged(ch["meshes_only"]["entries"]), stem,
                                         lod["resolution"][1])
                    summary["files"].append(f"{stem}.gltf")
                    if note:
                        summary["warnings"].append(note)
                        log(f"warning: {note}")
                    log(f"{stem}.gltf: {levels} levels")
                impostors = [e for e in merged(ch["entries"]) if e["technique"] not in TRIANGLE_MESHES]
                if impostors:
                    summary["files"].append(_sidecar(out, bundle, obj, entry, impostors, stem, lod))
                    log(f"{stem}.impostors.json: {', '.join(e['variant'] for e in impostors)}")
        out.file("export.json").write_text(json.dumps(summary, indent=1) + "\n")
        out.commit()
    except BaseException:
        out.abort()
        raise
    return summary


def merged(entries: list[dict]) -> list[dict]:
    """A chain's entries with neighbours of one variant as one level (lod.json splits a band within the limits
    from one over them: one mesh, not two copies of it)."""
    out = []
    for e in entries:
        if out and out[-1]["variant"] == e["variant"]:
            out[-1] = {**out[-1], "min_px": e["min_px"],
                       "screen_coverage": [out[-1]["screen_coverage"][0], e["screen_coverage"][1]]}
        else:
            out.append(e)
    return out


def finest_first(levels: list[dict], faces: list[int]) -> tuple[list[tuple[dict, int]], str | None]:
    """The levels as MSFT_lod needs them: finest first (most triangles), each distinct variant once, each paired
    with the band limit (px) down to which it shows: the smallest size it or a finer level was chosen at, so the
    switch sizes fall (a finer level takes over a band a coarser one held above it; a level whose bands all lie
    above a finer one's is never shown and is left out). With a note where that is not the chain as lod.json
    has it (a chain picked by noisy costs can come out coarse -> fine -> coarse)."""
    seen: dict[str, tuple[dict, int, int]] = {}
    for e, f in zip(levels, faces):
        first, _, low = seen.get(e["variant"], (e, f, e["min_px"]))
        seen[e["variant"]] = (first, f, min(low, e["min_px"]))
    out, switch = [], math.inf
    for e, _, low in sorted(seen.values(), key=lambda t: -t[1]):   # stable: equal counts keep the chain's order
        if min(switch, low) < switch:
            switch = min(switch, low)
            out.append((e, switch))
    if [e["variant"] for e, _ in out] == [e["variant"] for e in levels]:   # as it was (equal counts keep their order)
        return out, None
    was = " -> ".join(f"{e['variant']} ({f} triangles, from {e['min_px']} px)" for e, f in zip(levels, faces))
    now = " -> ".join(f"{e['variant']} down to {px} px" for e, px in out)
    left = [v for v in seen if v not in {e["variant"] for e, _ in out}]
    return out, (f"the chain's levels are not finest first ({was}); exported finest first, each level once ({now})"
                 + "".join(f"; {v} left out, chosen only above a finer level" for v in left)
                 + ". Check the chain's costs in lod.md, or render again.")


def _gltf(out, bundle, obj, entry, levels: list[dict], stem: str, height: int) -> tuple[int, str | None]:
    """The chain's triangle-mesh levels as STEM.gltf, finest first: level k shown while the object spans more than
    its switch size (MSFT_screencoverage: that over the frame height), the last down to nothing left to cull.
    Returns the number of levels and what was said about their order."""
    meshes = {}
    for e in levels:
        tech, value = variant_value(obj, e["variant"])
        rel = next(iter(REGISTRY[tech].reads(entry["techniques"][tech], value, obj))) if REGISTRY[tech].reads \
            else entry["mesh"]
        meshes[e["variant"]] = bundle.surface(entry, rel)
    ordered, note = finest_first(levels, [len(meshes[e["variant"]].faces) for e in levels])
    if note:
        note = f"{stem}.gltf: {note}"
    w = Writer()
    texture_uri = None
    nodes = []
    for k, (e, _) in enumerate(ordered):
        mesh = meshes[e["variant"]]
        if mesh.texture is not None and texture_uri is None:
            texture_uri = f"{obj.name}-albedo.png"
            from PIL import Image
            Image.fromarray(np.ascontiguousarray(mesh.texture[::-1])).save(out.file(texture_uri))
        material = w.material(f"{obj.name}_{e['variant']}", texture_uri if mesh.texture is not None else None,
                              obj.material.albedo, mesh.colors is not None)
        nodes.append(w.mesh(f"{obj.name}_LOD{k}_{e['variant']}", mesh, material))
    w.lod(nodes, [px / height for _, px in ordered[:-1]] + [0.0], bundle.scene.camera.up, [note] if note else [])
    w.save(out.file(f"{stem}.gltf"))
    return len(ordered), note


def rendered_from(tech: str, value, obj, entry: dict) -> dict:
    """The bundle parts a variant of `tech` renders from, {path: part kind}: those its bake step wrote (its
    `reads`), or, for a technique that bakes nothing over a molecule's spheres and cylinders (impostor,
    tessellated), the object's quadric list. Any other variant draws from parts this export does not describe
    (a mesostructure's maps over its base mesh): refused by name."""
    if REGISTRY[tech].reads:
        return REGISTRY[tech].reads(entry["techniques"][tech], value, obj)
    if entry.get("quadrics"):
        return {entry["quadrics"]: parts.QUADRICS}
    raise InputError(f"vdmexport: the chain chose {REGISTRY[tech].label(value)!r} for object {obj.name!r}, which draws "
                     "the base mesh with its mesostructure maps per pixel; vdmexport writes triangle-mesh levels and "
                     "impostors only (docs/export.md, what is not exported). Give the chain a limit that this variant "
                     "does not meet, or export another chain (--chain).")


def _sidecar(out, bundle, obj, entry, impostors: list[dict], stem: str, lod: dict) -> str:
    """STEM.impostors.json: per impostor of the chain its band, what it measured, and its parts (copied as
    OBJECT-PART) with the manifest's layout of each; an octahedral atlas also as a PNG to look at."""
    items = []
    for e in impostors:
        tech, value = variant_value(obj, e["variant"])
        files = []
        for rel, kind in rendered_from(tech, value, obj, entry).items():
            name = f"{obj.name}-{Path(rel).name}"
            part = _copied(bundle, rel, kind, out.file(name))
            meta = bundle.manifest["parts"][rel]
            files.append({"file": name, "kind": kind.name, "sha256": meta["sha256"],
                          "layout": {k: v for k, v in meta.items() if k not in ("sha256", "bytes", "kind")}})
            if kind.name == "octahedral":
                files[-1]["preview"] = _atlas_preview(out, part, name)
        items.append({"variant": e["variant"], "technique": tech, "band_px": [e["min_px"], e["max_px"]],
                      "screen_coverage": e["screen_coverage"], "within_limits": e["meets"], "measured": e["measured"],
                      "files": files})
    doc = {"format": SIDECAR, "version": 1, "object": obj.name, "device": lod["device"],
           "frame": lod["resolution"], "band": lod.get("band"),
           "read": "docs/export.md: each part kind's layout and how a shader reads it", "impostors": items}
    out.file(f"{stem}.impostors.json").write_text(json.dumps(doc, indent=1) + "\n")
    return f"{stem}.impostors.json"


def _copied(bundle: Bundle, rel: str, kind, dest: Path):
    """Copy part `rel` to `dest`, verified as it is made: its bytes against the manifest's sha256 and read by its
    kind's reader before they are written, the copy read back against the same sha256; returns what the reader
    made of it. A part that fails ends the export (InputError naming it) before any sidecar states its sha256."""
    data = bundle.read_bytes(rel)   # the manifest's sha256 (InputError: "checksum mismatch")
    meta = bundle.manifest["parts"][rel]
    if meta.get("kind") != kind.name:
        raise InputError(f"{bundle.path / rel}: the manifest records a {escaped(str(meta.get('kind')))!r} part where "
                         f"a {kind.name!r} part is expected; re-bake with vdmbake --force.")
    try:
        value = kind.unpack(data, meta, str(bundle.path / rel))
    except InputError:
        raise
    except Exception as e:   # a reader's own error on bytes that match their sha256: a bundle written wrong
        raise InputError(f"{bundle.path / rel}: the {kind.name} part does not read ({type(e).__name__}: "
                         f"{cut(str(e))}); re-bake with vdmbake --force.") from None
    if not dest.exists():
        dest.write_bytes(data)
    if hashlib.sha256(dest.read_bytes()).hexdigest() != meta["sha256"]:
        raise InputError(f"{dest}: the copy of {bundle.path / rel} does not have the manifest's sha256 (the "
                         "output disk changed it); export again to another folder.")
    return value


def _atlas_preview(out, atlas, name: str) -> str:
    """The atlas as an sRGB PNG, alpha the coverage: its albedo where it has one, else its normals (0.5 + n/2)."""
    from PIL import Image

    rgb = atlas.albedo if atlas.albedo is not None else np.dstack(
        [0.5 + 0.5 * atlas.normal, np.sqrt(np.clip(1 - (atlas.normal ** 2).sum(-1), 0, 1))[..., None]])
    rgba = np.dstack([to_srgb8(rgb), (255 * atlas.coverage).astype(np.uint8)])
    png = Path(name).stem + ".png"
    Image.fromarray(np.ascontiguousarray(rgba[::-1])).save(out.file(png))
    return png
