"""vdmbake: bake a scene's objects into a bundle."""
from __future__ import annotations

import json
from pathlib import Path

import click

from . import __version__
from .bake import bake
from .errors import InputError, fail


@click.command(context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("scene", type=click.Path(path_type=Path))
@click.option("-o", "--output", "out", required=True, type=click.Path(path_type=Path),
              help="Bundle directory to write, e.g. out/default.bundle.")
@click.option("--force", is_flag=True, help="Bake even if the bundle is up to date.")
@click.option("--json", "as_json", is_flag=True, help="Print the bake statistics as JSON on stdout.")
@click.option("--debug", is_flag=True, help="Show tracebacks instead of one-paragraph errors.")
@click.version_option(__version__)
def main(scene: Path, out: Path, force: bool, as_json: bool, debug: bool):
    """Bake what SCENE's objects need into the bundle OUTPUT.

    SCENE is a TOML file (see configs/default.toml): objects (a mesh file or a built-in
    primitive), cameras, light, material, and per object the techniques to compare.
    Only the parts those techniques need are baked: the full mesh for every object
    (the reference traces it), simplified meshes for `coarse`, and so on.

    The bundle is written atomically (a temporary sibling, renamed into place, the
    manifest last). Re-baking with unchanged inputs and settings does nothing unless
    --force. Exit codes: 0 done, 2 bad usage or bad input.

    \b
    Example:
      vdmbake configs/default.toml -o out/default.bundle
      vdmrender out/default.bundle -o out/default
    """
    log = (lambda m: None) if as_json else (lambda m: click.echo(m, err=True))
    try:
        stats = bake(scene, out, force=force, log=log)
    except InputError as e:
        fail(e, debug)
    if as_json:
        click.echo(json.dumps(stats, indent=1))
    elif not stats["up_to_date"]:
        click.echo(f"baked {stats['bundle']}: {stats['objects']} objects, {stats['parts']} parts, "
                   f"{stats['bytes'] / 1e6:.2f} MB in {stats['bake_s']:.2f} s")


if __name__ == "__main__":
    main()
