"""Export for engines (issue 22): a measured LOD chain (vdmrender's lod.json) as glTF 2.0 with MSFT_lod, and the
impostors it chose as images beside a JSON sidecar (docs/export.md)."""
