#include "procedures/engine_io.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "procedures/engine_detail.h"

namespace fpss {

using namespace engine_detail;

GimbalState EngineIo::read_gimbal() {
  GimbalState st;
  {
    Timed t(stats_.device_s);
    st = g_.read_state();
  }
  last_pitch_arcsec_ = st.pitch_arcsec;
  last_yaw_arcsec_ = st.yaw_arcsec;
  if (places_.empty()) note_place(st.pitch_arcsec, st.yaw_arcsec);  // where this run found it
  clock_.note_gimbal(static_cast<double>(st.sample_time_us) * 1e-6,
                     st.host_time_s > 0 ? st.host_time_s : clock_.host_now_s());
  return st;
}

double EngineIo::read_temperature_c(const Action& a) { return read_temperature_c(a, sensor()); }

double EngineIo::read_temperature_c(const Action& a, Sensor& sensor) {
  try {
    Timed t(stats_.device_s);
    return sensor.temperature_c();
  } catch (const DeviceError& e) {
    // No reply, a malformed one or an implausible value: the rows carry none (never the value).
    warn(&a, fmt::format("point {}: no temperature ({})", a.point + 1, e.what()));
    return std::numeric_limits<double>::quiet_NaN();
  }
}

void EngineIo::set_units(std::vector<EngineUnit> units) {
  if (units.empty()) throw std::logic_error("Engine::set_units: no unit");
  units_ = std::move(units);
  lost_.assign(units_.size(), false);
  strikes_.assign(units_.size(), 0);
  lead_ = 0;
}

std::vector<size_t> EngineIo::followers() const {
  std::vector<size_t> out;
  for (size_t i = 0; i < units_.size(); ++i) {
    if (i != lead_ && !lost_[i]) out.push_back(i);
  }
  return out;
}

// The lead paces the dwells at the first unit's rate (the plan's frames), and its frames' times
// carry its own clock offset.
void EngineIo::take_lead(size_t k) {
  clock_.set_sensor_offset_s(sensor_offset_s(k));
  if (std::abs(rate_hz(k) - b_.sample_rate_hz) < 1e-9) return;
  try {
    Timed t(stats_.device_s);
    units_[k].sensor->set_rate(static_cast<int>(std::lround(b_.sample_rate_hz)));  // taken while streaming (ICD)
    units_[k].sample_rate_hz = b_.sample_rate_hz;
  } catch (const DeviceError& e) {
    log_.warn("unit {}: could not set the pacing rate {} Hz: {}", unit_name(k), b_.sample_rate_hz, e.what());
  }
}

double EngineIo::rate_hz(size_t i) const {
  return std::isfinite(units_[i].sample_rate_hz) ? units_[i].sample_rate_hz : b_.sample_rate_hz;
}
double EngineIo::frame_timeout_s(size_t i) const {
  return std::isfinite(units_[i].frame_timeout_s) ? units_[i].frame_timeout_s : b_.frame_timeout_s;
}
double EngineIo::sensor_offset_s(size_t i) const {
  return std::isfinite(units_[i].sensor_time_offset_s) ? units_[i].sensor_time_offset_s : b_.sensor_time_offset_s;
}

std::string EngineIo::unit_name(size_t i) const {
  const EngineUnit& u = units_[i];
  return u.serial.empty() ? std::to_string(u.id + 1) : fmt::format("{} ({})", u.id + 1, u.serial);
}

bool EngineIo::can_lose_lead() const { return !followers().empty(); }

bool EngineIo::lose(size_t i, LossCause cause, const std::string& reason, int64_t point) {
  if (lost_[i]) return true;
  lost_[i] = true;
  const std::string msg = fmt::format("unit {} lost ({}): {}; the other units go on", unit_name(i), to_string(cause), reason);
  log_.error("{}", msg);
  events_.publish(Fault{Fault::Level::fault, point, msg, {}});
  if (on_lost_) on_lost_(UnitLoss{units_[i].id, cause, reason, point});
  // A silent unit would only make the stop wait out its command timeouts.
  if (cause != LossCause::silence) {
    try {
      Timed t(stats_.device_s);
      units_[i].sensor->stop();
    } catch (const DeviceError&) {
      // It is lost already: its stream need not stop cleanly.
    }
  }
  if (i == lead_) {
    for (size_t k = 0; k < units_.size(); ++k) {
      if (!lost_[k]) {
        lead_ = k;
        log_.warn("unit {} leads from here", unit_name(k));
        take_lead(k);
        return true;
      }
    }
    return false;
  }
  return true;
}

void EngineIo::command_rate(double arcsec_s) {
  g_.set_max_rate(arcsec_s);
  commanded_.max_rate_arcsec_s = arcsec_s;
}

void EngineIo::command_move(double pitch_arcsec, double yaw_arcsec) {
  g_.move_to(pitch_arcsec, yaw_arcsec);
  targets_written(pitch_arcsec, yaw_arcsec);
}

void EngineIo::command_home() {
  g_.home();
  commanded_.target_pitch_arcsec = commanded_.target_yaw_arcsec = 0;
  target_known_ = false;
  note_place(0, 0);
}

void EngineIo::command_watchdog(double s) {
  g_.set_watchdog(s);
  commanded_.watchdog_s = s;
}

void EngineIo::targets_written(double pitch_arcsec, double yaw_arcsec) {
  commanded_.target_pitch_arcsec = pitch_arcsec;
  commanded_.target_yaw_arcsec = yaw_arcsec;
  target_known_ = true;
  note_place(pitch_arcsec, yaw_arcsec);
}

void EngineIo::note_place(double pitch_arcsec, double yaw_arcsec) {
  if (!places_.empty() && places_.back() == std::pair{pitch_arcsec, yaw_arcsec}) return;
  places_.emplace_back(pitch_arcsec, yaw_arcsec);
}

void EngineIo::check_commanded_place(const GimbalState& st) const {
  // Three places in a row span every path the gimbal can take on this run's commands: a move
  // (each axis monotonic from one place to the next, so inside their box), the move queued
  // behind it, and a stop part-way, which the place after it continues from.
  if (places_.empty()) return;
  const double m = b_.in_position_tolerance_arcsec + kForeignMargin_arcsec;
  const double p = st.pitch_arcsec, y = st.yaw_arcsec;
  for (size_t i = 0; i < places_.size(); ++i) {
    const size_t lo = i == 0 ? 0 : i - 1, hi = std::min(i + 1, places_.size() - 1);
    double p0 = places_[i].first, p1 = p0, y0 = places_[i].second, y1 = y0;
    for (size_t k = lo; k <= hi; ++k) {
      p0 = std::min(p0, places_[k].first), p1 = std::max(p1, places_[k].first);
      y0 = std::min(y0, places_[k].second), y1 = std::max(y1, places_[k].second);
    }
    if (p >= p0 - m && p <= p1 + m && y >= y0 - m && y <= y1 + m) return;
  }
  throw GimbalFailure(fmt::format("gimbal found at {:.1f}, {:.1f} arcsec, which this run never commanded: another client?", p, y),
                      StopCause::commanded_elsewhere, /*final=*/true);
}

double EngineIo::move_rate_arcsec_s() const {
  return commanded_.max_rate_arcsec_s > 0 ? commanded_.max_rate_arcsec_s : b_.profile_rate_arcsec_s;
}

void EngineIo::verify_command() {
  std::optional<GimbalCommand> c;
  try {
    Timed t(stats_.device_s);
    c = g_.read_command();
  } catch (const DeviceError& e) {
    throw GimbalFailure(e.what());
  }
  if (!c) return;
  // The registers hold whole milliarcseconds (and ms for the watchdog): allow their rounding.
  const double mas = 1e-3 * 1.01;
  std::string what;
  auto differs = [&](const char* name, double read, double wrote, double tol, const char* unit) {
    if (std::fabs(read - wrote) > tol) what += fmt::format("{}{} {} {} (this run wrote {})", what.empty() ? "" : ", ", name, read, unit, wrote);
  };
  if (target_known_) {
    differs("pitch target", c->target_pitch_arcsec, commanded_.target_pitch_arcsec, mas, "arcsec");
    differs("yaw target", c->target_yaw_arcsec, commanded_.target_yaw_arcsec, mas, "arcsec");
  }
  if (commanded_.max_rate_arcsec_s > 0) differs("max rate", c->max_rate_arcsec_s, commanded_.max_rate_arcsec_s, mas, "arcsec/s");
  differs("watchdog", c->watchdog_s, commanded_.watchdog_s, 1.01e-3, "s");
  if (c->command == 5) what += fmt::format("{}rate mode commanded", what.empty() ? "" : ", ");
  if (!what.empty()) {
    throw GimbalFailure(fmt::format("gimbal commanded by another client: {}", what), StopCause::commanded_elsewhere);
  }
}

void EngineIo::check_still(const Action& a, const GimbalState& st, const char* when) {
  if (st.has(kFault) || st.fault != GimbalFault::none) {
    throw GimbalFailure(fmt::format("gimbal fault ({}) {} sampling", fault_name(st), when));
  }
  const double tol = b_.in_position_tolerance_arcsec;
  if (st.has(kMoving) || std::fabs(st.pitch_arcsec - a.pitch_arcsec) > tol || std::fabs(st.yaw_arcsec - a.yaw_arcsec) > tol) {
    check_commanded_place(st);  // another client's move explains it: say so
    verify_command();
    throw GimbalFailure(fmt::format("gimbal left the point {} sampling (pitch {}, yaw {}, status 0x{:02x})", when,
                                    deg(st.pitch_arcsec), deg(st.yaw_arcsec), st.status));
  }
}

void EngineIo::check_abort() {
  if (stopping_) return;
  if (ctl_.abort.load()) throw Aborted{};
}

void EngineIo::warn(const Action* a, const std::string& message) {
  log_.warn("{}", message);
  events_.publish(Fault{Fault::Level::warning, a && a->is_point() ? a->point : -1, message, {}});
}

}  // namespace fpss
