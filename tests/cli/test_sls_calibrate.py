#!/usr/bin/env python3
"""`sls calibrate` as a user drives it: every documented flag exists; the real procam
captures (a folder of captures, OpenCV's Gray-code order) calibrate to issue 17's RMS targets
with the figures in --json and the report; a calibration above --max-rms-px is written only
with --force and says so; bad input names the problem. Usage: test_sls_calibrate.py
PATH_TO_SLS PATH_TO_PROCAM_DATA (stdlib only)."""
import json
import pathlib
import subprocess
import sys
import tempfile
import unittest

SLS = None
PROCAM = None


def run(*args):
    return subprocess.run([SLS, *args], capture_output=True, text=True, timeout=600)


def procam_args(out):
    return ["calibrate", "--input", PROCAM, "--patterns", "opencv-graycode:1024x768", "--board", "9x7",
            "--square", "0.075", "--out", str(out)]


class SlsCalibrate(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.dir = pathlib.Path(self.tmp.name)

    def tearDown(self):
        self.tmp.cleanup()

    def test_help_documents_every_flag(self):
        self.assertIn("calibrate", run("--help").stdout)
        help_text = run("calibrate", "--help").stdout
        for flag in ("--input", "--out", "--patterns", "--board", "--square", "--report", "--max-rms-px", "--force",
                     "--estimate-k3", "--device", "opencv-graycode:WxH"):
            self.assertIn(flag, help_text)

    def test_real_captures_calibrate_with_figures_and_report(self):
        out = self.dir / "head" / "calibration.yml"
        result = run("--json", *procam_args(out), "--report", str(self.dir / "report"))
        self.assertEqual(result.returncode, 0, result.stderr)
        figures = json.loads(result.stdout)
        self.assertTrue(figures["ok"])
        self.assertTrue(figures["written"])
        self.assertLessEqual(figures["camera_rms_px"], 0.25)
        self.assertLessEqual(figures["projector_rms_px"], 0.5)
        self.assertLessEqual(figures["stereo_rms_px"], 0.5)
        self.assertEqual(figures["views_used"], ["capture_0", "capture_1", "capture_2", "capture_3", "capture_4"])
        self.assertEqual([v["name"] for v in figures["views_rejected"]], ["graycode_pattern"])
        self.assertIn("1024x768", figures["views_rejected"][0]["reason"])
        self.assertNotIn("truth", figures)  # real data: no exact calibration
        text = out.read_text()
        for key in ("camera_matrix", "projector_matrix", "T_camera_projector", "reprojection_rms_px", "camera_rms_px",
                    "projector_rms_px", "calibrated_utc"):
            self.assertIn(key, text)
        html = (self.dir / "report" / "calibration_report.html").read_text()
        self.assertIn("<svg", html)
        self.assertIn("graycode_pattern", html)
        self.assertEqual(json.loads((self.dir / "report" / "calibration.json").read_text())["stereo_rms_px"],
                         figures["stereo_rms_px"])

    def test_rms_above_the_limit_needs_force(self):
        out = self.dir / "calibration.yml"
        refused = run(*procam_args(out), "--max-rms-px", "0.01")
        self.assertEqual(refused.returncode, 1)
        self.assertIn("not written (--force writes it)", refused.stderr)
        self.assertFalse(out.exists())
        forced = run(*procam_args(out), "--max-rms-px", "0.01", "--force")
        self.assertEqual(forced.returncode, 0, forced.stderr)
        self.assertIn("written anyway (--force)", forced.stdout)
        self.assertTrue(out.exists())

    def test_bad_input_names_the_problem(self):
        missing = run("calibrate", "--input", str(self.dir / "nothing"), "--out", str(self.dir / "c.yml"))
        self.assertEqual(missing.returncode, 1)
        self.assertIn("nothing", missing.stderr)
        no_patterns = run("calibrate", "--input", PROCAM, "--board", "9x7", "--square", "0.075", "--out",
                          str(self.dir / "c.yml"))
        self.assertEqual(no_patterns.returncode, 1)
        self.assertIn("--patterns", no_patterns.stderr)
        no_square = run("calibrate", "--input", PROCAM, "--patterns", "opencv-graycode:1024x768", "--board", "9x7",
                        "--out", str(self.dir / "c.yml"))
        self.assertEqual(no_square.returncode, 1)
        self.assertIn("--square", no_square.stderr)
        bad_name = run("calibrate", "--input", PROCAM, "--patterns", "graycode", "--board", "9x7", "--square", "0.075",
                       "--out", str(self.dir / "c.yml"))
        self.assertEqual(bad_name.returncode, 1)
        self.assertIn("unknown pattern set name 'graycode'", bad_name.stderr)
        empty = self.dir / "empty"
        empty.mkdir()
        (empty / "pose_0").mkdir()
        nothing = run("calibrate", "--input", str(empty), "--patterns", "opencv-graycode:1024x768", "--board", "9x7",
                      "--square", "0.075", "--out", str(self.dir / "c.yml"))
        self.assertEqual(nothing.returncode, 1)
        self.assertIn("0 PNG images", nothing.stderr)


if __name__ == "__main__":
    SLS, PROCAM = sys.argv[1], sys.argv[2]
    unittest.main(argv=sys.argv[:1])
