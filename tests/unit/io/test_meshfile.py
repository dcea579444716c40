"""Mesh input: files through trimesh, arrays, and the bad input each named in one line."""

from __future__ import annotations

import logging

import numpy as np
import pytest

import tumble

TETRA_V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
TETRA_T = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


@pytest.mark.parametrize("ext", ["obj", "stl", "ply", "glb"])
def test_mesh_files_load_through_trimesh(tmp_path, ext):
    """Load the same tetrahedron from OBJ, STL, PLY and GLB with its four triangles."""
    import trimesh

    path = tmp_path / f"tetra.{ext}"
    trimesh.Trimesh(TETRA_V, TETRA_T).export(path)
    w = tumble.World()
    m = w.add_mesh(file=path, scale=2.0, position=(0, 0, 1))
    assert w.body_shape[m] == tumble.ShapeType.MESH
    assert w.body_inv_mass[m] == 0
    assert len(w.meshes.triangles[w.body_geometry[m]]) == 4
    np.testing.assert_allclose(np.unique(w.meshes.vertices[0], axis=0), np.unique(TETRA_V * 2, axis=0))


def test_mesh_bad_files(tmp_path):
    """Name the file: missing, unknown format, unreadable, no triangles, a device."""
    w = tumble.World()
    with pytest.raises(ValueError, match=r"nothing\.obj: no such mesh file"):
        w.add_mesh(file=tmp_path / "nothing.obj")
    (tmp_path / "a.dae").write_text("x")
    with pytest.raises(ValueError, match=r"a\.dae: unknown mesh format"):
        w.add_mesh(file=tmp_path / "a.dae")
    (tmp_path / "points.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    with pytest.raises(ValueError, match=r"points\.obj: .*no triangles"):
        w.add_mesh(file=tmp_path / "points.obj")
    (tmp_path / "zero.obj").symlink_to("/dev/zero")  # a device: its size is 0 and it never ends
    with pytest.raises(ValueError, match=r"zero\.obj: not a regular file"):
        w.add_mesh(file=tmp_path / "zero.obj")


def test_mesh_drops_nan_and_degenerate_triangles_with_counts(caplog):
    """Drop triangles with NaN vertices and zero-area triangles, telling each count in one line."""
    v = np.vstack([TETRA_V, [[np.nan, 0, 0], [2, 0, 0]]])
    t = np.vstack([TETRA_T, [[0, 1, 4], [0, 1, 5]]])  # one with the NaN vertex, one collinear
    w = tumble.World()
    with caplog.at_level(logging.WARNING, logger="tumble"):
        m = w.add_mesh(vertices=v, triangles=t)
    text = [r.getMessage() for r in caplog.records]
    assert any("dropped 1 triangles with non-finite vertices" in s for s in text)
    assert any("dropped 1 degenerate" in s for s in text)
    assert all("\n" not in s for s in text)
    assert len(w.meshes.triangles[w.body_geometry[m]]) == 4


@pytest.mark.parametrize(
    "triangles, message", [(np.zeros((0, 3), int), "no triangles"), ([[0, 1, 1]], "no usable triangles")]
)
def test_mesh_with_nothing_left_is_rejected(triangles, message):
    """Reject a mesh with no triangles, or none left after cleaning."""
    with pytest.raises(ValueError, match=message):
        tumble.World().add_mesh(vertices=TETRA_V, triangles=triangles)


def test_mesh_too_large_is_rejected(monkeypatch):
    """Reject a mesh over the triangle limit with one line saying so."""
    from tumble.io import meshfile

    monkeypatch.setattr(meshfile, "MAX_TRIANGLES", 3)
    with pytest.raises(ValueError, match="too large"):
        tumble.World().add_mesh(vertices=TETRA_V, triangles=TETRA_T)


def test_sphere_mesh_contact_depth_and_normal():
    """Give a sphere above a mesh face its depth and the face normal; inside a closed mesh, the way out."""
    w = tumble.World(gravity=(0, 0, 0))
    w.add_mesh(vertices=TETRA_V * 2, triangles=TETRA_T, position=(0, 0, -1))
    w.add_sphere(position=(0.3, 0.3, -1.09), radius=0.1)  # under the z = 0 face, outside
    w.collide()
    assert w.contact_depth == pytest.approx([0.01], abs=1e-6)
    n = w.contact_normal[0] * (1 if w.contact_pair[0, 0] == 0 else -1)  # mesh -> sphere
    np.testing.assert_allclose(n, [0, 0, -1], atol=1e-5)  # float32 BVH


def test_convex_and_mesh_tables_build_bodies(write_scene, tmp_path):
    """Build [[convex]] from points and [[mesh]] from a file named relative to the scene."""
    import trimesh

    from tumble.io.scene import load_scene

    trimesh.Trimesh(TETRA_V, TETRA_T).export(tmp_path / "tetra.stl")
    path = write_scene(
        "[[convex]]\nposition = [0, 0, 1]\npoints = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]\nscale = 0.1\n"
        '[[mesh]]\nfile = "tetra.stl"\nscale = 3\n'
    )
    w = load_scene(path)
    assert list(w.body_shape) == [tumble.ShapeType.CONVEX, tumble.ShapeType.MESH]
    assert w.body_mass[0] == pytest.approx(1000 * 0.1**3 / 6)
    np.testing.assert_allclose(w.body_position[0], [0.025, 0.025, 1.025])


def test_mesh_table_with_a_missing_file_names_it(write_scene):
    """Fail a [[mesh]] whose file is missing with one line naming the file and the table."""
    from tumble.errors import SceneError
    from tumble.io.scene import load_scene

    path = write_scene('[[mesh]]\nfile = "statue.obj"\n')
    with pytest.raises(SceneError, match=r"mesh.*statue\.obj: no such mesh file"):
        load_scene(path)


def test_convex_table_needs_points_or_file(write_scene):
    """Reject a [[convex]] with neither points nor file."""
    from tumble.errors import SceneError
    from tumble.io.scene import read_scene

    with pytest.raises(SceneError, match="points or file"):
        read_scene(write_scene("[[convex]]\nposition = [0, 0, 1]\n"))


def test_emitter_table_releases_capsules_and_hulls_of_a_file(write_scene, tmp_path):
    """An [[emitter]] of capsules and convex bodies hulled from a file named relative to the scene."""
    import trimesh

    from tumble.io.scene import load_scene

    trimesh.Trimesh(TETRA_V, TETRA_T).export(tmp_path / "tetra.stl")
    path = write_scene(
        '[[plane]]\n[[emitter]]\nshape = ["capsule", "convex"]\nrate = 2400\ncount = 20\nposition = [0, 0, 1]\n'
        'region = "box"\nextent = [1, 1, 0.5]\nradius = 0.02\nhalf_height = [0.03, 0.06]\nfile = "tetra.stl"\n'
        "scale = [0.05, 0.1]\nrandom_orientation = true\n"
    )
    w = load_scene(path)
    w.run(0.05)
    shapes = set(w.body_shape[1:].tolist())
    assert w.body_count == 21 and shapes == {tumble.ShapeType.CAPSULE, tumble.ShapeType.CONVEX}


@pytest.mark.parametrize(
    "text, fragment",
    [
        ('shape = "capsule"\nradius = 0.02\n', "half_height.*capsule emitter needs radius and half_height"),
        ('shape = "convex"\n', "points.*convex emitter needs points or file"),
        ('shape = "sphere"\nradius = 0.02\nfile = "rock.obj"\n', 'file.*is for shape "convex"'),
        ('shape = "cylinder"\n', "unknown shape 'cylinder'"),
        ('shape = "convex"\nfile = "rock.obj"\n', r"rock\.obj: no such mesh file"),
    ],
)
def test_bad_shape_emitter_tables_get_one_line(write_scene, text, fragment):
    """Reject a bad capsule or convex [[emitter]] with one line naming the table and the key or file."""
    from tumble.errors import SceneError
    from tumble.io.scene import load_scene

    path = write_scene("[[emitter]]\nrate = 10\ncount = 5\nposition = [0, 0, 1]\n" + text)
    with pytest.raises(SceneError, match=fragment) as info:
        load_scene(path)
    assert "\n" not in str(info.value) and "emitter" in str(info.value)
