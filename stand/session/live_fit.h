// The run's live fit: the streaming estimator on every recorded row, its honest uncertainty for the console and an adaptive stop.
#pragma once
#include <array>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "calib/streaming.h"
#include "procedures/events.h"
#include "procedures/plan.h"
#include "procedures/settings.h"

namespace fpss {

// The estimate is computed on a worker thread of its own, at the lowest priority: a fit costs
// milliseconds, and at --speed 1000 a millisecond the engine spent on it is a second of bench time.
class LiveFit {
 public:
  // The plan's dwells give the ranges the uncertainty is judged over (the sensor frame, through
  // the stand's axis mapping): all of them for the run's figure, each grid's own for its `until`.
  LiveFit(const Plan& plan, const AxisMapping& axes);
  ~LiveFit();
  LiveFit(const LiveFit&) = delete;
  LiveFit& operator=(const LiveFit&) = delete;

  // Rows recorded before this process (a resumed run), added at once.
  void add(const Sample& s);

  // After a point: its rows go to the worker, which refreshes the estimate at most twice a second
  // of wall time (a display's rate), the first time no sooner than half a second after the run's
  // start (this object's construction): a first estimate with its two sigma fits costs 12-34 ms of
  // CPU, which in a run of 0.2 s of wall time (the grid at --speed 1000) took the engine's and the
  // emulator's cores for 10-30 bench seconds (the grid at 1000x, 16 interleaved pairs: median
  // 1.099x before, 1.031x after). Returns an estimate the worker finished since the last call,
  // to be published now; with `force` (the last point, an adaptive stop) the estimate of every row
  // so far, waited for. The sigmas are the batch fit's honest ones (GLS) over the run's planned
  // range, NaN until an axis can be fitted. Nothing while no estimate is valid, but for a forced
  // one that has a sigma (an axis that stopped before the other has offsets: the RMS are NaN). A
  // fit that threw on the worker throws here.
  std::optional<FitUpdated> point_done(const std::vector<Sample>& rows, int64_t points, bool force);

  // For the engine's adaptive stop: the largest 1-sigma over the range of `a`'s grid, for the
  // axes of its group, over every row so far; infinite while the data cannot tell.
  double until_sigma(const Action& a);

  // A point done: its residual against the latest valid estimate, with those of the points done
  // before the first one (kept until it came); empty while there is none.
  struct PointResidual {
    int64_t point = 0;  // 1-based
    double ref_pitch_arcsec = 0, ref_yaw_arcsec = 0, residual_pitch_arcsec = 0, residual_yaw_arcsec = 0;
  };
  std::vector<PointResidual> residuals(int64_t point, const PointStats& stats);
  std::string text() const;

 private:
  using Range = std::optional<std::array<double, 2>>;
  struct Ranges {
    Range pitch, yaw;  // sensor frame: what alpha and beta measure
  };
  Ranges ranges_of(const Plan& plan, size_t step_index) const;  // step 0: every dwell of the plan
  // Largest listed sigma of one sensor axis over `r` (cached per axis and range, until the next
  // change: the run's range and a grid's are often the same, and then fitted once).
  double sigma(fit::Axis axis, const Ranges& r);
  // With fit_m_ held: the queued rows into the calibrator (in order: only its holder takes them).
  int64_t take_queued();
  std::optional<FitUpdated> update(int64_t points, bool force);  // with fit_m_ held
  void work();

  // fit_m_: the calibrator and what is derived from it; m_: the queue, the worker's results and
  // the published estimate (the engine's thread never waits on a fit but when it asks for one).
  mutable std::mutex fit_m_, m_;
  std::condition_variable cv_;
  StreamingCalibrator cal_;
  AxisMapping axes_;
  Ranges run_ranges_;
  std::map<size_t, Ranges> step_ranges_;
  struct Cached {
    size_t pairs = 0;
    double sigma = 0;
  };
  std::map<std::tuple<int, double, double>, Cached> cache_;  // (axis, lo, hi) -> sigma at `pairs` changes
  // The last refresh; the run's start counts as one (see point_done).
  std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
  std::vector<Sample> queued_;
  int64_t queued_points_ = 0;
  std::optional<FitUpdated> ready_;
  std::string error_;
  bool stop_ = false;
  std::optional<StreamingCalibrator::Estimate> est_;
  std::vector<std::pair<int64_t, PointStats>> unplotted_;  // points done before the first valid estimate
  std::string text_;
  std::thread worker_;
};

}  // namespace fpss
