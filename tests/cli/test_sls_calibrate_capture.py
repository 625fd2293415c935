#!/usr/bin/env python3
"""`sls calibrate --camera ...` as an operator drives it: the board views captured through
devices by URI (the simulator's calibration target, whose simulated operator places the board
at each pose), each hand pose confirmed on stdin (Enter, s to skip, q to stop), then calibrated
from the recording; --yes asks nothing; SIGINT at a prompt keeps the recording (exit 4); usage
errors. Usage: test_sls_calibrate_capture.py PATH_TO_SLS (stdlib only)."""
import json
import math
import os
import pathlib
import select
import signal
import subprocess
import sys
import tempfile
import time
import unittest

SLS = None
TARGET = "sim://chessboard?calibration=1&preset=ci&hand_poses={}&head=chessboard{}"


def run(*args, answers=None):
    return subprocess.run([SLS, *args], input=answers, capture_output=True, text=True, timeout=600)


def devices(hand_poses, turntable=True, extra=""):
    uri = TARGET.format(hand_poses, extra)
    args = ["--camera", uri, "--projector", uri]
    return args + (["--turntable", uri] if turntable else [])


def manifest(folder):
    return json.loads((folder / "manifest.json").read_text())


class SlsCalibrateCapture(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.dir = pathlib.Path(self.tmp.name)

    def tearDown(self):
        self.tmp.cleanup()

    def board_args(self, name):
        return ["--board", "9x7", "--square", "0.0006", "--out", str(self.dir / name / "calibration.yml")]

    def test_confirmed_poses_captured_then_calibrated(self):
        record = self.dir / "record"
        # Five hand poses, the third skipped; then the board onto the table (one answer), three angles.
        result = run("--json", "calibrate", *devices(5), "--record", str(record), "--hand-poses", "5",
                     "--turntable-angles", "320,0,40", *self.board_args("head"), answers="\n\ns\n\n\n\n")
        self.assertEqual(result.returncode, 0, result.stderr)
        for pose in range(1, 6):
            self.assertIn(f"Place the board for pose {pose} of 5 and press Enter (s: skip this pose, q: stop "
                          "capturing)", result.stderr)
        self.assertIn("Fix the board on the turntable for the 3 turntable pose(s)", result.stderr)
        figures = json.loads(result.stdout)
        self.assertTrue(figures["ok"] and figures["written"])
        capture = figures["capture"]
        self.assertEqual((capture["frames"], capture["hand_frames"], capture["turntable_frames"]), (7, 4, 3))
        self.assertEqual((capture["poses_captured"], capture["poses_skipped"], capture["stopped"]), (7, 1, False))
        self.assertEqual(capture["images_per_frame"], 42)
        self.assertEqual([p["captured"] for p in capture["poses"]], [True, True, False] + [True] * 5)
        self.assertEqual(capture["poses"][2]["pose"], "hand pose 3 of 5")
        self.assertGreater(capture["seconds_per_pose"], 0.0)
        # An ordinary recording, uncalibrated: angles null by hand, the table's reading on it.
        frames = manifest(record)["frames"]
        self.assertEqual(len(frames), 7)
        self.assertFalse((record / "calibration.yml").exists())
        angles = [f["turntable_angle_deg"] for f in frames]
        self.assertEqual(angles[:4], [None] * 4)
        for angle, commanded in zip(angles[4:], (320.0, 0.0, 40.0)):
            self.assertAlmostEqual(angle, commanded, delta=360.0 / 6400)
        # Calibrated from it as --input would: the figures, every view used, the axis.
        for key in ("camera_rms_px", "projector_rms_px", "stereo_rms_px"):
            self.assertLess(figures[key], 0.5, key)
        self.assertEqual(figures["views_used"], [f"frame {i}" for i in range(7)])
        self.assertTrue(figures["turntable_axis"]["fitted"])
        self.assertEqual(figures["turntable_axis"]["views"], 3)
        # Captured through simulated devices: the recording carries the exact calibration (as
        # `sls sim --calibration` writes it), so the truth is reported.
        self.assertTrue((record / "groundtruth" / "calibration.yml").exists())
        truth = figures["truth"]
        print(f"\ncaptured through sim:// against its truth: {json.dumps(truth)}")
        for key in ("focal_rel_err", "principal_point_err_px", "baseline_rel_err", "rotation_err_deg"):
            self.assertIn(key, truth)
            self.assertTrue(math.isfinite(truth[key]) and truth[key] >= 0.0, key)
        self.assertLess(truth["focal_rel_err"], 0.1)
        self.assertLess(truth["baseline_rel_err"], 0.1)
        self.assertLess(truth["rotation_err_deg"], 3.0)
        text = (self.dir / "head" / "calibration.yml").read_text()
        for key in ("camera_matrix", "projector_matrix", "T_camera_projector", "turntable_axis_direction",
                    "reprojection_rms_px", "calibrated_utc"):
            self.assertIn(key, text)
        again = run("--json", "calibrate", "--input", str(record), *self.board_args("again"))
        self.assertEqual(json.loads(again.stdout)["stereo_rms_px"], figures["stereo_rms_px"])

    def test_q_stops_the_capture_and_calibrates_the_poses_kept(self):
        record = self.dir / "record"
        result = run("calibrate", *devices(6), "--record", str(record), "--hand-poses", "6",
                     "--turntable-angles", "0,10", *self.board_args("head"), answers="\n\n\nq\n")
        self.assertEqual(result.returncode, 0, result.stderr)
        self.assertIn("Place the board for pose 4 of 6", result.stderr)
        self.assertNotIn("pose 5 of 6", result.stderr)
        self.assertNotIn("Fix the board on the turntable", result.stderr)
        self.assertIn("captured 3 frame(s) (3 by hand, 0 on the turntable; 0 pose(s) skipped, stopped by the operator)",
                      result.stderr)
        self.assertEqual(len(manifest(record)["frames"]), 3)
        self.assertIn("calibrated from 3 of 3 views", result.stdout)
        self.assertTrue((self.dir / "head" / "calibration.yml").exists())

    def test_yes_asks_nothing_and_a_failed_calibration_keeps_the_recording(self):
        # 64 pixels wide: captured quickly, too small for the board to be found.
        record = self.dir / "record"
        result = run("calibrate", *devices(2, turntable=False, extra="&width=64"), "--record", str(record),
                     "--hand-poses", "2", "--yes", *self.board_args("head"), answers="")
        self.assertEqual(result.returncode, 1)
        self.assertNotIn("Place the board", result.stderr)
        self.assertIn("captured 2 frame(s)", result.stderr)
        self.assertEqual(len(manifest(record)["frames"]), 2)
        self.assertFalse((self.dir / "head" / "calibration.yml").exists())
        # Stdin ends before a pose is confirmed: an error naming the pose, the poses before it kept.
        ended = run("calibrate", *devices(2, turntable=False, extra="&width=64"), "--record", str(self.dir / "ended"),
                    "--hand-poses", "2", *self.board_args("x"), answers="\n")
        self.assertEqual(ended.returncode, 1)
        self.assertIn("no answer for hand pose 2 of 2: stdin ended (--yes captures every pose without asking)",
                      ended.stderr)
        self.assertIn("--resume", ended.stderr)
        self.assertEqual(len(manifest(self.dir / "ended")["frames"]), 1)

    def test_sigint_at_a_prompt_keeps_the_recording(self):
        record = self.dir / "record"
        process = subprocess.Popen([SLS, "--json", "calibrate", *devices(3, extra="&width=64"), "--record",
                                    str(record), "--hand-poses", "3", *self.board_args("head")],
                                   stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        stderr = b""
        answered = False
        deadline = time.monotonic() + 120
        while b"pose 2 of 3" not in stderr and time.monotonic() < deadline:
            if b"pose 1 of 3" in stderr and not answered:  # pose 1 confirmed, then the prompt of pose 2 waits
                process.stdin.write(b"\n")
                process.stdin.flush()
                answered = True
            ready, _, _ = select.select([process.stderr], [], [], 1.0)
            if ready:
                chunk = os.read(process.stderr.fileno(), 4096)
                if not chunk:
                    break
                stderr += chunk
        self.assertIn(b"pose 2 of 3", stderr)
        process.send_signal(signal.SIGINT)
        stdout, rest = process.communicate(timeout=60)
        stderr += rest
        self.assertEqual(process.returncode, 4, stderr.decode())
        self.assertIn(b"interrupted by SIGINT during the calibration capture: 1 pose(s) captured", stderr)
        self.assertIn(b"--resume", stderr)
        report = json.loads(stdout)
        self.assertEqual((report["interrupted"], report["stage"], report["frames_captured"]), (True, "capture", 1))
        self.assertEqual(len(manifest(record)["frames"]), 1)

    def test_usage_errors(self):
        record = str(self.dir / "record")
        uri = TARGET.format(3, "")
        for args in (["--camera", uri, "--record", record],  # no projector
                     ["--camera", uri, "--projector", uri, "--record", record, "--input", record],
                     ["--camera", uri, "--projector", uri],  # no record
                     ["--camera", uri, "--projector", uri, "--record", record, "--turntable-angles", "10"],
                     ["--camera", uri, "--projector", uri, "--turntable", uri, "--record", record,
                      "--turntable-angles", "360"],
                     ["--projector", uri, "--input", record],
                     ["--yes", "--input", record],
                     []):
            result = run("calibrate", *args, *self.board_args("head"))
            self.assertEqual(result.returncode, 2, (args, result.stderr))
        no_board = run("calibrate", "--camera", uri, "--projector", uri, "--record", record, "--out", "c.yml")
        self.assertEqual(no_board.returncode, 2)
        self.assertIn("--board", no_board.stderr)
        (self.dir / "full").mkdir()
        (self.dir / "full" / "something").write_text("x")
        full = run("calibrate", *devices(3), "--record", str(self.dir / "full"), *self.board_args("head"))
        self.assertEqual(full.returncode, 1)
        self.assertIn("is not empty", full.stderr)
        nothing = run("calibrate", *devices(3), "--record", record, "--resume", *self.board_args("head"))
        self.assertEqual(nothing.returncode, 1)
        self.assertIn("holds no recording", nothing.stderr)
        help_text = run("calibrate", "--help").stdout
        for flag in ("--camera", "--projector", "--turntable", "--record", "--hand-poses", "--turntable-angles",
                     "--yes", "--resume", "--exposure-us", "Place the board for pose"):
            self.assertIn(flag, help_text)


if __name__ == "__main__":
    SLS = sys.argv[1]
    unittest.main(argv=sys.argv[:1])
