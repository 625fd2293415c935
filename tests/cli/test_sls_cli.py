#!/usr/bin/env python3
"""Drives the `sls` binary as a user would: help and version, JSON output, exit statuses,
`inspect` on good and corrupt files, `scan` tracking a simulated turntable scan (a corrupt
frame reported, an interrupt leaving a valid partial model, online deformation and the loop
closure, each switched off). `sim`, `decode` and `eval` are in test_sls_sim_decode_eval.py. Usage: test_sls_cli.py PATH_TO_SLS (stdlib only)."""
import json
import os
import pathlib
import re
import signal
import struct
import subprocess
import sys
import tempfile
import unittest

SLS = None


def run(*args):
    return subprocess.run([SLS, *args], capture_output=True, text=True, timeout=120)


def write_binary_ply(path, points):
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(points)}\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
    )
    with open(path, "wb") as f:
        f.write(header.encode())
        for p in points:
            f.write(struct.pack("<3f", *p))


class SlsCli(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.dir = pathlib.Path(self.tmp.name)

    def tearDown(self):
        self.tmp.cleanup()

    def test_help_lists_every_command_and_each_has_help(self):
        result = run("--help")
        self.assertEqual(result.returncode, 0)
        for command in ("info", "inspect", "scan", "sim", "decode", "eval", "devices"):
            self.assertIn(command, result.stdout)
            sub = run(command, "--help")
            self.assertEqual(sub.returncode, 0, sub.stderr)
            self.assertIn("Usage", sub.stdout)

    def test_version(self):
        result = run("--version")
        self.assertEqual(result.returncode, 0)
        self.assertRegex(result.stdout, r"sls \d+\.\d+\.\d+")

    def test_bad_command_line_is_exit_2(self):
        self.assertEqual(run("scan", "--sim", "nonsense", "--out", str(self.dir)).returncode, 2)
        unknown = run("no-such-command")
        self.assertEqual(unknown.returncode, 2)
        self.assertIn("unknown command 'no-such-command'", unknown.stderr)
        self.assertIn("scan", unknown.stderr)
        # Numbers out of range, NaN and a flag that would be ignored are refused (exit 2)
        # before any work.
        out = str(self.dir / "never")
        for args in (("--voxel-um", "1e-20"), ("--voxel-um", "1e9"), ("--voxel-um", "nan"),
                     ("--max-voxels", "nan"), ("--max-voxels", "inf"), ("--max-voxels", "-1"),
                     ("--max-gpu-memory", "-1"), ("--max-gpu-memory", "nan"), ("--max-gpu-memory", "inf")):
            result = run("scan", "--sim", "ci", *args, "--out", out)
            self.assertEqual(result.returncode, 2, args)
            self.assertIn(args[0], result.stderr)
        ignored = run("scan", "--input", str(self.dir), "--frames", "3", "--out", out)
        self.assertEqual(ignored.returncode, 2)
        self.assertIn("not with --input", ignored.stderr)
        self.assertFalse(os.path.exists(out))

    def test_info_json(self):
        result = run("--json", "info")
        self.assertEqual(result.returncode, 0)
        info = json.loads(result.stdout)
        self.assertIn("cuda_compiled", info)
        self.assertIsInstance(info["cuda_devices"], list)

    def test_bench_times_a_revolution_end_to_end(self):
        # A short ci-preset revolution, both inputs: the end-to-end seconds hold the frames, the
        # loop closure and the final model, with every stage's median and total beside them.
        for extra in (("--input", "depth", "--deformation", "off"),
                      ("--frames", "3", "--turntable-prior", "--upload-ahead", "off", "--background-shipping", "off",
                       "--stack-memory", "pinned")):
            # A GPU memory budget does not apply on the CPU: accepted, and the run is the same.
            args = ("--json", "bench", "--preset", "ci", "--object", "knurled-knob", "--device", "cpu",
                    "--max-gpu-memory", "6e9")
            if "--frames" not in extra:
                args += ("--frames", "4")
            result = run(*args, *extra)
            self.assertEqual(result.returncode, 0, result.stderr)
            bench = json.loads(result.stdout)
            frames = 3 if "--frames" in extra else 4
            self.assertEqual((bench["preset"], bench["frames"], bench["device"]), ("ci", frames, "cpu"))
            self.assertAlmostEqual(bench["end_to_end_s"],
                                   bench["frames_s"] + bench["loop_closure_s"] + bench["extract_s"], places=6)
            # The final model's parts lie within it (the assembly is part of the volume's surface;
            # a surface found beside the loop closure, on a GPU only, counts what it was waited for).
            parts = bench["extract_stages"]
            self.assertFalse(parts["volume_surface_beside_loop_closure"])
            self.assertEqual(parts["wait_volume_surface_s"], 0.0)
            self.assertLessEqual(parts["wait_ship_s"] + parts["volume_surface_s"] + parts["join_s"] + parts["deform_s"],
                                 bench["extract_s"] + 1e-6)
            self.assertLessEqual(parts["assemble_s"], parts["volume_surface_s"] + 1e-9)
            self.assertEqual(parts["deform_s"] > 0.0, "--deformation" not in extra)
            self.assertGreater(bench["frames_s"], 0.0)
            self.assertGreater(bench["points"], 0)
            # Frames fused at the turntable prior without being tracked are counted among the fused.
            self.assertLessEqual(bench["frames_unverified"], bench["frames_fused"])
            self.assertEqual(bench["frames_fused"] + bench["frames_lost"], frames)
            for stage in ("decode", "track", "integrate", "move", "raycast", "deform", "upload_wait"):
                self.assertGreaterEqual(bench["stages"][stage]["total_s"], 0.0)
            # The stages are parts of the frames' time, one after the other.
            self.assertLessEqual(sum(figures["total_s"] for figures in bench["stages"].values()),
                                 bench["frames_s"] + 1e-6)
            # A move's parts add up to no more than the moves' stage (on the CPU the ship is in the move).
            parts = bench["volume"]["move_stages"]
            self.assertLessEqual(parts["resample"]["total_s"] + parts["ship"]["total_s"],
                                 bench["stages"]["move"]["total_s"] + 1e-9)
            self.assertLessEqual(parts["ship_assemble"]["total_s"], parts["ship"]["total_s"] + 1e-9)
            self.assertLessEqual(bench["frame_ms"]["median"], bench["frame_ms"]["max"])
            # Every frame's own figures: the frames' time is their sum, the stages lie within each.
            per_frame = bench["per_frame"]
            self.assertEqual(sorted(per_frame), sorted(
                ("frame_ms", "decode_ms", "track_ms", "integrate_ms", "move_ms", "raycast_ms", "deform_ms",
                 "upload_wait_ms")))
            self.assertTrue(all(len(column) == frames for column in per_frame.values()))
            self.assertAlmostEqual(sum(per_frame["frame_ms"]) * 1e-3, bench["frames_s"], places=6)
            self.assertEqual(max(per_frame["frame_ms"]), bench["frame_ms"]["max"])
            for k in range(frames):
                stages = sum(per_frame[key][k] for key in per_frame if key != "frame_ms")
                self.assertLessEqual(stages, per_frame["frame_ms"][k] + 1e-6)
            self.assertNotIn("gpu", bench)
            self.assertFalse(bench["upload_ahead"])  # on the CPU there is nothing to upload
            self.assertEqual(bench["stages"]["upload_wait"]["total_s"], 0.0)
            self.assertFalse(bench["background_shipping"])  # nor to ship beside the frames
            # Pattern images page-locked only when asked for (auto: on a GPU) and a GPU can lock them.
            if "--stack-memory" in extra:
                has_gpu = bool(json.loads(run("--json", "info").stdout)["cuda_devices"])
                self.assertEqual(bench["stack_memory"], "pinned" if has_gpu else "host")
            else:
                self.assertEqual(bench["stack_memory"], "host")
            # The model's accuracy against the exact scene, measured after the timed part (JSON
            # has no NaN or infinity: a figure that could not be measured is null).
            accuracy = bench["accuracy"]
            self.assertGreater(bench["evaluate_s"], 0.0)
            self.assertEqual(accuracy["points"], bench["points"])
            self.assertEqual(accuracy["evaluated_points"], bench["points"])  # all of them at this size
            self.assertAlmostEqual(accuracy["edge_band_um"], 3 * bench["volume"]["voxel_size_m"] * 1e6, places=6)
            for key in ("c2c_mean_um", "c2c_rms_um", "c2c_p95_um", "c2c_edge_mean_um"):  # the knob has creases
                self.assertTrue(isinstance(accuracy[key], (int, float)), (key, accuracy))
            self.assertGreater(accuracy["c2c_mean_um"], 0.0)
            self.assertLess(accuracy["c2c_mean_um"], 1000.0)  # below 1 mm: the model is in the object frame
            self.assertLessEqual(accuracy["c2c_mean_um"], accuracy["c2c_rms_um"])
            for key in ("ate_rmse_um", "ate_max_um", "loop_closure_error_um", "loop_closure_error_deg"):
                self.assertIn(key, accuracy)
            if bench["frames_fused"] >= 2:
                for key in ("ate_rmse_um", "ate_max_um", "loop_closure_error_um", "loop_closure_error_deg"):
                    self.assertTrue(isinstance(accuracy[key], (int, float)) and accuracy[key] >= 0.0, (key, accuracy))
                self.assertLessEqual(accuracy["ate_rmse_um"], accuracy["ate_max_um"])
                self.assertLess(accuracy["loop_closure_error_um"], 1000.0)
                self.assertLess(accuracy["loop_closure_error_deg"], 1.0)
            else:  # one fused frame: no trajectory to measure, and the JSON says why
                self.assertIsNone(accuracy["ate_rmse_um"])
                self.assertIn("trajectory_note", accuracy)
        self.assertGreaterEqual(bench["frames_fused"], 2)  # with the turntable prior: a trajectory measured
        self.assertIsNotNone(accuracy["loop_closure_error_um"])
        self.assertEqual(bench["images_per_frame"], 22)
        self.assertGreater(bench["stages"]["decode"]["total_s"], 0.0)  # the stacks decoded in the timed part
        self.assertIsNotNone(bench["loop_closure"])
        if bench["loop_closure"]["closed"]:  # the loop closure's time holds its solve's
            self.assertLessEqual(bench["loop_closure"]["solve_ms"], bench["loop_closure"]["ms"])
        human = run("bench", "--preset", "ci", "--frames", "2", "--input", "depth", "--device", "cpu")
        self.assertEqual(human.returncode, 0, human.stderr)
        self.assertIn("end to end", human.stdout)
        self.assertIn("accuracy against the exact scene", human.stdout)
        self.assertEqual(run("bench", "--preset", "huge").returncode, 2)
        self.assertEqual(run("bench", "--upload-ahead", "maybe").returncode, 2)
        self.assertEqual(run("bench", "--background-shipping", "maybe").returncode, 2)
        self.assertEqual(run("bench", "--max-gpu-memory", "-1").returncode, 2)

    def test_devices_lists_the_simulator_with_an_openable_uri(self):
        # --json before or after the command.
        for args in (("--json", "devices"), ("devices", "--json")):
            result = run(*args)
            self.assertEqual(result.returncode, 0, result.stderr)
            out = json.loads(result.stdout)
            uris = [device["uri"] for device in out["devices"]]
            self.assertIn("sim://knurled-screw?preset=ci", uris)
            for device in out["devices"]:
                self.assertIn(device["kind"], ("camera", "projector", "controller", "scanner"))
                self.assertTrue(device["opens_as"], device)
            self.assertEqual(out["hardware_found"], any(d["kind"] != "scanner" for d in out["devices"]))
            self.assertEqual([t["name"] for t in out["transports"]], ["simulator", "Aravis", "USB"])
        human = run("devices")
        self.assertEqual(human.returncode, 0, human.stderr)
        lines = human.stdout.splitlines()
        # One line per device, each with its URI.
        for uri in uris:
            self.assertEqual(sum(uri in line for line in lines), 1, human.stdout)
        if not out["hardware_found"]:
            self.assertIn("No hardware found", human.stdout)

    def test_inspect_good_ply_and_trajectory(self):
        ply = self.dir / "cloud.ply"
        write_binary_ply(ply, [(0.0, 0.0, 0.0), (0.001, 0.002, 0.003)])
        tum = self.dir / "trajectory.txt"
        tum.write_text("# t tx ty tz qx qy qz qw\n0 0 0 0 0 0 0 1\n1 0.003 0.004 0 0 0 0 1\n")
        result = run("--json", "inspect", str(ply), str(tum))
        self.assertEqual(result.returncode, 0, result.stderr)
        out = json.loads(result.stdout)
        self.assertTrue(out["ok"])
        cloud, trajectory = out["results"]
        self.assertEqual(cloud["points"], 2)
        self.assertAlmostEqual(cloud["bounds_max_m"][2], 0.003, places=6)
        self.assertEqual(trajectory["poses"], 2)
        self.assertAlmostEqual(trajectory["path_length_m"], 0.005, places=9)

    def test_inspect_corrupt_files_name_file_and_problem(self):
        truncated = self.dir / "truncated.ply"
        write_binary_ply(truncated, [(0.0, 0.0, 0.0)] * 10)
        truncated.write_bytes(truncated.read_bytes()[:-7])
        recording = self.dir / "rec"
        recording.mkdir()
        (recording / "manifest.json").write_text('{"format": "slscan-recording", "format_ver')
        calibration = self.dir / "calibration.yml"
        calibration.write_text("%YAML:1.0\n---\ncamera_width: 100\n")
        for path in (truncated, recording, calibration):
            result = run("--json", "inspect", str(path))
            self.assertEqual(result.returncode, 1, path)
            out = json.loads(result.stdout)
            self.assertFalse(out["ok"])
            message = out["results"][0]["message"]
            self.assertIn(path.name, message)
            self.assertIn(path.name, result.stderr)

    def test_inspect_missing_path(self):
        result = run("inspect", str(self.dir / "nope.ply"))
        self.assertEqual(result.returncode, 1)
        self.assertIn("nope.ply", result.stderr)

    def knob_depth_recording(self):
        """A depth-mode recording of the knurled knob, 36 frames per revolution (ci preset)."""
        rec = self.dir / "rec"
        result = run("sim", "--preset", "ci", "--object", "knurled-knob", "--frames", "36", "--mode", "depth",
                     "--device", "cpu", "--out", str(rec))
        self.assertEqual(result.returncode, 0, result.stderr)
        return rec

    def test_scan_tracks_a_turntable_scan_and_reports_it(self):
        # A depth-mode recording of the knurled knob, 36 frames per revolution (10 degree steps:
        # the turntable prior gives the guess), one frame's depth map corrupted.
        rec = self.knob_depth_recording()
        depth = rec / "frames" / "000007" / "depth.png"
        depth.write_bytes(depth.read_bytes()[:200])
        out = self.dir / "tracked"
        result = run("--json", "scan", "--input", str(rec), "--turntable-prior", "--device", "cpu", "--out", str(out))
        self.assertEqual(result.returncode, 0, result.stderr)
        report = json.loads(result.stdout)
        self.assertEqual(report["poses"], "track")
        self.assertEqual(report["frames"], 36)
        # The corrupt frame is reported, not fused, and the scan went on past it.
        self.assertEqual([(f["frame"], f["status"]) for f in report["lost_frames"]], [(7, "skipped")])
        self.assertIn("depth.png", report["lost_frames"][0]["reason"])
        self.assertEqual(report["frames_fused"], 35)
        self.assertGreater(report["volume"]["moves"], 0)
        # One revolution (36 steps of 10 degrees, to 350): every pass shipped, none merged.
        self.assertEqual(report["revisits"]["policy"], "auto")
        self.assertAlmostEqual(report["revisits"]["turned_deg"], 350.0, delta=1e-6)
        self.assertIsNone(report["revisits"]["merged_from_frame"])
        for stage in ("read", "decode", "track", "integrate", "move", "raycast", "extract"):
            self.assertIn(stage, report["ms_per_stage"])
        for name in ("cloud.ply", "mesh.ply", "trajectory.txt", "report.json", "report.html", "render.png"):
            self.assertTrue((out / name).exists(), name)
        # Each tracked frame says how many live pixels lay outside the volume (not counted in its
        # overlap test); on the CPU a move ships with it, so its entry gives what it shipped.
        per_frame = json.loads((out / "report.json").read_text())["per_frame"]
        tracked_frames = [f["tracking"] for f in per_frame if "tracking" in f]
        self.assertGreater(len(tracked_frames), 30)
        for tracking in tracked_frames:
            self.assertGreaterEqual(tracking["pixels_outside_volume"], 0)
        moves = [f["move"] for f in per_frame if "move" in f]
        self.assertEqual(len(moves), report["volume"]["moves"])
        self.assertTrue(all(m["shipped_points"] >= 0 for m in moves))
        self.assertFalse(any("shipped" in f for f in per_frame))
        evaluation = json.loads(run("--json", "eval", "--result", str(out), "--truth", str(rec)).stdout)
        for key in ("ate_rmse_um", "loop_closure_error_um", "loop_closure_error_deg"):
            self.assertIn(key, evaluation)
        # 30 um pixels fused into ~60 um voxels: the model and the trajectory within a few voxels.
        self.assertLess(evaluation["c2c_mean_um"], 60.0)
        self.assertLess(evaluation["ate_rmse_um"], 300.0)
        self.assertGreater(evaluation["coverage"], 0.9)

        # Online deformation (on by default) and, the recording being a full revolution, the
        # loop closure: the last frame registered to the first, the graph solved.
        deformation, loop = report["deformation"], report["loop_closure"]
        self.assertTrue(deformation["enabled"], deformation)
        self.assertGreater(deformation["nodes"], 1)
        self.assertNotIn("error", deformation)
        # The simulator's calibration knows the table's repeatability: every fused frame's
        # table angle holds its pose in the graph.
        self.assertEqual(deformation["rotation_priors"], report["frames_fused"])
        self.assertTrue(loop["requested"], loop)
        self.assertIn("full turntable revolution", loop["why"])
        self.assertTrue(loop["closed"], loop)
        self.assertEqual((loop["first_frame"], loop["last_frame"]), (0, 35))
        for stage in ("deform", "loop_closure", "evaluate"):
            self.assertIn(stage, report["ms_per_stage"])
        # The model and trajectory as tracked beside the deformed ones, both measured.
        undeformed = out / "undeformed"
        inspect = json.loads(run("--json", "inspect", str(out / "cloud.ply"), str(undeformed / "cloud.ply"),
                                 str(undeformed / "trajectory.txt")).stdout)
        self.assertTrue(inspect["ok"], inspect)
        deformed_cloud, tracked_cloud, tracked_trajectory = inspect["results"]
        self.assertIn("correction", deformed_cloud["properties"])
        self.assertNotIn("correction", tracked_cloud["properties"])
        self.assertEqual(tracked_trajectory["poses"], 35)
        for key in ("evaluation", "evaluation_undeformed"):
            self.assertIn("ate_rmse_um", report[key], key)
            self.assertIn("c2c_mean_um", report[key], key)
        html = (out / "report.html").read_text()
        for needle in ("Deformation and loop closure", "Quality with and without deformation", "deformation-chart"):
            self.assertIn(needle, html)
        self.assertTrue((out / "report_correction_0.png").exists())
        # sls eval measures RESULT/undeformed too, at the result's voxel size: the figures the
        # scan reported for it.
        self.assertIn("undeformed", evaluation)
        tracked = evaluation["undeformed"]
        self.assertEqual(tracked["result"], str(undeformed))
        self.assertEqual(tracked["voxel_size_m"], evaluation["voxel_size_m"])
        for key in ("c2c_mean_um", "c2c_rms_um", "c2c_p95_um", "c2c_edge_mean_um", "coverage", "ate_rmse_um",
                    "loop_closure_error_um", "loop_closure_error_deg"):
            self.assertIn(key, tracked)
            self.assertAlmostEqual(tracked[key], report["evaluation_undeformed"][key], places=3, msg=key)
        human = run("eval", "--result", str(out), "--truth", str(rec))
        self.assertEqual(human.returncode, 0, human.stderr)
        self.assertRegex(human.stdout, r"deformed +as tracked")
        self.assertRegex(human.stdout, r"ATE RMSE +[0-9.]+ um +[0-9.]+ um")

        # --deformation off: the model as tracked, nothing in OUT/undeformed, no loop closure
        # (a short simulated scan: the switches, not the figures, are under test here).
        rigid = self.dir / "rigid"
        result = run("--json", "scan", "--sim", "ci", "--frames", "4", "--turntable-prior", "--device", "cpu",
                     "--deformation", "off", "--out", str(rigid))
        self.assertEqual(result.returncode, 0, result.stderr)
        report = json.loads(result.stdout)
        self.assertEqual(report["deformation"], {"enabled": False})
        self.assertEqual(report["loop_closure"], {"requested": False, "why": "--deformation off"})
        self.assertNotIn("evaluation_undeformed", report)
        self.assertFalse((rigid / "undeformed").exists())
        self.assertNotIn("Deformation and loop closure", (rigid / "report.html").read_text())
        self.assertNotIn("undeformed", json.loads(run("--json", "eval", "--result", str(rigid), "--truth",
                                                      str(rigid / "recording")).stdout))

        # --loop-closure off: deformation still runs, the loop is left open.
        open_loop = self.dir / "open"
        result = run("--json", "scan", "--sim", "ci", "--frames", "4", "--turntable-prior", "--device", "cpu",
                     "--loop-closure", "off", "--out", str(open_loop))
        self.assertEqual(result.returncode, 0, result.stderr)
        report = json.loads(result.stdout)
        self.assertTrue(report["deformation"]["enabled"])
        self.assertEqual(report["loop_closure"], {"requested": False, "why": "--loop-closure off"})
        self.assertTrue((open_loop / "undeformed" / "cloud.ply").exists())

    def test_scan_deformation_and_loop_closure_options(self):
        help_text = run("scan", "--help").stdout
        for option in ("--deformation", "--loop-closure"):
            self.assertIn(option, help_text)
        self.assertIn("undeformed", run("eval", "--help").stdout)
        for option in ("--deformation", "--loop-closure"):
            bad = run("scan", "--sim", "ci", option, "maybe", "--out", str(self.dir / "bad"))
            self.assertEqual(bad.returncode, 2, bad.stderr)
            self.assertIn(option, bad.stderr)
            self.assertFalse((self.dir / "bad").exists())

    def test_scan_with_another_calibration(self):
        # A recording decoded with a calibration other than its own (a new calibration of the
        # head), also when the recording has none; one of another camera size is refused.
        rec = self.dir / "rec"
        self.assertEqual(run("sim", "--preset", "ci", "--frames", "2", "--device", "cpu", "--out", str(rec)).returncode, 0)
        text = (rec / "calibration.yml").read_text()
        other = self.dir / "other.yml"
        other.write_text(text)
        (rec / "calibration.yml").unlink()
        manifest = json.loads((rec / "manifest.json").read_text())
        manifest["calibration"] = None
        (rec / "manifest.json").write_text(json.dumps(manifest))
        without = run("scan", "--input", str(rec), "--device", "cpu", "--out", str(self.dir / "none"))
        self.assertEqual(without.returncode, 1)
        self.assertIn("no calibration.yml", without.stderr)
        result = run("--json", "scan", "--input", str(rec), "--calibration", str(other), "--device", "cpu", "--out",
                     str(self.dir / "scan"))
        self.assertEqual(result.returncode, 0, result.stderr)
        self.assertEqual(json.loads(result.stdout)["calibration"], str(other))
        wrong = self.dir / "wrong.yml"
        wrong.write_text(text.replace("camera_width: 400", "camera_width: 404"))
        refused = run("scan", "--input", str(rec), "--calibration", str(wrong), "--device", "cpu", "--out",
                      str(self.dir / "wrong"))
        self.assertEqual(refused.returncode, 1)
        self.assertIn("was recorded at 400x300", refused.stderr)

    def test_gtsdf_parameters_decode_calibration_and_table_one_regions(self):
        # The GTSDF parameters reach the integrator (report.json), only with --fusion gtsdf; a
        # recording decoded with another calibration; the model's C2C in the four quadrants of
        # frame 0's view against that view's raw scan (the paper's Table I).
        out, rec = self.dir / "gt", self.dir / "gt" / "recording"
        result = run("--json", "scan", "--sim", "ci", "--frames", "4", "--device", "cpu", "--poses", "groundtruth",
                     "--gtsdf-lambda", "2", "--gtsdf-kappa", "0.3", "--gtsdf-penalty", "charbonnier",
                     "--gtsdf-iterations", "2", "--out", str(out))
        self.assertEqual(result.returncode, 0, result.stderr)
        fusion = json.loads((out / "report.json").read_text())["fusion"]
        self.assertEqual((fusion["lambda"], fusion["kappa"], fusion["penalty"], fusion["iterations"]),
                         (2.0, 0.3, "charbonnier", 2))
        refused = run("scan", "--sim", "ci", "--fusion", "tsdf", "--gtsdf-lambda", "2", "--out", str(self.dir / "t"))
        self.assertEqual(refused.returncode, 2)
        self.assertIn("--fusion gtsdf", refused.stderr)
        self.assertEqual(run("scan", "--sim", "ci", "--gtsdf-penalty", "huber", "--out",
                             str(self.dir / "t")).returncode, 2)

        other = self.dir / "other.yml"
        other.write_text((rec / "calibration.yml").read_text())
        decoded = run("--json", "decode", "--input", str(rec), "--calibration", str(other), "--no-clouds",
                      "--device", "cpu", "--out", str(self.dir / "decoded"))
        self.assertEqual(decoded.returncode, 0, decoded.stderr)
        self.assertEqual(json.loads((self.dir / "decoded" / "decode.json").read_text())["calibration"], str(other))
        wrong = self.dir / "wrong.yml"
        wrong.write_text(other.read_text().replace("camera_width: 400", "camera_width: 404"))
        refused = run("decode", "--input", str(rec), "--calibration", str(wrong), "--device", "cpu",
                      "--out", str(self.dir / "wrong"))
        self.assertEqual(refused.returncode, 1)
        self.assertIn("404x300", refused.stderr)

        raw = self.dir / "decoded" / "frames" / "000000" / "depth.pfm"
        evaluation = json.loads(run("--json", "eval", "--result", str(out), "--truth", str(rec), "--raw-scan",
                                    str(raw)).stdout)
        regions = evaluation["regions"]
        self.assertEqual(regions["frame"], 0)
        names = ("upper-left", "upper-right", "lower-left", "lower-right")
        self.assertEqual(sum(regions[n]["points"] for n in names), regions["visible_points"])
        self.assertGreater(regions["visible_points"], 0.2 * regions["model_points"])
        for name in names + ("all",):
            # 4 exact views of 30 um pixels: within a fraction of a voxel of the surface; the raw
            # scan is one noisy view, so farther.
            self.assertLess(regions[name]["to_surface_mean_um"], 15.0, name)
            self.assertGreater(regions[name]["to_raw_scan_mean_um"], regions[name]["to_surface_mean_um"], name)
        self.assertIn("C2C in the four quadrants", run("eval", "--result", str(out), "--truth", str(rec),
                                                       "--raw-scan", str(raw)).stdout)
        missing = run("eval", "--result", str(out), "--truth", str(rec), "--raw-scan", str(raw),
                      "--raw-scan-frame", "9")
        self.assertEqual(missing.returncode, 1)
        self.assertIn("frames 0..3", missing.stderr)

    def test_scan_refuses_an_output_it_cannot_write_or_inside_its_input_before_any_work(self):
        rec = self.dir / "rec"
        self.assertEqual(run("sim", "--preset", "ci", "--frames", "2", "--device", "cpu", "--out", str(rec)).returncode, 0)
        truth = (rec / "groundtruth" / "trajectory.txt").read_bytes()
        for out in (rec / "groundtruth", rec, self.dir / "link" / "x"):
            if out.parent.name == "link":
                (self.dir / "link").symlink_to(rec)
            result = run("--json", "scan", "--input", str(rec), "--poses", "groundtruth", "--device", "cpu",
                         "--out", str(out))
            self.assertEqual(result.returncode, 1, result.stderr)
            self.assertIn("inside the recording", result.stderr)
            self.assertEqual(json.loads(result.stdout)["ok"], False)
        self.assertEqual((rec / "groundtruth" / "trajectory.txt").read_bytes(), truth)
        blocker = self.dir / "a-file"
        blocker.write_text("x")
        for out in (blocker, blocker / "below"):
            result = run("scan", "--input", str(rec), "--device", "cpu", "--out", str(out))
            self.assertEqual(result.returncode, 1, result.stderr)
            self.assertIn(str(blocker), result.stderr)
            self.assertNotIn("internal error", result.stderr)
            self.assertNotIn("decode", result.stderr)  # refused before any frame
        if os.geteuid() != 0:  # root writes into read-only folders
            locked = self.dir / "locked"
            locked.mkdir()
            locked.chmod(0o555)
            result = run("scan", "--input", str(rec), "--device", "cpu", "--out", str(locked))
            locked.chmod(0o755)
            self.assertEqual(result.returncode, 1, result.stderr)
            self.assertIn("not writable", result.stderr)

    def test_scan_interrupted_leaves_a_valid_partial_model(self):
        rec = self.knob_depth_recording()
        out = self.dir / "partial"
        scan = subprocess.Popen([SLS, "scan", "--input", str(rec), "--turntable-prior", "--device", "cpu",
                                 "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        # Interrupt (SIGINT) once the progress display says a tenth of the frames are done.
        for line in scan.stderr:
            if line.startswith("scan: ") and not line.startswith("scan: 0/"):
                break
        scan.send_signal(signal.SIGINT)
        stdout, stderr = scan.communicate(timeout=120)
        self.assertEqual(scan.returncode, 4, stderr)
        report = json.loads((out / "report.json").read_text())
        self.assertTrue(report["interrupted"])
        self.assertGreater(report["frames_fused"], 0)
        self.assertLess(report["frames_processed"], 36)
        inspect = json.loads(run("--json", "inspect", str(out / "cloud.ply"), str(out / "mesh.ply"),
                                 str(out / "trajectory.txt")).stdout)
        self.assertTrue(inspect["ok"], inspect)
        self.assertIn("interrupted", stdout)

    def test_scan_fuses_with_ground_truth_poses_and_eval_measures_it(self):
        out = self.dir / "gt"
        result = run("--json", "scan", "--sim", "ci", "--frames", "4", "--device", "cpu", "--poses", "groundtruth",
                     "--fusion", "gtsdf", "--out", str(out))
        self.assertEqual(result.returncode, 0, result.stderr)
        report = json.loads(result.stdout)
        self.assertEqual(report["frames_fused"], 4)
        self.assertEqual(report["lost_frames"], [])
        self.assertGreater(report["points"], 10000)
        self.assertEqual(json.loads((out / "report.json").read_text())["points"], report["points"])
        # The simulator's own recording has no capture counters: no per-frame "capture" key.
        self.assertEqual([f for f in report["per_frame"] if "capture" in f], [])
        for name in ("cloud.ply", "mesh.ply", "trajectory.txt"):
            self.assertTrue((out / name).exists(), name)
        inspect = json.loads(run("--json", "inspect", str(out / "cloud.ply"), str(out / "mesh.ply"),
                                 str(out / "trajectory.txt")).stdout)
        self.assertTrue(inspect["ok"], inspect)
        evaluation = json.loads(run("--json", "eval", "--result", str(out), "--truth", str(out / "recording")).stdout)
        # Ground-truth poses, 4 views of 30 um pixels into ~70 um voxels: the model lies within
        # a fraction of a voxel of the exact surface, over everything the 4 views saw.
        self.assertLess(evaluation["c2c_mean_um"], 15.0)
        self.assertGreater(evaluation["coverage"], 0.95)
        # Fused with the true poses, its trajectory is the true one: no ATE, no loop error.
        self.assertEqual(evaluation["ate_frames"], 4)
        for key in ("ate_rmse_um", "loop_closure_error_um", "loop_closure_error_deg"):
            self.assertLess(evaluation[key], 1e-3, key)
        self.assertNotIn("trajectory_note", evaluation)
        human = run("eval", "--result", str(out), "--truth", str(out / "recording")).stdout
        self.assertIn("trajectory: ATE rmse", human)
        self.assertIn("loop closure", human)
        # A recording without ground truth cannot be fused with --poses groundtruth.
        (out / "recording" / "groundtruth" / "trajectory.txt").unlink()
        again = run("scan", "--input", str(out / "recording"), "--poses", "groundtruth", "--device", "cpu",
                    "--out", str(self.dir / "gt2"))
        self.assertEqual(again.returncode, 1)
        self.assertIn("ground-truth trajectory", again.stderr)

    def test_scan_devices_by_uri_through_the_sequencer(self):
        uri = "sim://knurled-screw?preset=ci"
        rec = self.dir / "calibrated"
        self.assertEqual(run("sim", "--preset", "ci", "--frames", "1", "--device", "cpu", "--out", str(rec)).returncode, 0)
        out = self.dir / "byuri"
        result = run("scan", "--camera", uri, "--projector", uri, "--turntable", uri, "--frames", "3",
                     "--calibration", str(rec / "calibration.yml"), "--device", "cpu", "--out", str(out))
        # Captured through the devices, then decoded, tracked and fused.
        self.assertEqual(result.returncode, 0, result.stderr)
        self.assertTrue((out / "cloud.ply").exists())
        inspect = json.loads(run("--json", "inspect", str(out / "recording")).stdout)["results"][0]
        self.assertTrue(inspect["calibrated"])
        self.assertEqual(inspect["frames"], 3)
        self.assertEqual(inspect["frames_with_turntable_angle"], 3)
        # Each frame's capture counters, kept in the recording: report.json's per_frame carries
        # them (the simulated camera counts no packets: no packet keys), also when the recording
        # is scanned again on its own.
        clean = {"attempts": 1, "incomplete_images": 0, "lost_images": 0, "stale_images": 0}
        report = json.loads((out / "report.json").read_text())
        self.assertEqual([f.get("capture") for f in report["per_frame"]], [clean] * 3)
        # Fused while it captured (a calibration given): each frame's captured_s and fused_s, in
        # order, and the pipeline's counts.
        self.assertEqual(report["pipeline"]["source"], "capture")
        self.assertEqual(report["pipeline"]["delivered"], 3)
        self.assertEqual(report["live_capture"]["frames_captured"], 3)
        for before, after in zip(report["per_frame"], report["per_frame"][1:]):
            self.assertLessEqual(before["fused_s"], after["fused_s"])
        for frame in report["per_frame"]:
            self.assertLessEqual(frame["captured_s"], frame["fused_s"])
        # The final model comes after the last frame fused, on the same clock.
        self.assertLessEqual(report["per_frame"][-1]["fused_s"], report["pipeline"]["model_s"])
        again = run("--json", "scan", "--input", str(out / "recording"), "--device", "cpu", "--out", str(self.dir / "again"))
        self.assertEqual(again.returncode, 0, again.stderr)
        again_report = json.loads(again.stdout)
        self.assertEqual([f.get("capture") for f in again_report["per_frame"]], [clean] * 3)
        self.assertEqual(again_report["pipeline"]["source"], "recording")
        self.assertNotIn("live_capture", again_report)
        # The model fused while capturing is the one the recording gives scanned on its own.
        self.assertEqual((out / "cloud.ply").read_bytes(), (self.dir / "again" / "cloud.ply").read_bytes())
        # Without a calibration the capture is kept and the command says why it stops.
        result = run("scan", "--camera", uri, "--projector", uri, "--frames", "1", "--device", "cpu",
                     "--out", str(self.dir / "uncalibrated"))
        self.assertEqual(result.returncode, 1)
        self.assertIn("without --calibration", result.stderr)
        self.assertEqual(json.loads(run("--json", "inspect", str(self.dir / "uncalibrated/recording")).stdout)
                         ["results"][0]["frames"], 1)
        # A scheme no driver handles is named.
        result = run("scan", "--camera", "nonsense://x", "--projector", uri, "--out", str(self.dir / "bad"))
        self.assertEqual(result.returncode, 3, result.stderr)
        self.assertIn("nonsense://x", result.stderr)

    def test_scan_no_record_writes_no_recording_and_the_recorded_runs_model(self):
        uri = "sim://knurled-screw?preset=ci"
        rec = self.dir / "calibration-source"
        self.assertEqual(run("sim", "--preset", "ci", "--frames", "1", "--device", "cpu", "--out", str(rec)).returncode, 0)
        common = ["--camera", uri, "--projector", uri, "--turntable", uri, "--frames", "3",
                  "--calibration", str(rec / "calibration.yml"), "--device", "cpu"]
        recorded, unrecorded = self.dir / "recorded", self.dir / "unrecorded"
        result = run("scan", *common, "--out", str(recorded))
        self.assertEqual(result.returncode, 0, result.stderr)
        images_recorded = re.search(r"captured 3 frame\(s\).* x (\d+) images", result.stderr)
        result = run("scan", *common, "--no-record", "--out", str(unrecorded))
        self.assertEqual(result.returncode, 0, result.stderr)
        # The summary counts the images it captured, recorded or not.
        images_unrecorded = re.search(r"captured 3 frame\(s\).* x (\d+) images", result.stderr)
        self.assertIsNotNone(images_recorded, result.stderr)
        self.assertIsNotNone(images_unrecorded, result.stderr)
        self.assertGreater(int(images_recorded.group(1)), 0)
        self.assertEqual(images_unrecorded.group(1), images_recorded.group(1))
        # Nothing of the capture on disk, the same model.
        self.assertFalse((unrecorded / "recording").exists())
        self.assertEqual((recorded / "cloud.ply").read_bytes(), (unrecorded / "cloud.ply").read_bytes())
        report = json.loads((unrecorded / "report.json").read_text())
        self.assertIsNone(report["input"])
        self.assertFalse(report["writer"]["recorded"])
        self.assertEqual(report["writer"]["frames_written"], 0)
        self.assertFalse(report["live_capture"]["recorded"])
        self.assertEqual(report["live_capture"]["frames_captured"], 3)
        self.assertTrue(all("written_s" not in frame for frame in report["per_frame"]))
        # The recorded run: its writer's figures, and when each frame was written.
        report = json.loads((recorded / "report.json").read_text())
        self.assertTrue(report["writer"]["recorded"])
        self.assertEqual(report["writer"]["frames_written"], 3)
        self.assertGreater(report["writer"]["write_s_total"], 0)
        for frame in report["per_frame"]:
            self.assertLessEqual(frame["captured_s"], frame["written_s"])
        # What cannot work is refused with exit status 2.
        for extra, said in ((["--resume"], "--resume"), (["--poses", "groundtruth"], "--poses groundtruth")):
            result = run("scan", "--sim", "ci", "--no-record", *extra, "--device", "cpu",
                         "--out", str(self.dir / "refused"))
            self.assertEqual(result.returncode, 2, result.stderr)
            self.assertIn(said, result.stderr)
        result = run("scan", "--camera", uri, "--projector", uri, "--no-record", "--device", "cpu",
                     "--out", str(self.dir / "refused"))
        self.assertEqual(result.returncode, 2, result.stderr)
        self.assertIn("--calibration", result.stderr)

    def test_scan_photometric_weight_is_passed_and_recorded(self):
        # The tracker's photometric term: off by default, a weight relative to ICP's otherwise.
        self.assertIn("--photometric-weight", run("scan", "--help").stdout)
        bad = run("scan", "--sim", "ci", "--photometric-weight", "-1", "--out", str(self.dir / "bad"))
        self.assertEqual(bad.returncode, 2, bad.stderr)
        self.assertIn("--photometric-weight", bad.stderr)
        # Pattern stacks of the knurled screw, 4 frames a revolution (90 degree steps alias onto
        # the knurl: this says nothing of the term's accuracy, which the unit tests measure): the
        # scan runs the term end to end (textures from white - black, reference frames) and
        # records the option.
        out = self.dir / "photometric"
        result = run("--json", "scan", "--sim", "ci", "--frames", "4", "--device", "cpu",
                     "--photometric-weight", "0.1", "--out", str(out))
        self.assertEqual(result.returncode, 0, result.stderr)
        report = json.loads(result.stdout)
        self.assertEqual(report["photometric_weight"], 0.1)
        self.assertGreaterEqual(report["frames_fused"], 1)
        self.assertEqual(json.loads((out / "report.json").read_text())["photometric_weight"], 0.1)

    def test_scan_cuda_without_gpu_or_cuda_is_clear(self):
        info = json.loads(run("--json", "info").stdout)
        if info["cuda_devices"]:
            self.skipTest("a GPU is present")
        result = run("scan", "--sim", "demo", "--device", "cuda:0", "--out", str(self.dir / "o"))
        self.assertIn(result.returncode, (1, 3))
        self.assertIn("cuda:0", result.stderr)


class SlsCliBadFiles(unittest.TestCase):
    """Data files that are not regular files: refused at once, naming the file and what it is."""

    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.dir = pathlib.Path(self.tmp.name)

    def tearDown(self):
        self.tmp.cleanup()

    def inspect_refuses_quickly(self, path, what):
        # A reader that blocks on a FIFO or reads /dev/zero would pass the timeout: a failure.
        try:
            result = subprocess.run([SLS, "--json", "inspect", str(path)], capture_output=True, text=True,
                                    timeout=20)
        except subprocess.TimeoutExpired:
            self.fail(f"sls inspect {path} did not return within 20 s")
        self.assertEqual(result.returncode, 1, result.stderr)
        message = json.loads(result.stdout)["results"][0]["message"]
        self.assertIn(path.name, message)
        self.assertIn(what, message)

    def test_inspect_refuses_a_fifo_in_place_of_each_kind_of_file(self):
        for name in ("model.ply", "calibration.yml", "trajectory.txt", "pattern_000.png"):
            fifo = self.dir / name
            os.mkfifo(fifo)
            self.inspect_refuses_quickly(fifo, "is a FIFO (named pipe), not a regular file")
        recording = self.dir / "rec"
        recording.mkdir()
        os.mkfifo(recording / "manifest.json")
        self.inspect_refuses_quickly(recording, "manifest.json: it is a FIFO")

    def test_inspect_refuses_a_ply_linked_to_dev_zero(self):
        link = self.dir / "zero.ply"
        os.symlink("/dev/zero", link)
        self.inspect_refuses_quickly(link, "is a character device, not a regular file")


if __name__ == "__main__":
    SLS = os.path.abspath(sys.argv.pop(1))
    unittest.main(verbosity=2)
