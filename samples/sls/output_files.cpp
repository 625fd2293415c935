#include "samples/sls/output_files.h"

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <filesystem>
#include <set>

#include <fmt/format.h>

#include "sdk/core/error.h"
#include "sdk/core/file_util.h"

namespace sls::cli {
namespace {

namespace fs = std::filesystem;

// The process that wrote a temporary of write_file_atomic (NAME.tmp-PID), or 0 for other names.
pid_t temporary_owner(const std::string& name) {
  const std::size_t at = name.rfind(".tmp-");
  if (at == std::string::npos || at + 5 == name.size()) return 0;
  const std::string digits = name.substr(at + 5);
  if (!std::all_of(digits.begin(), digits.end(), [](char c) { return c >= '0' && c <= '9'; }) || digits.size() > 9) {
    return 0;
  }
  return static_cast<pid_t>(std::stol(digits));
}

// Removes the temporaries in `folder` whose writer is gone (a kill -9 or a power cut during the
// write): never read, only in the way. A live writer's (another command at work) stays.
void remove_dead_temporaries(const fs::path& folder) {
  std::error_code error;
  for (fs::directory_iterator it(folder, error), end; !error && it != end; it.increment(error)) {
    const pid_t owner = temporary_owner(it->path().filename().string());
    if (owner <= 0 || owner == ::getpid() || !it->is_regular_file(error)) continue;
    if (::kill(owner, 0) != 0 && errno == ESRCH) fs::remove(it->path(), error);
  }
}

std::string join(const std::vector<std::string>& names) {
  std::string out;
  for (const std::string& name : names) out += (out.empty() ? "" : ", ") + name;
  return out;
}

}  // namespace

OutputFiles::OutputFiles(std::string folder, std::vector<std::string> planned, const std::vector<std::string>& reports)
    : folder_(std::move(folder)), planned_(std::move(planned)) {
  create_directories(folder_);
  std::set<fs::path> folders{fs::path(folder_)};
  for (const std::string& name : planned_) folders.insert((fs::path(folder_) / name).parent_path());
  for (const fs::path& each : folders) remove_dead_temporaries(each);
  bool removed = false;
  for (const std::string& report : reports) {
    std::error_code error;
    if (fs::remove(path(report), error)) removed = true;
    if (error) throw_error(ErrorCode::kIo, "cannot remove the earlier run's {}: {}", path(report), error.message());
  }
  if (removed) sync_directory(folder_);
}

void OutputFiles::write(const std::string& relative, const std::function<void(const std::string& path)>& write_file) {
  try {
    write_file(path(relative));
  } catch (const Error& error) {
    std::vector<std::string> missing;
    const auto next = std::find(planned_.begin(), planned_.end(), relative);
    for (auto it = next; it != planned_.end(); ++it) missing.push_back(*it);
    if (next == planned_.end()) missing.insert(missing.begin(), relative);
    throw Error(error.code(), fmt::format("cannot write the outputs into {}: {}; written: {}; not written: {}", folder_,
                                          error.what(), written_.empty() ? "none" : join(written_), join(missing)));
  }
  if (std::find(written_.begin(), written_.end(), relative) == written_.end()) written_.push_back(relative);
}

std::string OutputFiles::describe_written() const { return folder_ + "/" + join(written_); }

}  // namespace sls::cli
