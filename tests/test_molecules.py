"""Molecules as quadrics: PDB / mmCIF (and gzipped) through gemmi, radii per style, covalent-distance
bonds as half-cylinders, linear CPK colours, clear errors, and a 150k-atom scale run."""
from __future__ import annotations

import gzip
import importlib.util
from pathlib import Path

import gemmi
import numpy as np
import pytest

from vdmbake.errors import InputError
from vdmbake.assets.molecules import STYLES, find_bonds, load_molecule

from helpers import WATER, pdb_line, pdb_text

def _ethane():
    """Staggered ethane: C-C 1.54, C-H 1.09, tetrahedral angles; offset from the water."""
    atoms = [("C1", "C", (10.0, 0.0, 0.0)), ("C2", "C", (11.54, 0.0, 0.0))]
    t = np.deg2rad(180.0 - 109.47)
    for c, sx, phase, names in ((10.0, -1, 0.0, "H11 H12 H13"), (11.54, 1, 60.0, "H21 H22 H23")):
        for k, name in enumerate(names.split()):
            ph = np.deg2rad(phase + 120.0 * k)
            atoms.append((name, "H", (c + sx * 1.09 * np.cos(t), 1.09 * np.sin(t) * np.cos(ph),
                                      1.09 * np.sin(t) * np.sin(ph))))
    return atoms


ETHANE = _ethane()


def write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


@pytest.fixture
def water(tmp_path) -> Path:
    return write(tmp_path / "water.pdb", pdb_text([("HOH", 1, WATER)]))


@pytest.fixture
def mixed(tmp_path) -> Path:
    return write(tmp_path / "mixed.pdb", pdb_text([("HOH", 1, WATER), ("ETH", 2, ETHANE)]))


def lin(v8):
    c = v8 / 255.0
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


# ---------------------------------------------------------------------------------------- styles

def test_spacefill_is_vdw_spheres_without_bonds(water):
    q = load_molecule(water, "spacefill")
    assert q.spheres.shape == (3, 4) and q.spheres.dtype == np.float64
    np.testing.assert_allclose(q.spheres[:, :3], [a[2] for a in WATER], atol=5e-4)
    np.testing.assert_allclose(q.spheres[:, 3], [1.52, 1.10, 1.10])   # Bondi O, Rowland-Taylor H
    assert q.cylinders.shape == (0, 7) and q.cylinder_rgb.shape == (0, 3)
    assert q.sphere_rgb.shape == (3, 3) and q.sphere_rgb.dtype == np.float32


def test_ball_and_stick_radii_and_bond_count(water):
    q = load_molecule(water, "ball-and-stick")
    np.testing.assert_allclose(q.spheres[:, 3], [0.25 * 1.52, 0.25 * 1.10, 0.25 * 1.10])
    assert q.cylinders.shape == (4, 7) and q.cylinders.dtype == np.float64  # 2 bonds, 4 halves
    np.testing.assert_allclose(q.cylinders[:, 6], 0.15)
    assert q.cylinder_rgb.shape == (4, 3) and q.cylinder_rgb.dtype == np.float32


def test_licorice_radii(water):
    q = load_molecule(water, "licorice")
    np.testing.assert_allclose(q.spheres[:, 3], 0.3)
    np.testing.assert_allclose(q.cylinders[:, 6], 0.3)
    assert len(q.cylinders) == 4


def test_half_bonds_meet_at_the_midpoint_coloured_like_their_atom(water):
    q = load_molecule(water, "ball-and-stick")
    p, rgb = q.spheres[:, :3], q.sphere_rgb
    # bonds (0,1) and (0,2), sorted; each as [atom i -> mid, atom j -> mid]
    for k, (i, j) in enumerate([(0, 1), (0, 2)]):
        a, b = q.cylinders[2 * k], q.cylinders[2 * k + 1]
        np.testing.assert_allclose(a[:3], p[i])
        np.testing.assert_allclose(b[:3], p[j])
        np.testing.assert_allclose(a[3:6], 0.5 * (p[i] + p[j]))
        np.testing.assert_allclose(b[3:6], 0.5 * (p[i] + p[j]))
        np.testing.assert_array_equal(q.cylinder_rgb[2 * k], rgb[i])
        np.testing.assert_array_equal(q.cylinder_rgb[2 * k + 1], rgb[j])
    halves = np.linalg.norm(q.cylinders[:, :3] - q.cylinders[:, 3:6], axis=1)
    np.testing.assert_allclose(halves, 0.48, atol=1e-3)   # O-H 0.96; the H...H 1.52 is no bond


def test_ethane_has_seven_bonds_and_each_h_one(mixed):
    q = load_molecule(mixed, "ball-and-stick")
    assert len(q.spheres) == 11
    assert len(q.cylinders) == 2 * (2 + 7)
    ends = q.cylinders[:, :3]
    # how many half-bonds start at each atom = its number of bonds
    degree = [int(np.sum(np.all(np.isclose(ends, s), axis=1))) for s in q.spheres[:, :3]]
    assert degree == [2, 1, 1, 4, 4, 1, 1, 1, 1, 1, 1]


# --------------------------------------------------------------------------------------- colours

def test_colours_are_linear_cpk(water, mixed):
    q = load_molecule(mixed, "spacefill")
    assert np.all((q.sphere_rgb >= 0) & (q.sphere_rgb <= 1))
    o, h, c = q.sphere_rgb[0], q.sphere_rgb[1], q.sphere_rgb[3]
    np.testing.assert_array_equal(h, [1.0, 1.0, 1.0])                      # Jmol H FFFFFF
    np.testing.assert_allclose(o, [1.0, lin(0x0D), lin(0x0D)], rtol=1e-6)  # Jmol O FF0D0D
    np.testing.assert_allclose(c, [lin(0x90)] * 3, rtol=1e-6)              # Jmol C 909090
    assert abs(c[0] - 0.2789) < 1e-3                                       # not sRGB's 0.565


# --------------------------------------------------------------------------- formats: cif and gz

def _same(a, b):
    for f in ("spheres", "sphere_rgb", "cylinders", "cylinder_rgb"):
        np.testing.assert_allclose(getattr(a, f), getattr(b, f), atol=1e-9, err_msg=f)


def test_mmcif_round_trip_matches_pdb(mixed, tmp_path):
    st = gemmi.read_structure(str(mixed))
    st.setup_entities()
    cif = tmp_path / "mixed.cif"
    st.make_mmcif_document().write_file(str(cif))
    assert "_atom_site." in cif.read_text()
    for style in STYLES:
        _same(load_molecule(cif, style), load_molecule(mixed, style))


def test_gzipped_pdb_and_cif(mixed, tmp_path):
    gz = tmp_path / "mixed.pdb.gz"
    gz.write_bytes(gzip.compress(mixed.read_bytes()))
    _same(load_molecule(gz, "ball-and-stick"), load_molecule(mixed, "ball-and-stick"))
    st = gemmi.read_structure(str(mixed))
    st.setup_entities()
    cgz = tmp_path / "mixed.cif.gz"
    cgz.write_bytes(gzip.compress(st.make_mmcif_document().as_string().encode()))
    _same(load_molecule(cgz, "licorice"), load_molecule(mixed, "licorice"))


def test_first_model_and_first_altloc_only(tmp_path):
    h_a, h_b = (0.96, 0.0, 0.0), (0.0, 0.0, 0.96)
    lines = ["MODEL        1",
             pdb_line(1, "O", "O", (0, 0, 0)),
             pdb_line(2, "H1", "H", h_a, altloc="A"),
             pdb_line(3, "H1", "H", h_b, altloc="B"),
             "ENDMDL", "MODEL        2",
             pdb_line(1, "O", "O", (5, 5, 5)),
             pdb_line(2, "H1", "H", (5.96, 5, 5)),
             pdb_line(3, "H2", "H", (5, 5.96, 5)),
             "ENDMDL", "END", ""]
    q = load_molecule(write(tmp_path / "alt.pdb", "\n".join(lines)), "ball-and-stick")
    np.testing.assert_allclose(q.spheres[:, :3], [(0, 0, 0), h_a], atol=5e-4)
    assert len(q.cylinders) == 2


def test_overlapping_duplicates_are_not_bonded_to_each_other(tmp_path):
    dup = [("O", "O", (0, 0, 0)), ("H1", "H", (0.96, 0, 0)), ("H2", "H", (0.96, 0.2, 0))]
    q = load_molecule(write(tmp_path / "dup.pdb", pdb_text([("HOH", 1, dup)])), "ball-and-stick")
    assert len(q.cylinders) == 4   # O-H1 and O-H2; H1-H2 at 0.2 A (< 0.4) is no bond


def test_virtual_sites_of_unknown_element_are_dropped(tmp_path):
    lines = [pdb_line(1, "O", "O", (0, 0, 0)), pdb_line(2, "H1", "H", (0.96, 0, 0)),
             pdb_line(3, "MW", "", (0.15, 0.0, 0.0)), "END", ""]
    q = load_molecule(write(tmp_path / "tip4p.pdb", "\n".join(lines)), "spacefill")
    assert len(q.spheres) == 2


# ---------------------------------------------------------------------------------------- errors

def _error(path, style="ball-and-stick") -> str:
    with pytest.raises(InputError) as e:
        load_molecule(path, style)
    assert str(path) in str(e.value)
    return str(e.value)


def test_missing_file(tmp_path):
    assert "not found" in _error(tmp_path / "nope.pdb")


def test_directory_is_not_a_molecule(tmp_path):
    (tmp_path / "dir.pdb").mkdir()
    _error(tmp_path / "dir.pdb")


def test_garbage_files(tmp_path):
    rng = np.random.default_rng(1)
    _error(write(tmp_path / "text.pdb", "hello\nthis is not a structure\n"))
    binary = tmp_path / "binary.pdb"
    binary.write_bytes(rng.integers(0, 256, 4000, dtype=np.uint8).tobytes())
    _error(binary)
    assert "cannot be read" in _error(write(tmp_path / "broken.cif", "loop_ {{{ garbage\n"))
    bad_gz = tmp_path / "bad.pdb.gz"
    bad_gz.write_bytes(b"not gzip at all")
    _error(bad_gz)


def test_empty_pdb(tmp_path):
    assert "no atoms" in _error(write(tmp_path / "empty.pdb", "REMARK nothing here\nEND\n"))


def test_non_finite_coordinates(tmp_path):
    line = pdb_line(2, "H1", "H", (0.96, 0, 0)).replace("   0.960", "     nan")
    msg = _error(write(tmp_path / "nan.pdb", pdb_line(1, "O", "O", (0, 0, 0)) + "\n" + line + "\nEND\n"))
    assert "NaN or Inf" in msg and "atom 2" in msg


def test_unknown_style_names_the_allowed_ones(water):
    msg = _error(water, "wireframe")
    assert "wireframe" in msg and all(s in msg for s in STYLES)


# ------------------------------------------------------------------------------ the bond search

def test_cell_list_matches_brute_force():
    rng = np.random.default_rng(7)
    xyz = rng.uniform(0, 14, (1500, 3))                         # dense: many candidates per cell
    xyz[:40] = xyz[40:80] + rng.normal(0, 0.1, (40, 3))         # some near-duplicates (< 0.4 A)
    cov = rng.choice([0.31, 0.66, 0.76, 1.05, 1.41], len(xyz))  # H, O, C, S, Mg
    d = np.linalg.norm(xyz[:, None] - xyz[None], axis=-1)
    ok = (d <= cov[:, None] + cov[None] + 0.45) & (d > 0.4)
    expect = np.argwhere(np.triu(ok, 1))
    assert len(expect) > 1000
    for block in (1 << 22, 997):                                # one block, and many small ones
        np.testing.assert_array_equal(find_bonds(xyz, cov, max_candidates=block), expect)


def test_cell_list_far_flung_coordinates():
    xyz = np.array([[0, 0, 0], [1.5, 0, 0], [1e9, 0, 0], [1e9, 1.5, 0], [-3e8, 7e8, 1e9]], float)
    np.testing.assert_array_equal(find_bonds(xyz, np.full(5, 0.76)), [[0, 1], [2, 3]])


def test_150k_atoms_on_a_jittered_grid(tmp_path):
    """Full pipeline (mmCIF write, gemmi read, bonds) at ribosome size: must simply complete,
    with the exact bond count of a grid whose axis neighbours bond and whose diagonals don't."""
    nx, ny, nz, h = 50, 50, 60, 1.54
    g = np.stack(np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij"), -1)
    xyz = g.reshape(-1, 3) * h + np.random.default_rng(3).uniform(-0.05, 0.05, (nx * ny * nz, 3))
    n = len(xyz)
    rows = "\n".join(f"ATOM {i + 1} C C . UNK A 1 {i // 100 + 1} ? {x:.4f} {y:.4f} {z:.4f} 1 0 1"
                     for i, (x, y, z) in enumerate(xyz))
    cif = write(tmp_path / "grid.cif", "data_grid\nloop_\n" + "".join(
        f"_atom_site.{k}\n" for k in ("group_PDB id type_symbol label_atom_id label_alt_id "
                                      "label_comp_id label_asym_id label_entity_id label_seq_id "
                                      "pdbx_PDB_ins_code Cartn_x Cartn_y Cartn_z occupancy "
                                      "B_iso_or_equiv pdbx_PDB_model_num").split()) + rows + "\n")
    q = load_molecule(cif, "ball-and-stick")
    bonds = (nx - 1) * ny * nz + nx * (ny - 1) * nz + nx * ny * (nz - 1)
    assert n == 150_000 and len(q.spheres) == n
    assert len(q.cylinders) == 2 * bonds
    half = np.linalg.norm(q.cylinders[:, :3] - q.cylinders[:, 3:6], axis=1)
    assert 2 * half.max() < 1.97 and 2 * half.min() > 1.3


# ------------------------------------------------------------- a real structure from a package

def _pdbfixer_data() -> Path:
    # find_spec finds the installed package without importing it (pdbfixer imports openmm)
    spec = importlib.util.find_spec("pdbfixer")
    if spec is None or not spec.submodule_search_locations:
        pytest.skip("pdbfixer is not installed (pip install --no-deps pdbfixer==1.12.0)")
    return Path(list(spec.submodule_search_locations)[0]) / "tests" / "data"


@pytest.mark.parametrize("name", ["test.pdb", "1BHL.pdb"])   # 1VII with H (596), 1BHL (1101)
def test_real_protein_from_pdbfixer(name):
    path = _pdbfixer_data() / name
    records = [l for l in path.read_text().splitlines() if l.startswith(("ATOM  ", "HETATM"))]
    q = load_molecule(path, "ball-and-stick")
    assert len(q.spheres) == len(records) > 500
    xyz = np.array([[float(l[30:38]), float(l[38:46]), float(l[46:54])] for l in records])
    np.testing.assert_allclose(q.spheres[:, :3], xyz, atol=1e-6)
    lengths = 2 * np.linalg.norm(q.cylinders[:, :3] - q.cylinders[:, 3:6], axis=1)
    assert len(q.cylinders) > len(records) and lengths.max() <= 2.5 and lengths.min() > 0.9
    # every atom but a water's is within bonding range of some other atom
    starts = {tuple(np.round(p, 3)) for p in q.cylinders[:, :3]}
    lonely = [l for l, p in zip(records, xyz) if tuple(np.round(p, 3)) not in starts]
    assert all(l[17:20] == "HOH" for l in lonely), lonely[:3]


def _old_format(path: Path, out: Path) -> Path:
    """The file as a PDB writer before the 1996 format wrote it: columns 73-80 of each atom record hold
    the ID code and a line counter (as PyMOL's tutorial 1hpv does), where the current format has the
    element (77-78) and the charge (79-80)."""
    lines = []
    for k, line in enumerate(path.read_text().splitlines()):
        if line.startswith(("ATOM  ", "HETATM")):
            line = f"{line[:66]:<72}1VII{k + 1:4d}"
        lines.append(line)
    return write(out, "\n".join(lines) + "\n")


def test_old_format_pdb_is_read_with_a_warning(tmp_path):
    """Columns 73-80 that are not element and charge: gemmi refuses the file ("Wrong format for charge"),
    the loader reads it without them, guesses the elements from the atom names (all 596 of 1VII with
    hydrogens come out as the element column says) and warns, naming the columns it ignored."""
    original = _pdbfixer_data() / "test.pdb"
    old = _old_format(original, tmp_path / "old.pdb")
    with pytest.raises(Exception, match="Wrong format for charge"):
        gemmi.read_structure(str(old))
    heard = []
    q = load_molecule(old, "ball-and-stick", heard.append)
    assert len(heard) == 1 and "columns 73-80" in heard[0] and "Wrong format for charge" in heard[0]
    assert str(old) in heard[0]
    ref_heard = []
    ref = load_molecule(original, "ball-and-stick", ref_heard.append)
    assert ref_heard == []
    _same(q, ref)
    gz = tmp_path / "old.pdb.gz"
    gz.write_bytes(gzip.compress(old.read_bytes()))
    _same(load_molecule(gz, "ball-and-stick", heard.append), ref)
    assert len(heard) == 2
