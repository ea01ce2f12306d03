"""vdmbake: bake a scene's objects into a bundle."""
from __future__ import annotations

import json
import time
from pathlib import Path

import click

from . import __version__
from .library import batch
from .bake import bake
from .errors import escaped, guarded
from .scene import REGISTRY


def _techniques() -> str:
    """The --help epilog: every technique, the objects it draws and what it draws (from the registry)."""
    lines = ["\b", "Techniques ([objects.techniques] of each object; docs/scenes.md lists their settings):"]
    for t in REGISTRY.values():
        lines.append(f"  {t.name:12} ({'/'.join(t.kinds)}{', mesostructure' if t.mesostructure else ''}) "
                     f"{t.summary.split(':')[0]}")
    return "\n".join(lines)


@click.command(context_settings={"help_option_names": ["-h", "--help"]}, epilog=_techniques())
@click.argument("scenes", nargs=-1, metavar="SCENE_OR_FOLDER...", type=click.Path())   # as typed: a trailing slash names a folder
@click.option("-o", "--output", "out", type=click.Path(path_type=Path),
              help="One scene: the bundle directory to write, e.g. out/default.bundle. Several scenes (or a folder, "
                   "or a glob): the folder that gets OUT/<scene file stem>.bundle for each.")
@click.option("--force", is_flag=True, help="Bake even if the bundle is up to date.")
@click.option("-j", "--jobs", type=click.IntRange(1, 1024), default=None,
              help="Scenes baked at once on this machine, each in its own worker process (default: the cores "
                   "this process may use).")
@click.option("--scheduler", metavar="ADDRESS",
              help="Send each scene's bake to a Dask cluster: tcp://HOST:8786 (a running `dask scheduler`), or "
                   "local:N for N worker processes here. Needs the `cluster` extra (docs/cluster.md).")
@click.option("--workers-wait", type=click.FloatRange(0, 86400), default=60.0, show_default=True, metavar="SECONDS",
              help="With --scheduler: how long the scheduler may have no worker (before the first scene or later) "
                   "before the run stops (exit 2, naming the scheduler and what finished).")
@click.option("--cache", "cache_dir", type=click.Path(path_type=Path), envvar="VDM_CACHE", show_envvar=True,
              help="Part cache folder, shared by scenes, processes and machines (a shared file system): each bake "
                   "step's parts are stored under the hash of its inputs, settings and code, and taken from there "
                   "instead of baked. Bundles are the same bytes with or without it.")
@click.option("--cache-size", metavar="SIZE", envvar="VDM_CACHE_SIZE", show_envvar=True,
              help="Bound of the cache's size, least recently used entries removed beyond it (e.g. 500M, 10G; "
                   "default 10G).")
@click.option("--no-cache", is_flag=True, help="Use no part cache, even if VDM_CACHE names one.")
@click.option("--cache-stats", is_flag=True, help="Print the cache's size, entries and hit rate (after the bakes, "
                                                  "if scenes are given).")
@click.option("--cache-clear", is_flag=True, help="Empty the cache (before the bakes, if scenes are given).")
@click.option("--cache-verify", is_flag=True, help="Read every cache entry through its checksum; remove damaged ones.")
@click.option("-v", "--verbose", is_flag=True, help="Several scenes: print each scene's bake log as it finishes.")
@click.option("--json", "as_json", is_flag=True, help="Print the bake statistics as JSON on stdout.")
@click.option("--debug", is_flag=True, help="Show tracebacks instead of one-paragraph errors.")
@click.version_option(__version__)
def main(scenes: tuple[str, ...], out: Path | None, force: bool, jobs: int | None, scheduler: str | None,
         workers_wait: float, cache_dir: Path | None, cache_size: str | None, no_cache: bool, cache_stats: bool, cache_clear: bool,
         cache_verify: bool, verbose: bool, as_json: bool, debug: bool):
    """Bake what each scene's objects need into a bundle.

    A SCENE is a TOML file (see configs/*.toml and the scene reference, docs/scenes.md): objects (a mesh
    file, a built-in primitive, a molecule, or inline spheres and cylinders), cameras, light,
    material, and per object the techniques to compare. Only the parts those techniques need
    are baked: what the reference traces (the full mesh, the quadric list, the height field),
    then each technique's own parts: simplified meshes for `coarse`, VDM tables for `vdm`,
    displaced meshes for `displaced`, billboard maps for `billboards`.

    One scene: OUTPUT is its bundle. Several scenes, a folder (its *.toml) or a quoted glob:
    each scene is baked into OUTPUT/<scene file stem>.bundle, --jobs at a time in worker
    processes (or on a Dask cluster with --scheduler); a failing scene never stops the others,
    and a table closes the run (scene, status, parts baked and taken from the cache, seconds,
    the reason of a failure).

    Each bundle is written atomically (a temporary sibling, renamed into place, the manifest
    last). Re-baking with unchanged inputs and settings does nothing unless --force. With a
    part cache (--cache DIR or VDM_CACHE), a step whose inputs, settings and code were baked
    before, by any scene, process or machine sharing DIR, is read from it (checked by sha256)
    instead of baked. Exit codes: 0 every scene done, 1 some scenes failed (each named), 2 bad
    usage or bad input (also under --debug, which adds the traceback), or a --scheduler run
    stopped by its cluster (the scheduler lost, or no worker for --workers-wait; the closing
    table says what finished), 128 + N stopped by signal N (130 Ctrl-C, 143 SIGTERM, 129 SIGHUP).

    \b
    Examples:
      vdmbake configs/default.toml -o out/default.bundle
      vdmrender out/default.bundle -o out/default
      vdmbake configs/ -o out/bundles --jobs 2 --cache out/cache
      vdmbake 'scenes/*.toml' -o out/bundles --scheduler tcp://farm:8786 --cache /shared/vdm-cache
      vdmbake --cache out/cache --cache-stats
    """
    from .library.cache import PartCache
    from .errors import InputError, fail

    def cache_of() -> PartCache | None:
        if no_cache:
            return None
        try:
            return PartCache.from_env(cache_dir, cache_size)
        except InputError as e:
            fail(e, debug)

    cache = cache_of()
    if (cache_stats or cache_clear or cache_verify) and cache is None:
        raise click.UsageError("--cache-stats, --cache-clear and --cache-verify need a cache: --cache DIR or VDM_CACHE.")
    if not scenes and not (cache_stats or cache_clear or cache_verify):
        raise click.UsageError("give at least one SCENE (a scene file, a folder of them, or a glob), and -o.")
    if scenes and out is None:
        raise click.UsageError("missing option '-o' / '--output': the bundle (one scene) or the folder of bundles.")
    if cache_clear:
        done = guarded(cache.clear, debug)
        if done["left"] or done["stats_left"]:
            fail(InputError(f"{cache.root}: could not clear the part cache: {done['removed']} entries removed, "
                            f"{done['left']} left{', and stats.log' if done['stats_left'] else ''} "
                            f"({done['reason']}); is it read-only?"), debug)
        click.echo(f"cleared the part cache {cache.root} ({done['removed']} entries removed)", err=True)
    if cache_verify:
        found = guarded(cache.verify, debug)
        click.echo(f"{cache.root}: {found['entries']} entries intact, {found['removed_damaged']} damaged removed",
                   err=True)
        if found["not_removed"]:
            fail(InputError(f"{cache.root}: {found['not_removed']} damaged entries could not be removed (is the "
                            "cache read-only?); they stay misses until removed."), debug)
    code = 0
    if scenes:
        found, many = guarded(lambda: batch.expand(scenes), debug)
        if not many and scheduler is None:
            _one(found[0], out, force, cache, as_json, debug)
        else:
            code = _many(found, out, many, force, jobs, scheduler, workers_wait, cache, verbose, as_json, debug)
    if cache_stats:
        st = guarded(cache.stats, debug)
        if as_json and not scenes:
            click.echo(json.dumps(st, indent=1))
        else:
            rate = "n/a" if st["hit_rate"] is None else f"{100 * st['hit_rate']:.1f}%"
            click.echo(f"cache {st['cache']}: {st['entries']} entries, {st['bytes'] / 2**20:.1f} MiB of "
                       f"{st['max_bytes'] / 2**30:.3g} GiB; {st['bakes']} bakes: steps {st['hits']} from cache, "
                       f"{st['misses']} baked (hit rate {rate}), {st['corrupt']} damaged entries re-baked, "
                       f"{st['evicted']} evicted" + (f"; {st['skipped_lines']} unreadable lines of stats.log "
                                                     "skipped" if st["skipped_lines"] else ""), err=bool(scenes))
    raise SystemExit(code)


def _one(scene: Path, out: Path, force: bool, cache, as_json: bool, debug: bool) -> None:
    """One scene into the bundle `out` (the tool's original form)."""
    log = (lambda m: None) if as_json else (lambda m: click.echo(escaped(m), err=True))   # names are raw input
    stats = guarded(lambda: bake(scene, out, force=force, log=log, cache=cache), debug)
    if as_json:
        click.echo(json.dumps(stats, indent=1))
    elif not stats["up_to_date"]:
        took = f" ({stats['parts_from_cache']} from cache)" if "parts_from_cache" in stats else ""
        click.echo(f"baked {escaped(stats['bundle'])}: {stats['objects']} objects, {stats['parts']} parts{took}, "
                   f"{stats['bytes'] / 1e6:.2f} MB in {stats['bake_s']:.2f} s")


def _many(scenes: list[Path], out: Path, many: bool, force: bool, jobs: int | None, scheduler: str | None,
          workers_wait: float, cache, verbose: bool, as_json: bool, debug: bool) -> int:
    """Several scenes (or one on a cluster): the pool or the cluster, the progress, the closing table; the exit
    code (0 all done, 1 some failed, 2 the cluster stopped the run: its scheduler lost, or no worker)."""
    from . import signals
    from .errors import InputError, fail

    try:
        pairs = batch.targets(scenes, out) if many else [(scenes[0], out)]
        if scheduler is not None:
            from .cluster import check_address
            check_address(scheduler)
        if many:
            out.mkdir(parents=True, exist_ok=True)
    except InputError as e:
        fail(e, debug)
    except OSError as e:
        fail(InputError(f"{out}: cannot make the output folder ({e.strerror or e})."), debug)
    tasks = [batch.Task(str(s.absolute()), str(o.absolute()), force, str(cache.root.absolute()) if cache else None,
                        cache.max_bytes if cache else None, verbose) for s, o in pairs]
    jobs = min(jobs or batch.default_jobs(), len(tasks))
    where = f"Dask {scheduler}" if scheduler else f"{jobs} local worker process{'es' * (jobs > 1)}"
    if not as_json:
        click.echo(escaped(f"baking {len(tasks)} scenes into {out if many else out.parent} on {where}"
                           + (f", part cache {cache.root}" if cache else "")), err=True)
    progress = batch.Progress(len(tasks), quiet=as_json)
    signals.install()
    t0 = time.perf_counter()
    try:
        if scheduler is not None:
            from .library.batch import run_dask
            rows, about, stopped = run_dask(tasks, scheduler, progress, workers_wait)
        else:
            rows, about, stopped = batch.run_local(tasks, jobs, progress), where, None
    except InputError as e:
        progress.close()
        fail(e, debug)
    except (KeyboardInterrupt, signals.Interrupted) as e:
        progress.close()
        click.echo(f"interrupted{f' ({e})' if str(e) else ''} after {progress.n} of {len(tasks)} scenes: the bundles "
                   "of those finished are in place, the others were not written", err=True)
        raise SystemExit(signals.exit_code(e)) from None
    progress.close()
    wall = time.perf_counter() - t0
    failed = [r for r in rows if r["status"] == "failed"]
    if as_json:
        click.echo(json.dumps({"scenes": rows, "wall_s": round(wall, 3), "workers": about, "stopped": stopped,
                               "cache": cache.stats() if cache else None}, indent=1))
    else:
        click.echo(batch.table(rows, wall))
    if failed:
        click.echo(f"{len(failed)} of {len(rows)} scenes failed: " + ", ".join(escaped(r["scene"]) for r in failed),
                   err=True)
    if stopped:
        click.echo(escaped(f"error: the run stopped: {stopped}"), err=True)
    return 2 if stopped else 1 if failed else 0


if __name__ == "__main__":
    main()
