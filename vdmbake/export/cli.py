"""vdmexport: a bundle's objects as an engine ships them, by the LOD chain vdmrender measured."""
from __future__ import annotations

from pathlib import Path

import click

from .. import __version__
from ..errors import escaped, guarded
from .chain import export


@click.command(context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("bundle", type=click.Path(path_type=Path))
@click.option("--lod", "lod_path", required=True, type=click.Path(path_type=Path),
              help="lod.json from `vdmrender BUNDLE -o DIR` of a scene with [[render.sweep.lod]] (DIR/lod.json).")
@click.option("-o", "--output", "out", required=True, type=click.Path(path_type=Path),
              help="Output folder; replaced atomically.")
@click.option("--chain", help="Export only the chain of this name (default: every chain in lod.json).")
@click.option("--debug", is_flag=True, help="Show tracebacks instead of one-paragraph errors.")
@click.version_option(__version__)
def main(bundle, lod_path, out, chain, debug):
    """Export BUNDLE's objects by the LOD chains in lod.json, for engines.

    Per chain and object: the chain's triangle-mesh levels (the full mesh, coarse meshes)
    as glTF 2.0, finest first, one node per level under MSFT_lod with MSFT_screencoverage
    from the measured bands (the bounding sphere's diameter on screen over the frame
    height), with the asset's base-colour texture and UVs or its vertex colours (a chain
    out of order is written finest first, each level once, with a warning); and where the
    chain chose impostors (octahedral atlases, enhanced billboards), their bundle parts
    copied unchanged (EXR, PLY), each checked against the bundle's manifest as it is
    copied, with a JSON sidecar giving each one's band, measured error and cost, and
    layout. docs/export.md says how a shader reads them and what engines do with the glTF.

    \b
    OUTPUT/OBJECT-CHAIN.gltf, .bin     the mesh levels (MSFT_lod), OBJECT-albedo.png their texture
    OUTPUT/OBJECT-CHAIN.impostors.json the chain's impostors, beside OBJECT-PART files
    OUTPUT/export.json                 what was written, and any warnings

    Exit codes: 0 done; 2 bad usage or bad input (also under --debug, which adds the traceback);
    128 + N stopped by signal N.

    \b
    Example (the demo's scene asks for a chain per object):
      vdmbake configs/default.toml -o out/default.bundle
      vdmrender out/default.bundle -o out/default
      vdmexport out/default.bundle --lod out/default/lod.json -o out/default-export
    """
    result = guarded(lambda: export(bundle, lod_path, out, chain, lambda m: click.echo(escaped(m), err=True)), debug)
    click.echo(escaped(f"exported {len(result['files'])} files to {out}"))


if __name__ == "__main__":
    main()
