"""The calibration capture through the Python package (sls_calibration_capture.h) on the
simulated head with its simulated operator, 64-pixel-wide images (each capture well under a
second): the poses confirmed, skipped and stopped, the progress, an exception in a callback
stopping the capture cleanly and raised again, a cancel and a resume, and the mistakes. The
README's example (capture and calibration) is test_readme.py's."""
from __future__ import annotations

import json
import pathlib
from typing import Iterator, List, Tuple

import pytest

import slscan


def head_uri(hand_poses: int) -> str:
    return f"sim://chessboard?calibration=1&preset=ci&width=64&hand_poses={hand_poses}&head=chessboard"


Head = Tuple[slscan.Camera, slscan.Projector, slscan.Turntable]


@pytest.fixture
def head(context: slscan.Context) -> Iterator[Head]:
    uri = head_uri(3)
    with slscan.Projector(uri, context) as projector, slscan.Camera(uri, context) as camera, \
            slscan.Turntable(uri, context) as turntable:
        yield camera, projector, turntable


def frames(folder: pathlib.Path) -> list:
    return json.loads((folder / "manifest.json").read_text())["frames"]


def test_poses_confirmed_skipped_and_stopped(head: Head, tmp_path: pathlib.Path):
    camera, projector, turntable = head
    asked: List[slscan.CalibrationPose] = []
    seen: List[slscan.CalibrationProgress] = []

    def confirm(pose: slscan.CalibrationPose):
        asked.append(pose)
        if pose.kind == slscan.CalibrationPoseKind.HAND and pose.index == 1:
            return "skip"
        if pose.kind == slscan.CalibrationPoseKind.TURNTABLE and pose.index == 1:
            return slscan.PoseDecision.STOP
        return None  # capture

    result = slscan.capture_calibration(camera, projector, tmp_path / "rec", turntable=turntable, hand_poses=3,
                                        turntable_angles_deg=(350, 10), confirm=confirm, progress=seen.append)
    assert [pose.description for pose in asked] == ["hand pose 1 of 3", "hand pose 2 of 3", "hand pose 3 of 3",
                                                    "turntable pose 1 of 2 (350.000 deg)",
                                                    "turntable pose 2 of 2 (10.000 deg)"]
    assert asked[3].kind == slscan.CalibrationPoseKind.TURNTABLE and asked[3].turntable_angle_deg == 350.0
    assert (result.poses_captured, result.poses_skipped, result.stopped) == (3, 1, True)
    assert (result.frames, result.hand_frames, result.turntable_frames, result.images_per_frame) == (3, 2, 1, 42)
    assert result.cameras == 1
    assert result.seconds >= result.capture_seconds > 0
    assert [(p.stage, p.done, p.total) for p in seen] == [("calibration capture", n, 5) for n in range(1, 5)]
    assert seen[1].detail == "hand pose 2 of 3 skipped"
    angles = [frame["turntable_angle_deg"] for frame in frames(tmp_path / "rec")]
    assert angles[:2] == [None, None] and angles[2] == pytest.approx(350.0, abs=0.1)


def test_an_exception_in_a_callback_stops_cleanly_and_is_raised(head: Head, tmp_path: pathlib.Path):
    camera, projector, _ = head

    def operator_leaves(pose: slscan.CalibrationPose):
        if pose.index == 1:
            raise RuntimeError(f"no one placed the board for {pose.description}")

    with pytest.raises(RuntimeError, match="no one placed the board for hand pose 2 of 3"):
        slscan.capture_calibration(camera, projector, tmp_path / "rec", hand_poses=3, confirm=operator_leaves)
    assert len(frames(tmp_path / "rec")) == 1  # the pose before it, in a valid recording

    def progress_fails(progress: slscan.CalibrationProgress):
        raise KeyError(progress.detail)

    with pytest.raises(KeyError, match="hand pose 1 of 3"):
        slscan.capture_calibration(camera, projector, tmp_path / "other", hand_poses=3, progress=progress_fails)
    assert len(frames(tmp_path / "other")) == 1

    # An answer that is no decision is a ValueError (or TypeError), raised the same way.
    with pytest.raises(ValueError, match="'maybe'"):
        slscan.capture_calibration(camera, projector, tmp_path / "maybe", hand_poses=1, confirm=lambda pose: "maybe")
    with pytest.raises(TypeError, match="confirm returned 1"):
        slscan.capture_calibration(camera, projector, tmp_path / "one", hand_poses=1, confirm=lambda pose: 1)


def test_a_cancel_keeps_the_recording_and_resume_completes_it(head: Head, tmp_path: pathlib.Path):
    camera, projector, turntable = head
    folder = tmp_path / "rec"
    with pytest.raises(slscan.CancelledError) as cancelled:
        slscan.capture_calibration(camera, projector, folder, turntable=turntable, hand_poses=3,
                                   turntable_angles_deg=[10.0], progress=lambda p: p.done < 2)
    assert cancelled.value.function == "sls_calibration_capture"
    assert "cancelled after hand pose 2 of 3" in cancelled.value.message
    assert len(frames(folder)) == 2
    with pytest.raises(slscan.InvalidArgumentError, match="set config.resume"):
        slscan.capture_calibration(camera, projector, folder, turntable=turntable, hand_poses=3)
    asked: List[str] = []
    result = slscan.capture_calibration(camera, projector, folder, turntable=turntable, hand_poses=3,
                                        turntable_angles_deg=[10.0], resume=True,
                                        confirm=lambda pose: asked.append(pose.description))
    assert asked == ["hand pose 3 of 3", "turntable pose 1 of 1 (10.000 deg)"]
    assert (result.resumed_from, result.poses_captured, result.frames) == (2, 2, 4)


def test_mistakes(head: Head, tmp_path: pathlib.Path):
    camera, projector, turntable = head
    with pytest.raises(slscan.InvalidArgumentError, match="turntable angle"):
        slscan.capture_calibration(camera, projector, tmp_path / "a", turntable_angles_deg=[10.0])
    with pytest.raises(slscan.InvalidArgumentError, match="-2 hand poses"):
        slscan.capture_calibration(camera, projector, tmp_path / "a", hand_poses=-2)
    with pytest.raises(slscan.InvalidArgumentError, match="no-such-set"):
        slscan.capture_calibration(camera, projector, tmp_path / "a", hand_poses=1, pattern_set="no-such-set")
    with pytest.raises(slscan.InvalidArgumentError, match="holds no recording to continue"):
        slscan.capture_calibration(camera, projector, tmp_path / "a", hand_poses=1, resume=True)
    assert not (tmp_path / "a").exists()
    turntable.close()
    with pytest.raises(slscan.InvalidArgumentError, match="closed"):
        slscan.capture_calibration(camera, projector, tmp_path / "a", turntable=turntable)


def test_a_head_of_two_cameras_is_captured_together_and_resumed(context: slscan.Context, tmp_path: pathlib.Path):
    # Cameras 0 and 1 of one simulated head (cameras=2&camera=K): every pose taken by both, one
    # recording each in folder/camera0 and camera1; a cancel and a resume continue both.
    uri = f"{head_uri(3)}&cameras=2"
    folder = tmp_path / "head"
    with slscan.Projector(uri, context) as projector, slscan.Camera(f"{uri}&camera=0", context) as first, \
            slscan.Camera(f"{uri}&camera=1", context) as second:
        with pytest.raises(slscan.CancelledError, match="cancelled after hand pose 2 of 3"):
            slscan.capture_calibration(first, projector, folder, hand_poses=3, more_cameras=[second],
                                       progress=lambda p: p.done < 2)
        assert [len(frames(folder / f"camera{k}")) for k in range(2)] == [2, 2]
        result = slscan.capture_calibration(first, projector, folder, hand_poses=3, more_cameras=[second],
                                            resume=True)
        assert (result.cameras, result.resumed_from, result.poses_captured, result.frames) == (2, 2, 1, 3)
        assert [len(frames(folder / f"camera{k}")) for k in range(2)] == [3, 3]
        infos = [json.loads((folder / f"camera{k}" / "manifest.json").read_text())["device"] for k in range(2)]
        # Each recording names the head's projector, and its own camera by serial.
        assert infos[0]["uri"] == infos[1]["uri"] == projector.info.uri
        assert [info["serial"] for info in infos] == ["SIM-CAM-0", "SIM-CAM-1"]
        with pytest.raises(slscan.InvalidArgumentError, match="is camera 0 of the head again"):
            slscan.capture_calibration(first, projector, tmp_path / "x", hand_poses=1, more_cameras=[first])
