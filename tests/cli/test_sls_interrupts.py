#!/usr/bin/env python3
"""`sls scan` and `sls sim` captures stopped by SIGINT/SIGTERM or killed (-9) at any moment, the
fusion of `sls scan` killed at each stage, and `--resume` (issue 19 items 9, 10). Usage:
test_sls_interrupts.py PATH_TO_SLS [TEST...] (stdlib only)."""
import json
import os
import pathlib
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import unittest

SLS = None
FRAMES = 4
_shared = None


def reference():
    """An uninterrupted 4-frame recording of the ci preset, made once for the file (what `sls scan
    --sim ci --frames 4` records too)."""
    global _shared
    if _shared is None:
        _shared = tempfile.TemporaryDirectory()
        unittest.addModuleCleanup(_shared.cleanup)
    rec = pathlib.Path(_shared.name) / "reference"
    if not (rec / "manifest.json").exists():
        result = run("sim", "--preset", "ci", "--frames", str(FRAMES), "--device", "cpu", "--out", str(rec))
        assert result.returncode == 0, result.stderr
    return rec


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

    FRAMES = FRAMES
    TRUTH = ("depth.pfm", "projector_u.pfm", "projector_v.pfm", "depth_sigma.pfm", "valid.png")

    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.dir = pathlib.Path(self.tmp.name)

    def tearDown(self):
        self.tmp.cleanup()

    def reference(self):
        return reference()

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

    def test_sigint_and_sigterm_during_a_simulated_capture_exit_4_keep_and_fuse_it_and_resume(self):
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
            # Fused while it recorded: what was captured is in a valid partial model.
            report = json.loads((out / "report.json").read_text())
            self.assertTrue(report["interrupted"])
            self.assertEqual(report["frames_processed"], captured)
            self.assertEqual(report["live_capture"]["frames_captured"], captured)
            self.assertGreater(ply_counts(out / "cloud.ply")[0], 0)
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
        self.assertEqual(result["live_capture"]["frames_captured"], len(listed_frames(out / "recording")))
        self.assertEqual(result["live_capture"]["frames_planned"], self.FRAMES)
        self.assertEqual(result["live_capture"]["resume"], f"sls scan --resume --out {out}")

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

def digest(folder):
    """Every file under `folder` with its bytes: what "untouched" compares."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def ply_counts(path):
    """(vertices, faces) of a binary PLY that holds exactly the bytes its header announces."""
    data = path.read_bytes()
    end = data.find(b"end_header\n")
    if not data.startswith(b"ply\n") or end < 0:
        raise AssertionError(f"{path}: no PLY header")
    counts, sizes, element = {}, {}, None
    for line in data[:end].decode("ascii").splitlines():
        words = line.split()
        if words[:1] == ["element"]:
            element = words[1]
            counts[element], sizes[element] = int(words[2]), 0
        elif words[:2] == ["property", "list"]:
            sizes[element] += 1 + 3 * 4  # triangles: a uchar count and three ints
        elif words[:1] == ["property"]:
            sizes[element] += 1 if words[1] == "uchar" else 4
    expected = end + len(b"end_header\n") + sum(counts[e] * sizes[e] for e in counts)
    if len(data) != expected:
        raise AssertionError(f"{path}: {len(data)} bytes where its header announces {expected}")
    return counts.get("vertex", 0), counts.get("face", 0)


def trajectory_poses(path):
    """The poses of a TUM trajectory, each line 8 numbers."""
    poses = [line.split() for line in path.read_text().splitlines() if line.strip() and not line.startswith("#")]
    for pose in poses:
        if len(pose) != 8:
            raise AssertionError(f"{path}: a line of {len(pose)} values")
        [float(v) for v in pose]
    return poses


def waits_to_open(pid, path):
    """Whether a thread of process `pid` waits in open() of the FIFO `path` for a reader: the
    kernel's wait_for_partner, or (where /proc hides wait channels) an openat(2) of that path."""
    for task in pathlib.Path(f"/proc/{pid}/task").glob("*"):
        try:
            if (task / "wchan").read_text() == "wait_for_partner":
                return True
            call = (task / "syscall").read_text().split()
            if call[0] != {"x86_64": "257", "aarch64": "56"}.get(os.uname().machine):
                continue
            with open(f"/proc/{pid}/mem", "rb") as memory:
                memory.seek(int(call[2], 16))
                if memory.read(len(str(path)) + 1) == str(path).encode() + b"\0":
                    return True
        except (OSError, IndexError, ValueError):
            continue
    return False


class RunningScan:
    """`sls scan` in the background, its stderr read line by line."""

    def __init__(self, *args):
        self.process = subprocess.Popen([SLS, "scan", *args], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                        text=True)
        self.lines = []
        self.changed = threading.Condition()
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self):
        for line in self.process.stderr:
            with self.changed:
                self.lines.append(line)
                self.changed.notify_all()
        with self.changed:
            self.lines.append(None)
            self.changed.notify_all()

    def kill_after_line(self, needle, timeout=60):
        """SIGKILL once stderr has a line starting with `needle`; False when the scan ended first."""
        with self.changed:
            if not self.changed.wait_for(lambda: None in self.lines or any(
                    line.startswith(needle) for line in self.lines if line), timeout):
                return False
            if None in self.lines and not any(line.startswith(needle) for line in self.lines if line):
                return False
        return self.kill()

    def kill_when_it_writes(self, path, timeout=60):
        """SIGKILL once the scan opens `path` for writing: a FIFO is made there first, whose open()
        waits for a reader (never ours: the scan stays there until killed). False when the scan
        ended without writing it."""
        os.mkfifo(path)
        try:
            deadline = time.monotonic() + timeout
            while self.process.poll() is None and time.monotonic() < deadline:
                if waits_to_open(self.process.pid, path):
                    return self.kill()
                time.sleep(0.005)
            return False
        finally:
            os.unlink(path)  # ours, not the scan's: what is left is what the kill left

    def kill(self):
        self.process.send_signal(signal.SIGKILL)
        self.process.wait(60)
        self.reader.join(60)
        self.process.stderr.close()
        return self.process.returncode == -signal.SIGKILL

    def finish(self):
        self.process.wait(120)
        self.reader.join(60)
        self.process.stderr.close()
        return self.process.returncode, "".join(line for line in self.lines if line)


class SlsFusionKills(unittest.TestCase):
    """kill -9 of `sls scan` at each stage of its fusion (issue 19 item 9): while frames are
    decoded, tracked and integrated, after the last one (loop closure, extraction), and as each
    output file is written. The recording is untouched; every output file in OUT is whole (each
    is written to a temporary and renamed); report.json only stands beside the model it
    describes (the outputs of an earlier run in OUT are not taken for this one's); and the scan
    run again (`--resume` after a capture) writes every output."""

    # In the order sls scan writes them (undeformed/: deformation on); a FIFO at the temporary
    # name of each (NAME.tmp-PID) stops the scan there.
    OUTPUTS = ("undeformed/cloud.ply", "undeformed/trajectory.txt", "render.png", "cloud.ply", "mesh.ply",
               "trajectory.txt", "report.json", "report_view_0.png", "report.html")

    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.dir = pathlib.Path(self.tmp.name)

    def tearDown(self):
        self.tmp.cleanup()

    def assert_outputs_whole(self, out, complete=False):
        """Every output file in `out` whole; report.json, when there, describes the model beside it
        and report.html is there only beside it. A killed write may leave its temporary
        (NAME.tmp-PID), never read; `complete`: every output there and no temporary."""
        files = [p for p in out.rglob("*") if p.is_file() and p.relative_to(out).parts[0] != "recording"]
        for path in files:
            if ".tmp-" in path.name:
                self.assertFalse(complete, f"{path} left behind")
            elif path.suffix == ".ply":
                ply_counts(path)
            elif path.suffix == ".png":
                data = path.read_bytes()
                self.assertTrue(data.startswith(b"\x89PNG") and data.endswith(b"IEND\xaeB`\x82"), path)
            elif path.name == "trajectory.txt":
                trajectory_poses(path)
            elif path.name == "report.json":
                json.loads(path.read_text())
            elif path.name == "report.html":
                self.assertTrue(path.read_text().endswith("</html>\n"), path)
        report_path = out / "report.json"
        if complete:
            for name in self.OUTPUTS:
                self.assertTrue((out / name).is_file(), name)
        if not report_path.exists():
            self.assertFalse((out / "report.html").exists(), "report.html without the report.json it shows")
            return None
        report = json.loads(report_path.read_text())
        self.assertEqual(ply_counts(out / "cloud.ply")[0], report["points"], "cloud.ply of another scan")
        self.assertEqual(ply_counts(out / "mesh.ply")[1], report["triangles"], "mesh.ply of another scan")
        self.assertEqual(len(trajectory_poses(out / "trajectory.txt")), report["frames_fused"])
        return report

    def test_kill_9_at_each_stage_of_fusion_leaves_whole_outputs_and_a_rerun_writes_them_all(self):
        rec = reference()
        before = digest(rec)
        out = self.dir / "scan"
        scan = ("--input", str(rec), "--turntable-prior", "--device", "cpu", "--out", str(out))
        # An earlier scan's outputs in OUT (other poses: another model), as a re-run finds them.
        earlier = run("scan", "--input", str(rec), "--poses", "groundtruth", "--device", "cpu", "--out", str(out))
        self.assertEqual(earlier.returncode, 0, earlier.stderr)
        self.assert_outputs_whole(out, complete=False)
        killed = []
        # While frames are fused (scan: k/N is printed after frame k), after the last one.
        for done in (1, FRAMES - 1, FRAMES):
            running = RunningScan(*scan)
            self.assertTrue(running.kill_after_line(f"scan: {done}/{FRAMES}"), running.lines)
            self.assert_outputs_whole(out)
            killed.append(f"after frame {done}")
        # As each output is written.
        (out / "undeformed").mkdir(exist_ok=True)
        for name in self.OUTPUTS:
            running = RunningScan(*scan)
            self.assertTrue(running.kill_when_it_writes(out / f"{name}.tmp-{running.process.pid}"),
                            f"the scan ended without writing {name}: {running.finish()}")
            self.assert_outputs_whole(out)
            killed.append(name)
        self.assertEqual(digest(rec), before, "the recording changed")
        # A write killed half-way leaves its temporary: the next run removes those of processes
        # that are gone (and leaves a live one's).
        gone = subprocess.Popen(["true"])
        gone.wait()
        for name in ("cloud.ply", "undeformed/trajectory.txt"):
            (out / f"{name}.tmp-{gone.pid}").write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vert")
        (out / f"mesh.ply.tmp-{os.getpid()}").write_bytes(b"ply\n")
        status, stderr = RunningScan(*scan).finish()
        self.assertEqual(status, 0, stderr)
        self.assertTrue((out / f"mesh.ply.tmp-{os.getpid()}").exists(), "a live process's temporary removed")
        (out / f"mesh.ply.tmp-{os.getpid()}").unlink()
        report = self.assert_outputs_whole(out, complete=True)
        self.assertEqual(report["frames_fused"], FRAMES)
        self.assertEqual(digest(rec), before, "the recording changed")
        inspect = json.loads(run("--json", "inspect", "--deep", str(rec)).stdout)
        self.assertTrue(inspect["ok"], inspect)

    def test_kill_9_while_fusing_a_capture_and_resume_writes_every_output(self):
        # A capture done (sls scan --sim): OUT/recording complete, as the reference; its fusion
        # killed while fusing frames and while writing the model, then resumed.
        out = self.dir / "sim"
        shutil.copytree(reference(), out / "recording")
        before = digest(out / "recording")
        resume = ("--resume", "--turntable-prior", "--device", "cpu", "--out", str(out))
        running = RunningScan(*resume)
        self.assertTrue(running.kill_after_line(f"scan: 2/{FRAMES}"), running.lines)
        self.assert_outputs_whole(out)
        running = RunningScan(*resume)
        self.assertTrue(running.kill_when_it_writes(out / f"mesh.ply.tmp-{running.process.pid}"))
        self.assert_outputs_whole(out)
        self.assertEqual(digest(out / "recording"), before, "the recording changed")
        status, stderr = RunningScan(*resume).finish()
        self.assertEqual(status, 0, stderr)
        self.assertIn("is complete (4 frames): fusing it", stderr)
        self.assertEqual(self.assert_outputs_whole(out, complete=True)["frames_fused"], FRAMES)
        self.assertEqual(digest(out / "recording"), before, "the recording changed")


if __name__ == "__main__":
    SLS = os.path.abspath(sys.argv.pop(1))
    unittest.main(verbosity=2)
