#!/usr/bin/env python3
"""`sls scan` and `sls sim` captures stopped by SIGINT/SIGTERM or killed (-9) at any moment, and
`--resume` (issue 19 items 9, 10). Usage: test_sls_interrupts.py PATH_TO_SLS (stdlib only)."""
import json
import os
import pathlib
import signal
import subprocess
import sys
import tempfile
import time
import unittest

SLS = None


def run(*args):
    return subprocess.run([SLS, *args], capture_output=True, text=True, timeout=120)


def listed_frames(rec):
    """The frames the recording's manifest lists (none while it is absent)."""
    try:
        return json.loads((pathlib.Path(rec) / "manifest.json").read_text())["frames"]
    except (OSError, ValueError, KeyError):
        return []


def wait_for_frames(process, rec, count, timeout=120):
    """Until the manifest lists `count` frames; False when the process ended first."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if len(listed_frames(rec)) >= count:
            return True
        if process.poll() is not None:
            return False
        time.sleep(0.01)
    return False


def start(*args):
    return subprocess.Popen([SLS, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


class SlsCaptureInterrupts(unittest.TestCase):
    """Issue 19 items 9, 10 and --resume: a capture stopped by SIGINT/SIGTERM (exit 4, said,
    kept) or killed (-9) at any moment leaves a valid recording whose every listed frame has
    its ground truth, and `--resume` ends with the recording an uninterrupted run writes."""

    FRAMES = 4
    TRUTH = ("depth.pfm", "projector_u.pfm", "projector_v.pfm", "depth_sigma.pfm", "valid.png")

    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.dir = pathlib.Path(self.tmp.name)

    def tearDown(self):
        self.tmp.cleanup()

    @classmethod
    def tearDownClass(cls):
        if getattr(cls, "shared", None):
            cls.shared.cleanup()

    def reference(self):
        """An uninterrupted recording, made once for the class (what `sls scan --sim` records too)."""
        cls = type(self)
        if not getattr(cls, "shared", None):
            cls.shared = tempfile.TemporaryDirectory()
        rec = pathlib.Path(cls.shared.name) / "reference"
        if not (rec / "manifest.json").exists():
            result = run("sim", "--preset", "ci", "--frames", str(self.FRAMES), "--device", "cpu", "--out", str(rec))
            self.assertEqual(result.returncode, 0, result.stderr)
        return rec

    def assert_whole(self, rec, extra_poses=0):
        """The recording opens and checks; each listed frame has all its ground truth and its
        pose; trajectory.txt holds at most `extra_poses` more (of a frame not listed)."""
        inspect = json.loads(run("--json", "inspect", "--deep", str(rec)).stdout)
        self.assertTrue(inspect["ok"], inspect)
        frames = listed_frames(rec)
        for frame in frames:
            for name in self.TRUTH:
                self.assertTrue((rec / "groundtruth/frames" / f"{frame['index']:06d}" / name).is_file(),
                                f"listed frame {frame['index']} has no {name}")
        trajectory = rec / "groundtruth/trajectory.txt"
        # Written with the first frame: a recording killed before it has none.
        text = trajectory.read_text() if frames or trajectory.exists() else ""
        poses = [line.split() for line in text.splitlines() if line.strip() and not line.startswith("#")]
        self.assertGreaterEqual(len(poses), len(frames))
        self.assertLessEqual(len(poses), len(frames) + extra_poses)
        for frame, pose in zip(frames, poses):
            self.assertAlmostEqual(float(pose[0]), frame["timestamp_ns"] * 1e-9, places=6)
        return len(frames)

    def assert_same_recording(self, rec, reference):
        """Every file of the uninterrupted recording, byte for byte (the manifest but its date)."""
        def files(folder):
            return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())
        self.assertEqual(files(rec), files(reference))
        for name in files(reference):
            if name == "manifest.json":
                ours, theirs = (json.loads((f / name).read_text()) for f in (rec, reference))
                ours.pop("created_utc")
                theirs.pop("created_utc")
                self.assertEqual(ours, theirs)
            else:
                self.assertEqual((rec / name).read_bytes(), (reference / name).read_bytes(), name)

    def test_sigint_and_sigterm_during_a_simulated_capture_exit_4_keep_it_and_resume(self):
        for sig, name in ((signal.SIGTERM, "SIGTERM"), (signal.SIGINT, "SIGINT")):
            out = self.dir / f"scan-{name}"
            scan = start("scan", "--sim", "ci", "--frames", str(self.FRAMES), "--device", "cpu", "--out", str(out))
            self.assertTrue(wait_for_frames(scan, out / "recording", 1))
            scan.send_signal(sig)
            _, stderr = scan.communicate(timeout=120)
            self.assertEqual(scan.returncode, 4, stderr)
            captured = self.assert_whole(out / "recording")
            self.assertGreaterEqual(captured, 1)
            self.assertLess(captured, self.FRAMES, "stopped after the current frame, not at the end")
            self.assertIn(f"interrupted by {name} during the capture: {captured} of {self.FRAMES} frame(s) captured",
                          stderr)
            self.assertIn(f"sls scan --resume --out {out}", stderr)
            self.assertFalse((out / "cloud.ply").exists(), "an interrupted capture is not fused")
        # The resume reads the simulator's options from the recording, captures the rest, fuses.
        resumed = run("scan", "--resume", "--device", "cpu", "--out", str(out))
        self.assertEqual(resumed.returncode, 0, resumed.stderr)
        self.assertIn(f"(resumed at frame {captured})", resumed.stderr)
        self.assertTrue((out / "cloud.ply").exists())
        self.assert_same_recording(out / "recording", self.reference())
        # --json: the interruption is one JSON object on stdout.
        out = self.dir / "json"
        scan = start("--json", "scan", "--sim", "ci", "--frames", str(self.FRAMES), "--device", "cpu",
                     "--out", str(out))
        self.assertTrue(wait_for_frames(scan, out / "recording", 1))
        scan.send_signal(signal.SIGINT)
        stdout, stderr = scan.communicate(timeout=120)
        self.assertEqual(scan.returncode, 4, stderr)
        result = json.loads(stdout)
        self.assertTrue(result["interrupted"])
        self.assertEqual(result["frames_captured"], len(listed_frames(out / "recording")))
        self.assertEqual(result["frames_planned"], self.FRAMES)

    def test_sls_sim_stops_on_sigint_with_exit_4_and_resumes(self):
        out = self.dir / "sim"
        sim = start("sim", "--preset", "ci", "--frames", str(self.FRAMES), "--device", "cpu", "--out", str(out))
        self.assertTrue(wait_for_frames(sim, out, 1))
        sim.send_signal(signal.SIGINT)
        _, stderr = sim.communicate(timeout=120)
        self.assertEqual(sim.returncode, 4, stderr)
        captured = self.assert_whole(out)
        self.assertIn(f"interrupted by SIGINT: wrote {captured} of {self.FRAMES} frames", stderr)
        self.assertIn("--resume", stderr)
        # Other options than the recording's are refused, naming the difference; nothing written.
        for other, named in ((("--frames", "6"), "frames=6"), (("--seed", "2"), "seed=2"),
                             (("--frames", str(self.FRAMES), "--bit-depth", "8"), "8-bit"),
                             (("--frames", str(self.FRAMES), "--turntable-jitter-deg", "0.5"), "angle_jitter_deg")):
            refused = run("sim", "--preset", "ci", *other, "--device", "cpu", "--resume", "--out", str(out))
            self.assertEqual(refused.returncode, 1, refused.stderr)
            self.assertIn(named, refused.stderr)
        self.assertEqual(len(listed_frames(out)), captured)
        resumed = run("sim", "--preset", "ci", "--frames", str(self.FRAMES), "--device", "cpu", "--resume",
                      "--out", str(out))
        self.assertEqual(resumed.returncode, 0, resumed.stderr)
        self.assert_same_recording(out, self.reference())

    def test_kill_9_at_any_moment_of_a_capture_leaves_whole_frames_and_resume_completes_it(self):
        reference = self.reference()
        # Killed as soon as the recording exists, and in the middle of a frame.
        for moment, (frames, delay) in enumerate(((0, 0.0), (1, 0.3))):
            out = self.dir / f"killed{moment}"
            sim = start("sim", "--preset", "ci", "--frames", str(self.FRAMES), "--device", "cpu", "--out", str(out))
            deadline = time.monotonic() + 60
            while not (out / "manifest.json").exists() and time.monotonic() < deadline and sim.poll() is None:
                time.sleep(0.005)
            self.assertTrue(wait_for_frames(sim, out, frames))
            time.sleep(delay)
            sim.send_signal(signal.SIGKILL)
            sim.communicate(timeout=60)
            self.assertEqual(sim.returncode, -signal.SIGKILL)
            self.assert_whole(out, extra_poses=1)
            resumed = run("sim", "--preset", "ci", "--frames", str(self.FRAMES), "--device", "cpu", "--resume",
                          "--out", str(out))
            self.assertEqual(resumed.returncode, 0, resumed.stderr)
            self.assert_same_recording(out, reference)
        # sls scan killed mid-capture, resumed; then killed during the fusion and resumed again:
        # the complete recording is fused from the start.
        out = self.dir / "scan"
        scan = start("scan", "--sim", "ci", "--frames", str(self.FRAMES), "--device", "cpu", "--out", str(out))
        self.assertTrue(wait_for_frames(scan, out / "recording", 2))
        scan.send_signal(signal.SIGKILL)
        scan.communicate(timeout=60)
        self.assert_whole(out / "recording", extra_poses=1)
        scan = start("scan", "--resume", "--device", "cpu", "--out", str(out))
        self.assertTrue(wait_for_frames(scan, out / "recording", self.FRAMES))
        time.sleep(0.5)
        scan.send_signal(signal.SIGKILL)
        scan.communicate(timeout=60)
        self.assert_same_recording(out / "recording", reference)
        resumed = run("--json", "scan", "--resume", "--device", "cpu", "--out", str(out))
        self.assertEqual(resumed.returncode, 0, resumed.stderr)
        self.assertEqual(json.loads(resumed.stdout)["frames"], self.FRAMES)
        self.assert_same_recording(out / "recording", reference)
        # --resume with nothing to resume, or other options than the recording's, is refused.
        nothing = run("scan", "--resume", "--device", "cpu", "--out", str(self.dir / "empty"))
        self.assertEqual(nothing.returncode, 1)
        self.assertIn("holds no recording to resume", nothing.stderr)
        for other, named in ((("--sim", "demo"), "preset=demo"), (("--sim", "ci", "--object", "sphere"), "sim://sphere"),
                             (("--sim", "ci", "--frames", "6"), "frames=6")):
            refused = run("scan", "--resume", *other, "--device", "cpu", "--out", str(out))
            self.assertEqual(refused.returncode, 1, refused.stderr)
            self.assertIn(named, refused.stderr)
        self.assertEqual(run("scan", "--resume", "--input", str(reference), "--out", str(out)).returncode, 2)
        # Without --resume a cut-off recording is not written over.
        again = run("scan", "--sim", "ci", "--frames", str(self.FRAMES), "--device", "cpu", "--out", str(out))
        self.assertEqual(again.returncode, 1)
        self.assertIn("--resume", again.stderr)

    def test_a_signal_during_a_device_capture_exits_4_and_resume_continues_the_turntable(self):
        uri = "sim://knurled-screw?preset=ci"
        calibrated = self.dir / "calibrated"
        self.assertEqual(run("sim", "--preset", "ci", "--frames", "1", "--device", "cpu",
                             "--out", str(calibrated)).returncode, 0)
        devices = ("--camera", uri, "--projector", uri, "--turntable", uri, "--frames", "4")
        out = self.dir / "devices"
        scan = start("scan", *devices, "--calibration", str(calibrated / "calibration.yml"), "--device", "cpu",
                     "--out", str(out))
        self.assertTrue(wait_for_frames(scan, out / "recording", 2))
        scan.send_signal(signal.SIGTERM)
        _, stderr = scan.communicate(timeout=120)
        self.assertEqual(scan.returncode, 4, stderr)
        captured = len(listed_frames(out / "recording"))
        self.assertIn(f"interrupted by SIGTERM during the capture: {captured} of 4 frame(s)", stderr)
        self.assertIn(f"sls scan --resume {' '.join(devices)} --out {out}", stderr)
        first = (out / "recording/frames/000000/pattern_005.png").read_bytes()
        # A recording of devices is resumed with its devices; another frame count is refused.
        for other, named in (((), "--camera"), (devices[:-1] + ("8",), "8 frames per revolution")):
            refused = run("scan", "--resume", *other, "--device", "cpu", "--out", str(out))
            self.assertEqual(refused.returncode, 1, refused.stderr)
            self.assertIn(named, refused.stderr)
        resumed = run("scan", "--resume", *devices, "--device", "cpu", "--out", str(out))
        self.assertEqual(resumed.returncode, 0, resumed.stderr)
        self.assertIn(f"(resumed at frame {captured})", resumed.stderr)
        frames = listed_frames(out / "recording")
        self.assertEqual([f["index"] for f in frames], [0, 1, 2, 3])
        self.assertEqual([round(f["turntable_angle_deg"]) for f in frames], [0, 90, 180, 270])
        self.assertEqual((out / "recording/frames/000000/pattern_005.png").read_bytes(), first)
        self.assertTrue((out / "cloud.ply").exists())



if __name__ == "__main__":
    SLS = os.path.abspath(sys.argv.pop(1))
    unittest.main(verbosity=2)
