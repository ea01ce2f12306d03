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
corrupt and baked again. An entry is input from whoever can write the cache folder (a shared one: anyone with
write access there), so it is read as any other input: a regular file within a size bound (no FIFO, device or
link), a header of bounded depth, part names that are plain names of the step's own parts (`in_layout`: no
`..`, no path, no other step's part), a manifest block naming exactly the parts it carries; and the bundle made
from it passes the reader's own check before it is committed (BundleWriter.commit; vdmbake.bake bakes again
without the entries it took when it does not). Writes go to a temporary file in the same folder, fsynced, then
os.replace: readers see the old entry, no entry, or the complete new one, never a torn one, and two processes (or
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
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from .. import code_fingerprint, imported_closure
from ..bundle import staging
from ..bundle.budget import BUDGET
from ..errors import InputError, cut
from ..formats.safeio import read_regular

MAGIC = b"VDMCACHE1"
ENV = "VDM_CACHE"
ENV_SIZE = "VDM_CACHE_SIZE"
DEFAULT_MAX_BYTES = 10 << 30
STALE_TMP_S = 3600            # temporary files older than this are a killed writer's: removed by eviction
LIBRARIES = ("numpy", "embreex", "trimesh", "fast-simplification", "OpenEXR", "gemmi", "pillow", "scikit-image")
_SIZE = re.compile(r"(\d+(?:\.\d+)?)\s*([kmgt]?)i?b?", re.I)
MAX_DEPTH = 32                # a step's manifest block nests a few levels; deeper is no entry of ours
_PLAIN = re.compile(r"[A-Za-z0-9][A-Za-z0-9._+-]*")
# The parts of an object step (what vdmbake.bake._object_parts writes); a technique step's start with its name.
OBJECT_PARTS = frozenset({"mesh", "quadrics", "viewer-mesh", "albedo", "mesostructure", "mesostructure-albedo"})


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
                              "vdmbake.cluster"})


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
    taken: list = field(default_factory=list)     # the keys of the hits, to refuse if their bundle is refused

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
            data = self._read(p)
        except FileNotFoundError:
            self.counters.misses += 1
            return None
        entry = None if data is None else self._parse(key, data)
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

    def _read(self, path) -> bytes | None:
        """An entry's bytes, read as any other input: a regular file (a FIFO would block, a link to a device never
        end) no larger than the cache's bound; None if it is not one. FileNotFoundError passes through."""
        try:
            return read_regular(path, "cache entry", limit=min(self.max_bytes, BUDGET), follow=False)
        except InputError:
            return None
        except OSError as e:
            if isinstance(e, FileNotFoundError):
                raise
            return None

    @staticmethod
    def _parse(key: str, data: bytes) -> Entry | None:
        try:
            first, body = data.split(b"\n", 1)
            magic, checksum = first.split(b" ")
            if magic != MAGIC or hashlib.sha256(body).hexdigest().encode() != checksum:
                return None
            n = int.from_bytes(body[:8], "little")
            header = json.loads(body[8:8 + n])
            if header.get("key") != key or not isinstance(header["entry"], dict):
                return None
            parts, at = [], 8 + n
            for p in header["parts"]:
                if (type(p["bytes"]) is not int or not isinstance(p["meta"], dict) or not isinstance(p["kind"], str)
                        or not isinstance(p["name"], str) or not _PLAIN.fullmatch(p["name"])):
                    return None
                blob = body[at:at + p["bytes"]]
                at += p["bytes"]
                if len(blob) != p["bytes"] or hashlib.sha256(blob).hexdigest() != p["sha256"]:
                    return None
                parts.append((p["name"], p["kind"], p["meta"], blob))
            log = header.get("log", [])
            if (at != len(body) or not _carries(header["entry"], [name for name, *_ in parts])
                    or not isinstance(log, list) or not all(isinstance(line, str) for line in log)):
                return None
            return Entry(header["entry"], log, parts)
        except (ValueError, KeyError, TypeError, AttributeError, RecursionError):   # RecursionError: nested too deep
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
        tmp = final.parent / f".{key}.{staging.host()}.{os.getpid()}.{os.urandom(4).hex()}.tmp"
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
        line = json.dumps({"time": round(time.time(), 3), "host": staging.host(), "pid": os.getpid(),
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
        """Size, entry count and bound, and the hit counts summed over stats.log; `skipped_lines`: the lines it
        could not read as counts (a torn write's bytes, a line that is JSON but not counts), left out of the sums."""
        found = self._scan()
        sums = {k: 0 for k in Counters().as_dict()}
        bakes = skipped = 0
        for line in self._stats_lines():
            rec = _counts(line)
            if rec is None:
                skipped += 1
                continue
            bakes += 1
            for k in sums:
                sums[k] += rec.get(k, 0)
        steps = sums["hits"] + sums["misses"]
        return {"cache": str(self.root), "entries": len(found), "bytes": sum(s for _, s, _ in found),
                "max_bytes": self.max_bytes, "bakes": bakes, **sums,
                "hit_rate": round(sums["hits"] / steps, 4) if steps else None, "skipped_lines": skipped}

    def _stats_lines(self) -> list[bytes]:
        """The non-empty lines of stats.log, read as any other input (a regular file within the size bound)."""
        try:
            data = read_regular(self.root / "stats.log", "cache statistics", limit=min(self.max_bytes, BUDGET))
        except FileNotFoundError:
            return []
        return [line for line in data.split(b"\n") if line.strip()]

    def verify(self) -> dict:
        """Read every entry through the checks of get(); remove the damaged ones. Returns the counts, with
        `not_removed`: damaged entries that could not be removed (a read-only cache)."""
        good = bad = left = 0
        for _, _, path in self._scan():
            key = Path(path).name
            try:
                data = self._read(path)
            except FileNotFoundError:
                continue
            if data is None or self._parse(key, data) is None:
                try:
                    os.unlink(path)
                    bad += 1
                except FileNotFoundError:
                    bad += 1
                except OSError:
                    left += 1
            else:
                good += 1
        return {"entries": good, "removed_damaged": bad, "not_removed": left}

    def clear(self) -> dict:
        """Remove every entry and the statistics. Returns how many entries were removed and what is left (a
        read-only cache: `left` entries, `stats_left`), with the first reason."""
        before, errors = len(self._scan()), []
        shutil.rmtree(self.entries, onerror=lambda fn, path, exc: errors.append(f"{path}: {exc[1]}"))
        try:
            (self.root / "stats.log").unlink()
        except FileNotFoundError:
            pass
        except OSError as e:
            errors.append(f"{e.filename}: {e}")
        left = len(self._scan())
        return {"removed": before - left, "left": left, "stats_left": (self.root / "stats.log").exists(),
                "reason": errors[0] if errors else None}


def _counts(line: bytes) -> dict | None:
    """One stats.log line's counts, or None if it is not one: UTF-8 JSON, an object whose counters are
    non-negative integers."""
    try:
        rec = json.loads(line.decode("utf-8"))
    except (ValueError, RecursionError):            # UnicodeDecodeError is a ValueError
        return None
    if not isinstance(rec, dict):
        return None
    counts = {k: rec.get(k, 0) for k in Counters().as_dict()}
    if not all(type(v) is int and 0 <= v < 2**63 for v in counts.values()):
        return None
    return counts


# --------------------------------------------------------------------------------------------- steps

PART_PREFIX = "@part:"


def in_layout(name, kind: str, technique: str | None) -> bool:
    """Whether an entry may carry a part `name` of `kind`: a plain file name (no separator, no `..`, nothing
    hidden) with the kind's suffix, one of the step's own parts: the object step's OBJECT_PARTS, a technique
    step's its name or its name and a dash (coarse-0.5.ply). So an entry writes only inside its object's folder
    and never replaces another step's part."""
    from ..bundle.parts import KINDS

    if not isinstance(name, str) or not _PLAIN.fullmatch(name) or kind not in KINDS:
        return False
    suffix = KINDS[kind].suffix
    stem = name[:-len(suffix)] if suffix and name.endswith(suffix) else None
    if technique is None:
        return stem in OBJECT_PARTS
    return stem is not None and (stem == technique or stem.startswith(technique + "-"))


def _carries(entry, names: list) -> bool:
    """Whether a step's manifest block names (as `@part:NAME`) exactly the parts the entry carries, each once,
    and nests no deeper than MAX_DEPTH."""
    return len(set(names)) == len(names) and _named(entry, 0) == set(names)


def _named(value, depth: int) -> set:
    if depth > MAX_DEPTH:
        raise ValueError("nested too deep")
    if isinstance(value, dict):
        return set().union(*(_named(v, depth + 1) for v in value.values()))
    if isinstance(value, list):
        return set().union(*(_named(v, depth + 1) for v in value))
    if isinstance(value, str) and value.startswith(PART_PREFIX):
        return {value[len(PART_PREFIX):]}
    return set()


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


def run_step(cache: "PartCache | None", writer, key: str | None, prefix: str, name: str, make, log, prepare=None,
             technique: str | None = None):
    """One bake step through the cache: the step's manifest entry. On a hit its parts go into `writer`
    (each read back through its kind's checks first, as a freshly baked part is) and its log lines are
    said again; on a miss `prepare()` then `make(log)` bake it, and what it wrote (every part under `prefix`)
    is stored under `key`. `technique`: the technique whose step it is (None: the object's own parts), which
    part names the entry may carry (in_layout). Without a cache: make(log)."""
    if cache is None or key is None:
        return make(log)
    hit = cache.get(key)
    if hit is not None:
        from ..bundle.parts import KINDS

        try:
            for n, k, _, _ in hit.parts:
                if not in_layout(n, k, technique):
                    raise InputError(f"part name {n!r} is not one of the step's own ({technique or 'object'})")
            checked = [(prefix + n, KINDS[k], m, d) for n, k, m, d in hit.parts]
            for rel, kind, meta, data in checked:
                writer.check_packed(rel, kind, data, meta)
        except Exception as e:      # bytes intact but not a part this code reads (whatever its reader raises): bake it
            log(f"{name}: cache entry {key[:12]} unusable ({cut(str(e))}); baking it again")
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
            cache.counters.taken.append(key)
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
        own = [(rel[len(prefix):], k, m, d) for rel, k, m, d in made if rel.startswith(prefix)]
        if (len(own) < len(made) or prefix in json.dumps(relative) or not _carries(relative, [n for n, *_ in own])
                or not all(in_layout(n, k, technique) for n, k, *_ in own)):
            return entry      # not an entry a read would accept (a part outside its object, a path not its own)
        cache.put(key, relative, lines, own)
    except (OSError, TypeError, ValueError) as e:
        log(f"{name}: warning: not stored in the cache {cache.root} ({e})")
    return entry


def refuse_taken(cache: PartCache) -> int:
    """The entries a bake took, removed after the bundle made with them failed the reader's check (an entry
    that passes its own checks but not the bundle's: crafted, or from a foreign version of the code); the
    counters start again, those entries counted as corrupt. Returns how many."""
    taken = cache.counters.taken
    for key in taken:
        cache.discard(key)
    cache.counters = Counters(corrupt=cache.counters.corrupt + len(taken))
    return len(taken)
