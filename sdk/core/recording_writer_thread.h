// A capture's frames written to its recording on a thread of their own (issue 18; DESIGN.md
// section 1: "a writer that tees every captured frame to the recording"): the capture hands each
// frame's writes over through a bounded queue and goes on capturing, while the scan fuses the
// same frame. The images are shared read-only between the two (a frame's write captures a
// std::shared_ptr<const std::vector<Image16u>>): a 0.5 GB stack is never copied, and it is freed
// once both are done with it.
//
//   RecordingWriterThread writes(writer.folder(), 2);
//   writes.push(frame, [&writer, images, metadata] { writer.append_frame(*images, metadata); });
//   ...
//   writes.finish();  // every frame written, or the first write error thrown
//
// Order: the writes run one at a time, in the order pushed (a recording lists frames in order).
// Back-pressure: while `queue_frames` frames wait to be written, push() waits — the capture goes
// at the disk's pace — and the waits are counted (statistics()); no frame is ever dropped.
// queue_frames 0: each write runs inside push(), on the capture's thread (the synchronous
// capture, for comparison and for tests).
// Errors: a write that throws ends the writing: frames queued after it are not written (the
// recording lists the frames before it, and stays valid and resumable). The next push() or
// finish() throws sls::Error with the write's code, naming the folder and the frame (an
// exception that is not an sls::Error, e.g. a test's hook, is passed on unchanged).
// Ending: finish() waits for every queued frame. The destructor (a capture unwinding from a
// cancel, a device error or a failed fusion) also writes every frame still queued before it
// joins, so that everything captured is on disk (drain() does the same and stays usable); a
// write error then is logged, not thrown (the capture's own exception is what propagates).
// Threads: push() and finish() from one thread (the capture's); statistics() from any.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <exception>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "sdk/core/stopwatch.h"

namespace sls {

// What the writer did (all of it, or up to a write error).
struct RecordingWriteStatistics {
  struct Frame {
    int frame = 0;                   // as pushed
    SteadyClock::time_point written;  // the recording listed it
    double write_s = 0.0;            // its write alone
  };
  std::vector<Frame> frames;       // written, in order
  std::size_t queue_frames = 0;    // the queue's bound (0: written on the capture's thread)
  std::size_t waits = 0;           // pushes that waited for room in the queue
  double wait_s = 0.0;             // those waits summed
  std::size_t deepest_queue = 0;   // the most frames waiting to be written at once

  double write_s_total() const;
  double write_s_median() const;
};

class RecordingWriterThread {
 public:
  using Write = std::function<void()>;

  // `folder`: named in errors. The thread starts with the first push.
  explicit RecordingWriterThread(std::string folder, std::size_t queue_frames = 2);
  ~RecordingWriterThread();
  RecordingWriterThread(const RecordingWriterThread&) = delete;
  RecordingWriterThread& operator=(const RecordingWriterThread&) = delete;

  // Queues `write` (frame `frame`'s), waiting while the queue is full. Throws the error of an
  // earlier write (see the file comment); `write` is then not queued.
  void push(int frame, Write write);
  // Waits until every queued frame is written; throws the first write error.
  void finish();
  // The same without throwing, for a capture that is unwinding: a write error not thrown yet is
  // logged (once), so that it is never silent.
  void drain() noexcept;

  RecordingWriteStatistics statistics() const;

 private:
  struct Job {
    int frame = 0;
    Write write;
  };
  void run();
  // Runs one job, timing it; the error as this class throws it.
  std::exception_ptr write_one(Job& job);
  // Throws the write error, if any (mutex_ held); it is then the caller's, not logged.
  void throw_if_failed();
  void log_unthrown_error();  // mutex_ held

  const std::string folder_;
  const std::size_t capacity_;
  mutable std::mutex mutex_;
  std::condition_variable ready_, room_, idle_;
  std::deque<Job> queue_;
  bool writing_ = false;  // the thread is running a job
  bool stopping_ = false;
  std::exception_ptr error_;
  bool error_thrown_ = false;
  RecordingWriteStatistics statistics_;
  std::thread thread_;
};

}  // namespace sls
