#!/usr/bin/env python3
"""`sls scan` and `sls decode` on recordings with bad frames (issue 19): a frame whose image is
missing, empty, no PNG, of another size, beyond the camera's bit depth, or a stack with a
pattern stuck is reported with its reason and skipped; the other frames are scanned and
decoded. Usage: test_sls_bad_input.py PATH_TO_SLS (stdlib only)."""
import json
import os
import pathlib
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import unittest
import zlib

SLS = None


def run(*args, timeout=300):
    return subprocess.run([SLS, *args], capture_output=True, text=True, timeout=timeout)


def write_png16(path, width, height, value):
    """A 16-bit grey PNG of one constant value."""
    row = b"\x00" + struct.pack(">H", value) * width
    raw = row * height

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", width, height, 16, 0, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw)) +
                     chunk(b"IEND", b""))


class BadNumbers(unittest.TestCase):
    def test_numbers_out_of_range_nan_or_infinite_are_usage_errors_with_a_short_message(self):
        cases = [("scan", "--photometric-weight", "nan"), ("scan", "--photometric-weight", "1e300"),
                 ("scan", "--icp-crease-deg", "inf"), ("scan", "--voxel-um", "1e-20"), ("scan", "--max-voxels", "nan"),
                 ("sim", "--gamma", "1e300"), ("sim", "--turntable-jitter-deg", "nan"),
                 ("sim", "--mount-tilt-deg", "1e300"), ("sim", "--mount-offset-um", "-inf"),
                 ("sim", "--projector-gamma", "nan"), ("sim", "--reference-spacing-um", "nan")]
        with tempfile.TemporaryDirectory() as tmp:
            for command, flag, value in cases:
                args = [command, flag, value, "--out", os.path.join(tmp, "out")]
                if command == "scan":
                    args += ["--sim", "ci"]
                result = run(*args, timeout=30)
                self.assertEqual(result.returncode, 2, (args, result.stderr))
                self.assertIn(flag, result.stderr)
                self.assertLess(len(result.stderr.splitlines()[0]), 160, result.stderr)
                self.assertFalse(os.path.exists(os.path.join(tmp, "out")), args)


class FullDisk(unittest.TestCase):
    """A small tmpfs as the output's filesystem (needs root and a kernel that lets it mount)."""

    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.mount = pathlib.Path(self.tmp.name) / "disk"
        self.mount.mkdir()
        mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", str(self.mount)],
                                 capture_output=True, text=True)
        if mounted.returncode != 0:
            self.tmp.cleanup()
            self.skipTest(f"cannot mount a tmpfs here: {mounted.stderr.strip()}")

    def tearDown(self):
        subprocess.run(["umount", str(self.mount)], capture_output=True)
        self.tmp.cleanup()

    def resize(self, size):
        subprocess.run(["mount", "-o", f"remount,size={size}", str(self.mount)], check=True)

    def test_a_scan_needs_room_for_its_first_outputs_before_any_work(self):
        result = run("scan", "--sim", "ci", "--frames", "4", "--device", "cpu", "--out", str(self.mount / "out"))
        self.assertEqual(result.returncode, 1, result.stderr)
        self.assertIn("MiB free, less than the 64 MiB its first outputs need", result.stderr)
        self.assertFalse((self.mount / "out" / "recording").exists())

    def test_a_disk_that_fills_during_the_capture_keeps_the_frames_and_resume_completes_the_scan(self):
        self.resize("70m")  # room for the check and ~9 of 24 frames of the ci preset
        out = self.mount / "out"
        result = run("scan", "--sim", "ci", "--frames", "24", "--turntable-prior", "--device", "cpu",
                     "--out", str(out))
        self.assertEqual(result.returncode, 1, result.stderr)
        self.assertIn("No space left on device", result.stderr)
        self.assertRegex(result.stderr, r"the \d+ frame\(s\) captured before are kept in .*continue the capture with --resume")
        inspected = run("--json", "inspect", "--deep", str(out / "recording"))
        self.assertEqual(inspected.returncode, 0, inspected.stdout + inspected.stderr)
        kept = json.loads((out / "recording" / "manifest.json").read_text())["frames"]
        self.assertGreater(len(kept), 0)
        self.assertLess(len(kept), 24)
        self.resize("400m")  # space freed: the capture goes on and the whole recording is fused
        resumed = run("--json", "scan", "--resume", "--turntable-prior", "--device", "cpu", "--out", str(out))
        self.assertEqual(resumed.returncode, 0, resumed.stderr)
        report = json.loads(resumed.stdout)
        self.assertEqual((report["frames"], report["frames_fused"]), (24, 24))

    def fill(self, leave):
        """Fills the disk with a file that leaves `leave` bytes free."""
        stat = os.statvfs(self.mount)
        size = stat.f_bavail * stat.f_frsize - leave
        with open(self.mount / "filler", "wb") as filler:
            while size > 0:
                filler.write(b"x" * min(size, 1 << 20))
                size -= 1 << 20

    def test_a_disk_that_fills_before_the_outputs_names_the_file_leaves_no_partial_one_and_a_rerun_completes(self):
        rec = pathlib.Path(self.tmp.name) / "rec"  # beside the small disk, not on it
        made = run("sim", "--preset", "ci", "--frames", "6", "--mode", "depth", "--device", "cpu", "--out", str(rec))
        self.assertEqual(made.returncode, 0, made.stderr)
        self.resize("70m")  # the 64 MiB the up-front check asks for
        out = self.mount / "out"
        args = [SLS, "scan", "--input", str(rec), "--poses", "groundtruth", "--device", "cpu", "--out", str(out)]
        scan = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        # Stopped at its first frame (past the check), the disk filled up to 1 MiB, then on: the
        # frames are fused, render.png fits, cloud.ply (6 MB) does not.
        stderr = ""
        while not stderr.endswith("\n") or not stderr.splitlines()[-1].startswith("scan: 0/6"):
            line = scan.stderr.readline()
            self.assertTrue(line, stderr)
            stderr += line
        scan.send_signal(signal.SIGSTOP)
        self.assertEqual(list(out.iterdir()), [], "the outputs began before the disk was filled")
        self.fill(leave=1 << 20)
        scan.send_signal(signal.SIGCONT)
        _, rest = scan.communicate(timeout=300)
        stderr += rest
        self.assertEqual(scan.returncode, 1, stderr)
        self.assertIn(f"cannot write the outputs into {out}: cannot write {out}/cloud.ply.tmp-", stderr)
        self.assertIn("No space left on device; written: render.png; not written: cloud.ply, mesh.ply, "
                      "trajectory.txt, report.json, report.html", stderr)
        # No temporary, no partial file, no report of a model that is not there.
        self.assertEqual(sorted(p.name for p in out.iterdir()), ["render.png"])
        (self.mount / "filler").unlink()  # space freed: the scan run again writes everything
        again = run("--json", "scan", "--input", str(rec), "--poses", "groundtruth", "--device", "cpu",
                    "--out", str(out))
        self.assertEqual(again.returncode, 0, again.stderr)
        self.assertEqual(json.loads(again.stdout)["frames_fused"], 6)
        for name in ("render.png", "cloud.ply", "mesh.ply", "trajectory.txt", "report.json", "report.html"):
            self.assertTrue((out / name).is_file(), name)
        self.assertEqual([p.name for p in out.iterdir() if ".tmp-" in p.name], [])


class BadFrames(unittest.TestCase):
    """One 10-frame simulated recording, frames 1..7 each broken in another way."""

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.dir = pathlib.Path(cls.tmp.name)
        rec = cls.dir / "rec"
        result = run("sim", "--preset", "ci", "--frames", "10", "--device", "cpu", "--out", str(rec))
        assert result.returncode == 0, result.stderr
        manifest = json.loads((rec / "manifest.json").read_text())
        width, height = manifest["camera"]["width"], manifest["camera"]["height"]

        def image(frame, k):
            return rec / "frames" / f"{frame:06d}" / f"pattern_{k:03d}.png"

        image(1, 5).unlink()
        image(2, 5).write_bytes(b"")
        image(3, 5).write_bytes(b"not a png at all")
        write_png16(image(4, 5), width // 2, height // 2, 1000)
        write_png16(image(5, 2), width, height, 2048)   # Gray bit 9 stuck at a mid-grey
        write_png16(image(6, 17), width, height, 2048)  # a phase step stuck
        write_png16(image(7, 9), width, height, 5000)   # beyond the 12-bit camera
        cls.rec = rec
        # What each broken frame's reason must name.
        cls.expected = {1: "pattern_005.png", 2: "pattern_005.png", 3: "pattern_005.png", 4: "pattern_005.png",
                        5: "pattern images 2 (gray_c9) and 3 (gray_c9_inv)", 6: "pattern image 17",
                        7: "beyond the recording's 12-bit camera"}

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def test_scan_skips_each_bad_frame_with_its_reason_and_fuses_the_rest(self):
        out = self.dir / "scan"
        result = run("--json", "scan", "--input", str(self.rec), "--poses", "groundtruth", "--device", "cpu",
                     "--out", str(out))
        self.assertEqual(result.returncode, 0, result.stderr)
        report = json.loads(result.stdout)
        self.assertEqual(report["frames_fused"], 3)
        lost = {f["frame"]: f for f in report["lost_frames"]}
        self.assertEqual(sorted(lost), sorted(self.expected))
        for frame, needle in self.expected.items():
            self.assertEqual(lost[frame]["status"], "skipped")
            self.assertIn(needle, lost[frame]["reason"])
        for name in ("cloud.ply", "mesh.ply", "trajectory.txt", "report.json"):
            self.assertTrue((out / name).exists(), name)

    def test_decode_skips_each_bad_frame_with_its_reason_and_decodes_the_rest(self):
        out = self.dir / "decode"
        result = run("--json", "decode", "--input", str(self.rec), "--device", "cpu", "--no-clouds",
                     "--out", str(out))
        self.assertEqual(result.returncode, 0, result.stderr)
        summary = json.loads(result.stdout)
        self.assertEqual((summary["frames_decoded"], summary["frames_skipped"]), (3, 7))
        # The decoded frames are the good ones: their error against the truth is small.
        self.assertLess(summary["depth_rms_um"], 50.0)
        frames = {f["index"]: f for f in json.loads((out / "decode.json").read_text())["frames"]}
        for frame, needle in self.expected.items():
            self.assertEqual(frames[frame]["status"], "skipped")
            self.assertIn(needle, frames[frame]["reason"])
        for frame in (0, 8, 9):
            self.assertEqual(frames[frame]["status"], "decoded")
            self.assertTrue((out / "frames" / f"{frame:06d}" / "depth.pfm").exists())

    def test_decode_refuses_an_output_inside_the_recording_before_any_work(self):
        result = run("decode", "--input", str(self.rec), "--device", "cpu", "--out", str(self.rec / "decoded"))
        self.assertEqual(result.returncode, 1)
        self.assertIn("inside the recording", result.stderr)
        self.assertFalse((self.rec / "decoded").exists())

    def test_a_volume_beyond_the_memory_limit_is_refused_naming_sizes_and_the_flag(self):
        # ulimit -v 3 GB, as on a small machine: 18 um voxels around the screw would need ~13 GB.
        if b"__asan_init" in pathlib.Path(SLS).read_bytes():
            self.skipTest("AddressSanitizer reserves the address space ulimit -v would limit")
        import resource

        def limit_memory():
            resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))

        out = self.dir / "too-big"
        result = subprocess.run([SLS, "scan", "--input", str(self.rec), "--poses", "groundtruth", "--voxel-um", "18",
                                 "--device", "cpu", "--out", str(out)], capture_output=True, text=True, timeout=300,
                                preexec_fn=limit_memory)
        self.assertEqual(result.returncode, 1, result.stderr)
        for needle in ("MiB of host memory", "MiB are available (limited by ulimit -v)", "--voxel-um", "--max-voxels"):
            self.assertIn(needle, result.stderr)


class TurntableScan(unittest.TestCase):
    """A 24-frame turntable revolution of the knurled screw (15 degree steps)."""

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.dir = pathlib.Path(cls.tmp.name)
        cls.rec = cls.dir / "rec"
        result = run("sim", "--preset", "ci", "--frames", "24", "--device", "cpu", "--out", str(cls.rec))
        assert result.returncode == 0, result.stderr

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def test_one_bad_frame_does_not_lose_the_rest_with_the_turntable_prior(self):
        # A stuck pattern in frame 2: that frame is skipped; the next view overlaps too little of
        # the model to verify, so it is fused at the turntable's pose and flagged, and the scan
        # goes on instead of losing every later frame.
        rec = self.dir / "stuck"
        shutil.copytree(self.rec, rec)
        manifest = json.loads((rec / "manifest.json").read_text())
        write_png16(rec / "frames" / "000002" / "pattern_017.png", manifest["camera"]["width"],
                    manifest["camera"]["height"], 2048)
        result = run("--json", "scan", "--input", str(rec), "--turntable-prior", "--device", "cpu",
                     "--out", str(self.dir / "prior"))
        self.assertEqual(result.returncode, 0, result.stderr)
        report = json.loads(result.stdout)
        self.assertEqual([(f["frame"], f["status"]) for f in report["lost_frames"]], [(2, "skipped")])
        self.assertEqual(report["frames_fused"], 23)
        unverified = [f for f in report["per_frame"] if f.get("unverified")]
        for frame in unverified:
            self.assertIn("fused at the turntable prior", frame["reason"])
        if unverified:
            self.assertTrue(any("without verification" in w for w in report["warnings"]), report["warnings"])
        # The trajectory stays right: within a few 60 um voxels of the truth.
        self.assertLess(report["evaluation"]["ate_rmse_um"], 100.0)

    def test_tracking_that_disagrees_with_the_turntable_is_lost_not_fused(self):
        # Depth alone cannot see the screw turn about its own axis at 15 degree steps: ICP
        # converges with the rotation left at the guess. The turntable's angles expose it.
        result = run("--json", "scan", "--input", str(self.rec), "--device", "cpu", "--out", str(self.dir / "depth"))
        self.assertEqual(result.returncode, 0, result.stderr)
        report = json.loads(result.stdout)
        self.assertLess(report["frames_fused"], 24)
        disagreeing = [f for f in report["lost_frames"] if "disagrees with the turntable" in f.get("reason", "")]
        self.assertGreater(len(disagreeing), 0, report["lost_frames"])
        self.assertIn("--turntable-prior", disagreeing[0]["reason"])
        self.assertEqual(disagreeing[0]["status"], "lost")
        self.assertTrue(any("lost by tracking" in w for w in report["warnings"]), report["warnings"])

    def test_a_broken_ground_truth_spoils_the_evaluation_not_the_scan(self):
        rec = self.dir / "broken-truth"
        shutil.copytree(self.rec, rec)
        (rec / "groundtruth" / "trajectory.txt").write_text("garbage\n")
        out = self.dir / "scan-broken-truth"
        result = run("--json", "scan", "--input", str(rec), "--turntable-prior", "--device", "cpu", "--out", str(out))
        self.assertEqual(result.returncode, 0, result.stderr)
        report = json.loads(result.stdout)
        self.assertIn("trajectory.txt", report["evaluation_error"])
        self.assertTrue(any("could not be evaluated" in w for w in report["warnings"]), report["warnings"])
        for name in ("cloud.ply", "mesh.ply", "trajectory.txt", "report.json", "report.html"):
            self.assertTrue((out / name).exists(), name)


if __name__ == "__main__":
    SLS = os.path.abspath(sys.argv.pop(1))
    unittest.main(verbosity=2)
