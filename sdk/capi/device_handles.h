// The device handles of the C API (sls_camera, sls_projector, sls_turntable): the driver
// objects the registry opened, for the files that open them and for those that drive them
// (the calibration capture).
#pragma once

#include <memory>
#include <string>

#include "drivers/interfaces/camera.h"
#include "drivers/interfaces/projector.h"
#include "drivers/interfaces/turntable.h"

struct sls_camera {
  std::unique_ptr<sls::drivers::Camera> camera;
  sls::drivers::CameraInfo info;  // the strings sls_camera_get_info hands out
  bool acquiring = false;         // between start() and stop()

  // Stops acquisition so that whoever starts it next starts afresh: an image still in flight
  // for an earlier trigger (after a timeout) or the rest of an incomplete one is dropped with
  // the stream. Errors are swallowed: a camera that is gone cannot be stopped, and the caller's
  // own error (or the next start's) is the one to see.
  void stop_acquisition() noexcept {
    if (!acquiring) return;
    acquiring = false;
    try {
      camera->stop();
    } catch (...) {
    }
  }

  ~sls_camera() { stop_acquisition(); }
};

struct sls_projector {
  std::unique_ptr<sls::drivers::Projector> projector;
  sls::drivers::ProjectorInfo info;  // the strings sls_projector_get_info hands out

  ~sls_projector() {
    try {
      projector->go_dark();
    } catch (...) {  // a projector that is gone cannot go dark; closing must still succeed
    }
  }
};

struct sls_turntable {
  std::unique_ptr<sls::drivers::Turntable> turntable;
  std::string uri;  // as opened: errors name the table by it
};
