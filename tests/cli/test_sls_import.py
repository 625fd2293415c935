#!/usr/bin/env python3
"""`sls import` and `sls sim --patterns` as docs/import.md promises them: the simulator renders
a shipped description and `sls decode` meets the ground truth; a simulated capture taken apart
into folders of images is imported and `sls scan` fuses it; shared/data/procam-calibration is
imported from its folder with the shipped OpenCV Gray-code description and `sls decode` takes
it; the errors (wrong image count, unreadable calibration, a description that does not fit
the images) exit 1 with a message that says what is wrong. Usage: test_sls_import.py PATH_TO_SLS
REPO_ROOT SHARED_DATA (stdlib only)."""
import json
import pathlib
import subprocess
import sys
import tempfile
import unittest

SLS = None
ROOT = None
DATA = None


def run(*args):
    return subprocess.run([SLS, *map(str, args)], capture_output=True, text=True, timeout=300)


def pattern(name):
    return ROOT / "samples" / "patterns" / name


class SlsImport(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.dir = pathlib.Path(self.tmp.name)

    def tearDown(self):
        self.tmp.cleanup()

    def test_help_lists_the_flags(self):
        text = run("import", "--help").stdout
        for flag in ("--images", "--patterns", "--calibration", "--out", "--name-pattern", "--unit-mm",
                     "--bit-depth", "--no-check"):
            self.assertIn(flag, text)
        self.assertIn("--patterns", run("sim", "--help").stdout)

    def test_sim_renders_a_description_and_decode_meets_the_ground_truth(self):
        rec, out = self.dir / "rec", self.dir / "decoded"
        r = run("sim", "--preset", "ci", "--object", "plane", "--frames", "2", "--no-noise", "--device", "cpu", "-q",
                "--patterns", pattern("multi_period_gray_phase_shift.json"), "--out", rec)
        self.assertEqual(r.returncode, 0, r.stderr)
        manifest = json.loads((rec / "manifest.json").read_text())
        self.assertEqual(manifest["pattern_set"]["kind"], "phase_shift")
        self.assertEqual(manifest["images_per_frame"], 25)
        r = run("--json", "decode", "--input", rec, "--out", out, "--device", "cpu", "--no-clouds")
        self.assertEqual(r.returncode, 0, r.stderr)
        report = json.loads(r.stdout)
        self.assertLessEqual(report["projector_rms_px"], 0.02)
        self.assertGreater(report["valid_fraction"], 0.95)

    def test_a_capture_taken_apart_is_imported_and_scanned(self):
        rec, imported, scan = self.dir / "rec", self.dir / "imported", self.dir / "scan"
        desc = pattern("complementary_gray_phase_shift.json")
        r = run("sim", "--preset", "ci", "--frames", "4", "--device", "cpu", "-q", "--patterns", desc, "--out", rec)
        self.assertEqual(r.returncode, 0, r.stderr)
        # frames/NNNNNN/pattern_KKK.png: one stack per subfolder, as other tools lay them out.
        r = run("--json", "import", "--images", rec / "frames", "--patterns", desc, "--calibration",
                rec / "calibration.yml", "--bit-depth", "12", "--out", imported)
        self.assertEqual(r.returncode, 0, r.stderr)
        summary = json.loads(r.stdout)
        self.assertEqual(summary["frames"], 4)
        self.assertEqual(summary["bit_depth"], 12)
        self.assertEqual(summary["calibration_layout"], "slscan")
        # The right count in another order (Gray bits 6 and 2 swapped, in the explicit form): the
        # images do not behave as it says.
        swapped = self.dir / "swapped.json"
        explicit = json.loads((rec / "manifest.json").read_text())["pattern_set"]
        explicit["patterns"][2], explicit["patterns"][10] = explicit["patterns"][10], explicit["patterns"][2]
        swapped.write_text(json.dumps(explicit))
        bad = self.dir / "bad"
        r = run("import", "--images", rec / "frames", "--patterns", swapped, "--calibration", rec / "calibration.yml",
                "--bit-depth", "12", "--out", bad)
        self.assertEqual(r.returncode, 1, r.stderr)
        self.assertIn("does not fit the images", r.stderr)
        self.assertFalse(bad.exists())
        r = run("--json", "scan", "--input", imported, "--out", scan, "--device", "cpu")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(json.loads(r.stdout)["frames"], 4)
        self.assertTrue((scan / "cloud.ply").exists())

    def test_procam_calibration_folder(self):
        folder = DATA / "procam-calibration"
        if not folder.is_dir():
            self.skipTest("shared/data/procam-calibration is not here")
        rec, out = self.dir / "procam", self.dir / "decoded"
        r = run("--json", "import", "--images", folder, "--patterns", pattern("opencv_graycode_1024x768.json"),
                "--calibration", folder / "calibration_result.xml", "--out", rec)
        self.assertEqual(r.returncode, 0, r.stderr)
        summary = json.loads(r.stdout)
        self.assertEqual(summary["frames"], 5)
        self.assertEqual(len(summary["skipped"]), 1)  # graycode_pattern/: the patterns themselves
        self.assertEqual(summary["pattern_kind"], "gray_code")
        r = run("--json", "decode", "--input", rec, "--out", out, "--device", "cpu", "--no-clouds")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(json.loads(r.stdout)["frames_decoded"], 5)

        # Errors: exit 1 and a message that names the problem; no recording left behind.
        bad = self.dir / "bad"
        r = run("import", "--images", folder, "--patterns", pattern("slscan_gray_phase.json"), "--calibration",
                folder / "calibration_result.xml", "--out", bad)
        self.assertEqual(r.returncode, 1)
        self.assertIn("holds 42 images", r.stderr)
        self.assertIn("has 22 patterns", r.stderr)
        broken = self.dir / "broken.xml"
        broken.write_text("<?xml version=\"1.0\"?>\n<opencv_storage><cam_int>")
        r = run("import", "--images", folder, "--patterns", pattern("opencv_graycode_1024x768.json"),
                "--calibration", broken, "--out", bad)
        self.assertEqual(r.returncode, 1)
        self.assertIn("broken.xml", r.stderr)
        # A required flag missing: a usage error.
        self.assertEqual(run("import", "--images", folder, "--out", bad).returncode, 2)


if __name__ == "__main__":
    SLS = sys.argv[1]
    ROOT = pathlib.Path(sys.argv[2])
    DATA = pathlib.Path(sys.argv[3])
    unittest.main(argv=[sys.argv[0], *sys.argv[4:]])
