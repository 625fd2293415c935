// sdk/core/serial_worker.h: jobs run in order on one thread (the same one for every job), their
// results and exceptions come through the futures, the destructor runs what is queued, and
// WaitOnExit waits for a job when its scope unwinds.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <stdexcept>
#include <thread>
#include <vector>

#include "sdk/core/serial_worker.h"

namespace sls {
namespace {

TEST(SerialWorker, RunsJobsInOrderOnOneThread) {
  SerialWorker worker;
  std::vector<int> order;
  std::vector<std::thread::id> threads(20);
  std::vector<std::future<int>> results;
  for (int i = 0; i < 20; ++i) {
    results.push_back(worker.submit([i, &order, &threads] {
      order.push_back(i);  // only the worker's thread writes it
      threads[static_cast<std::size_t>(i)] = std::this_thread::get_id();
      return i * i;
    }));
  }
  for (int i = 0; i < 20; ++i) EXPECT_EQ(results[static_cast<std::size_t>(i)].get(), i * i);
  for (int i = 0; i < 20; ++i) EXPECT_EQ(order[static_cast<std::size_t>(i)], i);
  for (const std::thread::id& id : threads) EXPECT_EQ(id, threads[0]);
  EXPECT_NE(threads[0], std::this_thread::get_id());
}

TEST(SerialWorker, AJobsExceptionComesThroughItsFutureAndTheWorkerGoesOn) {
  SerialWorker worker;
  std::future<void> failed = worker.submit([] { throw std::runtime_error("ship failed"); });
  std::future<int> next = worker.submit([] { return 7; });
  EXPECT_THROW(failed.get(), std::runtime_error);
  EXPECT_EQ(next.get(), 7);
}

TEST(SerialWorker, TheDestructorRunsWhatIsQueued) {
  std::atomic<int> done{0};
  {
    SerialWorker worker;
    for (int i = 0; i < 5; ++i) {
      (void)worker.submit([&done] {
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
        ++done;
      });
    }
  }
  EXPECT_EQ(done.load(), 5);
  SerialWorker never_used;  // no job: no thread to join
}

TEST(SerialWorker, WaitOnExitWaitsForTheJobWhenItsScopeUnwinds) {
  SerialWorker worker;
  std::atomic<bool> finished{false};
  try {
    std::future<bool> job;
    const WaitOnExit<bool> wait(job);
    job = worker.submit([&finished] {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      finished = true;
      return true;
    });
    throw std::runtime_error("the frame failed");
  } catch (const std::runtime_error&) {
    EXPECT_TRUE(finished.load());  // the job was waited for before its scope was left
  }
}

}  // namespace
}  // namespace sls
