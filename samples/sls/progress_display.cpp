#include "samples/sls/progress_display.h"

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <memory>

namespace sls::cli {
namespace {

class ProgressDisplay {
 public:
  explicit ProgressDisplay(std::string stage)
      : stage_(std::move(stage)), terminal_(::isatty(STDERR_FILENO) != 0), start_(Clock::now()) {}

  bool update(const ProgressUpdate& update) {
    const double seconds = std::chrono::duration<double>(Clock::now() - start_).count();
    const double fraction = update.total > 0 ? static_cast<double>(update.done) / static_cast<double>(update.total) : 0.0;
    const std::string& stage = update.stage.empty() ? stage_ : update.stage;
    if (terminal_) {
      constexpr int kWidth = 30;
      const int filled = static_cast<int>(fraction * kWidth);
      std::fprintf(stderr, "\r%-10s [%-*.*s] %zu/%zu %5.1fs %s\033[K", stage.c_str(), kWidth, filled,
                   "##############################", update.done, update.total, seconds, update.detail.c_str());
      if (update.total > 0 && update.done >= update.total) std::fputc('\n', stderr);
      std::fflush(stderr);
    } else {
      // A log gets a line per tenth of a round. A new round (another stage, or the same stage
      // counting again from below: a head's next camera) starts its tenths again.
      if (stage != round_stage_ || update.done < round_done_) {
        round_stage_ = stage;
        last_decile_ = -1;
        finished_ = false;
      }
      round_done_ = update.done;
      const int decile = static_cast<int>(fraction * 10.0);
      if (decile > last_decile_ || (update.total > 0 && update.done >= update.total && !finished_)) {
        last_decile_ = decile;
        finished_ = update.total > 0 && update.done >= update.total;
        std::fprintf(stderr, "%s: %zu/%zu (%d%%) %.1fs%s%s\n", stage.c_str(), update.done, update.total,
                     static_cast<int>(fraction * 100.0), seconds, update.detail.empty() ? "" : " ",
                     update.detail.c_str());
      }
    }
    return true;
  }

 private:
  using Clock = std::chrono::steady_clock;
  std::string stage_;
  bool terminal_;
  Clock::time_point start_;
  std::string round_stage_;
  std::size_t round_done_ = 0;
  int last_decile_ = -1;
  bool finished_ = false;
};

}  // namespace

ProgressCallback make_progress_display(const std::string& stage) {
  auto display = std::make_shared<ProgressDisplay>(stage);
  return [display](const ProgressUpdate& update) { return display->update(update); };
}

}  // namespace sls::cli
