"""The part cache (vdmbake/cache.py, issue 24): keys, the store's checks and atomic writes, LRU eviction,
statistics, and the bundle's bytes with and without it. The fault tests: a damaged entry is detected
and baked again; two processes storing the same key at once leave one complete entry."""
import json
import os
import subprocess
import sys
from pathlib import Path

from vdmbake.bundle.directory import Bundle
from vdmbake.library.cache import PartCache, parse_size

from helpers import bake, cache_scene, entries, files

ROOT = Path(__file__).resolve().parents[1]


def test_parse_size():
    assert parse_size("10G") == 10 << 30 and parse_size("500M") == 500 << 20 and parse_size("2GiB") == 2 << 30
    assert parse_size("1234") == 1234 and parse_size("1.5k") == 1536


def test_bundle_through_the_cache_is_byte_identical(tmp_path):
    """Determinism: a bundle baked without a cache, through a cold one and through a warm one: the same bytes in
    every file but timing.json (which records wall times and which steps came from the cache)."""
    s, cache = cache_scene(tmp_path), tmp_path / "cache"
    assert bake(s, "-o", tmp_path / "plain.bundle").exit_code == 0
    cold = bake(s, "-o", tmp_path / "cold.bundle", "--cache", cache, "--json")
    warm = bake(s, "-o", tmp_path / "warm.bundle", "--cache", cache, "--json")
    assert cold.exit_code == 0 and warm.exit_code == 0, cold.output + warm.output
    assert json.loads(cold.stdout)["parts_from_cache"] == 0
    w = json.loads(warm.stdout)
    assert w["parts_from_cache"] == w["parts"] and w["steps_baked"] == 0, w
    plain = files(tmp_path / "plain.bundle")
    assert files(tmp_path / "cold.bundle") == plain and files(tmp_path / "warm.bundle") == plain
    timing = json.loads((tmp_path / "warm.bundle" / "timing.json").read_text())
    assert set(timing["cache"]["steps"].values()) == {"hit"} and timing["cache"]["parts_from_cache"] == w["parts"]
    Bundle(tmp_path / "warm.bundle")                  # the renderer's checks pass


def test_a_step_is_shared_across_scenes_and_names(tmp_path):
    """Another scene with the same asset and settings, under another object name and material (which the bake
    does not read for a surface), takes every step from the cache; another coarse ratio bakes only that step,
    after the object's parts come from the cache, and the bundle is the one a bake without a cache makes."""
    cache = tmp_path / "cache"
    assert bake(cache_scene(tmp_path, "a"), "-o", tmp_path / "a.bundle", "--cache", cache).exit_code == 0
    n = len(entries(cache))
    r = bake(cache_scene(tmp_path, "b", name="ring", grey=0.9), "-o", tmp_path / "b.bundle", "--cache", cache, "--json")
    assert json.loads(r.stdout)["steps_baked"] == 0 and len(entries(cache)) == n
    c = cache_scene(tmp_path, "c", ratio=0.25)
    r = bake(c, "-o", tmp_path / "c.bundle", "--cache", cache, "--json")
    stats = json.loads(r.stdout)
    assert stats["steps_baked"] == 1 and len(entries(cache)) == n + 1, stats
    assert bake(c, "-o", tmp_path / "c-plain.bundle").exit_code == 0
    assert files(tmp_path / "c.bundle") == files(tmp_path / "c-plain.bundle")


def test_corrupted_entry_is_detected_and_baked_again(tmp_path):
    """Fault test: one byte of a cache entry flipped on disk; the next bake finds the checksum wrong, removes
    the entry, bakes the step again (stores a good entry) and the bundle is intact."""
    s, cache = cache_scene(tmp_path), tmp_path / "cache"
    assert bake(s, "-o", tmp_path / "plain.bundle").exit_code == 0
    assert bake(s, "-o", tmp_path / "a.bundle", "--cache", cache).exit_code == 0
    victim = max(entries(cache), key=lambda p: p.stat().st_size)      # the largest: a part's bytes
    data = bytearray(victim.read_bytes())
    data[len(data) // 2] ^= 0x40
    victim.write_bytes(bytes(data))
    r = bake(s, "-o", tmp_path / "b.bundle", "--cache", cache, "--json")
    assert r.exit_code == 0, r.output
    stats = json.loads(r.stdout)
    assert stats["steps_baked"] == 1 and stats["steps_from_cache"] >= 1, stats
    timing = json.loads((tmp_path / "b.bundle" / "timing.json").read_text())
    assert timing["cache"]["corrupt_entries"] == 1
    assert files(tmp_path / "b.bundle") == files(tmp_path / "plain.bundle")
    assert PartCache(cache).verify() == {"entries": len(entries(cache)), "removed_damaged": 0,
                                         "not_removed": 0}
    st = PartCache(cache).stats()
    assert st["corrupt"] == 1 and st["hits"] >= 1


def test_truncated_and_foreign_entries_are_misses(tmp_path):
    c = PartCache(tmp_path / "c")
    key, other = "ab" * 32, "cd" * 32
    c.put(key, {"x": "@part:a.ply"}, ["line"], [("a.ply", "mesh", {"faces": 1}, b"hello")])
    got = c.get(key)
    assert got.entry == {"x": "@part:a.ply"} and got.parts == [("a.ply", "mesh", {"faces": 1}, b"hello")]
    c.path(other).parent.mkdir(parents=True, exist_ok=True)
    c.path(other).write_bytes(c.path(key).read_bytes())              # an entry under another key's name
    assert c.get(other) is None and not c.path(other).exists()
    c.path(key).write_bytes(c.path(key).read_bytes()[:-2])           # torn
    assert c.get(key) is None and not c.path(key).exists()
    assert c.counters.corrupt == 2 and c.counters.hits == 1


def test_lru_eviction_keeps_the_recently_used(tmp_path):
    c = PartCache(tmp_path / "c")
    keys = [f"{i:02x}" * 32 for i in range(4)]
    for i, k in enumerate(keys[:3]):
        c.put(k, {"m": "@part:p"}, [], [("p", "mesh", {}, bytes(800))])
        os.utime(c.path(k), (1000 + i, 1000 + i))                     # k0 oldest
    size = c.path(keys[0]).stat().st_size                             # the four entries are alike
    c.max_bytes = 3 * size + size // 2                                # room for three entries, not four
    assert c.get(keys[0]) is not None                                 # a hit: now the most recent
    c.put(keys[3], {"m": "@part:p"}, [], [("p", "mesh", {}, bytes(800))])          # over the bound: the oldest (k1) goes
    assert c.path(keys[0]).exists() and not c.path(keys[1]).exists() and c.path(keys[3]).exists()
    assert c.counters.evicted == 1 and c.stats()["bytes"] == 3 * size


WRITER = """
import sys
from vdmbake.library.cache import PartCache
c = PartCache(sys.argv[1])
blob = bytes(range(256)) * 4000            # 1 MB: a write takes long enough to overlap
for i in range(int(sys.argv[2])):
    c.put("ee" * 32, {"n": "@part:p.exr"}, [], [("p.exr", "vdm", {}, blob)])
    got = c.get("ee" * 32)
    assert got is not None and got.parts[0][3] == blob, "torn or lost"
assert c.counters.corrupt == 0
"""


def test_two_processes_storing_one_key_leave_one_entry(tmp_path):
    """Fault test: processes writing and reading the same key at once; every read is whole, one entry remains,
    no temporary file is left."""
    cache = tmp_path / "c"
    ps = [subprocess.Popen([sys.executable, "-c", WRITER, str(cache), "30"], cwd=ROOT, stderr=subprocess.PIPE)
          for _ in range(3)]
    for p in ps:
        assert p.wait(120) == 0, p.stderr.read().decode()
    assert [p.name for p in (cache / "entries").rglob("*") if p.is_file()] == ["ee" * 32]
    assert PartCache(cache).verify() == {"entries": 1, "removed_damaged": 0, "not_removed": 0}


def test_two_bakes_of_the_same_steps_at_once(tmp_path):
    """Fault test: two vdmbake processes baking scenes with the same steps into one cache at the same time: one
    entry per key, both bundles correct (the same bytes as a bake without the cache)."""
    a, b = cache_scene(tmp_path, "a"), cache_scene(tmp_path, "b", name="ring")
    cache = tmp_path / "cache"
    exe = str(Path(sys.executable).parent / "vdmbake")
    env = {k: v for k, v in os.environ.items() if k != "VDM_CACHE"}
    ps = [subprocess.Popen([exe, str(s), "-o", str(tmp_path / f"{s.stem}.bundle"), "--cache", str(cache)],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env) for s in (a, b)]
    for p in ps:
        out, err = p.communicate(timeout=300)
        assert p.returncode == 0, err.decode()
    assert bake(a, "-o", tmp_path / "plain.bundle").exit_code == 0
    plain = files(tmp_path / "plain.bundle")
    assert files(tmp_path / "a.bundle") == plain
    names = {k: v for k, v in files(tmp_path / "b.bundle").items() if k != "manifest.json"}
    assert names == {k.replace("objects/torus/", "objects/ring/"): v for k, v in plain.items() if k != "manifest.json"}
    keys = [p.name for p in entries(cache)]
    assert len(keys) == len(set(keys)) == 6          # torus, its 4 technique steps with parts, mol
    assert not [p for p in (cache / "entries").rglob("*.tmp")]
    assert PartCache(cache).verify()["removed_damaged"] == 0


def test_cache_flags_and_environment(tmp_path):
    s, cache = cache_scene(tmp_path), tmp_path / "cache"
    assert bake(s, "-o", tmp_path / "a.bundle", env={"VDM_CACHE": str(cache)}).exit_code == 0
    assert entries(cache)
    r = bake("--cache-stats", "--json", env={"VDM_CACHE": str(cache)})
    st = json.loads(r.stdout)
    assert r.exit_code == 0 and st["entries"] == len(entries(cache)) and st["misses"] >= 1 and st["hit_rate"] == 0
    r = bake(s, "-o", tmp_path / "b.bundle", "--force", "--no-cache", "--json", env={"VDM_CACHE": str(cache)})
    assert "parts_from_cache" not in json.loads(r.stdout)
    r = bake("--cache", cache, "--cache-clear", "--cache-stats")
    assert r.exit_code == 0 and "0 entries" in r.output and not entries(cache)
    assert bake("--cache-stats").exit_code == 2                       # no cache named
    assert bake(s, "-o", tmp_path / "c.bundle", "--cache", cache, "--cache-size", "lots").exit_code == 2


def test_step_code_follows_the_step_modules():
    """A technique step's code version covers its module and what it imports, not the other techniques; the
    object step's leaves out the technique registry."""
    from vdmbake import imported_closure
    from vdmbake.library.cache import OBJECT_STEP_STOP

    coarse = imported_closure(["vdmbake.techniques.coarse"])
    assert "vdmbake.kernels.coarse" in coarse and "vdmbake.techniques.vdm" not in coarse
    obj = imported_closure(["vdmbake.bake"], OBJECT_STEP_STOP)
    assert {"vdmbake.bake", "vdmbake.assets.primitives", "vdmbake.kernels.curvature"} <= set(obj)
    assert not [m for m in obj if m.startswith("vdmbake.techniques")]


def test_the_cache_is_an_argument_from_the_bake_to_each_step(tmp_path, monkeypatch):
    """The part cache reaches every step as an argument (issue 34): the cache given to bake() is the one each
    run_step call gets, no cache gives None, and no module of vdmbake hands state on through a ContextVar."""
    import vdmbake
    from vdmbake import bake as bake_module
    from vdmbake.library import cache as cache_module

    seen, run_step = [], cache_module.run_step

    def spy(cache, *args, **kwargs):
        seen.append(cache)
        return run_step(cache, *args, **kwargs)
    monkeypatch.setattr(cache_module, "run_step", spy)
    s = tmp_path / "s.toml"
    s.write_text('[[objects]]\nname = "a"\nprimitive = "sphere"\ntechniques = { mesh = {}, coarse = { ratios = [0.5] } }\n')
    cache = PartCache(tmp_path / "cache")
    bake_module.bake(s, tmp_path / "a.bundle", cache=cache)
    assert len(seen) == 2 and all(c is cache for c in seen)           # the object step, the coarse step
    seen.clear()
    bake_module.bake(s, tmp_path / "b.bundle")
    assert len(seen) == 2 and all(c is None for c in seen)
    assert not [p.name for p in Path(vdmbake.__file__).parent.rglob("*.py") if "ContextVar" in p.read_text()]
