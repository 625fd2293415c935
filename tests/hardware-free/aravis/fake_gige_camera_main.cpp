// A fake GigE Vision camera as a process of its own (FakeGigeCameraProcess starts it), so a
// test can make a camera vanish without a goodbye (SIGKILL). Prints "listening" once it serves,
// then runs until its stdin closes.
//   sls_fake_gige_camera --address 127.0.0.1 [--serial S] [--xml F] [--loss R] [--trigger-hz F]
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <string>

#include "tests/hardware-free/aravis/fake_gige_camera.h"

int main(int argc, char** argv) {
  sls::test::FakeGigeCameraOptions options;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    const char* value = argv[i + 1];
    if (key == "--address") {
      options.address = value;
    } else if (key == "--serial") {
      options.serial = value;
    } else if (key == "--xml") {
      options.genicam_xml = value;
    } else if (key == "--loss") {
      options.packet_loss_ratio = std::strtod(value, nullptr);
    } else if (key == "--trigger-hz") {
      options.trigger_poll_hz = std::strtod(value, nullptr);
    } else {
      std::printf("unknown option %s\n", key.c_str());
      return 2;
    }
  }
  try {
    sls::test::FakeGigeCamera camera(options);
    std::printf("listening on %s\n", camera.address().c_str());
    std::fflush(stdout);
    char byte = 0;
    while (read(STDIN_FILENO, &byte, 1) > 0) {
    }
  } catch (const std::exception& error) {
    std::printf("failed: %s\n", error.what());
    return 1;
  }
  return 0;
}
