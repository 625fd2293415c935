#include "drivers/interfaces/device_uri.h"

#include <cctype>
#include <cerrno>
#include <cstdlib>
#include <cstring>

#include "sdk/core/error.h"

namespace sls::drivers {
namespace {

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

std::string percent_decode(const std::string& text, const std::string& uri) {
  std::string out;
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (text[i] == '%') {
      if (i + 2 >= text.size()) {
        throw_error(ErrorCode::kInvalidArgument, "device URI '{}': truncated percent escape", uri);
      }
      const int high = hex_value(text[i + 1]);
      const int low = hex_value(text[i + 2]);
      if (high < 0 || low < 0) throw_error(ErrorCode::kInvalidArgument, "device URI '{}': bad percent escape", uri);
      out.push_back(static_cast<char>(high * 16 + low));
      i += 2;
    } else {
      out.push_back(text[i] == '+' ? ' ' : text[i]);
    }
  }
  return out;
}

// Escapes the characters in `special` (and '%' itself), so that parse_device_uri reads back
// exactly `text`: '+' would become a space, '?', '&' and '=' would split the URI.
std::string percent_encode(const std::string& text, const char* special) {
  static constexpr char kHex[] = "0123456789ABCDEF";
  std::string out;
  for (const char c : text) {
    if (c == '%' || c == '+' || std::strchr(special, c) != nullptr) {
      const auto byte = static_cast<unsigned char>(c);
      out += '%';
      out += kHex[byte >> 4];
      out += kHex[byte & 15];
    } else {
      out += c;
    }
  }
  return out;
}

}  // namespace

DeviceUri parse_device_uri(const std::string& text) {
  DeviceUri uri;
  const std::size_t separator = text.find("://");
  if (separator == std::string::npos) {
    if (text.empty()) throw_error(ErrorCode::kInvalidArgument, "empty device URI");
    uri.scheme = "file";
    uri.target = text;
    return uri;
  }
  uri.scheme = text.substr(0, separator);
  if (uri.scheme.empty()) throw_error(ErrorCode::kInvalidArgument, "device URI '{}' has no scheme", text);
  for (const char c : uri.scheme) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '+' || c == '-' || c == '.')) {
      throw_error(ErrorCode::kInvalidArgument, "device URI '{}': invalid scheme", text);
    }
  }
  const std::string rest = text.substr(separator + 3);
  const std::size_t question = rest.find('?');
  uri.target = percent_decode(rest.substr(0, question), text);
  if (question == std::string::npos) return uri;
  std::string query = rest.substr(question + 1);
  std::size_t start = 0;
  while (start <= query.size()) {
    const std::size_t end = std::min(query.find('&', start), query.size());
    const std::string pair = query.substr(start, end - start);
    if (!pair.empty()) {
      const std::size_t equals = pair.find('=');
      const std::string key = percent_decode(pair.substr(0, equals), text);
      const std::string value = equals == std::string::npos ? "" : percent_decode(pair.substr(equals + 1), text);
      if (key.empty()) throw_error(ErrorCode::kInvalidArgument, "device URI '{}': empty query key", text);
      if (!uri.query.emplace(key, value).second) {
        throw_error(ErrorCode::kInvalidArgument, "device URI '{}': '{}' given twice", text, key);
      }
    }
    start = end + 1;
  }
  return uri;
}

std::string DeviceUri::get(const std::string& key, const std::string& fallback) const {
  const auto found = query.find(key);
  return found == query.end() ? fallback : found->second;
}

int DeviceUri::get_int(const std::string& key, int fallback) const {
  const auto found = query.find(key);
  if (found == query.end()) return fallback;
  char* end = nullptr;
  errno = 0;
  const long value = std::strtol(found->second.c_str(), &end, 10);
  if (found->second.empty() || *end != '\0' || errno != 0 || value < -2147483647L || value > 2147483647L) {
    throw_error(ErrorCode::kInvalidArgument, "device URI {}: '{}={}' is not an integer", to_string(), key,
                found->second);
  }
  return static_cast<int>(value);
}

double DeviceUri::get_double(const std::string& key, double fallback) const {
  const auto found = query.find(key);
  if (found == query.end()) return fallback;
  char* end = nullptr;
  errno = 0;
  const double value = std::strtod(found->second.c_str(), &end);
  if (found->second.empty() || *end != '\0' || errno != 0) {
    throw_error(ErrorCode::kInvalidArgument, "device URI {}: '{}={}' is not a number", to_string(), key,
                found->second);
  }
  return value;
}

// parse_device_uri(to_string()) gives this URI back: the text is used as a key and parsed
// again (shared simulated scanners), so a decoded '&' or '+' must not change its meaning.
std::string DeviceUri::to_string() const {
  // A plain path is read verbatim, unless it would look like a URI or be empty.
  if (scheme == "file" && query.empty() && !target.empty() && target.find("://") == std::string::npos) return target;
  std::string text = scheme + "://" + percent_encode(target, "?");
  char separator = '?';
  for (const auto& [key, value] : query) {
    text += separator + percent_encode(key, "&=") + "=" + percent_encode(value, "&");
    separator = '&';
  }
  return text;
}

}  // namespace sls::drivers
