"""Molecules as quadrics: atoms as spheres, bonds as capped cylinders, from PDB / mmCIF files.

For GPU ray casting of quadrics (Sigg et al. 2006; de Poel & Bresser 2009). Parsing is gemmi's
(`gemmi.read_structure`: PDB, mmCIF, mmJSON, each optionally gzipped); everything else is numpy.

What is read
  * the first model only (NMR ensembles and multi-model files give their model 1);
  * alternate locations: the first conformer met at each residue position is kept (atoms with no
    altloc always are); bonds shorter than 0.4 A are dropped too, so copies that still overlap
    (duplicated atoms) are not bonded to each other;
  * hydrogens (and deuteriums, drawn as hydrogens) are kept when the file has them: X-ray entries
    usually have none, NMR and simulation files have many, and they roughly double the count;
  * waters and ions are kept: they are atoms (a water without H is a lone O sphere);
  * sites whose element is unknown (gemmi element X) are dropped: in practice these are the
    massless virtual sites of 4- and 5-site water models (TIP4P "M"/"MW", TIP5P "EP"), which
    would otherwise put a default-sized sphere inside every water;
  * no symmetry or periodic images are applied: coordinates are taken as they are.

Styles (radii in Angstrom)
  spacefill        sphere = van der Waals radius; no bonds.
  ball-and-stick   sphere = 0.25 x vdW radius; bonds as cylinders of radius 0.15.
  licorice         sphere = 0.3 at every atom (rounds the joints); bonds of radius 0.3.
Every bond i-j becomes TWO cylinders (half-bonds) that meet at the bond midpoint, each coloured
like its own atom: cylinders[2k] runs from atom i to the midpoint, cylinders[2k+1] from atom j to
the midpoint (x0 is always the atom end). Bonds are listed with i < j, sorted by (i, j).

Bonds come from the covalent-distance rule: i and j are bonded when
    0.4 < |p_i - p_j| <= r_cov(i) + r_cov(j) + 0.45
found with a vectorised cell list (no O(N^2) distances or memory): a 165k-atom ribosome mmCIF
loads and bonds in under 1 s on 2 cores. The rule also bonds metal ions to their ligands and,
rarely, to each other (two Mg 3.1 A apart in a kinase site): it is the distance rule, not chemistry.
Elements come from the file's element column, or gemmi's guess from the atom name when that is
blank (CHARMM's chloride 'CLA' then reads as carbon).
"""
from __future__ import annotations

import functools
import pathlib
from collections.abc import Callable

import numpy as np

from ..common.colour import srgb8_to_linear
from ..errors import InputError
from ..kernels.quadrics import QuadricSet

STYLES = ("ball-and-stick", "spacefill", "licorice")

BOND_TOLERANCE = 0.45      # A, added to the sum of covalent radii
MIN_BOND_LENGTH = 0.4      # A, shorter "bonds" are overlapping alternate locations
BALL_SCALE = 0.25          # ball-and-stick sphere = 0.25 x vdW radius
BALL_STICK_BOND_RADIUS = 0.15
LICORICE_RADIUS = 0.3
DEFAULT_VDW = 1.8          # A, for elements the Bondi table does not list (Fe, B, Al, Ca, ...)
DEFAULT_COVALENT = 1.5     # A, for Z > 96 (beyond the Cordero table; not met in the PDB)

# Van der Waals radii (A): A. Bondi, "van der Waals Volumes and Radii", J. Phys. Chem. 68 (1964)
# 441-451, Table I, as commonly tabulated; hydrogen replaced by 1.10 from R. S. Rowland and
# R. Taylor, "Intermolecular Nonbonded Contact Distances in Organic Crystal Structures",
# J. Phys. Chem. 100 (1996) 7384-7391 (Bondi's 1.20 is too large for H bonded to C).
# Elements not listed here get DEFAULT_VDW = 1.8 A.
VDW_RADII = {
    "H": 1.10, "He": 1.40, "Li": 1.82, "C": 1.70, "N": 1.55, "O": 1.52, "F": 1.47, "Ne": 1.54,
    "Na": 2.27, "Mg": 1.73, "Si": 2.10, "P": 1.80, "S": 1.80, "Cl": 1.75, "Ar": 1.88, "K": 2.75,
    "Ni": 1.63, "Cu": 1.40, "Zn": 1.39, "Ga": 1.87, "As": 1.85, "Se": 1.90, "Br": 1.85,
    "Kr": 2.02, "Pd": 1.63, "Ag": 1.72, "Cd": 1.58, "In": 1.93, "Sn": 2.17, "Te": 2.06,
    "I": 1.98, "Xe": 2.16, "Pt": 1.75, "Au": 1.66, "Hg": 1.55, "Tl": 1.96, "Pb": 2.02, "U": 1.86,
}

# Covalent radii (A), Z = 1..96: B. Cordero, V. Gomez, A. E. Platero-Prats, M. Reves,
# J. Echeverria, E. Cremades, F. Barragan and S. Alvarez, "Covalent radii revisited",
# Dalton Trans. (2008) 2832-2838, doi:10.1039/b801115j, Table 2 (C: sp3 0.76; Mn, Fe, Co: the
# low-spin values).
_COVALENT_Z1 = (
    0.31, 0.28, 1.28, 0.96, 0.84, 0.76, 0.71, 0.66, 0.57, 0.58,  # H .. Ne
    1.66, 1.41, 1.21, 1.11, 1.07, 1.05, 1.02, 1.06, 2.03, 1.76,  # Na .. Ca
    1.70, 1.60, 1.53, 1.39, 1.39, 1.32, 1.26, 1.24, 1.32, 1.22,  # Sc .. Zn
    1.22, 1.20, 1.19, 1.20, 1.20, 1.16, 2.20, 1.95, 1.90, 1.75,  # Ga .. Zr
    1.64, 1.54, 1.47, 1.46, 1.42, 1.39, 1.45, 1.44, 1.42, 1.39,  # Nb .. Sn
    1.39, 1.38, 1.39, 1.40, 2.44, 2.15, 2.07, 2.04, 2.03, 2.01,  # Sb .. Nd
    1.99, 1.98, 1.98, 1.96, 1.94, 1.92, 1.92, 1.89, 1.90, 1.87,  # Pm .. Yb
    1.87, 1.75, 1.70, 1.62, 1.51, 1.44, 1.41, 1.36, 1.36, 1.32,  # Lu .. Hg
    1.45, 1.46, 1.48, 1.40, 1.50, 1.50, 2.60, 2.21, 2.15, 2.06,  # Tl .. Th
    2.00, 1.96, 1.90, 1.87, 1.80, 1.69,                          # Pa .. Cm
)

# CPK colours as used by Jmol (https://jmol.sourceforge.net/jscolors/), sRGB 8-bit hex, Z = 1..109.
# Unknown / heavier: deep pink FF1493, RasMol's colour for "other" elements.
_JMOL_HEX_Z1 = (
    "FFFFFF D9FFFF CC80FF C2FF00 FFB5B5 909090 3050F8 FF0D0D 90E050 B3E3F5 AB5CF2 8AFF00 BFA6A6 "
    "F0C8A0 FF8000 FFFF30 1FF01F 80D1E3 8F40D4 3DFF00 E6E6E6 BFC2C7 A6A6AB 8A99C7 9C7AC7 E06633 "
    "F090A0 50D050 C88033 7D80B0 C28F8F 668F8F BD80E3 FFA100 A62929 5CB8D1 702EB0 00FF00 94FFFF "
    "94E0E0 73C2C9 54B5B5 3B9E9E 248F8F 0A7D8C 006985 C0C0C0 FFD98F A67573 668080 9E63B5 D47A00 "
    "940094 429EB0 57178F 00C900 70D4FF FFFFC7 D9FFC7 C7FFC7 A3FFC7 8FFFC7 61FFC7 45FFC7 30FFC7 "
    "1FFFC7 00FF9C 00E675 00D452 00BF38 00AB24 4DC2FF 4DA6FF 2194D6 267DAB 266696 175487 D0D0E0 "
    "FFD123 B8B8D0 A6544D 575961 9E4FB5 AB5C00 754F45 428296 420066 007D00 70ABFA 00BAFF 00A1FF "
    "008FFF 0080FF 006BFF 545CF2 785CE3 8A4FE3 A136D4 B31FD4 B31FBA B30DA6 BD0D87 C70066 CC0059 "
    "D1004F D90045 E00038 E6002E EB0026"
).split()
_OTHER_HEX = "FF1493"

# Extensions gemmi recognises by name; anything else is sniffed (CoorFormat.Detect).
_KNOWN_SUFFIXES = (".pdb", ".ent", ".cif", ".mmcif", ".json", ".mmjson")


def _tables():
    """Per-atomic-number arrays (index Z, 0..119): vdW radius, covalent radius, linear RGB."""
    import gemmi

    vdw = np.full(120, DEFAULT_VDW)
    for sym, r in VDW_RADII.items():
        vdw[gemmi.Element(sym).atomic_number] = r
    cov = np.full(120, DEFAULT_COVALENT)
    cov[1:1 + len(_COVALENT_Z1)] = _COVALENT_Z1
    hexes = [_OTHER_HEX] + _JMOL_HEX_Z1 + [_OTHER_HEX] * (119 - len(_JMOL_HEX_Z1))
    rgb8 = np.array([[int(h[k:k + 2], 16) for k in (0, 2, 4)] for h in hexes])
    return vdw, cov, srgb8_to_linear(rgb8).astype(np.float32)


@functools.cache
def element_tables():
    return _tables()


def _read_structure(path: pathlib.Path, fmt, warn: Callable[[str], None]):
    """gemmi's structure of the file. A PDB file that gemmi refuses is read a second time with columns
    73-80 of every line ignored, and `warn` says so: files written before the 1996 format (PyMOL's
    tutorial 1hpv, many simulation tools) keep a segment id or line counter there, where the current
    format puts the element (77-78) and the charge (79-80), hence gemmi's "Wrong format for charge".
    Elements are then gemmi's guess from the atom names."""
    import gemmi

    try:
        return gemmi.read_structure(str(path), format=fmt)
    except Exception as e:  # gemmi raises RuntimeError, ValueError, OSError, ... with a reason
        first = e
    try:
        st = gemmi.read_pdb(str(path), max_line_length=72)
    except Exception:
        st = None
    if st is None or len(st) == 0 or st[0].count_atom_sites() == 0:
        raise InputError(f"molecule file {path}: cannot be read as PDB or mmCIF ({first}).") from None
    warn(f"molecule file {path}: not in the current PDB format ({first}); read with columns 73-80 of every "
         f"line ignored (segment id, element, charge), elements guessed from the atom names")
    return st


def _read_atoms(path: pathlib.Path, warn: Callable[[str], None] = lambda m: None) -> tuple[np.ndarray, np.ndarray]:
    """(N, 3) float64 positions and (N,) int atomic numbers of the first model's atoms."""
    import gemmi

    if not path.exists():
        raise InputError(f"molecule file {path}: file not found.")
    if not path.is_file():
        raise InputError(f"molecule file {path}: not a regular file.")
    name = path.name.lower()
    stem = name[:-3] if name.endswith(".gz") else name
    fmt = gemmi.CoorFormat.Unknown if stem.endswith(_KNOWN_SUFFIXES) else gemmi.CoorFormat.Detect
    st = _read_structure(path, fmt, warn)
    if len(st) == 0:
        raise InputError(f"molecule file {path}: no atoms (no model found; is it a PDB or mmCIF "
                         f"coordinate file?).")
    # Alternate locations: keep atoms without an altloc and those whose altloc is the first one
    # met at that residue position (chain, sequence id), so point mutants written as two residues
    # at one position (microheterogeneity) keep the first too. Not gemmi's
    # remove_alternative_conformations: it also drops atoms of simulation files whose residue
    # numbers repeat (e.g. waters numbered modulo 10000), with no altloc at all.
    first_alt: dict[tuple[str, str], str] = {}
    xyz, z = [], []
    for chain in st[0]:
        for res in chain:
            for atom in res:
                if atom.altloc != "\0":
                    where = (chain.name, str(res.seqid))
                    if first_alt.setdefault(where, atom.altloc) != atom.altloc:
                        continue
                p = atom.pos
                xyz.append((p.x, p.y, p.z))
                z.append(atom.element.atomic_number)
    z = np.asarray(z, np.int64)
    xyz = np.asarray(xyz, np.float64).reshape(-1, 3)
    if len(z) == 0:
        raise InputError(f"molecule file {path}: no atoms in the first model (is it a PDB or mmCIF "
                         f"coordinate file?).")
    bad = ~np.isfinite(xyz).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"molecule file {path}: {int(bad.sum())} atoms have NaN or Inf coordinates "
                         f"(first: atom {i + 1} of the first model at {xyz[i].tolist()}); every "
                         f"coordinate must be finite.")
    known = z > 0
    if not known.any():
        raise InputError(f"molecule file {path}: no atom has a known element (all {len(z)} are X).")
    return xyz[known], z[known]


_HALF_OFFSETS = [(dx, dy, dz) for dx in (-1, 0, 1) for dy in (-1, 0, 1) for dz in (-1, 0, 1)
                 if (dx, dy, dz) > (0, 0, 0)]   # 13 offsets: each unordered cell pair once


def find_bonds(xyz: np.ndarray, covalent: np.ndarray, tolerance: float = BOND_TOLERANCE,
               min_length: float = MIN_BOND_LENGTH, max_candidates: int = 1 << 22) -> np.ndarray:
    """(B, 2) int64 pairs i < j (sorted) with min_length < |xyz_i - xyz_j| <= cov_i + cov_j + tolerance.

    Cell list: cells of the largest possible bond length; each cell meets itself and 13 of its
    26 neighbours. Cell coordinates are rank-compressed per axis, so sparse or far-flung
    coordinates cost no memory (compression can only add candidate pairs, which the exact
    distance test then rejects). Candidates are processed in blocks of <= max_candidates.
    """
    xyz = np.asarray(xyz, np.float64)
    covalent = np.asarray(covalent, np.float64)
    n = len(xyz)
    if n < 2:
        return np.zeros((0, 2), np.int64)
    cell = 2.0 * covalent.max() + tolerance
    ijk = np.empty((n, 3), np.int64)
    for a in range(3):
        _, ijk[:, a] = np.unique(np.floor((xyz[:, a] - xyz[:, a].min()) / cell), return_inverse=True)
    dims = ijk.max(axis=0) + 3          # one empty layer each side: offsets never wrap
    ijk += 1
    key = (ijk[:, 0] * dims[1] + ijk[:, 1]) * dims[2] + ijk[:, 2]
    order = np.argsort(key, kind="stable")
    skey, p, r = key[order], xyz[order], covalent[order]
    idx = np.arange(n)
    found = []
    for off in [(0, 0, 0)] + _HALF_OFFSETS:
        nkey = skey + (off[0] * dims[1] + off[1]) * dims[2] + off[2]
        lo = np.searchsorted(skey, nkey, "left")
        hi = np.searchsorted(skey, nkey, "right")
        if off == (0, 0, 0):
            lo = np.maximum(lo, idx + 1)          # within a cell: j after i only
        cnt = np.maximum(hi - lo, 0)
        ends = np.cumsum(cnt)
        start = 0
        while start < n:
            # the largest block of atoms whose candidates fit in max_candidates (at least one atom)
            base = ends[start - 1] if start else 0
            stop = max(int(np.searchsorted(ends, base + max_candidates, "right")), start + 1)
            c = cnt[start:stop]
            tot = int(c.sum())
            if tot:
                i = np.repeat(idx[start:stop], c)
                first = np.cumsum(c) - c
                j = np.repeat(lo[start:stop] - first, c) + np.arange(tot)
                d2 = np.einsum("ij,ij->i", p[i] - p[j], p[i] - p[j])
                lim = r[i] + r[j] + tolerance
                ok = (d2 <= lim * lim) & (d2 > min_length * min_length)
                found.append(np.stack([order[i[ok]], order[j[ok]]], axis=1))
            start = stop
    if not found:
        return np.zeros((0, 2), np.int64)
    pairs = np.concatenate(found)
    pairs.sort(axis=1)
    pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
    return pairs.astype(np.int64)


def quadrics_from_atoms(xyz: np.ndarray, z: np.ndarray, style: str, origin: str = "atoms") -> QuadricSet:
    """Spheres and half-bond cylinders for atoms at xyz (A) with atomic numbers z, in one style."""
    if style not in STYLES:
        raise InputError(f"{origin}: unknown molecule style {style!r}; allowed styles: "
                         f"{', '.join(STYLES)}.")
    vdw, cov, rgb = element_tables()
    xyz = np.asarray(xyz, np.float64).reshape(-1, 3)
    z = np.clip(np.asarray(z, np.int64), 0, 119)
    colours = rgb[z]
    if style == "spacefill":
        radius = vdw[z]
    elif style == "ball-and-stick":
        radius = BALL_SCALE * vdw[z]
    else:
        radius = np.full(len(z), LICORICE_RADIUS)
    spheres = np.concatenate([xyz, radius[:, None]], axis=1)
    if style == "spacefill":
        return QuadricSet(spheres, colours, np.zeros((0, 7)), np.zeros((0, 3), np.float32))
    bond_r = BALL_STICK_BOND_RADIUS if style == "ball-and-stick" else LICORICE_RADIUS
    pairs = find_bonds(xyz, cov[z])
    ends = pairs.reshape(-1)                   # i0, j0, i1, j1, ...: the atom end of each half
    mid = 0.5 * (xyz[pairs[:, 0]] + xyz[pairs[:, 1]])
    cylinders = np.concatenate([xyz[ends], np.repeat(mid, 2, axis=0),
                                np.full((len(ends), 1), bond_r)], axis=1)
    return QuadricSet(spheres, colours, cylinders, colours[ends])


def load_molecule(path: pathlib.Path, style: str, warn: Callable[[str], None] = lambda m: None) -> QuadricSet:
    """Atoms (spheres) and bonds (pairs of half-cylinders) of a PDB / mmCIF file's first model.

    Raises InputError, naming the file, when the style is unknown, the file is missing or cannot
    be parsed, has no atoms, or has non-finite coordinates; `warn` hears what was ignored to read it.
    """
    path = pathlib.Path(path)
    if style not in STYLES:
        raise InputError(f"molecule file {path}: unknown molecule style {style!r}; allowed styles: "
                         f"{', '.join(STYLES)}.")
    xyz, z = _read_atoms(path, warn)
    return quadrics_from_atoms(xyz, z, style, origin=f"molecule file {path}")
