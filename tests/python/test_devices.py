"""Contexts, errors and devices through the Python package: every C status maps to its
exception class with the library's message; the simulated scanner's camera, projector and
turntable by URI."""
from __future__ import annotations

import gc

import numpy as np
import pytest

import slscan

from conftest import SIM_URI


def test_version_and_build_info():
    assert slscan.version().count(".") == 2
    assert slscan.build_info().startswith("slscan ")
    assert slscan.cuda_device_count() >= 0


def test_context(context: slscan.Context):
    assert context.uses_cuda is False
    with slscan.Context(log_level="warning") as auto:
        assert auto.uses_cuda == (slscan.cuda_device_count() > 0)
    assert auto.closed
    auto.close()  # closing again does nothing
    with pytest.raises(slscan.InvalidArgumentError, match="closed"):
        auto.uses_cuda
    with pytest.raises(ValueError, match="device 'gpu'"):
        slscan.Context(device="gpu")


def test_every_status_has_its_class():
    assert set(slscan._errors.ERROR_CLASSES) == set(slscan.Status) - {slscan.Status.OK}
    for status, cls in slscan._errors.ERROR_CLASSES.items():
        error = slscan._errors.make_error(int(status), "sls_f", "what failed")
        assert type(error) is cls and isinstance(error, slscan.Error)
        assert error.status is status and error.function == "sls_f" and error.message == "what failed"
        assert str(error).startswith("sls_f: what failed (")
    unknown = slscan._errors.make_error(-42, "sls_f", "m")
    assert type(unknown) is slscan.Error and unknown.status == -42
    assert issubclass(slscan.InvalidArgumentError, ValueError)
    assert issubclass(slscan.DeviceTimeoutError, TimeoutError)
    assert issubclass(slscan.IoError, OSError)


def test_bad_uris_raise_the_c_status_and_message(context: slscan.Context):
    with pytest.raises(slscan.UnsupportedError) as unsupported:
        slscan.Camera("firewire://0", context)
    assert unsupported.value.status == slscan.Status.UNSUPPORTED
    assert unsupported.value.function == "sls_camera_open"
    assert "firewire" in unsupported.value.message
    with pytest.raises(slscan.InvalidArgumentError) as bad_scene:
        slscan.Camera("sim://no-such-object", context)
    assert "no-such-object" in bad_scene.value.message
    with pytest.raises(slscan.InvalidArgumentError) as no_camera:
        slscan.Camera("dlpc350://", context)
    assert no_camera.value.function == "sls_camera_open"
    with pytest.raises(slscan.Error) as no_projector:
        slscan.Projector("gige://127.0.0.1", context)
    assert no_projector.value.function == "sls_projector_open"


def test_devices_lists_the_simulator(context: slscan.Context):
    listed = slscan.devices(context)
    assert listed[0].uri.startswith("sim://") and listed[0].kind == slscan.DeviceKind.SCANNER
    assert listed[0].roles == slscan.DeviceRole.CAMERA | slscan.DeviceRole.PROJECTOR | slscan.DeviceRole.TURNTABLE
    assert isinstance(listed.problems, str) and listed.has_hardware == (len(listed) > 1)


def test_sim_camera_grab_sees_the_projector(context: slscan.Context):
    with slscan.Camera(SIM_URI, context) as camera, slscan.Projector(SIM_URI, context) as projector:
        info = camera.info
        assert (info.width, info.height, info.bit_depth) == (400, 300, 12)
        assert info.uri.startswith(SIM_URI) and info.model
        assert projector.load_scan_patterns() >= 2
        projector.show_pattern(0)  # white
        assert projector.current_pattern == 0
        white, frame = camera.grab(timeout_ms=10000)
        assert white.dtype == np.uint16 and white.shape == (info.height, info.width)
        assert (frame.width, frame.height, frame.bit_depth) == (400, 300, 12)
        assert white.max() < 2 ** info.bit_depth
        projector.show_pattern(1)  # black
        black = np.empty_like(white)
        again = camera.grab(10000, out=black)
        assert again.image is black and again.info.frame_id > frame.frame_id
        # The lit object is brighter than in the dark, and the image is not flat.
        assert white.mean() > black.mean() + 100 and white.std() > 10
        projector.go_dark()
        assert projector.current_pattern is None
        with pytest.raises(ValueError, match="out must be"):
            camera.grab(out=np.empty((2, 2), np.uint16))
        with pytest.raises(slscan.InvalidArgumentError) as outside:
            projector.show_pattern(10000)
        assert outside.value.function == "sls_projector_show_pattern"
        with pytest.raises(slscan.InvalidArgumentError):
            camera.set_exposure_us(-1.0)


def test_sim_turntable(context: slscan.Context):
    with slscan.Turntable(SIM_URI, context) as table:
        table.home()
        assert table.steps_per_revolution == 36
        table.move_to(90.0)
        assert table.position_deg == pytest.approx(90.0)
    assert table.closed


def test_handles_free_without_with(context: slscan.Context):
    camera = slscan.Camera(SIM_URI)  # a default context, made for the call
    assert not camera.closed
    del camera
    gc.collect()


def test_errors_pickle_and_name_the_package():
    import pickle
    error = slscan._errors.make_error(-4, "sls_scan_run_recording", "recording x: no such folder")
    again = pickle.loads(pickle.dumps(error))
    assert type(again) is slscan.NotFoundError and repr(again).startswith("NotFoundError(")
    assert (again.status, again.function, again.message) == (error.status, error.function, error.message)
    assert slscan.NotFoundError.__module__ == "slscan"
