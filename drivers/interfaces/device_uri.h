// Device URIs: how users name a scanner, a camera or a recording.
//   sim://knurled-screw?preset=demo&frames=120      the simulated scanner
//   gige://192.168.1.20   usb3://SERIAL              Aravis cameras (issue #7)
//   dlpc350://  headctl://                           USB devices (issue #7)
//   file:///path/to/recording   or a plain folder    a recording (read as input)
//   replay://path/to/recording?timing=recorded       a recording played back as devices
#pragma once

#include <map>
#include <string>

namespace sls::drivers {

struct DeviceUri {
  std::string scheme;                        // "sim", "gige", ...; "file" for plain paths
  std::string target;                        // what follows "scheme://" up to '?'
  std::map<std::string, std::string> query;  // key=value pairs after '?', percent-decoded

  // Throws sls::Error(kInvalidArgument) naming the key when absent or unparsable.
  std::string get(const std::string& key, const std::string& fallback) const;
  int get_int(const std::string& key, int fallback) const;
  double get_double(const std::string& key, double fallback) const;
  std::string to_string() const;
};

// Parses a URI; a string without "://" is a file path. Throws sls::Error(kInvalidArgument)
// with the text for a malformed URI (empty scheme, bad percent escape, duplicate key).
DeviceUri parse_device_uri(const std::string& text);

}  // namespace sls::drivers
