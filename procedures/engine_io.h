// The engine's hold on its devices and its operator: every command and reading goes through here, so each part knows what the gimbal should hold.
#pragma once
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include <spdlog/logger.h>

#include "drivers/gimbal.h"
#include "drivers/sensor.h"
#include "procedures/engine.h"
#include "procedures/engine_clock.h"
#include "procedures/events.h"
#include "procedures/plan.h"
#include "procedures/settings.h"

namespace fpss {

// Shared by the engine's parts, which borrow it: one record of what this run wrote to the gimbal
// (another client's change is noticed against it) and of where the gimbal last was.
class EngineIo {
 public:
  EngineIo(Gimbal& gimbal, Sensor& sensor, const EngineSettings& bench, EventBus& events, spdlog::logger& log,
           RunControl& control, EngineStats& stats, EngineClock& clock)
      : g_(gimbal), b_(bench), events_(events), log_(log), ctl_(control), stats_(stats), clock_(clock),
        units_{EngineUnit{.id = 0, .sensor = &sensor, .axes = bench.axes}}, lost_(1, false) {}

  Gimbal& gimbal() { return g_; }
  // The lead unit's sensor: its frames pace the dwells.
  Sensor& sensor() { return *units_[lead_].sensor; }
  const EngineUnit& lead() const { return units_[lead_]; }
  size_t lead_index() const { return lead_; }

  // --- several units (Engine::set_units) ---
  void set_units(std::vector<EngineUnit> units);
  size_t units() const { return units_.size(); }
  const EngineUnit& unit(size_t i) const { return units_[i]; }
  bool lost(size_t i) const { return lost_[i]; }
  // The units still read besides the lead, by index.
  std::vector<size_t> followers() const;
  // Drops unit i for the rest of the run (a Fault event says so); the lead's place passes to the
  // next unit still read. False when it was the last.
  bool lose(size_t i, LossCause cause, const std::string& reason, int64_t point);
  // Unit i's own sensor options, else the engine's.
  double rate_hz(size_t i) const;
  double frame_timeout_s(size_t i) const;
  double sensor_offset_s(size_t i) const;
  // "K (SERIAL)", K 1-based: how messages name unit i.
  std::string unit_name(size_t i) const;
  // Unit k leads from here: the first unit's rate and its own clock offset.
  void take_lead(size_t k);
  // Another unit could take the lead's place.
  bool can_lose_lead() const;
  void on_lost(std::function<void(const UnitLoss&)> f) { on_lost_ = std::move(f); }
  // A failing unit's strikes: the points in a row it gave nothing at (reset by a good point).
  int& strikes(size_t i) { return strikes_[i]; }
  const EngineSettings& settings() const { return b_; }
  EventBus& events() { return events_; }
  spdlog::logger& log() { return log_; }
  RunControl& control() { return ctl_; }
  EngineStats& stats() { return stats_; }
  EngineClock& clock() { return clock_; }

  GimbalState read_gimbal();
  double last_pitch_arcsec() const { return last_pitch_arcsec_; }
  double last_yaw_arcsec() const { return last_yaw_arcsec_; }
  // The sensor's temperature for point `a`'s rows; NaN (and a warning) when it does not answer.
  double read_temperature_c(const Action& a);
  double read_temperature_c(const Action& a, Sensor& sensor);

  // Every command the engine sends goes through these, so it knows what the gimbal should hold.
  void command_rate(double arcsec_s);
  void command_move(double pitch_arcsec, double yaw_arcsec);
  void command_home();  // a home need not write the target registers: they are not known after it
  void command_watchdog(double s);
  // The targets this run last wrote to the gimbal, which verify_command reads back.
  void targets_written(double pitch_arcsec, double yaw_arcsec);
  void targets_unknown() { target_known_ = false; }  // a command that failed may have written them
  const GimbalCommand& commanded() const { return commanded_; }
  // The rate moves run at: the last one commanded, else the profile's.
  double move_rate_arcsec_s() const;
  // Reads the gimbal's commanded state back; GimbalFailure (commanded_elsewhere) when another
  // client changed a target, the rate, the watchdog, or put it in rate mode.
  void verify_command();
  // A place the gimbal may be found at on this run's commands: each target written, a home's 0, 0,
  // where the run found it and where a stop of its own left it.
  void note_place(double pitch_arcsec, double yaw_arcsec);
  // GimbalFailure (commanded_elsewhere, final: the run stops) when `st` lies farther than the
  // tolerance and kForeignMargin_arcsec from every place and every path between them.
  void check_commanded_place(const GimbalState& st) const;
  // Beyond the in-position tolerance: overshoot, a stop's braking and encoder noise stay inside.
  static constexpr double kForeignMargin_arcsec = 36.0;  // 0.01 deg
  // GimbalFailure unless the gimbal is still at `a`'s point, unfaulted and not moving.
  void check_still(const Action& a, const GimbalState& st, const char* when);

  // Whether this run moved the gimbal: only then does the safe stop return it to null.
  bool moved() const { return moved_; }
  void mark_moved() { moved_ = true; }

  void check_abort();
  void set_stopping(bool stopping) { stopping_ = stopping; }  // during the safe stop an abort no longer interrupts
  void warn(const Action* a, const std::string& message);

 private:
  Gimbal& g_;
  const EngineSettings& b_;
  EventBus& events_;
  spdlog::logger& log_;
  RunControl& ctl_;
  EngineStats& stats_;
  EngineClock& clock_;
  GimbalCommand commanded_;
  bool target_known_ = false;
  bool moved_ = false;
  bool stopping_ = false;
  double last_pitch_arcsec_ = 0, last_yaw_arcsec_ = 0;  // the latest encoder reading
  std::vector<std::pair<double, double>> places_;        // note_place, in order
  std::vector<EngineUnit> units_;
  std::vector<bool> lost_;
  std::vector<int> strikes_ = std::vector<int>(1, 0);
  size_t lead_ = 0;
  std::function<void(const UnitLoss&)> on_lost_;
};

}  // namespace fpss
