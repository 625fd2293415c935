// A command's output files in their folder (sls scan: OUT), written so that a kill -9, a full
// disk or a fault part-way never leaves a file that looks whole but is not, nor an earlier
// run's report beside this run's model:
//   - each file is written to a temporary beside it and renamed (write_file_atomic);
//   - before the first is written, what an earlier run left is cleared: temporaries of runs
//     that were cut off (NAME.tmp-PID of a process that is gone), and the reports that would
//     describe the earlier run's files (sls scan: report.json, report.html). The reports are
//     written after the files they describe, so a report in the folder always stands beside
//     its own model;
//   - a file that cannot be written (no space left on the device, ...) ends the command with
//     sls::Error naming it, the OS's reason, and which files were written and which not.
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace sls::cli {

class OutputFiles {
 public:
  // `planned`: the files, relative to `folder`, in the order they will be written; `reports`:
  // those among them that describe the others, removed now if an earlier run left them.
  // Temporaries of dead processes are removed from `folder` and the folders of `planned`
  // (not deeper: a scan's OUT/recording is never touched).
  OutputFiles(std::string folder, std::vector<std::string> planned, const std::vector<std::string>& reports);

  // Runs `write_file` with the absolute path of `relative` (one of `planned`; written again, it
  // is listed once); on sls::Error rethrows it, with its code, as "cannot write the outputs
  // into FOLDER: <its message>; written: ...; not written: ...".
  void write(const std::string& relative, const std::function<void(const std::string& path)>& write_file);

  const std::string& folder() const { return folder_; }
  const std::vector<std::string>& written() const { return written_; }
  std::string path(const std::string& relative) const { return folder_ + "/" + relative; }
  // "FOLDER/a, b, c": the files written so far, for messages.
  std::string describe_written() const;

 private:
  std::string folder_;
  std::vector<std::string> planned_;
  std::vector<std::string> written_;
};

}  // namespace sls::cli
