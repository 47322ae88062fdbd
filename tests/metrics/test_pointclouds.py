"""Point-cloud readers and writers: round trips, foreign layouts, and clear errors."""

from __future__ import annotations

import numpy as np
import pytest

from nbv_gym.metrics.pointclouds import PointCloudError, read_points, write_points

POINTS = np.array([[0.0, 1.0, 2.0], [3.5, -4.25, 5.0], [1e-3, 2e3, -7.0]])


@pytest.mark.parametrize("suffix", [".ply", ".pcd", ".npy", ".xyz", ".txt"])
def test_round_trip(tmp_path, suffix):
    path = write_points(tmp_path / f"cloud{suffix}", POINTS)
    np.testing.assert_allclose(read_points(path), POINTS, rtol=1e-9)


def test_ascii_ply_with_extra_properties_and_faces(tmp_path):
    path = tmp_path / "mesh.ply"
    path.write_text(
        "ply\nformat ascii 1.0\ncomment made by hand\nelement vertex 2\nproperty float x\n"
        "property float y\nproperty float z\nproperty uchar red\nelement face 1\n"
        "property list uchar int vertex_indices\nend_header\n1 2 3 255\n4 5 6 0\n3 0 1 1\n"
    )
    np.testing.assert_allclose(read_points(path), [[1, 2, 3], [4, 5, 6]])


def test_big_endian_ply_with_float_fields(tmp_path):
    path = tmp_path / "be.ply"
    header = "ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty float z\nproperty float x\nproperty float y\nend_header\n"
    body = POINTS[:, [2, 0, 1]].astype(">f4").tobytes()
    path.write_bytes(header.encode() + body)
    np.testing.assert_allclose(read_points(path), POINTS, rtol=1e-6)


def test_ascii_pcd_with_intensity(tmp_path):
    path = tmp_path / "scan.pcd"
    path.write_text(
        "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\n"
        "COUNT 1 1 1 1\nWIDTH 2\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\nDATA ascii\n"
        "1 2 3 9\n4 5 6 9\n"
    )
    np.testing.assert_allclose(read_points(path), [[1, 2, 3], [4, 5, 6]])


def test_truncated_binary_files_name_the_file(tmp_path):
    for suffix in (".ply", ".pcd"):
        path = write_points(tmp_path / f"cut{suffix}", POINTS)
        path.write_bytes(path.read_bytes()[:-5])
        with pytest.raises(PointCloudError, match=rf"cut\{suffix}: truncated"):
            read_points(path)


def test_bad_inputs_raise_clear_errors(tmp_path):
    with pytest.raises(PointCloudError, match="missing.ply: no such file"):
        read_points(tmp_path / "missing.ply")
    with pytest.raises(PointCloudError, match="unknown point-cloud format '.obj'"):
        read_points(tmp_path / "mesh.obj")
    np.save(tmp_path / "empty.npy", np.zeros((0, 3)))
    with pytest.raises(PointCloudError, match="empty.npy: the point cloud is empty"):
        read_points(tmp_path / "empty.npy")
    (tmp_path / "junk.ply").write_bytes(b"\x00\x01garbage")
    with pytest.raises(PointCloudError, match="junk.ply: not a PLY file"):
        read_points(tmp_path / "junk.ply")
    (tmp_path / "bad.xyz").write_text("1 2 3\n4 five 6\n")
    with pytest.raises(PointCloudError, match="bad.xyz: line 2"):
        read_points(tmp_path / "bad.xyz")
