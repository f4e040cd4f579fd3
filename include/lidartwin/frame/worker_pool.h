#pragma once
// The render workers. Which thread runs an item never changes its result (items write disjoint
// outputs, noise is keyed by pixel), so the thread count is free. One pool serves every sensor of a
// process (a rig): several threads may run work at once, each doing its own items, and the pool's
// workers help the oldest unfinished run.
//
// A caller never waits for a worker that has not started on its run. On a busy host (many daemons,
// other work) a woken worker may not get a CPU for milliseconds; a caller that waited for it at the
// end of every run would be paced by the scheduler instead of by the work, and fall behind long
// before the CPU is used up. Here it does the items itself and returns.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <exception>
#include <functional>
#include <mutex>
#include <stop_token>
#include <thread>
#include <utility>
#include <vector>

namespace lidartwin {

// Leaves any real-time scheduling policy the calling thread inherited and sets its nice value.
void run_at_normal_priority(int nice);

// `count` consecutive items cut into pieces for `workers` workers, long ones first and shrinking to
// single items (guided self-scheduling): a worker that walks a piece shares work between its
// neighbouring items (the cast stage's walk casts the columns beside a piece only at its ends), and
// the short last pieces let the workers finish together.
struct WorkPiece {
  int first = 0;
  int size = 0;
};
std::vector<WorkPiece> guided_pieces(int count, int workers);

class WorkerPool {
 public:
  // threads: total including a calling thread; 0 = std::thread::hardware_concurrency().
  // The workers leave any real-time policy they inherit (the daemon's send clock may run as
  // SCHED_FIFO and must win the CPU from casting) and run at the given nice value.
  explicit WorkerPool(int threads, int nice = 0);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  int size() const { return static_cast<int>(threads_.size()) + 1; }
  // Calls task(worker, item) once for every item in [0, count) and returns when all are done; the
  // first exception is rethrown. worker is in [0, size()) and no two threads run one call's items
  // with the same worker index (the caller is 0), so per-worker scratch indexed by it is safe for
  // the task's own data. Any number of threads may call run at once.
  void run(int count, const std::function<void(int worker, int item)>& task);

 private:
  struct Run {
    const std::function<void(int, int)>* task = nullptr;
    int count = 0;
    std::atomic<int> next{0};
    int helpers = 0;           // workers draining it; guarded by mutex_
    std::exception_ptr error;  // guarded by mutex_
  };

  void worker_loop(const std::stop_token& stop, int worker);
  Run* open_run_locked() const;  // the oldest run with items left, or null
  void drain(Run& run, int worker);

  std::mutex mutex_;
  std::condition_variable_any wake_;
  std::condition_variable done_;
  std::deque<Run*> runs_;              // runs whose caller is still draining, oldest first; guarded by mutex_
  int idle_ = 0;                       // workers waiting for a run; guarded by mutex_
  std::vector<std::jthread> threads_;  // last: stopped and joined before the members above go
};

}  // namespace lidartwin
