"""glTF 2.0's numbers, shared by the reader (vdmbake.assets.gltf), the writer (vdmbake.export.gltf) and the tests'
file builder: accessor component types and their little-endian dtypes (§3.6.2.2), accessor types' widths,
buffer-view targets (§5.11), sampler wrap modes (§5.26) and primitive modes (§3.7.2.1)."""
from __future__ import annotations

import numpy as np

BYTE, UNSIGNED_BYTE, SHORT, UNSIGNED_SHORT, UNSIGNED_INT, FLOAT = 5120, 5121, 5122, 5123, 5125, 5126
DTYPES = {BYTE: np.dtype("i1"), UNSIGNED_BYTE: np.dtype("u1"), SHORT: np.dtype("<i2"),
          UNSIGNED_SHORT: np.dtype("<u2"), UNSIGNED_INT: np.dtype("<u4"), FLOAT: np.dtype("<f4")}
COMPONENT_OF = {d.char: c for c, d in DTYPES.items()}     # a numpy array's dtype char -> its componentType
WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}   # what a primitive's attributes and indices are

ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
CLAMP_TO_EDGE, MIRRORED_REPEAT, REPEAT = 33071, 33648, 10497
WRAPS = (CLAMP_TO_EDGE, MIRRORED_REPEAT, REPEAT)
MODES = {0: "points", 1: "lines", 2: "line loop", 3: "line strip", 4: "triangles", 5: "triangle strip",
         6: "triangle fan"}
INDEX_TYPES = (UNSIGNED_BYTE, UNSIGNED_SHORT, UNSIGNED_INT)          # indices and sparse indices (§3.6.2.3, §3.7.2.1)
COLOUR_TYPES = (UNSIGNED_BYTE, UNSIGNED_SHORT, FLOAT)                # COLOR_0 (§3.7.2.1)
