"""The part cache as a trust boundary (issue 32): an entry is input from whoever can write the cache folder.
Crafted entries with valid checksums (part names with `..`, absolute paths, another step's part, a manifest
block the bundle's reader refuses) and entries that are not regular files are misses, counted, and baked
again; nothing is written outside the bundle and the bundle is the one a bake without the cache makes."""
import json
import os
import threading
from pathlib import Path

import pytest

from vdmbake.library.cache import PartCache

from helpers import bake, cache_scene, entries, files


def _entry_of(cache: Path, wanted) -> tuple[str, object]:
    """(key, entry) of the first entry in `cache` for which wanted(entry) holds."""
    c = PartCache(cache)
    for p in entries(cache):
        got = c._parse(p.name, p.read_bytes())
        if got is not None and wanted(got):
            return p.name, got
    raise AssertionError("no such entry")


def _rename(entry, old: str, new: str):
    """The entry's manifest block with `@part:old` read as `@part:new`."""
    return json.loads(json.dumps(entry).replace(json.dumps("@part:" + old), json.dumps("@part:" + new)))


def _baked_with_crafted(tmp_path, craft) -> tuple[dict, dict]:
    """A scene baked into the cache; craft(cache, key, entry) rewrites one entry with valid checksums; then the
    scene baked again through the cache: (its --json stats, its timing.json's cache record)."""
    s, cache = cache_scene(tmp_path), tmp_path / "cache"
    assert bake(s, "-o", tmp_path / "plain.bundle").exit_code == 0
    assert bake(s, "-o", tmp_path / "a.bundle", "--cache", cache).exit_code == 0
    craft(PartCache(cache))
    r = bake(s, "-o", tmp_path / "b.bundle", "--cache", cache, "--json")
    assert r.exit_code == 0, r.output
    assert files(tmp_path / "b.bundle") == files(tmp_path / "plain.bundle")
    return json.loads(r.stdout), json.loads((tmp_path / "b.bundle" / "timing.json").read_text())["cache"]


def _coarse(c: PartCache):
    return _entry_of(c.root, lambda e: any(n.startswith("coarse-") for n, *_ in e.parts))


@pytest.mark.parametrize("where", ["dotdot", "absolute"])
def test_crafted_part_name_is_refused_and_nothing_written_outside(tmp_path, where):
    """Failed before the fix: the part was written where its name pointed (outside the bundle and the cache),
    exit 0. Now the entry is a miss, counted as corrupt, and the step is baked again."""
    target = tmp_path / "outside" / "evil.ply"
    target.parent.mkdir()

    def craft(c):
        key, e = _coarse(c)
        old = next(n for n, *_ in e.parts if n.startswith("coarse-"))
        new = "../../../../outside/evil.ply" if where == "dotdot" else str(target)
        c.put(key, _rename(e.entry, old, new), e.log,
              [(new if n == old else n, k, m, d) for n, k, m, d in e.parts])
    stats, record = _baked_with_crafted(tmp_path, craft)
    assert not target.exists() and not list(target.parent.iterdir())
    assert not list(tmp_path.rglob("evil.ply"))
    assert stats["steps_baked"] == 1 and record["corrupt_entries"] == 1, (stats, record)


def test_entry_carrying_another_steps_part_is_refused(tmp_path):
    """A technique step's entry that carries the object's mesh (mesh.ply) would replace it in the bundle."""
    def craft(c):
        key, e = _coarse(c)
        old = next(n for n, *_ in e.parts if n.startswith("coarse-"))
        c.put(key, _rename(e.entry, old, "mesh.ply"), e.log,
              [("mesh.ply" if n == old else n, k, m, d) for n, k, m, d in e.parts])
    stats, record = _baked_with_crafted(tmp_path, craft)
    assert stats["steps_baked"] == 1 and record["corrupt_entries"] == 1


def test_manifest_block_not_matching_its_parts_is_refused(tmp_path):
    """A block naming a part the entry does not carry (or leaving one out) is no entry of this cache."""
    def craft(c):
        key, e = _coarse(c)
        c.put(key, json.loads(json.dumps(e.entry).replace("@part:coarse-", "@part:other-")), e.log, e.parts)
    stats, record = _baked_with_crafted(tmp_path, craft)
    assert stats["steps_baked"] == 1 and record["corrupt_entries"] == 1


def test_entry_the_bundle_reader_refuses_is_removed_and_baked_again(tmp_path):
    """Failed before the fix: an object entry whose block the manifest check refuses (a negative radius) was
    committed, exit 0, as a bundle vdmrender refuses. Now the bundle is checked before commit, the entries it
    took are removed and counted as corrupt, and the scene is baked without them."""
    def craft(c):
        key, e = _entry_of(c.root, lambda e: "radius" in e.entry and "quadrics" in e.entry)
        c.put(key, {**e.entry, "radius": -1.0}, e.log, e.parts)
    stats, record = _baked_with_crafted(tmp_path, craft)
    assert record["corrupt_entries"] >= 1 and stats["steps_baked"] >= 1, (stats, record)


def _get_within(c: PartCache, key: str, seconds: float = 20.0):
    """c.get(key) in a thread: (finished, result); a get that blocks (a FIFO opened for reading) never finishes."""
    out = []
    t = threading.Thread(target=lambda: out.append(c.get(key)), daemon=True)
    t.start()
    t.join(seconds)
    return bool(out), (out[0] if out else None)


def test_fifo_entry_is_a_miss_not_a_hang(tmp_path):
    """Failed before the fix: get() (and --cache-verify) blocked for ever opening the FIFO."""
    c, key = PartCache(tmp_path / "c"), "ab" * 32
    c.path(key).parent.mkdir(parents=True)
    os.mkfifo(c.path(key))
    done, got = _get_within(c, key)
    assert done and got is None and c.counters.corrupt == 1 and not c.path(key).exists()


def test_link_to_a_device_is_a_miss(tmp_path):
    """Before the fix /dev/zero was read until memory ran out; a link is no entry this cache writes."""
    c, key = PartCache(tmp_path / "c"), "ab" * 32
    c.path(key).parent.mkdir(parents=True)
    c.path(key).symlink_to("/dev/zero")
    done, got = _get_within(c, key)
    assert done and got is None and c.counters.corrupt == 1 and not c.path(key).is_symlink()


def test_oversized_entry_is_a_miss(tmp_path):
    key = "ab" * 32
    PartCache(tmp_path / "c").put(key, {"mesh": "@part:p.ply"}, [], [("p.ply", "mesh", {}, bytes(2000))])
    c = PartCache(tmp_path / "c", max_bytes=1000)           # what a read accepts: no more than the bound
    assert c.get(key) is None and c.counters.corrupt == 1


def test_deeply_nested_header_is_a_miss(tmp_path):
    """Failed before the fix: RecursionError out of json.loads. Also a block nested past MAX_DEPTH."""
    import hashlib

    c = PartCache(tmp_path / "c")
    for depth in (100000, 100):
        key = f"{depth % 256:02x}" * 32
        head = ("[" * depth + "]" * depth).encode()
        body = len(head).to_bytes(8, "little") + head
        c.path(key).parent.mkdir(parents=True, exist_ok=True)
        c.path(key).write_bytes(b"VDMCACHE1 " + hashlib.sha256(body).hexdigest().encode() + b"\n" + body)
        assert c.get(key) is None
    key = "cc" * 32
    deep = "@part:p.ply"
    for _ in range(100):
        deep = [deep]
    c.put(key, {"mesh": deep}, [], [("p.ply", "mesh", {}, b"x")])
    assert c.get(key) is None and c.counters.corrupt == 3


# ------------------------------------------------------------------ maintenance that tells the truth

def test_stats_skip_lines_that_are_not_counts_and_say_so(tmp_path):
    """Failed before the fix: a line that is JSON but not a count (a list, a string count) raised a traceback,
    a torn write's non-UTF-8 bytes UnicodeDecodeError."""
    cache = tmp_path / "cache"
    cache.mkdir()
    good = json.dumps({"hits": 2, "misses": 1, "stored": 1})
    (cache / "stats.log").write_bytes("\n".join([good, "[1, 2]", '{"hits": "3"}', '{"hits": -1}', '"x"',
                                                 '{"hits": 1e400}', good]).encode() + b"\n\xff\xfe{\"hits\n")
    r = bake("--cache", cache, "--cache-stats")
    assert r.exit_code == 0, r.output
    assert "2 bakes: steps 4 from cache, 2 baked" in r.output and "6 unreadable lines of stats.log skipped" in r.output
    st = json.loads(bake("--cache", cache, "--cache-stats", "--json").stdout)
    assert st["skipped_lines"] == 6 and st["hits"] == 4


def _read_only(monkeypatch):
    """os.unlink and os.rmdir fail as on a read-only file system (the tests may run as root, whom permissions
    do not stop)."""
    import errno

    def refuse(path, *args, **kwargs):
        raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(path))
    monkeypatch.setattr(os, "unlink", refuse)
    monkeypatch.setattr(os, "rmdir", refuse)


def test_clear_on_a_read_only_cache_says_so(tmp_path, monkeypatch):
    """Failed before the fix: "cleared the part cache", exit 0, every entry still there."""
    c = PartCache(tmp_path / "cache")
    c.put("ab" * 32, {"m": "@part:p.ply"}, [], [("p.ply", "mesh", {}, b"x")])
    c.record()
    _read_only(monkeypatch)
    r = bake("--cache", c.root, "--cache-clear")
    monkeypatch.undo()
    assert r.exit_code == 2 and "could not clear" in r.output and "1 left" in r.output, r.output
    assert entries(c.root)
    r = bake("--cache", c.root, "--cache-clear")
    assert r.exit_code == 0 and "1 entries removed" in r.output and not entries(c.root)


def test_verify_on_a_read_only_cache_says_what_it_could_not_remove(tmp_path, monkeypatch):
    """Failed before the fix: the damaged entry counted as removed, exit 0."""
    c = PartCache(tmp_path / "cache")
    c.put("ab" * 32, {"m": "@part:p.ply"}, [], [("p.ply", "mesh", {}, b"x")])
    c.path("ab" * 32).write_bytes(c.path("ab" * 32).read_bytes()[:-1])
    _read_only(monkeypatch)
    r = bake("--cache", c.root, "--cache-verify")
    monkeypatch.undo()
    assert r.exit_code == 2 and "1 damaged entries could not be removed" in r.output, r.output
    assert PartCache(c.root).verify() == {"entries": 0, "removed_damaged": 1, "not_removed": 0}


def test_log_that_is_not_lines_is_a_miss(tmp_path):
    """Found by test_fuzz_cache_entries: a header whose log is null (valid checksums) raised TypeError in the bake
    that took it (exit 1); the log must be a list of strings."""
    c, key = PartCache(tmp_path / "c"), "ab" * 32
    c.put(key, {"m": "@part:p.ply"}, None, [("p.ply", "mesh", {}, b"x")])
    assert c.get(key) is None and c.counters.corrupt == 1
