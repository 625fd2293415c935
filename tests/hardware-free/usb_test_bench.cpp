#include "tests/hardware-free/usb_test_bench.h"

namespace sls::test {

void UsbDevicesTest::plug(fwif::models::Dlpc350ModelOptions projector_options,
                          fwif::models::HeadctlModelOptions head_options) {
  // ctest runs this executable under umockdev-wrapper; run by hand it must be too.
  ASSERT_TRUE(fwif::models::umockdev_preload_active()) << "run under umockdev-wrapper";
  bus_ = std::make_unique<fwif::models::EmulatedUsbBus>();
  projector_model_ = std::make_shared<fwif::models::Dlpc350Model>(std::move(projector_options));
  head_model_ = std::make_shared<fwif::models::HeadctlModel>(std::move(head_options));
  bus_->plug(projector_model_, 1, 2);
  bus_->plug(head_model_, 1, 3);
}

}  // namespace sls::test
