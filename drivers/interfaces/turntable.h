// The turntable interface (a stepper on the head controller board, issue #7, or simulated).
#pragma once

#include <chrono>

namespace sls::drivers {

class Turntable {
 public:
  virtual ~Turntable() = default;

  // Finds the home (index) position and calls it 0°.
  virtual void home(std::chrono::milliseconds timeout) = 0;
  // Moves to an absolute angle in degrees [0, 360) and waits until it is reached; throws
  // kTimeout naming the device when it is not reached in time.
  virtual void move_to_deg(double angle_deg, std::chrono::milliseconds timeout) = 0;
  // The commanded angle the table reports (what a recording stores as turntable_angle_deg);
  // the real angle may differ by the table's jitter.
  virtual double position_deg() const = 0;
  virtual int steps_per_revolution() const = 0;
};

}  // namespace sls::drivers
