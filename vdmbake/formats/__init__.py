"""File formats: binary PLY and multi-part EXR (the bundle's parts are written in them) and the safe
reading of any input file (regular files only, within a size bound)."""
