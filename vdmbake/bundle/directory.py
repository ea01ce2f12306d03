"""The bundle: a directory with manifest.json and its parts (PLY meshes, EXR tables and maps),
each of a kind in vdmbake.bundle.parts; docs/bundle.md is its specification.

Writing goes to a hidden temporary sibling directory; the manifest is written last and
the directory is renamed into place, so an interrupted bake never leaves a bundle that
looks valid. Each part is read back through its kind's checks before it is listed, so a bake
never commits a bundle the renderer would refuse. Reading checks the format version, then the
whole manifest (vdmbake.bundle.manifest) before any part; each part is read once, a regular file of the
size listed, and its sha256, kind and contents are checked on the very bytes that are parsed. The manifest
and the parts are found the same way (part_path): nothing is read through a symbolic link out of the bundle.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path, PurePosixPath

from .. import __version__
from ..errors import InputError, cut
from .parts import PartKind
from ..formats.safeio import read_regular
from .staging import StagedDir

FORMAT = "vdm-bundle"
FORMAT_VERSION = 2
MANIFEST = "manifest.json"
TIMING = "timing.json"  # wall times: kept out of the manifest so the manifest's bytes are deterministic
MAX_MANIFEST_BYTES = 256 << 20


class RefusedBundle(InputError):
    """A bundle staged but refused by the reader's own check (Bundle), so not committed."""


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def dumps(obj) -> str:
    """Deterministic JSON; key order is the code's and the scene's (technique order matters)."""
    return json.dumps(obj, indent=1) + "\n"


def update_scene(path: Path, scene: dict) -> bool:
    """Give the complete bundle at `path` the scene `scene` where its manifest holds another whose difference the
    bake does not read (the render settings, vdmbake.bake.RENDER_ONLY: vdmrender renders with the bundle's copy):
    the manifest rewritten beside it and renamed over it, so a reader sees the old or the new one whole. Returns
    whether it changed."""
    manifest = Bundle(path).manifest
    if manifest["scene"] == scene:
        return False
    tmp = Path(path) / f".{MANIFEST}.tmp-{os.getpid()}"
    tmp.write_text(dumps({**manifest, "scene": scene}))
    os.replace(tmp, Path(path) / MANIFEST)
    return True


class BundleWriter:
    """Collects parts in a staging folder; commit() writes the manifest last and moves the bundle into place."""

    def __init__(self, path: Path):
        self.stage = StagedDir(path, MANIFEST, "bundle")
        self.parts: dict[str, dict] = {}
        self._made: list | None = None       # the parts of the step being recorded (record), for the part cache

    def add(self, rel: str, kind: PartKind, value) -> str:
        """Write `value` as a part of `kind` at `rel` (its suffix appended); returns the part's path."""
        return self.add_read(rel, kind, value)[0]

    def add_read(self, rel: str, kind: PartKind, value):
        """add, returning also the value as a reader of the bundle gets it (parts.stored's, from the bytes
        written: float32 rounding included): (the part's path, that value)."""
        data, meta = kind.pack(value)
        return self.add_packed(rel + kind.suffix, kind, data, meta)

    def check_packed(self, rel: str, kind: PartKind, data: bytes, meta: dict):
        """The checks the renderer will make, on a part's bytes and manifest metadata: the metadata by the kind's
        schema, the bytes by the kind's reader; returns the value read."""
        origin = f"{self.stage.path / rel} (as baked)"
        from .manifest import check_meta
        check_meta(kind, meta, rel, origin)                 # what the renderer will check: the manifest entry
        return kind.unpack(data, meta, origin)              # and the part

    def add_packed(self, rel: str, kind: PartKind, data: bytes, meta: dict, checked: bool = False):
        """Write a packed part at `rel` (suffix included) after check_packed (unless `checked`: the caller made
        them); the parts of a bake step come here whether baked or taken from the part cache (vdmbake.cache).
        Returns (rel, the value read back; None if `checked`)."""
        pure = PurePosixPath(rel)
        if pure.is_absolute() or ".." in pure.parts or "\\" in rel:
            raise InputError(f"{self.stage.path}: part path {rel!r} leaves the bundle; refusing to write it.")
        read = None if checked else self.check_packed(rel, kind, data, meta)
        self.stage.file(rel).write_bytes(data)
        self.parts[rel] = {"kind": kind.name, "sha256": _sha256(data), "bytes": len(data), **meta}
        if self._made is not None:
            self._made.append((rel, kind.name, meta, data))
        return rel, read

    def record(self, stop: list | None = None) -> list:
        """Start recording the parts written (rel, kind name, metadata, bytes) into a new list, returned;
        record(stop=that list) stops."""
        self._made = None if stop is not None else []
        return stop if stop is not None else self._made

    def commit(self, manifest: dict, timing: dict) -> None:
        manifest = {"format": FORMAT, "format_version": FORMAT_VERSION, "tool_version": __version__,
                    **manifest, "parts": self.parts}
        self.stage.file(TIMING).write_text(dumps(timing))
        self.stage.file(MANIFEST).write_text(dumps(manifest))  # last: its presence marks a complete bundle
        try:
            Bundle(self.stage.tmp)          # what the renderer checks first: a bake never commits what it refuses
        except InputError as e:
            raise RefusedBundle(f"{self.stage.path}: the bundle baked fails the reader's check ({e}); not "
                                "committed") from None
        self.stage.commit()

    def abort(self) -> None:
        self.stage.abort()


class Bundle:
    """A bundle opened for reading; each part is checked against its manifest sha256 when read."""

    def __init__(self, path: Path):
        self.path = Path(path)
        if not (self.path / MANIFEST).is_file():
            raise InputError(f"{self.path}: not a bundle ({MANIFEST} missing); make one with vdmbake.")
        mf = self.part_path(MANIFEST)
        try:
            data = read_regular(mf, "manifest", limit=MAX_MANIFEST_BYTES)
            self.identity = _sha256(data)   # what ties a file made from the bundle (lod.json) to it
            self.manifest = json.loads(data)
        except (OSError, ValueError, RecursionError) as e:
            raise InputError(f"{mf}: unreadable manifest ({type(e).__name__}: {cut(str(e))}); re-bake with "
                             "vdmbake --force.") from None
        if not isinstance(self.manifest, dict):
            json_type = {list: "array", str: "string", type(None): "null"}.get(type(self.manifest), "number")
            raise InputError(f"{mf}: the manifest is a JSON {json_type}, not an object; "
                             "re-bake with vdmbake --force.")
        m = self.manifest
        version = m.get("format_version")
        if m.get("format") != FORMAT or type(version) is not int or version != FORMAT_VERSION:
            raise InputError(f"{mf}: format {cut(str(m.get('format')), 40)!r} version {cut(str(version), 40)}; this tool "
                             f"reads {FORMAT!r} version {FORMAT_VERSION}. Re-bake the scene with this vdmbake.")
        from .manifest import validate
        self.scene = validate(self.manifest, str(mf))
        for rel in self.manifest["parts"]:
            self.part_path(rel)

    def part_path(self, rel: str) -> Path:
        """The file at `rel` in the bundle (the manifest, a part), resolved: refused if its path or a symbolic link
        on the way leads out of the bundle."""
        pure = PurePosixPath(rel)
        if pure.is_absolute() or ".." in pure.parts or not pure.parts:
            raise InputError(f"{self.path / MANIFEST}: part path {rel!r} leaves the bundle; refusing to read it.")
        p = (self.path / pure).resolve()
        if not p.is_relative_to(self.path.resolve()):
            raise InputError(f"{self.path}: {rel!r} resolves outside the bundle (to {p}); refusing to read it.")
        return p

    def read_bytes(self, rel: str) -> bytes:
        """The part's bytes, checked against its sha256."""
        meta = self.manifest["parts"].get(rel)
        if meta is None:
            raise InputError(f"{self.path}: the manifest lists no part {rel!r}.")
        try:
            data = read_regular(self.part_path(rel), "bundle part", size=meta["bytes"])
        except OSError as e:
            raise InputError(f"{self.path / rel}: bundle part missing or unreadable ({e.strerror or e}).") from None
        if _sha256(data) != meta["sha256"]:
            raise InputError(f"{self.path / rel}: checksum mismatch (the part is corrupted or was edited); "
                             "re-bake with vdmbake --force.")
        return data

    def surface(self, entry: dict, rel: str | None = None):
        """A surface object's mesh part `rel` (default: its full mesh, the manifest entry's `mesh`) with the
        asset's albedo map (`albedo_map`) attached if it has one and the mesh has texture coordinates."""
        from .parts import ALBEDO_MAP, MESH

        mesh = self.read(rel or entry["mesh"], MESH)
        if entry.get("albedo_map") and mesh.uvs is not None:
            mesh.texture = self.read(entry["albedo_map"], ALBEDO_MAP)
        return mesh

    def read(self, rel: str, kind: PartKind):
        """The part at `rel`, which the manifest must record as of `kind`, unpacked from the bytes checked."""
        data = self.read_bytes(rel)
        meta = self.manifest["parts"][rel]
        if meta.get("kind") != kind.name:
            raise InputError(f"{self.path / rel}: the manifest records a {meta.get('kind')!r} part where a "
                             f"{kind.name!r} part is expected; re-bake with vdmbake --force.")
        return kind.unpack(data, meta, str(self.path / rel))
