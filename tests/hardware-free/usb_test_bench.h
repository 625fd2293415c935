// A USB bus for the hardware-free tests: the emulated DLPC350 at bus 1 address 2 and the
// emulated head controller at bus 1 address 3, behind real libusb through umockdev.
#pragma once

#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <string>

#include "firmware-interface/models/dlpc350_model.h"
#include "firmware-interface/models/headctl_model.h"
#include "firmware-interface/models/umockdev/emulated_usb_bus.h"
#include "sdk/core/error.h"

namespace sls::test {

class UsbDevicesTest : public ::testing::Test {
 protected:
  // Plugs the two models in; call once at the start of a test, before opening drivers.
  void plug(fwif::models::Dlpc350ModelOptions projector_options = {},
            fwif::models::HeadctlModelOptions head_options = {});

  std::unique_ptr<fwif::models::EmulatedUsbBus> bus_;  // declared first: drivers close before it goes
  std::shared_ptr<fwif::models::Dlpc350Model> projector_model_;
  std::shared_ptr<fwif::models::HeadctlModel> head_model_;
};

// The message of the sls::Error that `f` throws; a test failure when it throws none or
// another code.
template <typename F>
std::string error_message(F&& f, ErrorCode expected) {
  try {
    f();
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), expected) << error.what();
    return error.what();
  }
  ADD_FAILURE() << "no sls::Error thrown";
  return {};
}

inline double elapsed_ms(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - since).count();
}

}  // namespace sls::test
