"""The bundle format (docs/bundle.md): `directory` writes a bundle (staged, committed last) and opens one
(every check before any part is used), `manifest` is the manifest's schema and checks, `parts` holds one
module per part kind (its bytes, its metadata, its checks), `staging` the atomic swap of a directory."""
