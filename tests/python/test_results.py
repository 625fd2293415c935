"""A scan's results in memory (sls_results.h), frames fed from Python (sls_feed.h) and the log
callback (sls_log.h): the in-memory cloud and mesh equal the PLY files of the same scan, the
trajectory the TUM file's, snapshots outlive their scan, the model live from the frame callback
(and BusyError from another thread meanwhile), the frames' depth maps, depth maps fed back giving
the run's model bit for bit, the feed's mistakes, and the library's warnings in Python."""
from __future__ import annotations

import json
import pathlib
import struct
import threading
import zlib
from typing import Dict, List, Tuple

import numpy as np
import pytest

import slscan

PLY_TYPES = {"float": "<f4", "uchar": "u1", "int": "<i4", "uint": "<u4", "double": "<f8"}


def read_ply(path: pathlib.Path) -> Tuple[np.ndarray, np.ndarray]:
    """The vertices (a structured array) and the faces (F x 3) of a binary PLY as sls writes it."""
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    counts: Dict[str, int] = {}
    fields: List[Tuple[str, str]] = []
    element = ""
    for line in data[:end].decode().splitlines():
        words = line.split()
        if words[0] == "element":
            element = words[1]
            counts[element] = int(words[2])
        elif words[0] == "property" and element == "vertex":
            fields.append((words[2], PLY_TYPES[words[1]]))
    vertices = np.frombuffer(data, dtype=np.dtype(fields), count=counts["vertex"], offset=end)
    faces = np.zeros((0, 3), np.int32)
    if counts.get("face"):
        records = np.frombuffer(data, dtype=np.dtype([("n", "u1"), ("v", "<i4", 3)]), count=counts["face"],
                                offset=end + vertices.nbytes)
        assert (records["n"] == 3).all()
        faces = records["v"]
    return vertices, faces


def xyz(vertices: np.ndarray, names: str) -> np.ndarray:
    return np.stack([vertices[name] for name in names.split()], axis=1)


def test_cloud_mesh_and_trajectory_equal_the_files(context: slscan.Context, recording: pathlib.Path,
                                                    tmp_path: pathlib.Path):
    with slscan.Scan(context, use_turntable_prior=True) as scan:
        scan.run_recording(recording)
        scan.write_cloud(tmp_path / "cloud.ply")
        scan.write_mesh(tmp_path / "mesh.ply")
        scan.write_trajectory(tmp_path / "trajectory.txt")
        cloud = scan.cloud()
        mesh = scan.mesh()
        stamps, poses = scan.trajectory()
    vertices, _ = read_ply(tmp_path / "cloud.ply")
    assert len(cloud) == len(vertices) > 1000
    assert cloud.positions.dtype == np.float32 and cloud.positions.shape == (len(vertices), 3)
    np.testing.assert_array_equal(cloud.positions, xyz(vertices, "x y z"))  # bit for bit
    np.testing.assert_array_equal(cloud.normals, xyz(vertices, "nx ny nz"))
    np.testing.assert_array_equal(cloud.confidence, vertices["confidence"])
    np.testing.assert_array_equal(cloud.correction, vertices["correction"])  # online deformation
    assert not cloud.positions.flags.writeable

    mesh_vertices, faces = read_ply(tmp_path / "mesh.ply")
    np.testing.assert_array_equal(mesh.vertices, xyz(mesh_vertices, "x y z"))
    np.testing.assert_array_equal(mesh.faces, faces)
    assert mesh.faces.dtype == np.int32 and len(mesh.faces) > 1000

    rows = np.loadtxt(tmp_path / "trajectory.txt", comments="#").reshape(-1, 8)
    assert stamps.shape == (4,) and poses.shape == (4, 4, 4)
    np.testing.assert_allclose(stamps, rows[:, 0], atol=1e-9)
    np.testing.assert_allclose(poses[:, :3, 3], rows[:, 1:4], atol=1e-6)
    np.testing.assert_allclose(poses[0], np.eye(4), atol=1e-9)


def test_snapshot_outlives_its_scan(context: slscan.Context, recording: pathlib.Path):
    scan = slscan.Scan(context, use_turntable_prior=True, online_deformation=False)
    scan.run_recording(recording)
    positions = scan.cloud().positions  # the Cloud itself is gone: the view keeps the snapshot
    before = positions.copy()
    scan.close()
    np.testing.assert_array_equal(positions, before)
    assert scan.closed


def test_live_model_from_the_callback_and_busy_elsewhere(context: slscan.Context, recording: pathlib.Path):
    seen: List[Tuple[int, int, int, int]] = []
    elsewhere: List[BaseException] = []

    with slscan.Scan(context, use_turntable_prior=True) as scan:
        def on_frame(report: slscan.FrameReport) -> None:
            preview = scan.render_preview(96, 72)
            assert preview.shape == (72, 96) and preview.dtype == np.uint8
            stamps, _ = scan.trajectory()
            seen.append((report.index, len(scan.cloud()), len(stamps), int((preview > 0).sum())))
            assert report.depth_m is not None and report.depth_m.shape == (300, 400)
            assert int(((report.depth_m > 0) & np.isfinite(report.depth_m)).sum()) == report.depth_pixels
            assert report.depth_device is None  # a CPU context: nothing on a GPU to lend
            if report.index == 1:
                def other() -> None:
                    try:
                        scan.cloud()
                    except BaseException as error:  # noqa: B036 - checked below
                        elsewhere.append(error)
                thread = threading.Thread(target=other)
                thread.start()
                thread.join()

        scan.run_recording(recording, on_frame=on_frame, with_depth=True)
    assert [index for index, *_ in seen] == [0, 1, 2, 3]
    assert all(points > 1000 and lit > 96 * 72 // 10 for _, points, _, lit in seen)
    assert [poses for _, _, poses, _ in seen] == [1, 2, 3, 4]
    assert len(elsewhere) == 1 and isinstance(elsewhere[0], slscan.BusyError)


def read_png16(path: pathlib.Path) -> np.ndarray:
    """A 16-bit grey PNG (as the recordings store depth), decoded here: no imaging package needed."""
    data = path.read_bytes()
    position, chunks, header = 8, b"", None
    while position < len(data):
        length, kind = struct.unpack(">I4s", data[position:position + 8])
        body = data[position + 8:position + 8 + length]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            chunks += body
        position += 12 + length
    assert header is not None
    width, height, depth, colour, _, _, interlace = header
    assert (depth, colour, interlace) == (16, 0, 0)
    raw = np.frombuffer(zlib.decompress(chunks), np.uint8).reshape(height, 1 + 2 * width)
    rows = np.zeros((height, 2 * width), np.int32)
    for y in range(height):
        kind, line = raw[y, 0], raw[y, 1:].astype(np.int32)
        above = rows[y - 1] if y > 0 else np.zeros(2 * width, np.int32)
        if kind == 2:
            line = (line + above) & 0xFF
        elif kind in (1, 3, 4):  # depend on the decoded bytes to the left: byte by byte
            out = line.copy()
            for x in range(2 * width):
                left = out[x - 2] if x >= 2 else 0
                upper_left = above[x - 2] if x >= 2 else 0
                if kind == 1:
                    predictor = left
                elif kind == 3:
                    predictor = (left + above[x]) // 2
                else:
                    p = left + above[x] - upper_left
                    pa, pb, pc = abs(p - left), abs(p - above[x]), abs(p - upper_left)
                    predictor = left if pa <= pb and pa <= pc else (above[x] if pb <= pc else upper_left)
                out[x] = (out[x] + predictor) & 0xFF
            line = out
        rows[y] = line
    return (rows[:, 0::2] << 8 | rows[:, 1::2]).astype(np.uint16)


def recorded_frames(recording: pathlib.Path) -> List[Tuple[np.ndarray, int, float]]:
    """Each frame's depth map (metres, decoded as the library decodes it), timestamp and angle."""
    manifest = json.loads((recording / "manifest.json").read_text())
    encoding = manifest["depth_encoding"]
    frames = []
    for frame in manifest["frames"]:
        steps = read_png16(recording / frame["depth"])
        depth = (encoding["offset_m"] + steps.astype(np.float64) * encoding["unit_m"]).astype(np.float32)
        depth[steps == 0] = 0.0
        frames.append((depth, frame["timestamp_ns"], frame["turntable_angle_deg"]))
    return frames


def test_fed_depth_maps_give_the_runs_model(context: slscan.Context, recording: pathlib.Path):
    with slscan.Scan(context, use_turntable_prior=True, online_deformation=False) as run:
        run.run_recording(recording)
        expected = run.cloud()
    with slscan.Scan(context, use_turntable_prior=True, online_deformation=False) as fed:
        patterns = fed.start_feed(recording / "calibration.yml")
        assert patterns > 8
        for index, (depth, timestamp_ns, angle) in enumerate(recorded_frames(recording)):
            # A padded view (every other column of a wider array) is read through its stride.
            wide = np.zeros((300, 800), np.float32)
            wide[:, ::2] = depth
            got = fed.add_depth(wide[:, ::2], timestamp_ns=timestamp_ns, turntable_angle_deg=angle, with_depth=True)
            assert got.index == index and got.fused and got.recording_frames == 0
            np.testing.assert_array_equal(got.depth_m, depth)  # the depth the frame was fused from
        np.testing.assert_array_equal(fed.cloud().positions, expected.positions)
        assert fed.summary().fused == 4


def test_feed_mistakes(context: slscan.Context, recording: pathlib.Path):
    with slscan.Scan(context) as scan:
        depth = np.full((300, 400), 0.1, np.float32)
        with pytest.raises(slscan.InvalidArgumentError, match="sls_scan_start_feed"):
            scan.add_depth(depth)
        with pytest.raises(slscan.NotFoundError, match="missing.yml"):
            scan.start_feed(recording / "missing.yml")
        patterns = scan.start_feed(recording / "calibration.yml")
        with pytest.raises(slscan.InvalidArgumentError, match="400x300") as wrong:
            scan.add_depth(np.zeros((300, 401), np.float32))
        assert wrong.value.function == "sls_scan_add_depth"
        with pytest.raises(ValueError):
            scan.add_depth(np.zeros((2, 300, 400), np.float32))
        with pytest.raises(slscan.InvalidArgumentError, match=f"has {patterns}"):
            scan.add_stack(np.zeros((3, 300, 400), np.uint16))
        with pytest.raises(ValueError):
            scan.add_stack([np.zeros((300, 400), np.uint16), np.zeros((300, 400), np.uint8)])
        skipped = scan.add_stack(np.full((patterns, 300, 400), 100, np.uint16))
        assert skipped.index == 0 and skipped.status == slscan.FrameStatus.SKIPPED and skipped.reason
        with pytest.raises(slscan.InvalidArgumentError, match="bit_depth"):
            scan.start_feed(recording / "calibration.yml", bit_depth=4)


def test_log_callback(context: slscan.Context, recording: pathlib.Path):
    messages: List[Tuple[slscan.LogLevel, str]] = []
    assert slscan.get_log_level() == slscan.LogLevel.WARNING
    slscan.set_log_callback(lambda level, message: messages.append((level, message)))
    try:
        with slscan.Scan(context) as scan:
            scan.start_feed(recording / "calibration.yml")
            report = scan.add_depth(np.zeros((300, 400), np.float32))
            assert report.status == slscan.FrameStatus.SKIPPED
            assert messages == [(slscan.LogLevel.WARNING, "scan: frame 0 skipped: no valid depth in the frame")]
            slscan.set_log_level("error")
            assert slscan.get_log_level() == slscan.LogLevel.ERROR
            scan.add_depth(np.zeros((300, 400), np.float32))
            assert len(messages) == 1
    finally:
        slscan.set_log_level(slscan.LogLevel.WARNING)
        slscan.set_log_callback(None)
    with pytest.raises(KeyError):
        slscan.set_log_level("loud")


def test_lent_arrays_are_dlpack_without_a_copy_and_raise_once_released():
    """slscan.LentArray (a frame's device depth map on a CUDA context): DLPack and CUDA's array
    interface over the library's memory, rows strided, no copy; released, it refuses every use.
    Shown on host memory (numpy.from_dlpack), where no GPU is needed."""
    import gc

    from slscan import _device_array

    buffer = np.arange(6 * 8, dtype=np.float32).reshape(6, 8)  # rows of 8, of which 5 are the map
    lent = slscan.LentArray(buffer.ctypes.data, (6, 5), buffer.strides[0], _device_array.KDL_CPU)
    assert lent.__dlpack_device__() == (_device_array.KDL_CPU, 0) and not lent.is_cuda
    view = np.from_dlpack(lent)
    assert view.shape == (6, 5) and view.dtype == np.float32 and np.array_equal(view, buffer[:, :5])
    buffer[2, 3] = -1.0
    assert view[2, 3] == -1.0  # the same memory
    assert not hasattr(lent, "__cuda_array_interface__")
    del view
    gc.collect()
    unconsumed = lent.__dlpack__()  # a capsule nobody took: freed with it
    del unconsumed
    gc.collect()
    assert not _device_array._exported
    lent._release()
    with pytest.raises(RuntimeError, match="frame callback only"):
        np.from_dlpack(lent)
    assert "released" in repr(lent)

    on_gpu = slscan.LentArray(0x7F0000000000, (300, 400), 1664, _device_array.KDL_CUDA, 1)
    assert on_gpu.__dlpack_device__() == (_device_array.KDL_CUDA, 1)
    assert on_gpu.__cuda_array_interface__ == {"shape": (300, 400), "typestr": "<f4", "data": (0x7F0000000000, True),
                                               "strides": (1664, 4), "version": 3, "stream": None}
    with pytest.raises(ValueError, match="row stride"):
        slscan.LentArray(0x7F0000000000, (300, 400), 1000, _device_array.KDL_CUDA)
