"""Quality figures and reports (sls_eval.h): a scan's result folder measured against a simulated
recording's ground truth, as ``sls eval`` measures it, and the HTML report ``sls scan`` writes.

    import slscan

    with slscan.evaluate("out", "out/recording") as evaluation:
        figures = evaluation.summary
        print(f"C2C mean {figures.c2c_mean_m * 1e6:.2f} um, ATE {figures.ate_rmse_m * 1e6:.2f} um")
    slscan.write_report("out", recording_path="out/recording")
"""
from __future__ import annotations

import ctypes
import json
import os
from dataclasses import dataclass
from typing import Any, Callable, Dict, List, Optional, Union

import numpy as np

from . import _lib
from ._context import Context, Handle, context_or_default
from ._errors import call
from ._progress import progress_trampoline
from ._types import EvalConfigC, EvalProgressC, EvaluationSummaryC, ReportConfigC

PathLike = Union[str, "os.PathLike[str]"]


@dataclass(frozen=True)
class EvalProgress:
    """Progress of :func:`evaluate` and :func:`write_report` (sls_eval_progress)."""
    stage: str
    """What runs: "register", "c2c", "visibility" (measuring) or "report" (writing)."""
    done: int
    total: int
    """Units in all; 0 when unknown."""
    detail: str


@dataclass(frozen=True)
class EvaluationSummary:
    """The figures of one model (sls_evaluation_summary): metres and degrees, NaN where there
    is nothing to measure (no crease, no trajectory)."""
    voxel_size_m: float
    points: int
    c2c_mean_m: float
    c2c_rms_m: float
    c2c_p95_m: float
    c2c_max_m: float
    edge_points: int
    edge_c2c_mean_m: float
    edge_c2c_rms_m: float
    coverage: float
    has_trajectory: bool
    trajectory_frames: int
    ate_rmse_m: float
    ate_max_m: float
    loop_closure_error_m: float
    loop_closure_error_deg: float
    has_undeformed: bool


class Evaluation(Handle):
    """The figures of a result folder (sls_evaluation, from :func:`evaluate`); immutable. Close it
    (or use ``with``)."""

    _destroy_name = "sls_evaluation_destroy"

    def _summary(self, undeformed: bool) -> EvaluationSummary:
        summary = _lib.init(EvaluationSummaryC, "sls_evaluation_summary_init")
        call(_lib.lib.sls_evaluation_get_summary, self._checked(), int(undeformed), ctypes.byref(summary))
        return _lib.dataclass_from_c(EvaluationSummary, summary)

    @property
    def summary(self) -> EvaluationSummary:
        """The model's figures (cloud.ply, trajectory.txt)."""
        return self._summary(False)

    @property
    def undeformed_summary(self) -> Optional[EvaluationSummary]:
        """The figures of the model as tracked (RESULT/undeformed, before online deformation);
        None when the result holds none."""
        summary = self.summary
        return self._summary(True) if summary.has_undeformed else None

    def as_dict(self) -> Dict[str, Any]:
        """Every figure, as ``sls eval --json`` prints them (micrometres and degrees, None where
        there is nothing to measure; the model as tracked under "undeformed")."""
        text = ctypes.c_char_p()
        call(_lib.lib.sls_evaluation_json, self._checked(), ctypes.byref(text))
        return json.loads(_lib.decode(text.value))

    @property
    def point_errors_m(self) -> np.ndarray:
        """Each model point's distance from the exact surface, metres (float32, cloud.ply's
        point order), e.g. for a heat map."""
        count = ctypes.c_size_t(0)
        call(_lib.lib.sls_evaluation_get_point_errors, self._checked(), None, 0, ctypes.byref(count))
        errors = np.empty(count.value, dtype=np.float32)
        call(_lib.lib.sls_evaluation_get_point_errors, self._checked(),
             errors.ctypes.data_as(ctypes.c_void_p), errors.size, ctypes.byref(count))
        return errors


_EVAL_KEYS = ("voxel_size_m", "edge_band_voxels", "coverage_radius_voxels", "visibility_stride", "align_first_pose",
              "register_to_surface")


def _run(function: Callable[..., int], progress: Optional[Callable[[EvalProgress], Any]], before: tuple,
         after: tuple = ()) -> None:
    """Calls `function(*before, callback, user, *after)` with the progress callback; an exception
    the callback raised (Ctrl-C included) is raised again in place of the cancel it caused."""
    raised: List[BaseException] = []
    c_callback = progress_trampoline(EvalProgressC, EvalProgress, progress, raised)
    try:
        call(function, *before, ctypes.cast(c_callback, ctypes.c_void_p), None, *after)
    except BaseException:
        if raised:
            raise raised[0] from None
        raise
    finally:
        del c_callback


def evaluate(result_path: PathLike, recording_path: PathLike, context: Optional[Context] = None,
             progress: Optional[Callable[[EvalProgress], Any]] = None, **config: Any) -> Evaluation:
    """Measures a result folder (cloud.ply; trajectory.txt, report.json and undeformed/ when
    there) against the simulated recording it was scanned from (sls_evaluate). Blocks: seconds.

    Args:
        result_path: the folder ``sls scan --out`` wrote, or one a program filled with
            :meth:`Scan.write_cloud` and :meth:`Scan.write_trajectory`.
        recording_path: the recording, with its groundtruth/.
        context: None: a default one.
        progress: called as the work goes on; returning False stops it (:class:`CancelledError`).
        **config: sls_eval_config fields: voxel_size_m (needed when the folder has no
            report.json), edge_band_voxels, coverage_radius_voxels, visibility_stride,
            align_first_pose, register_to_surface."""
    unknown = sorted(set(config) - set(_EVAL_KEYS))
    if unknown:
        raise TypeError(f"evaluate: unknown config {', '.join(unknown)}; known: {', '.join(_EVAL_KEYS)}")
    c_config = _lib.init(EvalConfigC, "sls_eval_config_init")
    for key, value in config.items():
        if key in ("align_first_pose", "register_to_surface"):
            value = int(bool(value))
        elif key == "visibility_stride":
            value = int(value)
        else:
            value = float(value)
        setattr(c_config, key, value)
    result = Evaluation()
    with context_or_default(context) as handle:
        _run(_lib.lib.sls_evaluate, progress,
             (handle, _lib.encode_path(result_path), _lib.encode_path(recording_path), ctypes.byref(c_config)),
             (ctypes.byref(result._handle),))
    return result


def write_report(result_path: PathLike, recording_path: Optional[PathLike] = None, title: Optional[str] = None,
                 image_size_px: int = 800, voxel_size_m: float = 0.0, context: Optional[Context] = None,
                 progress: Optional[Callable[[EvalProgress], Any]] = None) -> str:
    """Writes RESULT/report.html with its PNG figures, as ``sls scan`` does (sls_report_write_html):
    renders of the model, the trajectory, and with `recording_path` the quality figures and an
    error heat map (measured at `voxel_size_m`; 0: RESULT/report.json's). Returns the report's
    path."""
    c_config = _lib.init(ReportConfigC, "sls_report_config_init")
    recording = None if recording_path is None else _lib.encode_path(recording_path)
    title_bytes = _lib.encode(title)
    c_config.recording_path = recording
    c_config.title = title_bytes
    c_config.image_size_px = int(image_size_px)
    c_config.voxel_size_m = float(voxel_size_m)
    with context_or_default(context) as handle:
        _run(_lib.lib.sls_report_write_html, progress, (handle, _lib.encode_path(result_path), ctypes.byref(c_config)))
    return os.path.join(os.fsdecode(result_path), "report.html")
