"""Scans through the Python package: a small simulated recording scanned with a frame callback
receiving every frame, cancels (from the callback, by an exception in it, by Ctrl-C), the
errors of bad input, and the model written."""
from __future__ import annotations

import dataclasses
import json
import os
import pathlib
import signal
import threading
from typing import List

import numpy as np
import pytest

import slscan


def test_run_recording_reports_every_frame(context: slscan.Context, recording: pathlib.Path, tmp_path: pathlib.Path):
    reports: List[slscan.FrameReport] = []
    threads = set()

    def on_frame(report: slscan.FrameReport) -> None:
        reports.append(report)
        threads.add(threading.get_ident())

    with slscan.Scan(context, use_turntable_prior=True) as scan:
        assert scan.config.use_turntable_prior is True and scan.config.online_deformation is True
        summary = scan.run_recording(recording, on_frame=on_frame)
        assert (summary.frames, summary.fused, summary.lost, summary.skipped) == (4, 4, 0, 0)
        assert summary.cancelled is False and summary.voxel_size_m > 0
        assert scan.summary() == summary
        assert [report.index for report in reports] == [0, 1, 2, 3]
        assert len(threads) == 1 and threading.get_ident() not in threads  # the package's worker
        first, last = reports[0], reports[-1]
        assert first.fused and first.status == slscan.FrameStatus.FUSED and first.reason == ""
        assert first.recording_frames == 4 and first.depth_pixels > 10000 and first.total_ms > 0
        assert first.T_world_camera.shape == (4, 4) and first.T_world_camera.dtype == np.float64
        np.testing.assert_allclose(first.T_world_camera, np.eye(4), atol=1e-12)  # the world frame
        assert not first.T_world_camera.flags.writeable
        # 90 degree steps about the table's axis: the last pose is a rotation of 270 degrees.
        rotation = last.T_world_camera[:3, :3]
        np.testing.assert_allclose(rotation @ rotation.T, np.eye(3), atol=1e-6)
        assert np.degrees(np.arccos((np.trace(rotation) - 1) / 2)) == pytest.approx(90.0, abs=2.0)
        assert last.timestamp_ns > first.timestamp_ns
        with pytest.raises(dataclasses.FrozenInstanceError):
            last.index = 7  # type: ignore[misc]
        for name in ("cloud.ply", "mesh.ply"):
            getattr(scan, "write_" + name.split(".")[0])(tmp_path / name)
            assert (tmp_path / name).read_bytes().startswith(b"ply\n")
        scan.write_trajectory(tmp_path / "trajectory.txt")
        poses = [line for line in (tmp_path / "trajectory.txt").read_text().splitlines() if not line.startswith("#")]
        assert len(poses) == 4
    assert scan.closed
    with pytest.raises(slscan.InvalidArgumentError) as no_closure:
        scan.close_loop()  # closed: refused by the package
    assert "closed" in no_closure.value.message


def test_exception_in_callback_cancels_and_is_raised(context: slscan.Context, recording: pathlib.Path):
    calls: List[int] = []

    def on_frame(report: slscan.FrameReport) -> None:
        calls.append(report.index)
        if report.index == 1:
            raise KeyError("stop at frame 1")

    with slscan.Scan(context, use_turntable_prior=True) as scan:
        with pytest.raises(KeyError, match="stop at frame 1"):
            scan.run_recording(recording, on_frame=on_frame)
        assert calls == [0, 1]  # no frame after the one that raised
        summary = scan.summary()
        assert summary.cancelled and summary.frames == 2 and summary.fused == 2
        assert not scan.running
        with pytest.raises(slscan.CancelledError):  # a cancel is final
            scan.run_recording(recording)


def test_cancel_from_the_callback(context: slscan.Context, recording: pathlib.Path, tmp_path: pathlib.Path):
    with slscan.Scan(context, use_turntable_prior=True) as scan:
        busy: List[slscan.Error] = []

        def on_frame(report: slscan.FrameReport) -> None:
            try:
                scan.summary()  # every call but cancel() is refused during a run
            except slscan.BusyError as error:
                busy.append(error)
            scan.cancel()

        with pytest.raises(slscan.CancelledError) as cancelled:
            scan.run_recording(recording, on_frame=on_frame)
        assert cancelled.value.function == "sls_scan_run_recording"
        assert len(busy) == 1 and busy[0].function == "sls_scan_get_summary"
        assert scan.summary().frames == 1
        scan.write_cloud(tmp_path / "partial.ply")  # the model keeps what was fused


def test_ctrl_c_cancels_the_run(context: slscan.Context, recording: pathlib.Path):
    with slscan.Scan(context, use_turntable_prior=True) as scan:
        seen: List[int] = []

        def on_frame(report: slscan.FrameReport) -> None:
            seen.append(report.index)
            if report.index == 0:
                os.kill(os.getpid(), signal.SIGINT)  # as Ctrl-C: handled by the waiting thread

        with pytest.raises(KeyboardInterrupt):
            scan.run_recording(recording, on_frame=on_frame)
        assert scan.summary().cancelled and len(seen) < 4


def test_bad_input_raises_the_c_status(context: slscan.Context, recording: pathlib.Path, tmp_path: pathlib.Path):
    with pytest.raises(slscan.InvalidArgumentError) as bad_value:
        slscan.Scan(context, voxel_size_m=-1.0)
    assert bad_value.value.function == "sls_scan_create" and "voxel_size_m" in bad_value.value.message
    with pytest.raises(slscan.InvalidArgumentError, match="volume_size_m"):
        slscan.Scan(context, volume_size_m=(0.1, 0.0, 0.1))
    with pytest.raises(TypeError, match="unknown config voxel_size"):
        slscan.Scan(context, voxel_size=1e-4)
    with pytest.raises(ValueError, match="fusion: 'marching'"):
        slscan.Scan(context, fusion="marching")
    with slscan.Scan(context) as scan:
        missing = tmp_path / "no-such-recording"
        with pytest.raises(slscan.NotFoundError) as not_found:
            scan.run_recording(missing)
        assert not_found.value.status == slscan.Status.NOT_FOUND
        assert not_found.value.function == "sls_scan_run_recording" and str(missing) in not_found.value.message
        corrupt = tmp_path / "corrupt"
        corrupt.mkdir()
        (corrupt / "manifest.json").write_text("{ not json")
        with pytest.raises(slscan.FormatError):
            scan.run_recording(corrupt)
        with pytest.raises(slscan.InvalidArgumentError) as no_loop:
            scan.close_loop()
        assert no_loop.value.function == "sls_scan_close_loop"
        with pytest.raises(slscan.InvalidArgumentError) as nothing_fused:
            scan.write_mesh(tmp_path / "mesh.ply")
        assert nothing_fused.value.function == "sls_scan_write_mesh"
        with pytest.raises(slscan.InvalidArgumentError, match="camera_uri|calibration"):
            scan.run_devices(camera="", projector="", calibration=recording / "calibration.yml",
                             recording=tmp_path / "captured")
        with pytest.raises(slscan.UnsupportedError, match="firewire"):
            scan.run_devices(camera="firewire://0", projector="firewire://0",
                             calibration=recording / "calibration.yml", recording=tmp_path / "captured2")
    # A newer recording format than the library reads.
    newer = tmp_path / "newer"
    newer.mkdir()
    manifest = json.loads((recording / "manifest.json").read_text())
    manifest["format_version"] = 99
    (newer / "manifest.json").write_text(json.dumps(manifest))
    with slscan.Scan(context) as scan, pytest.raises(slscan.VersionMismatchError):
        scan.run_recording(newer)


def test_every_config_field_round_trips(context: slscan.Context, recording: pathlib.Path):
    """Every sls_scan_config field by keyword (enums by value or by their `sls scan` spelling)
    or in a ScanConfig, and read back resolved; the unset ones keep the library's defaults."""
    defaults = slscan.Scan(context).config
    assert defaults == slscan.ScanConfig(
        fusion=slscan.FusionMethod.GTSDF, use_turntable_prior=False, voxel_size_m=0.0, volume_size_m=(0.0, 0.0, 0.0),
        max_voxels=0.0, online_deformation=True, calibration_path=None, gtsdf_lambda=0.0, gtsdf_kappa=0.0,
        gtsdf_penalty=slscan.GtsdfPenalty.DEFAULT, gtsdf_iterations=0, poses=slscan.PoseSource.TRACK, loop_frames=2,
        photometric_weight=0.0, icp_crease_deg=15.0, icp_weights=slscan.IcpWeights.CONFIDENCE,
        loop_closure=slscan.LoopClosureMode.CALLER, max_gpu_bytes=0.0, revisits=slscan.RevisitPolicy.AUTO,
        no_record=False)
    given = dict(fusion="gtsdf", use_turntable_prior=True, voxel_size_m=2e-4, volume_size_m=(0.03, 0.04, 0.05),
                 max_voxels=2e6, online_deformation=False, calibration_path=str(recording / "calibration.yml"),
                 gtsdf_lambda=2.5, gtsdf_kappa=0.07, gtsdf_penalty="charbonnier", gtsdf_iterations=5,
                 poses="groundtruth", loop_frames=4, photometric_weight=0.5, icp_crease_deg=30.0,
                 icp_weights="equal", loop_closure="auto", max_gpu_bytes=6e9, revisits="merge",
                 no_record=False)  # True is refused with known poses (test_no_record_...)
    assert set(given) == {field.name for field in dataclasses.fields(slscan.ScanConfig)}
    expected = dict(given, fusion=slscan.FusionMethod.GTSDF, gtsdf_penalty=slscan.GtsdfPenalty.CHARBONNIER,
                    poses=slscan.PoseSource.GROUNDTRUTH, icp_weights=slscan.IcpWeights.EQUAL,
                    loop_closure=slscan.LoopClosureMode.AUTO, revisits=slscan.RevisitPolicy.MERGE)
    with slscan.Scan(context, **given) as scan:
        assert dataclasses.asdict(scan.config) == expected
    with slscan.Scan(context, slscan.ScanConfig(**given), loop_frames=7) as scan:
        assert scan.config.loop_frames == 7 and scan.config.poses == slscan.PoseSource.GROUNDTRUTH


def test_no_record_fuses_the_capture_and_writes_nothing(context: slscan.Context, recording: pathlib.Path,
                                                        tmp_path: pathlib.Path):
    """no_record=True (`sls scan --no-record`): run_devices fuses the capture with no recording,
    and the model is the recorded run's; refused with known poses or a recording path."""
    uri = "sim://knurled-screw?preset=ci"
    calibration = recording / "calibration.yml"
    with slscan.Scan(context) as scan:
        scan.run_devices(camera=uri, projector=uri, calibration=calibration, recording=tmp_path / "recorded")
        scan.write_cloud(tmp_path / "recorded.ply")
    with slscan.Scan(context, no_record=True) as scan:
        assert scan.config.no_record is True
        summary = scan.run_devices(camera=uri, projector=uri, calibration=calibration, recording=None)
        assert summary.fused == 1
        scan.write_cloud(tmp_path / "unrecorded.ply")
        with pytest.raises(slscan.InvalidArgumentError, match="no_record"):
            scan.run_devices(camera=uri, projector=uri, calibration=calibration, recording=tmp_path / "refused")
    assert (tmp_path / "recorded.ply").read_bytes() == (tmp_path / "unrecorded.ply").read_bytes()
    assert sorted(path.name for path in tmp_path.iterdir()) == ["recorded", "recorded.ply", "unrecorded.ply"]
    with pytest.raises(slscan.InvalidArgumentError, match="no_record"):
        slscan.Scan(context, no_record=True, poses="groundtruth")


def test_bad_config_values_name_the_field(context: slscan.Context):
    for field, value in (("gtsdf_lambda", 1e4), ("gtsdf_kappa", -1.0), ("gtsdf_iterations", 101), ("loop_frames", 0),
                         ("photometric_weight", -1.0), ("icp_crease_deg", 180.0), ("max_gpu_bytes", -1.0)):
        with pytest.raises(slscan.InvalidArgumentError, match=f"config.{field}"):
            slscan.Scan(context, **{field: value})
    with pytest.raises(slscan.InvalidArgumentError, match="need SLS_FUSION_GTSDF"):
        slscan.Scan(context, fusion="tsdf", gtsdf_penalty="perona-malik")
    with pytest.raises(slscan.NotFoundError, match="no-such.yml"):
        slscan.Scan(context, calibration_path="no-such.yml")
    with pytest.raises(ValueError, match="icp_weights: 'median'"):
        slscan.Scan(context, icp_weights="median")
    with pytest.raises(ValueError, match="loop_frames"):
        slscan.Scan(context, loop_frames=2.5)


def test_known_poses_give_the_ground_truth_trajectory(context: slscan.Context, recording: pathlib.Path):
    """poses="groundtruth" reaches the run (`sls scan --poses groundtruth`): the trajectory is the
    simulated recording's own, in one fixed volume."""
    with slscan.Scan(context, poses="groundtruth", max_voxels=2e6) as scan:
        summary = scan.run_recording(recording)
        assert summary.fused == 4 and summary.volume_moves == 0
        _, poses = scan.trajectory()
    truth = [line.split() for line in (recording / "groundtruth" / "trajectory.txt").read_text().splitlines()
             if line and not line.startswith("#")]
    assert len(truth) == len(poses) == 4
    for pose, row in zip(poses, truth):
        assert np.allclose(pose[:3, 3], [float(v) for v in row[1:4]], atol=1e-6)
