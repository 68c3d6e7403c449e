#include "procedures/procedure.h"

#include <fmt/format.h>

#include <cmath>

#include "base/errors.h"
#include "base/text_file.h"
#include "calib/coefficients.h"

namespace fpss {

const char* to_string(StandAxis a) { return a == StandAxis::pitch ? "pitch" : "yaw"; }

int FrameSpec::count(double sample_rate_hz) const {
  if (frames > 0) return frames;
  return std::max(1, static_cast<int>(std::lround(duration_s * sample_rate_hz)));
}

namespace {

// Indices 0..n-1 of increasing offsets, coarse to fine: the largest, then the one nearest the
// middle of the widest gap left (between zero and the largest first), and so on.
std::vector<size_t> spread_order(size_t n) {
  std::vector<size_t> order;
  std::vector<bool> taken(n, false);
  if (n == 0) return order;
  order.push_back(n - 1);
  taken[n - 1] = true;
  while (order.size() < n) {
    // Magnitudes are (k + 1) step: the gaps are between taken indices, with -1 standing for zero.
    long best = -1, best_gap = -1, prev = -1;
    for (long k = 0; k < static_cast<long>(n); ++k) {
      if (!taken[static_cast<size_t>(k)]) continue;
      const long gap = k - prev;
      if (gap > best_gap && gap > 1) { best_gap = gap; best = prev + gap / 2; }
      prev = k;
    }
    taken[static_cast<size_t>(best)] = true;
    order.push_back(static_cast<size_t>(best));
  }
  return order;
}

}  // namespace

std::vector<double> GridStep::offsets_arcsec() const {
  std::vector<double> pos;
  // A small tolerance so that 0.42 / 0.06 gives 7 offsets despite rounding.
  // Bounded (parse_grid refuses a grid beyond kMaxPlanPoints): never an overflowing int.
  const double nd = std::floor(extent_arcsec / step_arcsec + 1e-9);
  const int n = nd >= 0 && nd <= kMaxPlanPoints ? static_cast<int>(nd) : 0;
  // To the microarcsecond: 3 x (0.14 deg) is 1512 arcsec, not 1512.0000000000002.
  for (int k = 1; k <= n; ++k) pos.push_back(std::round(k * step_arcsec * 1e6) / 1e6);
  std::vector<double> out;
  switch (order) {
    case Order::outward:
      for (double p : pos) { out.push_back(p); out.push_back(-p); }
      break;
    case Order::ascending:
      for (auto it = pos.rbegin(); it != pos.rend(); ++it) out.push_back(-*it);
      for (double p : pos) out.push_back(p);
      break;
    case Order::descending:
      for (auto it = pos.rbegin(); it != pos.rend(); ++it) out.push_back(*it);
      for (double p : pos) out.push_back(-p);
      break;
    case Order::spread:
      for (size_t k : spread_order(pos.size())) { out.push_back(pos[k]); out.push_back(-pos[k]); }
      break;
  }
  return out;
}

std::vector<double> GridStep::offsets_arcsec(StandAxis axis) const {
  if (!listed()) return offsets_arcsec();
  return axis == StandAxis::pitch ? pitch_offsets_arcsec : yaw_offsets_arcsec;
}

const std::vector<std::string_view>& step_types() {
  static const std::vector<std::string_view> t{"home", "move", "settle", "sample", "null_offset_grid",
                                               "continuous_slew", "calibrate", "check",
                                               "diagnose"};
  return t;
}

namespace {

std::optional<FrameSpec> read_frames(MapReader& r, bool required) {
  FrameSpec f;
  const bool has_frames = r.has("frames"), has_duration = r.has("duration_s");
  auto n = r.integer("frames", false, 1, 1000000);
  auto dur = r.positive("duration_s");
  auto inv = r.integer("max_invalid_frames", false, 0, 1000000);
  if (has_frames && has_duration) {
    r.diagnostics().error(r.node("duration_s"),
                          fmt::format("{}: give frames or duration_s, not both", r.where()));
    return std::nullopt;
  }
  if (!has_frames && !has_duration) {
    if (required) r.diagnostics().error(r.mark(), fmt::format("{}: missing field frames or duration_s", r.where()));
    return std::nullopt;
  }
  if (n) f.frames = static_cast<int>(*n);
  if (dur) f.duration_s = *dur;
  if (inv) f.max_invalid = static_cast<int>(*inv);
  if (!n && !dur) return std::nullopt;
  return f;
}

std::optional<StandAxis> parse_axis(const YAML::Node& n, const std::string& what, Diagnostics& d) {
  if (n.IsScalar()) {
    if (n.Scalar() == "pitch") return StandAxis::pitch;
    if (n.Scalar() == "yaw") return StandAxis::yaw;
  }
  d.error(n, fmt::format("{}: expected pitch or yaw, got {}", what, describe_node(n)));
  return std::nullopt;
}

// The numbers listed under the first of `keys` present (each key with its factor to the base
// unit), each passing `valid` (else an error naming `rule`); empty when none is present. A present
// key that is not a non-empty list is an error.
std::vector<double> read_number_list(MapReader& r, std::initializer_list<std::pair<const char*, double>> keys,
                                     const char* noun, bool (*valid)(double), const char* rule) {
  Diagnostics& d = r.diagnostics();
  std::vector<double> out;
  for (auto [key, factor] : keys) {
    YAML::Node n = r.node(key);
    if (!n.IsDefined()) continue;
    const std::string what = fmt::format("{}: field {}", r.where(), key);
    if (!n.IsSequence() || n.size() == 0) {
      d.error(n, fmt::format("{}: expected a list of {}, got {}", what, noun, describe_node(n)));
      continue;
    }
    if (n.size() > static_cast<std::size_t>(kMaxPlanPoints)) {
      d.error(n, fmt::format("{}: {} {} listed; at most {} (docs/procedures.md, Limits)", what, n.size(), noun,
                             kMaxPlanPoints));
      continue;
    }
    for (const auto& e : n) {
      if (auto v = MapReader::as_number(e, what, d, key)) {
        if (!valid(*v * factor)) d.error(e, fmt::format("{}: {}, got {}", what, rule, *v));
        else out.push_back(*v * factor);
      }
    }
  }
  return out;
}

// Offsets listed one by one (`pitch_offsets_deg: [...]`, `yaw_offsets_arcsec: [...]`): non-zero,
// within the gimbal's +-180 deg.
void read_listed_offsets(MapReader& r, GridStep& s) {
  auto offset_ok = [](double a) { return a != 0 && std::fabs(a) <= 648000; };
  const char* rule = "an offset must be non-zero and within +-180 deg";
  s.pitch_offsets_arcsec = read_number_list(r, {{"pitch_offsets_arcsec", 1.0}, {"pitch_offsets_deg", 3600.0}},
                                            "offsets", +offset_ok, rule);
  s.yaw_offsets_arcsec = read_number_list(r, {{"yaw_offsets_arcsec", 1.0}, {"yaw_offsets_deg", 3600.0}},
                                          "offsets", +offset_ok, rule);
  if (!s.listed()) return;
  s.axes.clear();
  if (!s.pitch_offsets_arcsec.empty()) s.axes.push_back(StandAxis::pitch);
  if (!s.yaw_offsets_arcsec.empty()) s.axes.push_back(StandAxis::yaw);
  for (const char* k : {"extent_deg", "extent_arcsec", "step_deg", "step_arcsec", "axes", "order", "layout"}) {
    if (r.has(k)) {
      r.diagnostics().error(r.node(k), fmt::format("{}: {} does not go with listed offsets", r.where(), k));
    }
  }
}

// until: {angle_sigma_max_arcsec: S}, the adaptive stop (docs/procedures.md).
void read_until(MapReader& r, GridStep& s) {
  if (!r.has("until")) return;
  MapReader u(r.node("until"), fmt::format("{}: field until", r.where()), r.diagnostics());
  if (auto v = u.positive("angle_sigma_max_arcsec", true)) s.until_sigma_arcsec = *v;
  u.finish();
}

StepBody parse_home(MapReader& r) {
  HomeStep s;
  s.timeout_s = r.positive("timeout_s");
  return s;
}

StepBody parse_move(MapReader& r) {
  MoveStep s;
  s.pitch_arcsec = r.angle_arcsec("pitch");
  s.yaw_arcsec = r.angle_arcsec("yaw");
  s.rate_arcsec_s = r.rate_arcsec_s("rate");
  const bool any = r.has("pitch_deg") || r.has("pitch_arcsec") || r.has("yaw_deg") || r.has("yaw_arcsec");
  if (!any && r.ok()) {
    r.diagnostics().error(r.mark(), fmt::format("{}: missing field pitch_deg/pitch_arcsec or yaw_deg/yaw_arcsec "
                                                "(a move needs at least one target)",
                                                r.where()));
  }
  return s;
}

StepBody parse_settle(MapReader& r) {
  SettleStep s;
  if (auto v = r.positive("duration_s", true)) s.duration_s = *v;
  return s;
}

StepBody parse_sample(MapReader& r) {
  SampleStep s;
  if (auto f = read_frames(r, true)) s.frames = *f;
  if (auto p = r.choice("phase", {"null", "offset"})) s.phase = parse_phase(*p);
  if (auto v = r.non_negative("settle_s")) s.settle_s = *v;
  return s;
}

// GCC 12 at -O3 reports the grid's optional extent and step, and the step's fields, as "may be used
// uninitialized" here depending on how the unity batch inlines (every path sets them first): a false
// alarm that -Werror would turn into a failed build, silenced for this function only.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
StepBody parse_grid(MapReader& r) {
  GridStep s;
  Diagnostics& d = r.diagnostics();
  read_listed_offsets(r, s);
  read_until(r, s);
  if (s.listed()) {
    if (auto v = r.non_negative("settle_s")) s.settle_s = *v;
    if (auto f = read_frames(r, true)) s.frames = *f;
    return s;
  }
  YAML::Node axes = r.node("axes");
  if (axes.IsDefined()) {
    const std::string what = fmt::format("{}: field axes", r.where());
    if (!axes.IsSequence() || axes.size() == 0) {
      d.error(axes, fmt::format("{}: expected a list such as [pitch, yaw], got {}", what, describe_node(axes)));
    } else {
      s.axes.clear();
      for (const auto& a : axes) {
        auto ax = parse_axis(a, what, d);
        if (!ax) continue;
        for (auto seen : s.axes) {
          if (seen == *ax) d.error(a, fmt::format("{}: {} appears twice", what, to_string(*ax)));
        }
        s.axes.push_back(*ax);
      }
    }
  }
  auto extent = r.angle_arcsec("extent", true);
  auto step = r.angle_arcsec("step", true);
  if (extent && *extent <= 0) {
    d.error(r.mark(), fmt::format("{}: extent must be > 0", r.where()));
    extent.reset();
  }
  if (step && *step <= 0) {
    d.error(r.mark(), fmt::format("{}: step must be > 0", r.where()));
    step.reset();
  }
  // The gimbal resolves 1 mas (docs/icd.md): a finer step would repeat points.
  if (step && *step < 0.001) {
    d.error(r.node(r.has("step_deg") ? "step_deg" : "step_arcsec"),
            fmt::format("{}: step {} arcsec is finer than the gimbal's resolution of 0.001 arcsec", r.where(), *step));
    step.reset();
  }
  if (extent && step && *step > *extent * (1 + 1e-9)) {
    d.error(r.mark(), fmt::format("{}: step ({} arcsec) is larger than extent ({} arcsec): no offsets", r.where(),
                                  *step, *extent));
  }
  if (extent) s.extent_arcsec = *extent;
  if (step) s.step_arcsec = *step;
  if (auto v = r.non_negative("settle_s")) s.settle_s = *v;
  if (auto f = read_frames(r, true)) s.frames = *f;
  if (auto o = r.choice("order", {"outward", "ascending", "descending", "spread"})) {
    s.order = *o == "outward" ? GridStep::Order::outward
              : *o == "ascending" ? GridStep::Order::ascending
              : *o == "spread" ? GridStep::Order::spread : GridStep::Order::descending;
  }
  if (auto l = r.choice("layout", {"axes", "diagonals", "full"})) {
    s.layout = *l == "axes" ? GridStep::Layout::axes
               : *l == "diagonals" ? GridStep::Layout::diagonals : GridStep::Layout::full;
  }
  // The plan's size, counted before anything is built (docs/procedures.md, Limits).
  if (extent && step) {
    const double n = std::floor(*extent / *step + 1e-9);  // offsets per direction
    const double per_axis = 2 * n, axes_n = static_cast<double>(s.axes.size());
    const double points = s.layout == GridStep::Layout::full        ? (2 * n + 1) * (2 * n + 1) - 1
                          : s.layout == GridStep::Layout::diagonals ? axes_n * per_axis + 2 * per_axis
                                                                    : axes_n * per_axis;
    if (!(2 * points + 1 <= kMaxPlanPoints)) {
      d.error(r.mark(), fmt::format("{}: extent {} arcsec in steps of {} arcsec gives {:.4g} points; a plan may have at "
                                    "most {} (docs/procedures.md, Limits)",
                                    r.where(), *extent, *step, 2 * points + 1, kMaxPlanPoints));
    }
  }
  if (s.layout != GridStep::Layout::axes && s.axes.size() != 2 && axes.IsDefined()) {
    d.error(axes, fmt::format("{}: layout {} needs both axes", r.where(),
                              s.layout == GridStep::Layout::full ? "full" : "diagonals"));
  }
  return s;
}
#pragma GCC diagnostic pop

StepBody parse_slew(MapReader& r) {
  SlewStep s;
  Diagnostics& d = r.diagnostics();
  YAML::Node axis = r.node("axis");
  if (!axis.IsDefined()) {
    if (r.ok()) d.error(r.mark(), fmt::format("{}: missing field axis", r.where()));
  } else if (auto a = parse_axis(axis, fmt::format("{}: field axis", r.where()), d)) {
    s.axis = *a;
  }
  if (auto a = r.angle_arcsec("amplitude", true)) {
    if (*a <= 0) d.error(r.mark(), fmt::format("{}: amplitude must be > 0", r.where()));
    s.amplitude_arcsec = *a;
  }
  // One rate (rate_arcsec_s) or several (rates_arcsec_s: [..]); deg/s spellings too.
  const bool one = r.has("rate_arcsec_s") || r.has("rate_deg_s");
  const bool many = r.has("rates_arcsec_s") || r.has("rates_deg_s");
  if (one && many) {
    d.error(r.mark(), fmt::format("{}: give rate_* or rates_*, not both", r.where()));
  }
  if (auto v = r.rate_arcsec_s("rate")) s.rates_arcsec_s.push_back(*v);
  auto rate_ok = [](double v) { return v > 0; };
  for (double v : read_number_list(r, {{"rates_arcsec_s", 1.0}, {"rates_deg_s", 3600.0}}, "rates", +rate_ok,
                                   "a rate must be > 0")) {
    s.rates_arcsec_s.push_back(v);
  }
  if (!one && !many && r.ok()) {
    d.error(r.mark(), fmt::format("{}: missing field rate_arcsec_s or rates_arcsec_s (or _deg_s)", r.where()));
  }
  if (auto v = r.choice("directions", {"both", "positive", "negative"})) {
    s.directions = *v == "both" ? SlewStep::Directions::both
                   : *v == "positive" ? SlewStep::Directions::positive : SlewStep::Directions::negative;
  }
  if (auto v = r.positive("sample_period_s", true)) s.sample_period_s = *v;
  if (auto v = r.non_negative("settle_s")) s.settle_s = *v;
  if (auto v = r.integer("reversals", false, 0, kMaxSlewReversals)) s.reversals = static_cast<int>(*v);
  return s;
}

// A coefficient file named in a step, relative to the procedure file, read now (before anything
// moves); nullopt with an error at the field when it cannot be read.
std::optional<std::filesystem::path> coefficient_file(MapReader& r, const std::string& key, const std::string& origin,
                                                      bool required) {
  auto p = r.string(key, required);
  if (!p) return std::nullopt;
  std::filesystem::path f(*p);
  if (f.is_relative()) f = std::filesystem::path(origin).parent_path() / f;
  try {
    load_coefficients(f);
    return f;
  } catch (const InputError& e) {
    r.diagnostics().error(r.node(key), fmt::format("{}: field {}: {}", r.where(), key, e.what()));
  }
  return std::nullopt;
}

StepBody parse_diagnose(MapReader& r, const std::string& origin) {
  DiagnoseStep s;
  const bool listed = r.has("models");
  if (auto f = coefficient_file(r, "model", origin, !listed)) s.model = *f;
  if (listed) {
    const YAML::Node m = r.node("models");
    if (!m.IsMap() || m.size() == 0 || m.size() > 64) {
      r.diagnostics().error(m, fmt::format("{}: field models: expected a map of 1 to 64 units, SERIAL: FILE", r.where()));
    } else {
      MapReader units(m, r.where() + ".models", r.diagnostics());
      for (auto it = m.begin(); it != m.end(); ++it) {
        const std::string serial = it->first.as<std::string>();
        if (auto f = coefficient_file(units, serial, origin, true)) s.models[serial] = *f;
      }
      units.finish();
    }
  }
  if (auto v = r.boolean("partial")) s.partial = *v;
  if (auto v = r.non_negative("settle_s")) s.settle_s = *v;
  return s;
}

StepBody parse_calibrate(MapReader& r, const std::string& origin) {
  CalibrateStep s;
  if (auto m = r.choice("method", {"differences", "absolute"})) s.method = *m;
  s.init = coefficient_file(r, "init", origin, false);
  if (auto v = r.integer("max_iterations", false, 1, 100000)) s.max_iterations = static_cast<int>(*v);
  if (auto v = r.integer("refine_nodes", false, 1, 1000)) s.refine_nodes = static_cast<int>(*v);
  if (auto v = r.integer("threads", false, 0, 256)) s.threads = static_cast<int>(*v);
  return s;
}

void read_limits(MapReader& r, ResidualLimits& l) {
  if (auto v = r.positive("mean_abs_arcsec")) l.mean_abs_arcsec = v;
  if (auto v = r.positive("sd_arcsec")) l.sd_arcsec = v;
  if (auto v = r.positive("max_abs_arcsec")) l.max_abs_arcsec = v;
  if (auto v = r.integer("min_points", false, 1)) l.min_points = v;
}

StepBody parse_check(MapReader& r) {
  CheckStep s;
  ResidualLimits both;
  read_limits(r, both);  // top-level limits apply to both axes
  s.pitch = s.yaw = both;
  for (auto [key, lim] : {std::pair{"pitch", &s.pitch}, std::pair{"yaw", &s.yaw}}) {
    YAML::Node n = r.node(key);
    if (!n.IsDefined()) continue;
    MapReader a(n, fmt::format("{}.{}", r.where(), key), r.diagnostics());
    read_limits(a, *lim);
    a.finish();
  }
  if (!s.pitch.any() && !s.yaw.any() && r.ok()) {
    r.diagnostics().error(r.mark(), fmt::format("{}: no limits given (mean_abs_arcsec, sd_arcsec, max_abs_arcsec, "
                                                "min_points; at top level or under pitch/yaw)",
                                                r.where()));
  }
  return s;
}

}  // namespace

Procedure parse_procedure(std::string_view text, const std::string& origin, Diagnostics& d) {
  Procedure p;
  p.origin = origin;
  p.text = std::string(text);
  p.name = std::filesystem::path(origin).stem().string();
  YAML::Node root = parse_yaml_map(text, d, "procedure: expected a map with name, description and steps");
  if (!d.empty()) return p;
  MapReader top(root, "procedure", d);
  if (auto n = top.string("name")) p.name = *n;
  if (auto s = top.string("description")) p.description = *s;
  YAML::Node steps = top.node("steps");
  top.finish();
  if (!steps.IsDefined()) {
    d.error(root, "procedure: missing field steps (a list of steps)");
    return p;
  }
  if (!steps.IsSequence() || steps.size() == 0) {
    d.error(steps, fmt::format("procedure: steps: expected a non-empty list of steps, got {}", describe_node(steps)));
    return p;
  }
  std::string known;
  for (auto t : step_types()) known += (known.empty() ? "" : ", ") + std::string(t);
  bool calibrated = false;
  size_t index = 0;
  for (const auto& item : steps) {
    ++index;
    std::string type;
    YAML::Node fields;
    if (item.IsScalar()) {
      type = item.Scalar();  // a step with no fields: "- home"
    } else if (item.IsMap() && item.size() == 1) {
      type = item.begin()->first.Scalar();
      fields = item.begin()->second;
    } else {
      d.error(item, fmt::format("step {}: expected one step (\"- type: {{fields}}\", one of {}), got {}", index,
                                known, item.IsMap() ? fmt::format("a map with {} keys", item.size())
                                                    : describe_node(item)));
      continue;
    }
    const size_t errors_before = d.size();
    const std::string where = fmt::format("step {} ({})", index, type);
    const TextMark mark = TextMark::of(item.IsMap() ? item.begin()->first : item);
    MapReader r(fields, where, d);
    Step st{type, index, mark, HomeStep{}};
    if (type == "home") st.body = parse_home(r);
    else if (type == "move") st.body = parse_move(r);
    else if (type == "settle") st.body = parse_settle(r);
    else if (type == "sample") st.body = parse_sample(r);
    else if (type == "null_offset_grid") st.body = parse_grid(r);
    else if (type == "continuous_slew") st.body = parse_slew(r);
    else if (type == "calibrate") { st.body = parse_calibrate(r, origin); calibrated = true; }
    else if (type == "diagnose") st.body = parse_diagnose(r, origin);
    else if (type == "check") {
      st.body = parse_check(r);
      if (!calibrated) d.error(mark, fmt::format("{}: a check needs a calibrate step before it", where));
    } else {
      d.error(mark, fmt::format("step {}: unknown step \"{}\" (known: {})", index, type, known));
      continue;
    }
    r.finish();
    st.valid = d.size() == errors_before;
    p.steps.push_back(std::move(st));
  }
  return p;
}

Procedure load_procedure(const std::filesystem::path& path) {
  return load_yaml_file(path, "procedure file", parse_procedure);
}

}  // namespace fpss
