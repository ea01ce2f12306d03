"""vdmbake: bake a scene's objects into a bundle."""
from __future__ import annotations

import json
from pathlib import Path

import click

from . import __version__
from .bake import bake
from .errors import guarded
from .scene import REGISTRY


def _techniques() -> str:
    """The --help epilog: every technique, the objects it draws and what it draws (from the registry)."""
    lines = ["\b", "Techniques ([objects.techniques] of each object; README lists their settings):"]
    for t in REGISTRY.values():
        lines.append(f"  {t.name:12} ({'/'.join(t.kinds)}{', mesostructure' if t.mesostructure else ''}) "
                     f"{t.summary.split(':')[0]}")
    return "\n".join(lines)


@click.command(context_settings={"help_option_names": ["-h", "--help"]}, epilog=_techniques())
@click.argument("scene", type=click.Path(path_type=Path))
@click.option("-o", "--output", "out", required=True, type=click.Path(path_type=Path),
              help="Bundle directory to write, e.g. out/default.bundle.")
@click.option("--force", is_flag=True, help="Bake even if the bundle is up to date.")
@click.option("--json", "as_json", is_flag=True, help="Print the bake statistics as JSON on stdout.")
@click.option("--debug", is_flag=True, help="Show tracebacks instead of one-paragraph errors.")
@click.version_option(__version__)
def main(scene: Path, out: Path, force: bool, as_json: bool, debug: bool):
    """Bake what SCENE's objects need into the bundle OUTPUT.

    SCENE is a TOML file (see configs/*.toml and README's scene reference): objects (a mesh
    file, a built-in primitive, a molecule, or inline spheres and cylinders), cameras, light,
    material, and per object the techniques to compare. Only the parts those techniques need
    are baked: what the reference traces (the full mesh, the quadric list, the height field),
    then each technique's own parts: simplified meshes for `coarse`, VDM tables for `vdm`,
    displaced meshes for `displaced`, billboard maps for `billboards`.

    The bundle is written atomically (a temporary sibling, renamed into place, the
    manifest last). Re-baking with unchanged inputs and settings does nothing unless
    --force. Exit codes: 0 done, 2 bad usage or bad input (also under --debug, which adds
    the traceback), 128 + N stopped by signal N (130 Ctrl-C, 143 SIGTERM, 129 SIGHUP).

    \b
    Example:
      vdmbake configs/default.toml -o out/default.bundle
      vdmrender out/default.bundle -o out/default
    """
    log = (lambda m: None) if as_json else (lambda m: click.echo(m, err=True))
    stats = guarded(lambda: bake(scene, out, force=force, log=log), debug)
    if as_json:
        click.echo(json.dumps(stats, indent=1))
    elif not stats["up_to_date"]:
        click.echo(f"baked {stats['bundle']}: {stats['objects']} objects, {stats['parts']} parts, "
                   f"{stats['bytes'] / 1e6:.2f} MB in {stats['bake_s']:.2f} s")


if __name__ == "__main__":
    main()
