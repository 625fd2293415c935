#!/usr/bin/env python3
"""A turntable scan from Python (the `slscan` package over libsls): one revolution of the
scanner's turntable, step by step (move, project the patterns, capture a stack), each stack
decoded, tracked and fused with live figures while the next is captured, the loop closed, and
the model written.

    python3 samples/python/turntable_scan.py                        # the simulated knurled knob
    python3 samples/python/turntable_scan.py --frames 12 --out out/knob
    python3 samples/python/turntable_scan.py --camera gige://192.168.1.20 --projector dlpc350:// \\
        --turntable headctl:// --calibration head/calibration.yml

OUT (--out) receives recording/ (the captured stacks: scan it again with `sls scan --input`),
cloud.ply, mesh.ply, trajectory.txt and report.json (the figures). Without --calibration the
devices must be the simulator's (its exact calibration is taken from a one-frame recording of
the `sls` tool, `sls sim`) or replay://REC (REC's calibration and frames). Ctrl-C stops the scan after the current frame and writes what was
fused. Exit status: 0 done, 1 the scan failed, 2 bad usage, 130 interrupted.
"""
from __future__ import annotations

import argparse
import json
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile
import threading
import time
import urllib.parse
from dataclasses import asdict
from typing import Any, Dict, List, Optional

try:
    import slscan
except ImportError:  # run from a source checkout: the package beside this sample's folder
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "python"))
    import slscan


def parse_args(argv: Optional[List[str]]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        description="Scan a full turntable revolution (the simulated scanner by default) and write "
                    "the model and a report.", formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--preset", default="ci", choices=["ci", "demo", "paper"],
                        help="simulated scanner preset (with the default sim:// devices)")
    parser.add_argument("--object", default="knurled-knob",
                        help="simulated object (with the default sim:// devices): knurled-knob, knurled-screw, ...")
    parser.add_argument("--camera", help="camera URI (default: the simulated scanner sim://OBJECT?preset=PRESET)")
    parser.add_argument("--projector", help="projector URI (default: the camera's when it is sim://)")
    parser.add_argument("--turntable", help="turntable URI, or 'none' (default: the camera's when it is sim://)")
    parser.add_argument("--frames", type=int, default=0,
                        help="stops per revolution (0: the turntable's, 36 for the simulator, a replay's frames)")
    parser.add_argument("--out", default="out/turntable_scan", help="output folder")
    parser.add_argument("--overwrite", action="store_true", help="replace OUT/recording when it exists")
    parser.add_argument("--calibration", help="the head's calibration.yml (default: the simulator's, from `sls sim`, "
                                              "or a replay:// camera's recording's)")
    parser.add_argument("--sls", help="the sls tool, for the simulator's calibration (default: $SLS_TOOL, beside "
                                      "libsls in its prefix or build tree, or on PATH)")
    parser.add_argument("--device", default="auto", help="where to fuse: auto, cpu, cuda or cuda:N")
    parser.add_argument("--fusion", default="gtsdf", choices=["gtsdf", "tsdf"], help="fusion method")
    parser.add_argument("--no-turntable-prior", action="store_true",
                        help="track from depth alone (default: the turntable angle guesses each pose)")
    args = parser.parse_args(argv)
    if args.frames < 0:
        parser.error("--frames must be 0 or positive")
    simulated = f"sim://{args.object}?preset={args.preset}"
    args.camera = args.camera or simulated
    sim_camera = args.camera.startswith("sim://")
    if args.projector is None:
        if not sim_camera:
            parser.error("--projector is needed with a camera that is not sim://")
        args.projector = args.camera
    if args.turntable is None:
        args.turntable = args.camera if sim_camera else "none"
    if args.turntable == "none":
        args.turntable = None
    if args.calibration is None and not sim_camera and not args.camera.startswith("replay://"):
        parser.error("--calibration is needed with devices that are not sim:// or replay://")
    return args


def find_sls_tool(explicit: Optional[str]) -> str:
    """The `sls` tool: --sls, $SLS_TOOL, beside the loaded libsls (an installed prefix's bin/, a
    build tree's samples/sls/), or on PATH."""
    if explicit:
        return explicit
    if os.environ.get("SLS_TOOL"):
        return os.environ["SLS_TOOL"]
    library = pathlib.Path(slscan.library_path).resolve()
    for candidate in (library.parent.parent / "bin" / "sls", library.parents[2] / "samples" / "sls" / "sls"):
        if candidate.is_file() and os.access(candidate, os.X_OK):
            return str(candidate)
    found = shutil.which("sls")
    if found:
        return found
    raise SystemExit("turntable_scan: cannot find the sls tool for the simulator's calibration: "
                     "give --sls or --calibration")


def replayed_recording(camera_uri: str) -> Optional[pathlib.Path]:
    """The recording a replay:// URI plays (None for other schemes)."""
    if not camera_uri.startswith("replay://"):
        return None
    return pathlib.Path(urllib.parse.unquote(camera_uri[len("replay://"):].split("?", 1)[0]))


def replayed_frames(recording: pathlib.Path) -> int:
    """How many frames a recording holds (its manifest's)."""
    return len(json.loads((recording / "manifest.json").read_text())["frames"])


def simulator_calibration(camera_uri: str, sls: str, folder: pathlib.Path) -> pathlib.Path:
    """The simulated scanner's exact calibration: `sls sim` writes it into every recording, so a
    one-frame depth recording (under a second) of the same preset and object gives it."""
    uri = urllib.parse.urlsplit(camera_uri)
    preset = urllib.parse.parse_qs(uri.query).get("preset", ["ci"])[0]
    recording = folder / "sim"
    command = [sls, "-q", "sim", "--preset", preset, "--object", uri.netloc, "--frames", "1", "--mode", "depth",
               "--device", "cpu", "--reference-spacing-um", "1000", "--out", str(recording)]
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0:
        raise SystemExit(f"turntable_scan: {' '.join(command)} failed ({result.returncode}): {result.stderr.strip()}")
    return recording / "calibration.yml"


class CaptureProgress(threading.Thread):
    """Prints each stack as the capture appends it to the recording. The C API reports frames
    as they are fused, which may be a little behind the capture, so this reads the recording's
    manifest.json, which the capture replaces atomically after each stack (README, "File
    formats")."""

    def __init__(self, manifest: pathlib.Path, frames: int) -> None:
        super().__init__(name="capture-progress", daemon=True)
        self.manifest, self.frames, self.done = manifest, frames, threading.Event()
        self.seen = 0

    def run(self) -> None:
        finished = False
        while not finished:
            finished = self.done.wait(0.2)  # once done, a last look at the manifest
            try:
                frames = json.loads(self.manifest.read_text()).get("frames", [])
            except (OSError, ValueError):
                continue
            for frame in frames[self.seen:]:
                angle = frame.get("turntable_angle_deg")
                where = f" at {angle:6.1f} deg" if isinstance(angle, (int, float)) else ""
                total = f" of {self.frames}" if self.frames else ""
                print(f"  captured stack {frame.get('index', 0) + 1}{total}{where}: {frame.get('status', '')}", flush=True)
            self.seen = max(self.seen, len(frames))


class FrameProgress:
    """The frame callback: one line per frame with the running figures."""

    def __init__(self) -> None:
        self.fused = self.lost = self.skipped = 0
        self.frames: List[Dict[str, Any]] = []

    def __call__(self, report: slscan.FrameReport) -> None:
        if report.status == slscan.FrameStatus.FUSED:
            self.fused += 1
        elif report.status == slscan.FrameStatus.LOST:
            self.lost += 1
        else:
            self.skipped += 1
        self.frames.append({"index": report.index, "status": report.status.name.lower(), "reason": report.reason,
                            "tracked": report.tracked, "unverified": report.unverified,
                            "inlier_fraction": report.inlier_fraction, "residual_rms_m": report.residual_rms_m,
                            "depth_pixels": report.depth_pixels, "keyframe": report.keyframe,
                            "total_ms": report.total_ms, "T_world_camera": report.T_world_camera.tolist()})
        if report.unverified:
            figures = "unverified: at the turntable angle"
        elif report.tracked:
            figures = f"inliers {report.inlier_fraction:5.3f}, rms {report.residual_rms_m * 1e6:6.2f} um"
        else:
            figures = "first frame" if report.fused else ""
        why = f": {report.reason}" if report.reason else ""
        print(f"  frame {report.index + 1:3d}/{report.recording_frames}: {report.status.name.lower():7s} "
              f"{figures:34s} {report.total_ms:6.0f} ms | fused {self.fused}, lost {self.lost}"
              f"{f', skipped {self.skipped}' if self.skipped else ''}{why}", flush=True)


def main(argv: Optional[List[str]] = None) -> int:
    args = parse_args(argv)
    out = pathlib.Path(args.out)
    recording = out / "recording"
    if recording.exists() and any(recording.iterdir()):
        if not args.overwrite:
            print(f"turntable_scan: {recording} exists: choose another --out or pass --overwrite", file=sys.stderr)
            return 2
        shutil.rmtree(recording)
    out.mkdir(parents=True, exist_ok=True)
    print(slscan.build_info())
    started = time.monotonic()
    report: Dict[str, Any] = {"build": slscan.build_info(), "camera": args.camera, "projector": args.projector,
                              "turntable": args.turntable, "frames_per_revolution": args.frames,
                              "fusion": args.fusion, "turntable_prior": not args.no_turntable_prior}
    progress = FrameProgress()
    status = 0
    with tempfile.TemporaryDirectory(prefix="turntable_scan-") as scratch:
        replayed = replayed_recording(args.camera)
        if args.calibration or replayed:
            calibration = args.calibration  # None: the replayed recording's (sls_capture_config)
        else:
            calibration = simulator_calibration(args.camera, find_sls_tool(args.sls), pathlib.Path(scratch))
        report["calibration"] = str(args.calibration or ("the replayed recording's" if replayed else
                                                         "the simulator's (sls sim)"))
        with slscan.Context(device=args.device) as context, \
                slscan.Scan(context, fusion=args.fusion, use_turntable_prior=not args.no_turntable_prior) as scan:
            print(f"capturing and fusing one revolution from {args.camera} on the "
                  f"{'GPU' if context.uses_cuda else 'CPU'} ...", flush=True)
            # sls_capture_config.frames 0: 36 stops with a turntable, else 1; a replay's frames.
            stops = args.frames or (replayed_frames(replayed) if replayed else 36 if args.turntable else 1)
            watcher = CaptureProgress(recording / "manifest.json", stops)
            watcher.start()
            first_frame: List[float] = []

            def on_frame(frame: slscan.FrameReport) -> None:
                if not first_frame:
                    first_frame.append(time.monotonic())  # fused while the capture goes on
                progress(frame)

            try:
                summary = scan.run_devices(camera=args.camera, projector=args.projector, turntable=args.turntable,
                                           calibration=calibration, recording=recording, frames=args.frames,
                                           on_frame=on_frame)
            except KeyboardInterrupt:
                print("interrupted: writing what was fused", file=sys.stderr)
                summary, status = scan.summary(), 130
            except slscan.CancelledError as error:
                print(f"cancelled: {error.message}", file=sys.stderr)
                summary, status = scan.summary(), 130
            except slscan.Error as error:
                print(f"turntable_scan: the scan failed: {error}", file=sys.stderr)
                return 1
            finally:
                watcher.done.set()
                watcher.join()
            scanned = time.monotonic()
            report["summary"] = asdict(summary)
            report["first_frame_s"] = (first_frame[0] if first_frame else scanned) - started
            report["scan_s"] = scanned - started
            print(f"fused {summary.fused} of {summary.frames} frames ({summary.lost} lost, {summary.skipped} "
                  f"skipped), voxels of {summary.voxel_size_m * 1e6:.1f} um, {summary.volume_moves} volume moves")
            tracked = [frame for frame in progress.frames if frame["tracked"] and not frame["unverified"]]
            report["figures"] = {
                "mean_frame_ms": sum(frame["total_ms"] for frame in progress.frames) / max(1, len(progress.frames)),
                "tracked_frames": len(tracked),
                "mean_inlier_fraction": sum(frame["inlier_fraction"] for frame in tracked) / max(1, len(tracked)),
                "mean_residual_rms_m": sum(frame["residual_rms_m"] for frame in tracked) / max(1, len(tracked))}
            print(f"{report['figures']['mean_frame_ms']:.0f} ms a frame; {len(tracked)} frames tracked, inliers "
                  f"{report['figures']['mean_inlier_fraction']:.3f}, rms "
                  f"{report['figures']['mean_residual_rms_m'] * 1e6:.2f} um on average")
            if summary.fused == 0:
                print("turntable_scan: no frame fused: nothing to write", file=sys.stderr)
                return 1
            if status == 0:
                try:
                    loop = scan.close_loop()
                    report["loop_closure"] = asdict(loop)
                    print(f"loop closed: frame {loop.last_frame} registered to frame {loop.first_frame} "
                          f"(inliers {loop.registration_inlier_fraction:.3f}); the last pose moved "
                          f"{loop.last_pose_correction_m * 1e6:.1f} um, {loop.last_pose_correction_deg:.4f} deg "
                          f"({loop.ms:.0f} ms)")
                except slscan.InvalidArgumentError as error:  # a partial revolution: the model as tracked
                    report["loop_closure"] = {"error": error.message}
                    print(f"loop not closed: {error.message}")
            files = {"cloud": out / "cloud.ply", "mesh": out / "mesh.ply", "trajectory": out / "trajectory.txt"}
            scan.write_cloud(files["cloud"])
            scan.write_mesh(files["mesh"])
            scan.write_trajectory(files["trajectory"])
    report["files"] = {name: str(path) for name, path in files.items()}
    report["recording"] = str(recording)
    report["per_frame"] = progress.frames
    report["total_s"] = time.monotonic() - started
    (out / "report.json").write_text(json.dumps(report, indent=1) + "\n")
    print(f"wrote {files['cloud']}, {files['mesh']}, {files['trajectory']} and {out / 'report.json'} "
          f"in {report['total_s']:.1f} s")
    return status


if __name__ == "__main__":
    sys.exit(main())
