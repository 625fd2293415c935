#!/usr/bin/env python3
"""Drives `sls sim`, `sls decode` and `sls eval` as a user would: recordings with their ground
truth (pattern stacks, depth mode, projector gamma, calibration captures, a two-camera head
calibrated), decoding against the ground truth and its bad input, and evaluating a result
(the model as tracked side by side). Usage: test_sls_sim_decode_eval.py PATH_TO_SLS [TEST...]
(stdlib only)."""
import json
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile
import unittest

SLS = None


def run(*args):
    return subprocess.run([SLS, *args], capture_output=True, text=True, timeout=120)


class SlsSimDecodeEval(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.dir = pathlib.Path(self.tmp.name)

    def tearDown(self):
        self.tmp.cleanup()

    def test_sim_writes_recording_with_ground_truth(self):
        out = self.dir / "rec"
        result = run("--json", "sim", "--preset", "ci", "--object", "knurled-knob", "--frames", "3",
                     "--device", "cpu", "--out", str(out))
        self.assertEqual(result.returncode, 0, result.stderr)
        summary = json.loads(result.stdout)
        self.assertEqual(summary["frames"], 3)
        self.assertEqual(summary["images_per_frame"], 22)
        inspect = json.loads(run("--json", "inspect", "--deep", str(out), str(out / "groundtruth/reference.ply"),
                                 str(out / "groundtruth/trajectory.txt"), str(out / "calibration.yml")).stdout)
        self.assertTrue(inspect["ok"], inspect)
        recording, reference, trajectory, calibration = inspect["results"]
        self.assertTrue(recording["groundtruth"])
        self.assertEqual(recording["frames_with_turntable_angle"], 3)
        self.assertGreater(reference["points"], 10000)
        self.assertEqual(trajectory["poses"], 3)
        self.assertAlmostEqual(calibration["projector_angle_deg"], 25.0, places=6)
        for name in ("depth.pfm", "projector_u.pfm", "projector_v.pfm", "valid.png", "depth_sigma.pfm"):
            self.assertTrue((out / "groundtruth/frames/000002" / name).exists(), name)
        # A second run into the same folder refuses instead of mixing two scans.
        again = run("sim", "--preset", "ci", "--frames", "1", "--device", "cpu", "--out", str(out))
        self.assertEqual(again.returncode, 1)
        self.assertIn(str(out), again.stderr)

    def test_sim_calibration_capture(self):
        out = self.dir / "calib"
        result = run("--json", "sim", "--calibration", "--preset", "ci", "--hand-poses", "3", "--turntable-poses", "2",
                     "--device", "cpu", "--out", str(out))
        self.assertEqual(result.returncode, 0, result.stderr)
        summary = json.loads(result.stdout)
        self.assertTrue(summary["calibration"])
        self.assertEqual((summary["hand_poses"], summary["turntable_poses"], summary["frames"]), (3, 2, 5))
        self.assertEqual(summary["object"], "chessboard")
        self.assertEqual(summary["head_object"], "knurled-screw")  # the head as set up for the demo's object
        self.assertEqual(summary["images_per_frame"], 42)  # projector columns and rows
        truth = out / "groundtruth"
        inspect = json.loads(run("--json", "inspect", "--deep", str(out), str(truth / "calibration.yml"),
                                 str(truth / "board_poses.txt")).stdout)
        self.assertTrue(inspect["ok"], inspect)
        recording, calibration, poses = inspect["results"]
        # Made uncalibrated, as a calibration capture is; the exact calibration is the truth.
        self.assertFalse(recording["calibrated"])
        self.assertFalse((out / "calibration.yml").exists())
        self.assertEqual(recording["frames"], 5)
        self.assertEqual(recording["frames_with_turntable_angle"], 2)
        self.assertAlmostEqual(calibration["projector_angle_deg"], 25.0, places=6)
        self.assertEqual(poses["poses"], 5)
        capture = json.load(open(truth / "capture.json"))
        self.assertEqual([f["kind"] for f in capture["frames"]], ["hand"] * 3 + ["turntable"] * 2)
        board = json.load(open(truth / "board.json"))
        self.assertEqual(board["inner_corners"], [9, 7])
        corners = json.load(open(truth / "frames/000004/corners.json"))
        self.assertEqual((len(corners["camera_px"]), len(corners["projector_px"])), (63, 63))
        for name in ("rig.json", "scene.json"):
            self.assertTrue((truth / name).exists(), name)
        # The scan's own options do not apply to a calibration capture; its own need it.
        for args in (("--mode", "depth"), ("--frames", "4"), ("--mount-tilt-deg", "0"),
                     ("--mount-offset-um", "0"), ("--reference-spacing-um", "100")):
            bad = run("sim", "--calibration", *args, "--out", str(self.dir / "bad"))
            self.assertEqual(bad.returncode, 2, args)
            self.assertIn("--calibration", bad.stderr)
        for option in ("--hand-poses", "--turntable-poses"):
            bad = run("sim", option, "3", "--out", str(self.dir / "bad"))
            self.assertEqual(bad.returncode, 2, option)
            self.assertIn("--calibration", bad.stderr)
        self.assertFalse((self.dir / "bad").exists())
        help_text = run("sim", "--help").stdout
        for option in ("--calibration", "--hand-poses", "--turntable-poses"):
            self.assertIn(option, help_text)

    def test_sim_and_calibrate_a_two_camera_head(self):
        # --cameras 2: one recording per camera (camera0, camera1: the same board poses), the
        # head's exact calibration in groundtruth/; `sls calibrate --input` on that folder
        # calibrates each camera against the projector and the cameras against each other.
        head = self.dir / "head"
        result = run("--json", "sim", "--calibration", "--cameras", "2", "--preset", "ci", "--hand-poses", "3",
                     "--turntable-poses", "0", "--device", "cpu", "--out", str(head))
        self.assertEqual(result.returncode, 0, result.stderr)
        summary = json.loads(result.stdout)
        self.assertEqual(summary["cameras"], 2)
        self.assertEqual(summary["camera_recordings"], [str(head / "camera0"), str(head / "camera1")])
        self.assertEqual(summary["frames"], 3)
        truth_text = (head / "groundtruth/calibration.yml").read_text()
        self.assertIn("camera_count: 2\n", truth_text)
        self.assertIn("T_camera0_camera1: !!opencv-matrix", truth_text)
        for camera in ("camera0", "camera1"):
            inspect = json.loads(run("--json", "inspect", str(head / camera)).stdout)
            self.assertEqual(inspect["results"][0]["frames"], 3, camera)
            self.assertTrue((head / camera / "groundtruth/calibration.yml").exists(), camera)
        out = self.dir / "head.yml"
        result = run("--json", "calibrate", "--input", str(head), "--out", str(out), "--report", str(self.dir / "report"))
        if result.returncode == 3 and "without OpenCV" in result.stderr:
            self.skipTest("sls built without OpenCV: no calibration")
        self.assertEqual(result.returncode, 0, result.stderr)
        calibration = json.loads(result.stdout)
        self.assertEqual(calibration["camera_count"], 2)
        self.assertGreater(calibration["camera_camera_rms_px"], 0.0)
        self.assertLess(calibration["camera_camera_rms_px"], 0.5)
        cameras = calibration["cameras"]
        self.assertEqual([c["folder"] for c in cameras], [str(head / "camera0"), str(head / "camera1")])
        for camera in cameras:
            for key in ("camera_rms_px", "projector_rms_px", "stereo_rms_px"):
                self.assertGreater(camera[key], 0.0, key)
            for key in ("focal_rel_err", "principal_point_err_px"):
                self.assertIn(key, camera["truth"])
        self.assertNotIn("T_camera0_camera", cameras[0])
        pair = cameras[1]
        self.assertEqual(pair["camera_camera_views"], 3)
        self.assertAlmostEqual(pair["T_camera0_camera"]["rotation_deg"], 50.0, delta=2.0)
        for block in (pair["truth"]["camera_camera"], pair["truth"]["camera_camera"]["via_projector"]):
            self.assertIn("baseline_rel_err", block)
            self.assertIn("rotation_err_deg", block)
        text = out.read_text()
        self.assertIn("camera_count: 2\n", text)
        self.assertIn("camera1_matrix: !!opencv-matrix", text)
        self.assertTrue((self.dir / "report/calibration_report.html").exists())
        self.assertTrue((self.dir / "report/camera1/calibration_report.html").exists())
        inspected = json.loads(run("--json", "inspect", str(out)).stdout)
        self.assertTrue(inspected["ok"])
        self.assertEqual(inspected["results"][0]["camera_count"], 2)
        self.assertAlmostEqual(inspected["results"][0]["additional_cameras"][0]["angle_to_camera0_deg"], 50.0,
                               delta=2.0)
        # Bad layouts name the folder: a gap in the cameras, a camera with other poses, one camera.
        (head / "camera1").rename(head / "camera2")
        gap = run("calibrate", "--input", str(head), "--out", str(self.dir / "bad.yml"))
        self.assertEqual(gap.returncode, 1)
        self.assertIn(f"{head}/camera2 is there but {head}/camera1 is missing", gap.stderr)
        (head / "camera2").rename(head / "camera1")
        other = self.dir / "other"
        self.assertEqual(run("sim", "--calibration", "--preset", "ci", "--hand-poses", "2", "--turntable-poses", "0",
                             "--device", "cpu", "--out", str(other)).returncode, 0)
        (head / "camera1").rename(self.dir / "camera1-kept")
        other.rename(head / "camera1")
        mismatched = run("calibrate", "--input", str(head), "--out", str(self.dir / "bad.yml"))
        self.assertEqual(mismatched.returncode, 1)
        self.assertIn(f"{head}/camera1: 2 board poses, {head}/camera0 has 3", mismatched.stderr)
        shutil.rmtree(head / "camera1")
        alone = run("calibrate", "--input", str(head), "--out", str(self.dir / "bad.yml"))
        self.assertEqual(alone.returncode, 1)
        self.assertIn("only camera0", alone.stderr)
        self.assertFalse((self.dir / "bad.yml").exists())
        # --cameras belongs to --calibration, and the simulated head has places for 1 to 4.
        for args in (("--cameras", "2"), ("--calibration", "--cameras", "5"), ("--calibration", "--cameras", "0")):
            bad = run("sim", *args, "--out", str(self.dir / "bad"))
            self.assertEqual(bad.returncode, 2, args)
            self.assertIn("--cameras", bad.stderr)
        self.assertIn("--cameras", run("sim", "--help").stdout)

    def test_decode_reports_accuracy_against_ground_truth(self):
        rec, out = self.dir / "rec", self.dir / "decoded"
        self.assertEqual(run("sim", "--preset", "ci", "--frames", "2", "--device", "cpu", "--out", str(rec)).returncode, 0)
        result = run("--json", "decode", "--input", str(rec), "--out", str(out), "--device", "cpu")
        self.assertEqual(result.returncode, 0, result.stderr)
        summary = json.loads(result.stdout)
        self.assertEqual(summary["frames_decoded"], 2)
        report = json.load(open(out / "decode.json"))
        for key in ("projector_rms_px", "projector_max_px", "depth_rms_um", "valid_fraction"):
            self.assertIn(key, report)
        # Sanity bounds (the accuracy itself is tested in tests/unit/decode): no period jumps.
        self.assertLess(report["projector_max_px"], 8.0)
        self.assertGreater(report["valid_fraction"], 0.9)
        self.assertEqual(len(report["frames"]), 2)
        self.assertTrue((out / "frames/000001/depth.pfm").exists())
        cloud = json.loads(run("--json", "inspect", str(out / "frames/000001/cloud.ply")).stdout)["results"][0]
        self.assertTrue(cloud["normals"])
        self.assertGreater(cloud["points"], 50000)

    def test_sim_projector_gamma(self):
        # A projector with a display gamma: recorded in the rig, its phase images differ from a
        # linear projector's, and the 8-step phase shift still decodes them without jumps.
        images = {}
        for gamma in ("1", "2.2"):
            rec, out = self.dir / f"rec{gamma}", self.dir / f"dec{gamma}"
            result = run("sim", "--preset", "ci", "--object", "plane", "--frames", "1", "--device", "cpu",
                         "--no-noise", "--projector-gamma", gamma, "--out", str(rec))
            self.assertEqual(result.returncode, 0, result.stderr)
            self.assertEqual(json.loads((rec / "groundtruth" / "rig.json").read_text())["projector"]["gamma"],
                             float(gamma))
            frame = sorted((rec / "frames" / "000000").iterdir())
            images[gamma] = [f.read_bytes() for f in frame]
            self.assertEqual(run("decode", "--input", str(rec), "--out", str(out), "--no-clouds", "--device",
                                 "cpu").returncode, 0)
            report = json.loads((out / "decode.json").read_text())
            self.assertLess(report["projector_max_px"], 1.0)
            self.assertGreater(report["valid_fraction"], 0.95)
        # White, black and the Gray code (levels 0 and 255) stay; the phase-shift images change.
        same = sum(a == b for a, b in zip(images["1"], images["2.2"]))
        self.assertGreaterEqual(same, 2)
        self.assertLess(same, len(images["1"]))
        self.assertEqual(run("sim", "--preset", "ci", "--projector-gamma", "20", "--out",
                             str(self.dir / "bad")).returncode, 2)

    def test_decode_bad_input(self):
        depth = self.dir / "depth"
        self.assertEqual(run("sim", "--preset", "ci", "--mode", "depth", "--frames", "1", "--device", "cpu",
                             "--out", str(depth)).returncode, 0)
        result = run("decode", "--input", str(depth), "--out", str(self.dir / "o"))
        self.assertEqual(result.returncode, 1)
        self.assertIn("depth-only", result.stderr)
        missing = run("decode", "--input", str(self.dir / "nothing"), "--out", str(self.dir / "o2"))
        self.assertEqual(missing.returncode, 1)
        self.assertIn("nothing", missing.stderr)

    def test_sim_depth_mode(self):
        out = self.dir / "depth"
        result = run("sim", "--preset", "ci", "--mode", "depth", "--frames", "2", "--device", "cpu",
                     "--out", str(out))
        self.assertEqual(result.returncode, 0, result.stderr)
        recording = json.loads(run("--json", "inspect", "--deep", str(out)).stdout)["results"][0]
        self.assertEqual(recording["images_per_frame"], 0)
        self.assertEqual(recording["frames_with_depth"], 2)

    def test_eval_measures_a_result_against_the_ground_truth(self):
        rec = self.dir / "rec"
        self.assertEqual(run("sim", "--preset", "ci", "--mode", "depth", "--object", "sphere", "--frames", "4",
                             "--device", "cpu", "--out", str(rec)).returncode, 0)
        # The exact reference as the result: no error, and it covers everything the views saw.
        result = self.dir / "result"
        result.mkdir()
        (result / "cloud.ply").write_bytes((rec / "groundtruth/reference.ply").read_bytes())
        (result / "report.json").write_text(json.dumps({"voxel_size_m": 50e-6}))
        out = run("--json", "eval", "--result", str(result), "--truth", str(rec))
        self.assertEqual(out.returncode, 0, out.stderr)
        metrics = json.loads(out.stdout)
        self.assertTrue(metrics["ok"])
        for key in ("c2c_mean_um", "c2c_rms_um", "c2c_p95_um"):
            self.assertLess(metrics[key], 0.01, key)
        self.assertIsNone(metrics["c2c_edge_mean_um"])  # a sphere has no creases
        self.assertEqual(metrics["coverage"], 1.0)
        self.assertEqual(metrics["coverage_basis"], "visible")
        self.assertEqual(metrics["scene"], "sphere")
        # No trajectory.txt in the result: the trajectory keys are absent and a note says why.
        for key in ("ate_rmse_um", "loop_closure_error_um", "loop_closure_error_deg"):
            self.assertNotIn(key, metrics)
        self.assertIn("trajectory.txt", metrics["trajectory_note"])
        human = run("eval", "--result", str(result), "--truth", str(rec))
        self.assertEqual(human.returncode, 0, human.stderr)
        self.assertIn("c2c: mean", human.stdout)
        self.assertIn("coverage: 1.0000", human.stdout)
        self.assertIn("trajectory: n/a", human.stdout)
        # Without report.json the voxel size must be given.
        (result / "report.json").unlink()
        missing_voxel = run("eval", "--result", str(result), "--truth", str(rec))
        self.assertEqual(missing_voxel.returncode, 1)
        self.assertIn("--voxel-um", missing_voxel.stderr)
        self.assertEqual(run("eval", "--result", str(result), "--truth", str(rec), "--voxel-um", "50").returncode, 0)
        # A result without a cloud, a recording without ground truth: exit 1, naming the problem.
        empty = self.dir / "empty"
        empty.mkdir()
        no_cloud = run("--json", "eval", "--result", str(empty), "--truth", str(rec))
        self.assertEqual(no_cloud.returncode, 1)
        self.assertIn("cloud.ply", no_cloud.stderr)
        self.assertFalse(json.loads(no_cloud.stdout)["ok"])
        for path in sorted((rec / "groundtruth").rglob("*"), reverse=True):
            path.rmdir() if path.is_dir() else path.unlink()
        (rec / "groundtruth").rmdir()
        no_truth = run("eval", "--result", str(result), "--truth", str(rec), "--voxel-um", "50")
        self.assertEqual(no_truth.returncode, 1)
        self.assertIn("groundtruth", no_truth.stderr)

if __name__ == "__main__":
    SLS = os.path.abspath(sys.argv.pop(1))
    unittest.main(verbosity=2)
