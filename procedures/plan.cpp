#include "procedures/plan.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace fpss {

namespace {

std::string deg(double arcsec) { return fmt::format("{:+.4f} deg", arcsec / 3600.0); }

std::string duration_text(double s) {
  if (s < 60) return fmt::format("{:.1f} s", s);
  const auto total = static_cast<long>(std::lround(s));
  if (total < 3600) return fmt::format("{} min {:02} s", total / 60, total % 60);
  return fmt::format("{} h {:02} min {:02} s", total / 3600, (total % 3600) / 60, total % 60);
}

double axis_move_s(double d, double v, double a) {
  d = std::fabs(d);
  if (d <= 0) return 0;
  if (a <= 0) return d / v;
  // Triangle when the axis cannot reach full speed, trapezoid otherwise.
  if (d <= v * v / a) return 2 * std::sqrt(d / a);
  return d / v + v / a;
}

class Expander {
 public:
  Expander(const Procedure& proc, const EngineSettings& bench, Diagnostics& d) : proc_(proc), b_(bench), d_(d) {}

  Plan run() {
    for (const auto& st : proc_.steps) {
      // A step with errors of its own is already reported; the others are still checked against
      // the stand, so one pass shows every error.
      if (!st.valid) continue;
      step_ = &st;
      std::visit([this](const auto& body) { add(body); }, st.body);
      flush_limit_errors();
      if (too_many_) {
        d_.error(st.mark, fmt::format("step {} ({}): the plan reaches more than {} points; a plan may have at most {} "
                                      "(docs/procedures.md, Limits)",
                                      st.index, st.type, kMaxPlanPoints, kMaxPlanPoints));
        break;
      }
    }
    // The engine returns to null at the end of every run.
    plan_.physical_s += move_duration_s(p_, y_, 0, 0, b_.profile_rate_arcsec_s, b_.acceleration_arcsec_s2);
    link_s_ += 2 * link();
    plan_.estimated_s = plan_.physical_s + link_s_;
    return std::move(plan_);
  }

 private:
  Action base(Action::Kind k) {
    Action a;
    a.kind = k;
    a.step_index = step_->index;
    a.mark = step_->mark;
    if (k == Action::Kind::dwell && until_.until_group >= 0) {
      a.until_sigma_arcsec = until_.until_sigma_arcsec;
      a.until_group = until_.until_group;
      a.until_both_axes = until_.until_both_axes;
      a.axis = until_.axis;
    }
    return a;
  }

  // The adaptive-stop group the grid's next dwells belong to (none when the grid has no `until`).
  void until_group(const GridStep& s, StandAxis axis, bool both) {
    if (s.until_sigma_arcsec <= 0) return;
    until_.until_sigma_arcsec = s.until_sigma_arcsec;
    until_.until_group = next_group_++;
    until_.until_both_axes = both;
    until_.axis = axis;
  }

  void push(Action a) {
    if (a.is_point() && plan_.points >= kMaxPlanPoints) {
      too_many_ = true;  // reported once, by run(); nothing more is built
      return;
    }
    if (a.is_point()) {
      a.point = static_cast<int64_t>(plan_.points++);
      plan_.point_action.push_back(plan_.actions.size());
    }
    plan_.actions.push_back(std::move(a));
  }

  void check_target(double p, double y) {
    const auto& l = b_.limits;
    const double eps = 1e-6;
    if (p < l.pitch_min_arcsec - eps || p > l.pitch_max_arcsec + eps) {
      bad_.push_back(fmt::format("pitch {} (soft limits {} .. {})", deg(p), deg(l.pitch_min_arcsec),
                                 deg(l.pitch_max_arcsec)));
    }
    if (y < l.yaw_min_arcsec - eps || y > l.yaw_max_arcsec + eps) {
      bad_.push_back(fmt::format("yaw {} (soft limits {} .. {})", deg(y), deg(l.yaw_min_arcsec),
                                 deg(l.yaw_max_arcsec)));
    }
  }

  void check_rate(double r) {
    if (r > b_.limits.max_rate_arcsec_s * (1 + 1e-9)) {
      d_.error(step_->mark, fmt::format("step {} ({}): rate {} arcsec/s is above the soft limit {} arcsec/s",
                                        step_->index, step_->type, r, b_.limits.max_rate_arcsec_s));
    }
  }

  // Reports the step's out-of-limit targets as one error (the first few named, the rest counted).
  void flush_limit_errors() {
    if (bad_.empty()) return;
    std::vector<std::string> uniq;
    for (auto& s : bad_) if (std::find(uniq.begin(), uniq.end(), s) == uniq.end()) uniq.push_back(s);
    std::string list;
    const size_t shown = std::min<size_t>(uniq.size(), 3);
    for (size_t i = 0; i < shown; ++i) list += (i ? "; " : "") + uniq[i];
    if (uniq.size() > shown) list += fmt::format("; and {} more", uniq.size() - shown);
    d_.error(step_->mark, fmt::format("step {} ({}): target out of soft limits: {}", step_->index, step_->type,
                                      list));
    bad_.clear();
  }

  // A device request's round trip in bench seconds.
  double link() const { return b_.link_round_trip_s * b_.time_scale; }

  // Whether the engine schedules the move to dwell `a` while the dwell before it is measured.
  bool scheduled_after_last_dwell(const Action& a) const {
    if (!b_.timed_moves || b_.clock != ClockSync::shared || a.until_group >= 0 || plan_.actions.empty()) return false;
    const Action& last = plan_.actions.back();
    return last.kind == Action::Kind::dwell && (last.frames - 0.5) / b_.sample_rate_hz >= 3 * link();
  }

  void travel(double p, double y, double rate) {
    plan_.physical_s += move_duration_s(p_, y_, p, y, rate > 0 ? rate : b_.profile_rate_arcsec_s,
                                         b_.acceleration_arcsec_s2);
    p_ = p;
    y_ = y;
  }

  void dwell(double p, double y, Phase phase, double settle_s, const FrameSpec& f) {
    check_target(p, y);
    Action a = base(Action::Kind::dwell);
    a.pitch_arcsec = p;
    a.yaw_arcsec = y;
    a.phase = phase;
    a.settle_s = settle_s;
    a.frames = f.count(b_.sample_rate_hz);
    a.max_invalid = f.max_invalid;
    travel(p, y, 0);
    plan_.physical_s += settle_s + a.frames / b_.sample_rate_hz;
    // The links: the move's command (targets, then go), the reading that finds the gimbal there,
    // and the encoder reading after the last frame (the others overlap the frames); none when
    // the move was scheduled on the gimbal's clock during the dwell before, if its three requests
    // fit in that dwell (docs/procedures.md, "How the engine waits").
    if (!scheduled_after_last_dwell(a)) link_s_ += 3 * link();
    plan_.frames += a.frames;
    push(a);
  }

  void add(const HomeStep& s) {
    Action a = base(Action::Kind::home);
    a.timeout_s = s.timeout_s.value_or(0);
    travel(0, 0, 0);
    push(a);
  }

  void add(const MoveStep& s) {
    Action a = base(Action::Kind::move);
    a.pitch_arcsec = s.pitch_arcsec.value_or(p_);
    a.yaw_arcsec = s.yaw_arcsec.value_or(y_);
    a.rate_arcsec_s = s.rate_arcsec_s.value_or(0);
    check_target(a.pitch_arcsec, a.yaw_arcsec);
    if (a.rate_arcsec_s > 0) check_rate(a.rate_arcsec_s);
    travel(a.pitch_arcsec, a.yaw_arcsec, a.rate_arcsec_s);
    push(a);
  }

  void add(const SettleStep& s) {
    Action a = base(Action::Kind::settle);
    a.settle_s = s.duration_s;
    plan_.physical_s += s.duration_s;
    push(a);
  }

  void add(const SampleStep& s) {
    const bool at_null = std::fabs(p_) < 1e-9 && std::fabs(y_) < 1e-9;
    dwell(p_, y_, s.phase.value_or(at_null ? Phase::null : Phase::offset), s.settle_s, s.frames);
  }

  void add(const GridStep& s) {
    const auto offs = s.offsets_arcsec();
    std::vector<std::pair<double, double>> pts;
    auto on_axis = [](StandAxis ax, double o) {
      return ax == StandAxis::pitch ? std::pair{o, 0.0} : std::pair{0.0, o};
    };
    if (s.layout == GridStep::Layout::full) {
      // Every lattice point of the field; the first listed axis is the outer loop.
      std::vector<double> all{0.0};
      all.insert(all.end(), offs.begin(), offs.end());
      const StandAxis outer = s.axes.front();
      for (double a : all) {
        for (double b : all) {
          if (a == 0 && b == 0) continue;
          pts.push_back(outer == StandAxis::pitch ? std::pair{a, b} : std::pair{b, a});
        }
      }
    } else {
      for (auto ax : s.axes) for (double o : s.offsets_arcsec(ax)) pts.push_back(on_axis(ax, o));
      if (s.layout == GridStep::Layout::diagonals) {
        for (double o : offs) pts.emplace_back(o, o);
        for (double o : offs) pts.emplace_back(o, -o);
      }
    }
    // With `until`, each axis's offsets are a group (layout axes); other layouts move both at once.
    const bool per_axis = s.layout == GridStep::Layout::axes;
    auto axis_of = [](std::pair<double, double> pt) { return pt.first != 0 ? StandAxis::pitch : StandAxis::yaw; };
    if (!pts.empty()) until_group(s, axis_of(pts.front()), !per_axis);
    dwell(0, 0, Phase::null, s.settle_s, s.frames);
    for (size_t i = 0; i < pts.size(); ++i) {
      if (per_axis && i > 0 && axis_of(pts[i]) != axis_of(pts[i - 1])) until_group(s, axis_of(pts[i]), false);
      dwell(pts[i].first, pts[i].second, Phase::offset, s.settle_s, s.frames);
      dwell(0, 0, Phase::null, s.settle_s, s.frames);
    }
    until_ = Action{};
  }

  void add(const SlewStep& s) {
    if (s.rates_arcsec_s.empty()) return;
    check_rate(*std::max_element(s.rates_arcsec_s.begin(), s.rates_arcsec_s.end()));
    if (s.sample_period_s * b_.sample_rate_hz < 1 - 1e-9) {
      d_.error(step_->mark, fmt::format("step {} ({}): sample_period_s {} s is shorter than the sensor's frame "
                                        "period {} s (sample rate {} Hz)",
                                        step_->index, step_->type, s.sample_period_s, 1 / b_.sample_rate_hz,
                                        b_.sample_rate_hz));
    }
    std::vector<double> dirs;
    if (s.directions != SlewStep::Directions::negative) dirs.push_back(+1);
    if (s.directions != SlewStep::Directions::positive) dirs.push_back(-1);
    for (double rate : s.rates_arcsec_s) {
      for (double dir : dirs) {
        Action a = base(Action::Kind::slew);
        a.axis = s.axis;
        a.phase = Phase::slew;
        a.rate_arcsec_s = rate;
        a.sample_period_s = s.sample_period_s;
        a.settle_s = s.settle_s;
        a.reversals = s.reversals;
        const double from = -dir * s.amplitude_arcsec, to = dir * s.amplitude_arcsec;
        if (s.axis == StandAxis::pitch) {
          a.start_pitch_arcsec = from; a.pitch_arcsec = to;
        } else {
          a.start_yaw_arcsec = from; a.yaw_arcsec = to;
        }
        check_target(a.start_pitch_arcsec, a.start_yaw_arcsec);
        check_target(a.pitch_arcsec, a.yaw_arcsec);
        travel(a.start_pitch_arcsec, a.start_yaw_arcsec, 0);
        plan_.physical_s += s.settle_s;
        const double before = plan_.physical_s;
        for (int leg = 0; leg <= s.reversals; ++leg) {
          if (leg % 2 == 0) travel(a.pitch_arcsec, a.yaw_arcsec, rate);
          else travel(a.start_pitch_arcsec, a.start_yaw_arcsec, rate);
        }
        plan_.frames += static_cast<size_t>((plan_.physical_s - before) / s.sample_period_s);
        push(a);
      }
    }
  }

  void add(const CalibrateStep& s) {
    Action a = base(Action::Kind::calibrate);
    a.calibrate = &s;
    push(a);
  }

  void add(const CheckStep& s) {
    Action a = base(Action::Kind::check);
    a.check = &s;
    push(a);
  }

  void add(const DiagnoseStep& s) {
    Action a = base(Action::Kind::diagnose);
    a.diagnose = &s;
    push(a);
  }

  const Procedure& proc_;
  const EngineSettings& b_;
  Diagnostics& d_;
  const Step* step_ = nullptr;
  Plan plan_;
  double p_ = 0, y_ = 0;  // planned position: a run starts from null
  std::vector<std::string> bad_;
  Action until_;  // the adaptive-stop fields of the grid being expanded
  int next_group_ = 0;
  bool too_many_ = false;
  double link_s_ = 0;  // bench seconds the device links add to the physical minimum
};

}  // namespace

double move_duration_s(double from_pitch, double from_yaw, double to_pitch, double to_yaw, double rate_arcsec_s,
                       double accel_arcsec_s2) {
  return std::max(axis_move_s(to_pitch - from_pitch, rate_arcsec_s, accel_arcsec_s2),
                  axis_move_s(to_yaw - from_yaw, rate_arcsec_s, accel_arcsec_s2));
}

Plan expand(const Procedure& proc, const EngineSettings& bench, Diagnostics& d) {
  return Expander(proc, bench, d).run();
}

std::string Action::describe() const {
  switch (kind) {
    case Kind::home: return "home";
    case Kind::move:
      return fmt::format("move to pitch {}, yaw {}{}", deg(pitch_arcsec), deg(yaw_arcsec),
                         rate_arcsec_s > 0 ? fmt::format(" at {} arcsec/s", rate_arcsec_s) : "");
    case Kind::settle: return fmt::format("settle {} s", settle_s);
    case Kind::dwell:
      return fmt::format("point {:>4} {:<6} pitch {}, yaw {}: settle {} s, {} frames", point + 1, to_string(phase),
                         deg(pitch_arcsec), deg(yaw_arcsec), settle_s, frames);
    case Kind::slew:
      return fmt::format("point {:>4} slew   {} {} -> {}{} at {} arcsec/s, one sample per {} s", point + 1,
                         to_string(axis), deg(axis == StandAxis::pitch ? start_pitch_arcsec : start_yaw_arcsec),
                         deg(axis == StandAxis::pitch ? pitch_arcsec : yaw_arcsec),
                         reversals > 0 ? fmt::format(" and back ({} reversal{})", reversals, reversals > 1 ? "s" : "")
                                       : "",
                         rate_arcsec_s, sample_period_s);
    case Kind::calibrate:
      return fmt::format("calibrate ({}) on the points so far", calibrate ? calibrate->method : "?");
    case Kind::check: return "check the calibration's residuals against limits";
    case Kind::diagnose:
      return fmt::format("diagnose the points so far against {} (GAP.json, GAP.html)",
                         diagnose ? diagnose->model.filename().string() : "?");
  }
  return "?";
}

std::string format_plan(const Procedure& proc, const Plan& plan, const EngineSettings& b) {
  std::string s = fmt::format("procedure {} ({}): {} steps\n", proc.name, proc.origin, proc.steps.size());
  s += fmt::format("stand: {}; soft limits pitch {} .. {}, yaw {} .. {}, rate <= {} arcsec/s\n", b.axes.describe(),
                   deg(b.limits.pitch_min_arcsec), deg(b.limits.pitch_max_arcsec), deg(b.limits.yaw_min_arcsec),
                   deg(b.limits.yaw_max_arcsec), b.limits.max_rate_arcsec_s);
  s += fmt::format("gimbal profile {} arcsec/s, {} arcsec/s^2; sensor {} Hz\n", b.profile_rate_arcsec_s,
                   b.acceleration_arcsec_s2, b.sample_rate_hz);
  size_t nulls = 0, offsets = 0, slews = 0;
  for (const auto& a : plan.actions) {
    s += fmt::format("  step {:>2}  {}\n", a.step_index, a.describe());
    if (a.kind == Action::Kind::dwell) (a.phase == Phase::null ? nulls : offsets)++;
    if (a.kind == Action::Kind::slew) ++slews;
  }
  s += fmt::format("points: {} ({} null, {} offset, {} slew segments); frames kept: {}\n", plan.points, nulls,
                   offsets, slews, plan.frames);
  s += fmt::format("physical minimum: {} of bench time (moves at the profile rate and acceleration, settles, "
                   "frames)\n", duration_text(plan.physical_s));
  s += fmt::format("estimated duration: {} of bench time", duration_text(plan.estimated_s));
  if (b.time_scale != 1) {
    s += fmt::format(" ({} of wall time at speed-up {})", duration_text(plan.estimated_s / b.time_scale),
                     b.time_scale);
  }
  const bool adaptive = std::any_of(plan.actions.begin(), plan.actions.end(),
                                    [](const Action& a) { return a.until_group >= 0; });
  if (adaptive) s += "; at most: a grid's adaptive stop (until) may end it sooner";
  s += "\nall targets inside the soft limits\n";
  return s;
}

}  // namespace fpss
