"""The content-addressed part cache (`vdmbake --cache DIR`, or VDM_CACHE): every bake step's parts stored
under the hash of exactly what the step depends on, so another scene with the same asset and settings,
another machine or a CI job gets them without baking them (docs/library.md).

A bake has two kinds of step (vdmbake.bake): an object's own parts (its full mesh, albedo map, height
field, quadric list) and each technique's bake step (coarse meshes, VDM tables, billboards...). The key
of a step is sha256 over canonical JSON of:

* the object's resolved settings (the scene's object table, every default filled in, without its name,
  its technique list, `expect_empty` and, unless it holds inline spheres or cylinders, its material:
  no step reads them) and the sha256 of every file the object
  reads (mesh file and every file it reaches, molecule, height and albedo pictures);
* for a technique step, the object step's key, the technique's name and its resolved settings;
* the code of the step: sha256 over the source of every vdmbake module the step's module imports,
  directly or through others (`step_code`), plus the bundle format and tool versions and the versions
  of the libraries that compute the parts (numpy, embreex, trimesh, ...). A hash of the code rather
  than a hand-bumped version constant, because a forgotten bump silently serves stale parts, while a
  hash can only cost a re-bake.

An entry is one file, `entries/KEY[:2]/KEY`: a first line `VDMCACHE1 <sha256 of the rest>`, then the
header's length (8 bytes), the header (JSON: the key, the manifest entry of the step, its log lines,
each part's name, kind, metadata, size and sha256) and the parts' bytes. Every read checks the whole
file against that sha256 and the key inside against the name: a damaged entry is deleted, counted as
corrupt and baked again. Writes go to a temporary file in the same folder, fsynced, then os.replace:
readers see the old entry, no entry, or the complete new one, never a torn one, and two processes (or
machines on one shared file system) writing the same key leave one complete entry (the bake is
deterministic: both wrote the same bytes). A hit sets the entry's modification time (the LRU clock,
kept in mtime because atime is often not updated); after each store, entries beyond the size bound
are removed oldest first. Statistics: one JSON line per bake appended to `stats.log` (O_APPEND).
"""
from __future__ import annotations

import functools
import hashlib
import importlib.metadata
import json
import os
import re
import shutil
import socket
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from .. import code_fingerprint, imported_closure
from ..errors import InputError

MAGIC = b"VDMCACHE1"
ENV = "VDM_CACHE"
ENV_SIZE = "VDM_CACHE_SIZE"
DEFAULT_MAX_BYTES = 10 << 30
STALE_TMP_S = 3600            # temporary files older than this are a killed writer's: removed by eviction
LIBRARIES = ("numpy", "embreex", "trimesh", "fast-simplification", "OpenEXR", "gemmi", "pillow", "scikit-image")
_SIZE = re.compile(r"(\d+(?:\.\d+)?)\s*([kmgt]?)i?b?", re.I)


def parse_size(text: str | int) -> int:
    """Bytes from `10G`, `500M`, `2GiB`, `1048576`."""
    if isinstance(text, int):
        return text
    m = _SIZE.fullmatch(str(text).strip())
    if not m:
        raise InputError(f"cache size {text!r}: give a number of bytes with an optional unit (K, M, G, T), e.g. 10G.")
    return int(float(m[1]) * 1024 ** ("kmgt".index(m[2].lower()) + 1 if m[2] else 0))


# ------------------------------------------------------------------------------------------------ keys

# What the object step (vdmbake.bake) imports but does not run: the technique registry and the scene reader
# (each technique step has its own key), the bundle's reader and manifest check, the batch machinery.
OBJECT_STEP_STOP = frozenset({"vdmbake.techniques", "vdmbake.scene", "vdmbake.bundle.directory",
                              "vdmbake.bundle.manifest", "vdmbake.library.cache", "vdmbake.library.batch",
                              "vdmbake.library.cluster"})


@functools.lru_cache(maxsize=None)
def step_code(module: str, stop: frozenset = frozenset()) -> str:
    """The code version of a step: sha256 over the names and sources of `module` and every vdmbake module it
    imports (vdmbake.bake for the object step, vdmbake.techniques.NAME for a technique's), with the bundle
    format, the tool version, the Python version and the versions of the libraries that compute parts."""
    from .. import __version__
    from ..bundle.directory import FORMAT_VERSION

    h = hashlib.sha256(code_fingerprint(imported_closure([module], stop)).encode())
    h.update(json.dumps({"format_version": FORMAT_VERSION, "tool_version": __version__,
                         "python": list(sys.version_info[:2]), "libraries": _library_versions()},
                        sort_keys=True).encode())
    return h.hexdigest()


@functools.lru_cache(maxsize=None)
def _library_versions() -> dict:
    versions = {}
    for name in LIBRARIES:
        try:
            versions[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            versions[name] = None
    return versions


def digest(data: dict) -> str:
    return hashlib.sha256(json.dumps(data, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def object_key(obj_dict: dict, inputs: dict) -> str:
    """The key of an object's own parts: its settings (`obj_dict`, the scene's resolved object table), the
    sha256 of the files it reads (`inputs`) and the object step's code. The material is read by the bake only
    as the colour of inline spheres and cylinders; elsewhere it is left out (a recoloured asset is the same
    bake)."""
    unread = {"name", "techniques", "expect_empty"}
    if not (obj_dict.get("spheres") or obj_dict.get("cylinders")):
        unread.add("material")
    settings = {k: v for k, v in obj_dict.items() if k not in unread}
    return digest({"step": "object", "settings": settings, "inputs": inputs,
                   "code": step_code("vdmbake.bake", OBJECT_STEP_STOP)})


def technique_key(object_key_: str, technique: str, options: dict) -> str:
    """The key of a technique's bake step: the object step's key (everything the step's mesh, height field and
    object settings come from), the technique's resolved settings and its module's code."""
    return digest({"step": "technique", "object": object_key_, "technique": technique, "options": options,
                   "code": step_code(f"vdmbake.techniques.{technique}")})


# ----------------------------------------------------------------------------------------------- store

@dataclass
class Entry:
    """A verified entry: the step's manifest entry (part paths relative to the object), its log lines and
    its parts as (name, kind, metadata, bytes)."""
    entry: object
    log: list
    parts: list


@dataclass
class Counters:
    hits: int = 0
    misses: int = 0
    corrupt: int = 0
    stored: int = 0
    evicted: int = 0
    parts_from_cache: int = 0
    bytes_from_cache: int = 0
    events: list = field(default_factory=list)    # (step, "hit" | "baked" | "corrupt"), for timing.json

    def as_dict(self) -> dict:
        return {k: getattr(self, k) for k in ("hits", "misses", "corrupt", "stored", "evicted",
                                             "parts_from_cache", "bytes_from_cache")}


class PartCache:
    """A cache folder (created on first use); `max_bytes` bounds the entries' total size."""

    def __init__(self, root: Path | str, max_bytes: int = DEFAULT_MAX_BYTES):
        self.root = Path(root)
        self.max_bytes = int(max_bytes)
        self.counters = Counters()
        if self.root.exists() and not self.root.is_dir():
            raise InputError(f"{self.root}: the cache folder is a file; give --cache a folder (it is created).")

    @classmethod
    def from_env(cls, path, size) -> "PartCache | None":
        """The cache named by --cache (or VDM_CACHE) and --cache-size (or VDM_CACHE_SIZE); None without one."""
        path = path or os.environ.get(ENV) or None
        if not path:
            return None
        return cls(path, parse_size(size or os.environ.get(ENV_SIZE) or DEFAULT_MAX_BYTES))

    @property
    def entries(self) -> Path:
        return self.root / "entries"

    def path(self, key: str) -> Path:
        if not re.fullmatch(r"[0-9a-f]{64}", key):
            raise ValueError(f"not a cache key: {key!r}")
        return self.entries / key[:2] / key

    # ---- reading

    def get(self, key: str) -> Entry | None:
        """The verified entry of `key`, or None (a miss; a damaged entry is removed and counted as corrupt)."""
        p = self.path(key)
        try:
            with open(p, "rb") as f:
                data = f.read()
        except FileNotFoundError:
            self.counters.misses += 1
            return None
        except OSError:
            self.counters.misses += 1
            return None
        entry = self._parse(key, data)
        if entry is None:
            self.counters.corrupt += 1
            self.counters.misses += 1
            self.discard(key)
            return None
        try:
            os.utime(p)                                  # the LRU clock
        except OSError:
            pass
        self.counters.hits += 1
        return entry

    @staticmethod
    def _parse(key: str, data: bytes) -> Entry | None:
        try:
            first, body = data.split(b"\n", 1)
            magic, checksum = first.split(b" ")
            if magic != MAGIC or hashlib.sha256(body).hexdigest().encode() != checksum:
                return None
            n = int.from_bytes(body[:8], "little")
            header = json.loads(body[8:8 + n])
            if header.get("key") != key:
                return None
            parts, at = [], 8 + n
            for p in header["parts"]:
                blob = body[at:at + p["bytes"]]
                at += p["bytes"]
                if len(blob) != p["bytes"] or hashlib.sha256(blob).hexdigest() != p["sha256"]:
                    return None
                parts.append((p["name"], p["kind"], p["meta"], blob))
            if at != len(body):
                return None
            return Entry(header["entry"], header.get("log", []), parts)
        except (ValueError, KeyError, TypeError, AttributeError):
            return None

    def discard(self, key: str) -> None:
        try:
            self.path(key).unlink()
        except OSError:
            pass

    # ---- writing

    def put(self, key: str, entry, log: list, parts: list) -> None:
        """Store the step's entry and parts [(name, kind, metadata, bytes)] under `key`, atomically; then evict
        beyond the size bound. A failure to store (a full disk, a read-only folder) is not the bake's: it
        raises OSError for the caller to report and go on."""
        header = {"key": key, "entry": entry, "log": log,
                  "parts": [{"name": n, "kind": k, "meta": m, "bytes": len(d), "sha256": hashlib.sha256(d).hexdigest()}
                            for n, k, m, d in parts]}
        head = json.dumps(header, separators=(",", ":")).encode()
        body = b"".join([len(head).to_bytes(8, "little"), head, *(d for *_, d in parts)])
        final = self.path(key)
        final.parent.mkdir(parents=True, exist_ok=True)
        tmp = final.parent / f".{key}.{socket.gethostname()}.{os.getpid()}.{os.urandom(4).hex()}.tmp"
        try:
            with open(tmp, "wb") as f:
                f.write(MAGIC + b" " + hashlib.sha256(body).hexdigest().encode() + b"\n")
                f.write(body)
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, final)
        except BaseException:
            try:
                tmp.unlink()
            except OSError:
                pass
            raise
        self.counters.stored += 1
        self.evict()

    def _scan(self):
        """(mtime, size, path) of every entry, and the stale temporary files (removed)."""
        found, now = [], time.time()
        if not self.entries.is_dir():
            return found
        for sub in os.scandir(self.entries):
            if not sub.is_dir(follow_symlinks=False):
                continue
            for e in os.scandir(sub.path):
                try:
                    st = e.stat(follow_symlinks=False)
                except OSError:
                    continue
                if e.name.endswith(".tmp"):
                    if now - st.st_mtime > STALE_TMP_S:
                        try:
                            os.unlink(e.path)
                        except OSError:
                            pass
                    continue
                found.append((st.st_mtime, st.st_size, e.path))
        return found

    def evict(self) -> int:
        """Remove the least recently used entries until the total is within the bound; returns how many."""
        found = self._scan()
        total = sum(s for _, s, _ in found)
        removed = 0
        for _, size, path in sorted(found):
            if total <= self.max_bytes:
                break
            try:
                os.unlink(path)
                removed += 1
            except FileNotFoundError:
                pass
            except OSError:
                continue
            total -= size
        self.counters.evicted += removed
        return removed

    # ---- statistics and maintenance

    def record(self, **extra) -> None:
        """Append this process's counters since the last record to stats.log (one line, O_APPEND), and reset them."""
        c = self.counters
        if not (c.hits or c.misses or c.stored or c.evicted):
            return
        line = json.dumps({"time": round(time.time(), 3), "host": socket.gethostname(), "pid": os.getpid(),
                           **c.as_dict(), **extra}, separators=(",", ":")) + "\n"
        try:
            self.root.mkdir(parents=True, exist_ok=True)
            fd = os.open(self.root / "stats.log", os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
            try:
                os.write(fd, line.encode())
            finally:
                os.close(fd)
        except OSError:
            pass
        self.counters = Counters()

    def stats(self) -> dict:
        """Size, entry count and bound, and the hit counts summed over stats.log."""
        found = self._scan()
        sums = {k: 0 for k in Counters().as_dict()}
        bakes = 0
        try:
            lines = (self.root / "stats.log").read_text().splitlines()
        except OSError:
            lines = []
        for line in lines:
            try:
                rec = json.loads(line)
            except ValueError:
                continue                         # a line cut by a full disk
            bakes += 1
            for k in sums:
                sums[k] += int(rec.get(k, 0))
        steps = sums["hits"] + sums["misses"]
        return {"cache": str(self.root), "entries": len(found), "bytes": sum(s for _, s, _ in found),
                "max_bytes": self.max_bytes, "bakes": bakes, **sums,
                "hit_rate": round(sums["hits"] / steps, 4) if steps else None}

    def verify(self) -> dict:
        """Read every entry through the checks of get(); remove the damaged ones. Returns the counts."""
        good = bad = 0
        for _, _, path in self._scan():
            key = Path(path).name
            try:
                data = Path(path).read_bytes()
            except OSError:
                continue
            if self._parse(key, data) is None:
                bad += 1
                try:
                    os.unlink(path)
                except OSError:
                    pass
            else:
                good += 1
        return {"entries": good, "removed_damaged": bad}

    def clear(self) -> None:
        """Remove every entry and the statistics."""
        shutil.rmtree(self.entries, ignore_errors=True)
        try:
            (self.root / "stats.log").unlink()
        except OSError:
            pass


# --------------------------------------------------------------------------------------------- steps

PART_PREFIX = "@part:"


def _relative(value, prefix: str, rels: set):
    """The step's manifest entry with each path of a part it wrote as `@part:NAME` (NAME relative to the
    object's folder), so an entry serves an object of any name."""
    if isinstance(value, dict):
        return {k: _relative(v, prefix, rels) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_relative(v, prefix, rels) for v in value]
    if isinstance(value, str) and value in rels:
        return PART_PREFIX + value[len(prefix):]
    return value


def _absolute(value, prefix: str):
    if isinstance(value, dict):
        return {k: _absolute(v, prefix) for k, v in value.items()}
    if isinstance(value, list):
        return [_absolute(v, prefix) for v in value]
    if isinstance(value, str) and value.startswith(PART_PREFIX):
        return prefix + value[len(PART_PREFIX):]
    return value


def run_step(cache: "PartCache | None", writer, key: str | None, prefix: str, name: str, make, log, prepare=None):
    """One bake step through the cache: the step's manifest entry. On a hit its parts go into `writer`
    (each read back through its kind's checks first, as a freshly baked part is) and its log lines are
    said again; on a miss `prepare()` then `make(log)` bake it, and what it wrote (every part under `prefix`)
    is stored under `key`. Without a cache: make(log)."""
    if cache is None or key is None:
        return make(log)
    hit = cache.get(key)
    if hit is not None:
        from ..bundle.parts import KINDS

        try:
            checked = [(prefix + n, KINDS[k], m, d) for n, k, m, d in hit.parts]
            for rel, kind, meta, data in checked:
                writer.check_packed(rel, kind, data, meta)
        except (InputError, KeyError) as e:      # bytes intact but not a part this code reads: bake it
            log(f"{name}: cache entry {key[:12]} unusable ({str(e)[:200]}); baking it again")
            cache.counters.hits -= 1
            cache.counters.corrupt += 1
            cache.counters.misses += 1
            cache.discard(key)
        else:
            for rel, kind, meta, data in checked:
                writer.add_packed(rel, kind, data, meta, checked=True)
            for line in hit.log:
                log(f"{line} (from cache)")
            cache.counters.events.append((name, "hit"))
            cache.counters.parts_from_cache += len(checked)
            cache.counters.bytes_from_cache += sum(len(d) for *_, d in checked)
            return _absolute(hit.entry, prefix)
    if prepare is not None:
        prepare()
    lines = []

    def say(m):
        lines.append(m)
        log(m)

    made = writer.record()
    try:
        entry = make(say)
    finally:
        writer.record(stop=made)
    cache.counters.events.append((name, "baked"))
    try:
        relative = _relative(entry, prefix, {rel for rel, *_ in made})
        if any(not rel.startswith(prefix) for rel, *_ in made) or prefix in json.dumps(relative):
            return entry      # a step that writes outside its object, or names a part it did not write: not cached
        cache.put(key, relative, lines, [(rel[len(prefix):], k, m, d) for rel, k, m, d in made])
    except (OSError, TypeError, ValueError) as e:
        log(f"{name}: warning: not stored in the cache {cache.root} ({e})")
    return entry
