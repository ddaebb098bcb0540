"""`objects add`: a mesh file becomes an object folder; a bad mesh is refused in one line and writes nothing."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh
from conftest import FAST_IMPORT

from kgn_bench.objects.importer import ImportConfig, import_mesh, repair_mesh
from kgn_bench.shapes.grasp_sampling import SamplingConfig
from kgn_bench.shapes.mesh_object import MeshObject, ObjectError

FAST = ImportConfig(**FAST_IMPORT, sampling=SamplingConfig(points=150))


def _objects(root):
    return sorted(p.name for p in root.iterdir() if p.is_dir() and not p.name.startswith("."))


def test_imported_block_folder(object_library):
    folder = object_library / "test_block"
    manifest = json.loads((folder / "object.json").read_text())
    assert manifest["name"] == "test_block" and manifest["faces"] == 12
    assert np.allclose(sorted(manifest["extents_m"]), [0.04, 0.06, 0.10], atol=1e-6)
    assert manifest["mass"] == pytest.approx(700.0 * 0.04 * 0.06 * 0.10)
    assert 1 <= manifest["hulls"] <= 2
    assert manifest["grasps"]["held"] >= 8 and (folder / "preview.png").stat().st_size > 10_000
    shape = MeshObject(folder)
    assert np.allclose(shape.mesh().center_mass, 0.0, atol=1e-9)  # the object frame sits at the centre of mass
    assert sum(p["probability"] for p in manifest["rest_poses"]) == pytest.approx(1.0)


@pytest.mark.parametrize("ext", ["obj", "ply", "glb"])
def test_formats_and_size_option(tmp_path, ext):
    path = tmp_path / f"tin.{ext}"
    trimesh.creation.cylinder(radius=30.0, height=100.0, sections=24).export(path)  # millimetres
    folder = import_mesh(path, "tin", ImportConfig(**FAST_IMPORT, size=0.10, sampling=SamplingConfig(points=150)),
                         root=tmp_path / "lib", preview=False)
    m = json.loads((folder / "object.json").read_text())
    assert max(m["extents_m"]) == pytest.approx(0.10) and m["scale"] == pytest.approx(0.001)


def test_repair_merges_seams_and_fills_a_hole():
    box = trimesh.creation.box((0.05, 0.05, 0.05))
    split = trimesh.Trimesh(box.vertices[box.faces].reshape(-1, 3), np.arange(36).reshape(12, 3), process=False)
    holed = trimesh.Trimesh(split.vertices, split.faces[1:], process=False)  # one triangle missing, seams open
    assert not holed.is_watertight
    fixed = repair_mesh(holed)
    assert fixed.is_watertight and fixed.volume == pytest.approx(0.05**3)


def test_repair_caps_an_open_tube():
    """A cylinder without its caps has two 24-edge holes, beyond trimesh's ``fill_holes``; each is capped."""
    c = trimesh.creation.cylinder(radius=0.03, height=0.08, sections=24)
    side = np.abs(c.face_normals[:, 2]) < 0.5
    tube = trimesh.Trimesh(c.vertices, c.faces[side])
    assert not tube.is_watertight
    fixed = repair_mesh(tube)
    assert fixed.is_watertight and fixed.volume == pytest.approx(c.volume, rel=1e-9)


def test_repair_unites_overlapping_parts():
    """Two 4 cm cubes overlapping by half: one solid of 6 × 4 × 4 cm, the shared half counted once."""
    a, b = trimesh.creation.box((0.04, 0.04, 0.04)), trimesh.creation.box((0.04, 0.04, 0.04))
    b.apply_translation((0.02, 0.0, 0.0))
    both = trimesh.util.concatenate([a, b])
    assert both.volume == pytest.approx(2 * 0.04**3)
    fixed = repair_mesh(both)
    assert len(fixed.split()) == 1 and fixed.volume == pytest.approx(0.06 * 0.04 * 0.04, rel=1e-6)


def _finned_box():
    """A closed box with one extra triangle on an edge: a non-manifold edge and an open fin, not a loop."""
    box = trimesh.creation.box((0.05, 0.05, 0.05))
    e = box.edges_unique[0]
    tip = box.vertices[e].mean(axis=0) * 3.0
    return trimesh.Trimesh(np.vstack([box.vertices, tip]), np.vstack([box.faces, [[e[0], e[1], 8]]]), process=False)


@pytest.mark.parametrize("mesh, config, reason", [
    (None, FAST, "holds no triangles"),
    ("nan", FAST, "non-finite"),
    (trimesh.creation.box((0.5, 0.1, 0.1)), FAST, "more than the workspace"),
    (trimesh.creation.box((0.1, 0.1, 0.002)), FAST, "thick"),
    (trimesh.creation.box((0.25, 0.25, 0.25)), FAST, "no antipodal grasp"),
])
def test_bad_meshes_are_refused_and_write_nothing(tmp_path, mesh, config, reason):
    path = tmp_path / "bad.obj"
    if mesh is None:
        path.write_text("this is not a mesh\n")
    elif mesh == "nan":
        box = trimesh.creation.box((0.05, 0.05, 0.05))
        v = box.vertices.copy()
        v[0, 0] = np.nan
        trimesh.Trimesh(v, box.faces, process=False).export(path)
    else:
        mesh.export(path)
    root = tmp_path / "lib"
    with pytest.raises(ObjectError, match=reason) as e:
        import_mesh(path, "bad", config, root=root)
    assert "\n" not in str(e.value)
    assert not root.exists() or _objects(root) == []


@pytest.mark.parametrize("make, thickened", [("walled", False), ("fin", True)])
def test_a_surface_repair_cannot_close_is_remeshed_and_says_how_far_it_moved(tmp_path, make, thickened):
    """An inner wall (closed, non-manifold) and a fin (an open sheet on an edge): the voxel fallback makes
    each a solid, and the manifest says why, at what pitch and within what distance of the file's surface."""
    from test_remesh import walled_box

    path = tmp_path / f"{make}.obj"
    (walled_box() if make == "walled" else _finned_box()).export(path)
    folder = import_mesh(path, make, FAST, root=tmp_path / "lib", preview=False)
    m = json.loads((folder / "object.json").read_text())
    r = m["remeshed"]
    assert r["thickened"] is thickened and r["pitch_m"] == pytest.approx(0.002)
    assert ("shared by more than two faces" in r["reason"]) and 0 < r["deviation_m"] < (0.008 if thickened else 0.0015)
    assert m["grasps"]["held"] >= 8 and MeshObject(folder).mesh().is_watertight


def test_names_are_checked(tmp_path, object_library):
    path = tmp_path / "b.stl"
    trimesh.creation.box((0.04, 0.04, 0.04)).export(path)
    with pytest.raises(ObjectError, match="built-in"):
        import_mesh(path, "mug", FAST, root=tmp_path / "lib")
    with pytest.raises(ObjectError, match="lower-case"):
        import_mesh(path, "My Mesh", FAST, root=tmp_path / "lib")
    with pytest.raises(ObjectError, match="lower-case"):
        import_mesh(path, "block\n", FAST, root=tmp_path / "lib")  # a trailing newline is no name
    with pytest.raises(ObjectError, match="already exists"):
        import_mesh(path, "test_block", FAST, root=object_library)
    with pytest.raises(ObjectError, match="an object set's name"):
        import_mesh(path, "pybullet_test", FAST, root=tmp_path / "lib")
    with pytest.raises(ObjectError, match=r"belongs to a packaged set .* pass --overwrite to shadow it"):
        import_mesh(path, "pb_mug", FAST, root=tmp_path / "lib")


def test_decomposition_is_cached(tmp_path):
    path = tmp_path / "bar.stl"
    trimesh.creation.box((0.08, 0.02, 0.03)).export(path)
    root = tmp_path / "lib"
    import_mesh(path, "a", FAST, root=root, preview=False)
    cached = list((root / ".cache" / "coacd").glob("*.npz"))
    assert len(cached) == 1
    stamp = cached[0].stat().st_mtime_ns
    import_mesh(path, "b", FAST, root=root, preview=False)
    assert [p.stat().st_mtime_ns for p in (root / ".cache" / "coacd").glob("*.npz")] == [stamp]
    assert _objects(root) == ["a", "b"]


def test_decomposition_errors_come_back_from_the_child():
    """CoACD runs in a spawned child: what it raises (here a bad setting) returns as ``CoACDCrash``, and the
    caller lives on."""
    from kgn_bench.objects.coacd_worker import CoACDCrash, decompose

    box = trimesh.creation.box((0.05, 0.05, 0.05))
    assert len(decompose(box.vertices, box.faces, {"max_convex_hull": 1})) >= 1
    with pytest.raises(CoACDCrash, match="CoACD failed"):
        decompose(box.vertices, box.faces, {"no_such_setting": 1})


def test_archives_are_refused_before_they_are_unpacked(tmp_path):
    import zipfile

    bomb = tmp_path / "mesh.zip"
    with zipfile.ZipFile(bomb, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("a.obj", "v 0 0 0\n" * 1_000_000)  # small on disk, large unpacked
    with pytest.raises(ObjectError, match="an archive; unpack it"):
        import_mesh(bomb, "zipped", FAST, root=tmp_path / "lib")
    disguised = tmp_path / "mesh.stl"
    disguised.write_bytes(bomb.read_bytes())  # the bytes decide, not the name
    with pytest.raises(ObjectError, match="an archive"):
        import_mesh(disguised, "zipped", FAST, root=tmp_path / "lib")
    big = tmp_path / "big.3mf"
    with zipfile.ZipFile(big, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("3D/3dmodel.model", b"\0" * 300_000_000)
    with pytest.raises(ObjectError, match="unpacks to 300 MB, more than 256 MB"):
        import_mesh(big, "model3mf", FAST, root=tmp_path / "lib")
    assert not (tmp_path / "lib").exists()


def test_the_rest_pose_search_works_on_a_bounded_hull():
    from kgn_bench.objects.importer import REST_HULL_FACES, _bounded_hull, _rest_poses

    sphere = trimesh.creation.icosphere(subdivisions=6, radius=0.04)  # 40 962 hull vertices
    assert len(sphere.convex_hull.faces) > REST_HULL_FACES >= len(_bounded_hull(sphere).faces)
    box = trimesh.creation.box((0.04, 0.06, 0.10))
    assert _bounded_hull(box).faces.shape == box.convex_hull.faces.shape  # small hulls are used as they are
    poses = _rest_poses(box, 0)
    assert len(poses) == 6 and sum(p["probability"] for p in poses) == pytest.approx(1.0)


def test_a_huge_collision_hull_is_rebuilt_from_a_bounded_vertex_subset():
    from kgn_bench.objects.importer import MAX_HULL_VERTICES, _bounded

    sphere = trimesh.creation.icosphere(subdivisions=7, radius=0.05).convex_hull  # 163 842 vertices
    small = _bounded(sphere, MAX_HULL_VERTICES)
    assert len(small.vertices) == MAX_HULL_VERTICES and small.is_convex
    assert small.volume == pytest.approx(sphere.volume, rel=0.005)
    assert np.array_equal(small.vertices, _bounded(sphere, MAX_HULL_VERTICES).vertices)  # the same every time
    box = trimesh.creation.box((0.04, 0.06, 0.10))
    assert _bounded(box, MAX_HULL_VERTICES) is box


def test_every_test_set_and_example_mesh_becomes_a_closed_solid():
    """The importer's read and repair (or remesh) steps on all 43 meshes of the real test set and the examples'
    mesh (dm_control's dog humerus): each gives a watertight solid. (The full import, with its physics checks,
    takes about 25 s an object; ``kgn-bench objects import-set`` runs it.)"""
    from pathlib import Path

    import dm_control

    from kgn_bench.objects.importer import _read, _repaired
    from kgn_bench.objects.pybullet_set import set_items

    meshes = [(it.mesh, ImportConfig(scale=it.scale, size=it.size)) for it in set_items("test")]
    humerus = Path(dm_control.__file__).parent / "suite" / "dog_assets" / "BONEhumerus_L.stl"
    meshes.append((humerus, ImportConfig()))
    for path, config in meshes:
        mesh, _ = _repaired(_read(path), config, path, lambda _: None)
        assert mesh.is_watertight and mesh.volume > 0, path


def test_every_rest_pose_of_the_stanford_bunny_gets_grasps_from_above(tmp_path):
    """The bunny (pybullet_data's copy of the Stanford scan), 12 cm: the uniform sampling approaches it from
    above in 1 of its 205 candidates when it lies on a flank (40 % of its rest probability); aimed candidates
    give every rest pose verified grasps the gripper can execute, and the manifest counts them."""
    from kgn_bench.objects.pybullet_set import data_path

    folder = import_mesh(data_path() / "bunny.obj", "bunny", ImportConfig(size=0.12), root=tmp_path, preview=False)
    manifest = json.loads((folder / "object.json").read_text())
    assert manifest["grasps"]["aimed"] > 0
    per_pose = [rest["grasps"] for rest in manifest["rest_poses"]]
    assert len(per_pose) >= 4 and min(per_pose) >= 4, per_pose
