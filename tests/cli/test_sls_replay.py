"""`sls scan` through replay:// devices (drivers/replay): a scan of a recording captured through
the replay camera, projector and turntable writes the very bytes of `sls scan --input` of that
recording (cloud, mesh, trajectory), its OUT/recording is a copy of the recording (images byte
for byte, timestamps, angles, the calibration), with --calibration and --frames defaulting to the
replayed recording's; timing=recorded keeps the recorded pace (a lower bound only), and a missing
recording or another frame count is a clear error.
Usage: test_sls_replay.py SLS"""
import json
import os
import subprocess
import sys
import tempfile
import time
import unittest

SLS = None
FRAMES = 4


def run(*args, timeout=300):
    return subprocess.run([SLS, *args], capture_output=True, text=True, timeout=timeout)


def read(path):
    with open(path, "rb") as f:
        return f.read()


class ScanThroughReplayDevices(unittest.TestCase):
    tmp = None
    recording = None

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.recording = os.path.join(cls.tmp.name, "rec")
        made = run("-q", "sim", "--preset", "ci", "--object", "knurled-knob", "--frames", str(FRAMES),
                   "--device", "cpu", "--out", cls.recording)
        assert made.returncode == 0, made.stderr
        # The turntable prior: depth alone cannot follow the knob's 90 degree steps, and every
        # frame should be in the model compared.
        scanned = run("-q", "scan", "--input", cls.recording, "--device", "cpu", "--turntable-prior",
                      "--out", os.path.join(cls.tmp.name, "input"))
        assert scanned.returncode == 0, scanned.stderr

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def replay_scan(self, out, query="", frames=FRAMES, defaults=False):
        """`sls scan` through the replay devices; `defaults`: without --calibration and --frames
        (the recording's)."""
        uri = "replay://" + self.recording + query
        given = [] if defaults else ["--calibration", os.path.join(self.recording, "calibration.yml"),
                                     "--frames", str(frames)]
        return run("-q", "scan", "--camera", uri, "--projector", uri, "--turntable", uri, *given,
                   "--device", "cpu", "--turntable-prior", "--out", os.path.join(self.tmp.name, out))

    def expect_same_model(self, out):
        report = json.loads(read(os.path.join(self.tmp.name, out, "report.json")))
        self.assertEqual(report["frames_fused"], FRAMES)
        for name in ("cloud.ply", "mesh.ply", "trajectory.txt"):
            with self.subTest(name=name):
                ours = read(os.path.join(self.tmp.name, out, name))
                self.assertEqual(ours, read(os.path.join(self.tmp.name, "input", name)),
                                 f"{name} of the replayed scan differs from sls scan --input's")
        self.assertEqual(len(read(os.path.join(self.tmp.name, out, "trajectory.txt")).splitlines()), 1 + FRAMES)
        self.assertGreater(len(read(os.path.join(self.tmp.name, out, "cloud.ply"))), 100000)

    def test_the_model_is_bit_identical_to_scanning_the_recording(self):
        # The calibration and the frame count are the recording's (given by hand: the paced test).
        result = self.replay_scan("replayed", defaults=True)
        self.assertEqual(result.returncode, 0, result.stderr)
        self.expect_same_model("replayed")
        # OUT/recording is a copy: every image file byte for byte, the frames' timestamps and
        # angles, and the calibration it was decoded with.
        copy = os.path.join(self.tmp.name, "replayed", "recording")
        self.assertTrue(os.path.isfile(os.path.join(copy, "calibration.yml")))
        original_manifest = json.loads(read(os.path.join(self.recording, "manifest.json")))
        copy_manifest = json.loads(read(os.path.join(copy, "manifest.json")))
        self.assertEqual(copy_manifest["pattern_set"], original_manifest["pattern_set"])
        # The simulator's recordings name one model for the whole scanner; a capture names the
        # projector's and the camera's, which the replay devices both take from it.
        self.assertEqual(copy_manifest["device"]["model"], "slscan simulated scanner + slscan simulated scanner")
        self.assertEqual(copy_manifest["device"]["uri"], "replay://" + self.recording)
        self.assertEqual(len(copy_manifest["frames"]), FRAMES)
        for ours, theirs in zip(copy_manifest["frames"], original_manifest["frames"]):
            for key in ("index", "timestamp_ns", "turntable_angle_deg", "status", "images"):
                self.assertEqual(ours[key], theirs[key], key)
            for image in theirs["images"]:
                self.assertEqual(read(os.path.join(copy, image)), read(os.path.join(self.recording, image)), image)

    def test_recorded_timing_keeps_the_pace_and_the_model(self):
        frames = json.loads(read(os.path.join(self.recording, "manifest.json")))["frames"]
        recorded_s = (frames[-1]["timestamp_ns"] - frames[0]["timestamp_ns"]) * 1e-9
        self.assertGreater(recorded_s, 0.5, "the simulator's frames should be a third of a second apart")
        start = time.monotonic()
        result = self.replay_scan("paced", "?timing=recorded")
        elapsed = time.monotonic() - start
        self.assertEqual(result.returncode, 0, result.stderr)
        self.assertGreaterEqual(elapsed, recorded_s, "the last frame may not come before its recorded time")
        self.expect_same_model("paced")

    def test_another_frame_count_names_the_angle_the_recording_lacks(self):
        result = self.replay_scan("five", frames=5)
        self.assertNotEqual(result.returncode, 0)
        self.assertIn("no recorded frame at 72.000 deg", result.stderr)
        self.assertIn("replay://" + self.recording, result.stderr)

    def test_a_missing_recording_names_the_uri(self):
        uri = "replay://" + os.path.join(self.tmp.name, "nothing")
        result = run("-q", "scan", "--camera", uri, "--projector", uri, "--device", "cpu",
                     "--out", os.path.join(self.tmp.name, "missing"))
        self.assertNotEqual(result.returncode, 0)
        self.assertIn(uri, result.stderr)


if __name__ == "__main__":
    SLS = os.path.abspath(sys.argv.pop(1))
    unittest.main(verbosity=2)
