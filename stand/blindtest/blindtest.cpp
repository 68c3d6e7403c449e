#include "stand/blindtest/blindtest.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <numeric>
#include <random>
#include <set>

#include "base/text_file.h"
#include "calib/units.h"

namespace fpss {

using ojson = nlohmann::ordered_json;

const std::vector<std::string>& blindtest_classes() {
  static const std::vector<std::string> k = [] {
    std::vector<std::string> v = diagnosis_effect_names();
    v.push_back("none");
    return v;
  }();
  return k;
}

SessionPlan blindtest_plan() {
  SessionPlan p;
  GridPlan g;
  g.extent_deg = 0.42;
  g.step_deg = 0.06;
  g.samples_per_dwell = 25;
  g.sample_rate_hz = 50.0;
  g.settle_s = 0.2;  // longer than any time skew drawn, short enough for settling to show
  p.grids.push_back(g);
  for (int axis : {0, 1}) {
    for (double rate : {300.0, 600.0}) {
      SlewPlan s;
      s.axis = axis;
      s.amplitude_arcsec = 1500.0;
      s.rate_arcsec_s = rate;
      s.sample_period_s = 0.02;
      p.slews.push_back(s);
    }
  }
  return p;
}

BenchConfig blindtest_bench(uint64_t seed) {
  BenchConfig c = default_bench_config();
  c.seed = seed;
  c.temperature.t0_c = 20.0;
  c.temperature.ramp_c_per_s = 0.02;
  c.temperature.amplitude_c = 1.5;
  c.temperature.period_s = 60.0;
  return c;
}

DiagnosisOptions blindtest_diagnosis_options() {
  DiagnosisOptions o;
  // The recorder polls in-position every 10 ms, then waits settle_s: a dwell's first row comes
  // settle_s + 5 ms (on average) after the arrival.
  o.settle_s = blindtest_plan().grids.front().settle_s + 0.005;
  return o;
}

namespace {

uint64_t mix(uint64_t a, uint64_t b) {
  uint64_t x = a * 0x9E3779B97F4A7C15ull + b + 0x632BE59BD9B4E019ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

struct Draw {
  std::mt19937_64 g;
  explicit Draw(uint64_t s) : g(s) {}
  double uniform(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(g); }
  double sign() { return std::bernoulli_distribution(0.5)(g) ? 1.0 : -1.0; }
  double signed_mag(double lo, double hi) { return sign() * uniform(lo, hi); }
};

Effect make(const std::string& name, std::map<std::string, double> p) {
  Effect e;
  e.name = name;
  e.params = std::move(p);
  return e;
}

// Relative error of x against truth t.
double rel(double x, double t) { return std::abs(x - t) / std::max(std::abs(t), 1e-12); }

double param(const ojson& j, const char* k) { return j.contains(k) ? j.at(k).get<double>() : 0.0; }

}  // namespace

// RMS over the counts the recording covers of (fitted - true) transfer function, relative to the
// RMS of (true - model): how much of the coefficient change the refit got wrong.
double coefficient_error(const AxisCoeffs& fitted, const AxisCoeffs& truth, const AxisCoeffs& model, double max_arcsec) {
  const AxisModel t(truth);
  const double lo = t.counts_for_angle(arcsec_to_rad(-max_arcsec)), hi = t.counts_for_angle(arcsec_to_rad(max_arcsec));
  double e2 = 0, d2 = 0;
  const int steps = 400;
  for (int i = 0; i <= steps; ++i) {
    const double n = lo + (hi - lo) * i / steps;
    const double e = rad_to_arcsec(transfer_angle(fitted.data(), n) - transfer_angle(truth.data(), n));
    const double d = rad_to_arcsec(transfer_angle(truth.data(), n) - transfer_angle(model.data(), n));
    e2 += e * e;
    d2 += d * d;
  }
  return std::sqrt(e2 / std::max(d2, 1e-30));
}

CoefficientSet with_sinusoids_changed(CoefficientSet s, const std::function<double()>& amplitude,
                                      const std::function<double()>& phase_rad) {
  for (AxisCoeffs* c : {&s.alpha, &s.beta}) {
    (*c)[2] *= 1 + amplitude();
    (*c)[4] += phase_rad();
    (*c)[5] *= 1 + amplitude();
    (*c)[7] += phase_rad();
  }
  return s;
}

std::vector<Effect> draw_effects(const std::string& cls, uint64_t seed, const BenchConfig& bench) {
  Draw d(seed);
  if (cls == "none") return {};
  if (cls == "bias") return {make(cls, {{"pitch_arcsec", d.signed_mag(1, 5)}, {"yaw_arcsec", d.signed_mag(1, 5)}})};
  if (cls == "drift") {
    return {make(cls, {{"pitch_arcsec_per_s", d.signed_mag(0.005, 0.05)}, {"yaw_arcsec_per_s", d.signed_mag(0.005, 0.05)}})};
  }
  if (cls == "scale_factor") return {make(cls, {{"pitch_ppm", d.signed_mag(200, 2000)}, {"yaw_ppm", d.signed_mag(200, 2000)}})};
  if (cls == "boresight_roll") return {make(cls, {{"roll_arcsec", d.signed_mag(60, 600)}})};
  if (cls == "axis_nonorthogonality") return {make(cls, {{"skew_arcsec", d.signed_mag(60, 600)}})};
  if (cls == "backlash") return {make(cls, {{"width_arcsec", d.uniform(1, 6)}})};
  if (cls == "settling") return {make(cls, {{"amplitude_arcsec", d.uniform(2, 8)}, {"tau_s", d.uniform(0.3, 2)}})};
  if (cls == "time_skew") return {make(cls, {{"skew_s", d.uniform(0.02, 0.12)}})};
  if (cls == "temperature") {
    return {make(cls, {{"pitch_arcsec_per_c", d.signed_mag(0.2, 2)}, {"yaw_arcsec_per_c", d.signed_mag(0.2, 2)}})};
  }
  if (cls == "coefficients") {
    Effect e;
    e.name = cls;
    for (int attempt = 0; attempt < 100; ++attempt) {
      CoefficientSet s = bench.truth;
      if (d.uniform(0, 1) < 0.3) {
        // Another published set of the same sensor (in-flight fits of other periods).
        const char* names[] = {"a-4-fpss1", "a-5-fpss1"};
        s = load_published(names[d.uniform(0, 1) < 0.5 ? 0 : 1]);
        s.extra["perturbation"] = "published";
      } else {
        // The model's set with its sinusoids changed by 5-25 % in amplitude and 0.05-0.3 rad in phase.
        s = with_sinusoids_changed(
            s, [&] { return d.signed_mag(0.05, 0.25); }, [&] { return d.signed_mag(0.05, 0.3); });
        s.extra["perturbation"] = "perturbed";
      }
      try {
        s.alpha_model().check_monotonic();
        s.beta_model().check_monotonic();
      } catch (const NotMonotonicError&) {
        continue;
      }
      e.coefficients = s;
      return {e};
    }
    throw std::runtime_error("blindtest: no monotonic coefficient perturbation found");
  }
  throw std::invalid_argument("blindtest: unknown class " + cls);
}

BlindCase run_blind_case(int index, const std::string& cls, const std::vector<Effect>& effects, uint64_t seed,
                         const std::string& save_dir) {
  BenchConfig cfg = blindtest_bench(seed);
  // The sim model: the coefficient file the bench used as truth, with the scatter it expects.
  CoefficientSet model = cfg.truth;
  model.extra["expected_scatter_arcsec"] = expected_scatter_arcsec(cfg);
  cfg.effects = effects;
  Bench bench(cfg);
  SampleTable rec = record_session(bench, blindtest_plan());
  rec.origin = fmt::format("blindtest case {}", index);

  // Only the recording, the model and the procedure's timing go in.
  const Diagnosis dg = diagnose(rec, model, blindtest_diagnosis_options());

  BlindCase c;
  c.index = index;
  c.truth = cls;
  c.rows = rec.size();
  c.cause = dg.cause;
  for (const auto& e : dg.causes) c.causes.push_back(e.name);
  if (effects.size() <= 1) {
    c.correct = dg.cause == cls;
  } else {
    std::set<std::string> want, got;
    for (const auto& e : effects) want.insert(e.name);
    for (const auto& e : dg.causes) got.insert(e.name);
    c.correct = want == got;
  }
  c.gap_before_arcsec = dg.gap_before_arcsec;
  c.gap_after_arcsec = dg.gap_after_arcsec;
  c.gap_after_all_arcsec = dg.gap_after_all_arcsec;
  c.noise_floor_arcsec = dg.noise_floor_arcsec;
  if (!dg.where.empty()) c.where = dg.where.front().factor + "/" + dg.where.front().axis;
  auto truth_of = [](const Effect& t) {
    ojson j = ojson::object();
    if (t.name == "coefficients") {
      j = {{"alpha", t.coefficients->alpha}, {"beta", t.coefficients->beta},
           {"source", t.coefficients->extra.value("perturbation", "")}};
    } else {
      for (const auto& [k, v] : t.params) j[k] = v;
    }
    return j;
  };
  if (effects.size() == 1) c.truth_params = truth_of(effects.front());
  for (size_t k = 0; effects.size() > 1 && k < effects.size(); ++k) c.truth_params[effects[k].name] = truth_of(effects[k]);
  if (dg.causes.size() == 1) c.fitted_params = dg.causes.front().params;
  for (size_t k = 0; dg.causes.size() > 1 && k < dg.causes.size(); ++k) c.fitted_params[dg.causes[k].name] = dg.causes[k].params;
  if (!save_dir.empty()) {
    namespace fs = std::filesystem;
    fs::create_directories(save_dir);
    const fs::path dir = save_dir;
    write_samples_csv(dir / fmt::format("case-{}.csv", index), rec);
    save_coefficients(dir / "model.json", model);
    write_text_atomic(dir / fmt::format("case-{}-gap.json", index), dg.to_json().dump(1) + "\n");
    ojson truth{{"class", cls}, {"effects", ojson::array()}, {"settle_s", blindtest_diagnosis_options().settle_s}};
    for (const auto& e : effects) {
      ojson p = ojson::object();
      for (const auto& [k, v] : e.params) p[k] = v;
      if (e.coefficients) p = {{"alpha", e.coefficients->alpha}, {"beta", e.coefficients->beta}};
      truth["effects"].push_back({{"name", e.name}, {"params", p}});
    }
    write_text_atomic(dir / fmt::format("case-{}-truth.json", index), truth.dump(1) + "\n");
  }
  if (c.correct && !effects.empty()) {
    double worst = 0;
    for (const Effect& t : effects) {
      const ojson* fp = nullptr;
      for (const auto& e : dg.causes) if (e.name == t.name) fp = &e.params;
      const ojson& f = *fp;  // correct: every truth effect is among the causes
      const std::string pre = effects.size() > 1 ? t.name + "." : "";
      if (t.name == "coefficients") {
        const double ea = coefficient_error(f.at("alpha").get<AxisCoeffs>(), t.coefficients->alpha, model.alpha, 1500);
        const double eb = coefficient_error(f.at("beta").get<AxisCoeffs>(), t.coefficients->beta, model.beta, 1500);
        c.param_errors[pre + "alpha_transfer"] = ea;
        c.param_errors[pre + "beta_transfer"] = eb;
        worst = std::max({worst, ea, eb});
      } else {
        for (const auto& [k, v] : t.params) {
          const double e = rel(param(f, k.c_str()), v);
          c.param_errors[pre + k] = e;
          worst = std::max(worst, e);
        }
        if (t.name == "temperature") c.param_errors[pre + "t0_c_abs"] = std::abs(param(f, "t0_c") - cfg.temperature.t0_c);
      }
    }
    c.param_error = worst;
  } else {
    c.param_error = std::numeric_limits<double>::quiet_NaN();
  }
  return c;
}

namespace {

// Every unordered pair of different effects but the two a refitted transfer function contains.
std::vector<std::vector<std::string>> effect_pairs() {
  const auto& names = diagnosis_effect_names();
  std::vector<std::vector<std::string>> all;
  for (size_t a = 0; a < names.size(); ++a) {
    for (size_t b = a + 1; b < names.size(); ++b) {
      const bool contained = (names[a] == "coefficients" || names[b] == "coefficients") &&
                             (names[a] == "bias" || names[b] == "bias" || names[a] == "scale_factor" || names[b] == "scale_factor");
      if (!contained) all.push_back({names[a], names[b]});
    }
  }
  return all;
}

// A cycle through `items` in shuffled blocks: each block holds every item once, in an order drawn
// from the random seed, the salt and the block's number, so every item comes equally often.
class ShuffledBlocks {
 public:
  ShuffledBlocks(std::vector<std::vector<std::string>> items, uint64_t seed, uint64_t salt)
      : items_(std::move(items)), seed_(seed), salt_(salt) {}

  // The i-th item; called with i = 0, 1, 2, ... in turn.
  const std::vector<std::string>& next(int i) {
    const size_t k = static_cast<size_t>(i) % items_.size();
    if (k == 0) {
      block_ = items_;
      std::mt19937_64 g(mix(seed_, salt_ + static_cast<uint64_t>(i) / items_.size()));
      std::shuffle(block_.begin(), block_.end(), g);
    }
    return block_[k];
  }

 private:
  std::vector<std::vector<std::string>> items_, block_;
  uint64_t seed_, salt_;
};

}  // namespace

BlindTestReport run_blindtest(const BlindTestOptions& opts, const std::function<void(const BlindCase&)>& progress) {
  BlindTestReport rep;
  rep.pairs = opts.pairs;
  // What each case draws: one class, or (pairs) two different effects at once.
  std::vector<std::vector<std::string>> kinds;
  if (opts.pairs) {
    kinds = effect_pairs();
  } else {
    for (const auto& cls : blindtest_classes()) kinds.push_back({cls});
  }
  ShuffledBlocks draws(std::move(kinds), opts.seed, opts.pairs ? 0x9A1B : 0xB10C);
  for (int i = 0; i < opts.cases; ++i) {
    const std::vector<std::string>& names = draws.next(i);
    const uint64_t seed = mix(opts.seed, static_cast<uint64_t>(i) + 1);
    const BenchConfig cfg = blindtest_bench(seed);
    std::vector<Effect> effects;
    std::string label;
    for (size_t e = 0; e < names.size(); ++e) {
      const auto drawn = draw_effects(names[e], mix(seed, 0xEFFEC7 + e), cfg);
      effects.insert(effects.end(), drawn.begin(), drawn.end());
      label += (e == 0 ? "" : "+") + names[e];
    }
    rep.cases.push_back(run_blind_case(i, label, effects, seed, opts.save_dir));
    if (progress) progress(rep.cases.back());
  }
  return rep;
}

double BlindTestReport::accuracy() const {
  if (cases.empty()) return 0;
  return static_cast<double>(std::count_if(cases.begin(), cases.end(), [](const BlindCase& c) { return c.correct; })) /
         static_cast<double>(cases.size());
}

double BlindTestReport::accuracy(const std::string& cls) const {
  size_t n = 0, ok = 0;
  for (const auto& c : cases) if (c.truth == cls) { ++n; ok += c.correct; }
  return n ? static_cast<double>(ok) / static_cast<double>(n) : std::numeric_limits<double>::quiet_NaN();
}

double BlindTestReport::false_alarm_rate() const {
  size_t n = 0, bad = 0;
  for (const auto& c : cases) if (c.truth == "none") { ++n; bad += c.cause != "none"; }
  return n ? static_cast<double>(bad) / static_cast<double>(n) : std::numeric_limits<double>::quiet_NaN();
}

namespace {

struct Stats {
  size_t n = 0;
  double median = 0, p90 = 0, max = 0;
};

Stats stats(std::vector<double> v) {
  Stats s;
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return !std::isfinite(x); }), v.end());
  s.n = v.size();
  if (v.empty()) return s;
  std::sort(v.begin(), v.end());
  s.median = v[v.size() / 2];
  s.p90 = v[std::min(v.size() - 1, static_cast<size_t>(std::ceil(0.9 * v.size())) - 1)];
  s.max = v.back();
  return s;
}

ojson stats_json(const Stats& s) { return {{"n", s.n}, {"median", s.median}, {"p90", s.p90}, {"max", s.max}}; }

}  // namespace

namespace {

std::vector<std::string> split_pair(const std::string& cls) {
  const auto p = cls.find('+');
  if (p == std::string::npos) return {cls};
  return {cls.substr(0, p), cls.substr(p + 1)};
}

ojson case_json(const BlindCase& c) {
  return {{"index", c.index}, {"truth", c.truth}, {"cause", c.cause}, {"causes", c.causes}, {"correct", c.correct},
          {"truth_params", c.truth_params}, {"fitted_params", c.fitted_params}, {"param_errors", c.param_errors},
          {"param_error", std::isfinite(c.param_error) ? ojson(c.param_error) : ojson()},
          {"gap_before_arcsec", c.gap_before_arcsec}, {"gap_after_arcsec", c.gap_after_arcsec},
          {"gap_after_all_arcsec", c.gap_after_all_arcsec}, {"noise_floor_arcsec", c.noise_floor_arcsec},
          {"where", c.where}, {"rows", c.rows}};
}

}  // namespace

ojson BlindTestReport::to_json() const {
  const auto& classes = blindtest_classes();
  ojson j;
  if (pairs) {
    size_t both = 0, one = 0, within10 = 0, within_noise = 0;
    std::vector<double> pe, shrink;
    std::map<std::string, std::pair<int, int>> per;  // effect: present, found
    for (const auto& c : cases) {
      both += c.correct;
      size_t found = 0;
      for (const auto& e : split_pair(c.truth)) {
        const bool f = std::find(c.causes.begin(), c.causes.end(), e) != c.causes.end();
        found += f;
        per[e].first++;
        per[e].second += f;
      }
      one += found > 0;
      shrink.push_back(c.gap_after_all_arcsec / c.noise_floor_arcsec);
      within_noise += c.gap_after_all_arcsec <= 1.5 * c.noise_floor_arcsec;
      if (c.correct) { pe.push_back(c.param_error); within10 += c.param_error <= 0.10; }
    }
    const double n = std::max<double>(1, static_cast<double>(cases.size()));
    j["summary"] = {{"mode", "pairs"},
                    {"cases", cases.size()},
                    {"both_found", both / n},
                    {"at_least_one_found", one / n},
                    {"param_relative_error", stats_json(stats(pe))},
                    {"params_within_10_percent", within10},
                    {"both_found_cases", both},
                    {"shrink_gap_after_all_over_noise", stats_json(stats(shrink))},
                    {"gap_after_all_within_1_5_noise", within_noise}};
    ojson pj = ojson::object();
    for (const auto& [e, pf] : per) pj[e] = {{"present", pf.first}, {"found", pf.second}};
    j["per_effect"] = pj;
    ojson cs = ojson::array();
    for (const auto& c : cases) cs.push_back(case_json(c));
    j["cases"] = cs;
    return j;
  }
  ojson conf = ojson::object();
  for (const auto& t : classes) {
    ojson row = ojson::object();
    for (const auto& p : classes) {
      row[p] = std::count_if(cases.begin(), cases.end(), [&](const BlindCase& c) { return c.truth == t && c.cause == p; });
    }
    conf[t] = row;
  }
  ojson per = ojson::object();
  for (const auto& t : classes) {
    std::vector<double> pe, shrink;
    size_t n = 0, within10 = 0, within_noise = 0;
    for (const auto& c : cases) {
      if (c.truth != t) continue;
      ++n;
      shrink.push_back(c.gap_after_arcsec / c.noise_floor_arcsec);
      within_noise += c.gap_after_arcsec <= 1.5 * c.noise_floor_arcsec;
      if (c.correct && t != "none") {
        pe.push_back(c.param_error);
        within10 += c.param_error <= 0.10;
      }
    }
    std::map<std::string, int> wh;
    for (const auto& c : cases) if (c.truth == t) ++wh[c.where];
    std::string lead;
    int most = 0;
    for (const auto& [w, k] : wh) if (k > most) { most = k; lead = w; }
    ojson e{{"cases", n}, {"accuracy", n ? accuracy(t) : 0.0}, {"where_leading", lead}, {"where_leading_cases", most},
            {"shrink_gap_after_over_noise", stats_json(stats(shrink))},
            {"gap_after_within_1_5_noise", within_noise}};
    if (t != "none") e["param_relative_error"] = stats_json(stats(pe)), e["params_within_10_percent"] = within10;
    per[t] = e;
  }
  std::vector<double> pe_all, shrink_all;
  size_t within10 = 0, correct_effects = 0, within_noise = 0;
  for (const auto& c : cases) {
    shrink_all.push_back(c.gap_after_arcsec / c.noise_floor_arcsec);
    within_noise += c.gap_after_arcsec <= 1.5 * c.noise_floor_arcsec;
    if (c.correct && c.truth != "none") {
      ++correct_effects;
      pe_all.push_back(c.param_error);
      within10 += c.param_error <= 0.10;
    }
  }
  double min_acc = 1.0;
  for (const auto& t : classes) if (std::isfinite(accuracy(t))) min_acc = std::min(min_acc, accuracy(t));
  j["summary"] = {{"cases", cases.size()},
                  {"accuracy", accuracy()},
                  {"lowest_class_accuracy", min_acc},
                  {"false_alarm_rate_on_none", false_alarm_rate()},
                  {"param_relative_error", stats_json(stats(pe_all))},
                  {"params_within_10_percent", within10},
                  {"correct_effect_cases", correct_effects},
                  {"shrink_gap_after_over_noise", stats_json(stats(shrink_all))},
                  {"gap_after_within_1_5_noise", within_noise}};
  j["per_class"] = per;
  j["confusion"] = conf;
  ojson cs = ojson::array();
  for (const auto& c : cases) cs.push_back(case_json(c));
  j["cases"] = cs;
  return j;
}

std::string BlindTestReport::to_text() const {
  const auto& classes = blindtest_classes();
  if (pairs) {
    const ojson j = to_json();
    const ojson& m = j["summary"];
    std::string s = fmt::format("blind test, two effects per case: {} cases\n\n{:>22} {:>8} {:>6}\n", cases.size(),
                                "effect", "present", "found");
    for (auto it = j["per_effect"].begin(); it != j["per_effect"].end(); ++it) {
      s += fmt::format("{:>22} {:>8} {:>6}\n", it.key(), (*it)["present"].get<int>(), (*it)["found"].get<int>());
    }
    s += "\nmissed:\n";
    for (const auto& c : cases) {
      if (c.correct) continue;
      std::string got;
      for (const auto& e : c.causes) got += (got.empty() ? "" : ", ") + e;
      s += fmt::format("  case {:3d}  {:<40} -> {}\n", c.index, c.truth, got.empty() ? "none" : got);
    }
    s += fmt::format(
        "\nboth found {:.1f}%, at least one {:.1f}%; parameters within 10% of the truth: {}/{} (median error {:.2f}%, "
        "max {:.2f}%)\ngap_after_all within 1.5x noise floor: {}/{} (median {:.2f}, max {:.2f})\n",
        100 * m["both_found"].get<double>(), 100 * m["at_least_one_found"].get<double>(),
        m["params_within_10_percent"].get<size_t>(), m["both_found_cases"].get<size_t>(),
        100 * m["param_relative_error"]["median"].get<double>(), 100 * m["param_relative_error"]["max"].get<double>(),
        m["gap_after_all_within_1_5_noise"].get<size_t>(), cases.size(),
        m["shrink_gap_after_all_over_noise"]["median"].get<double>(), m["shrink_gap_after_all_over_noise"]["max"].get<double>());
    return s;
  }
  const std::map<std::string, std::string> abbr = {
      {"bias", "bias"},   {"drift", "drft"},    {"scale_factor", "scal"}, {"boresight_roll", "roll"},
      {"axis_nonorthogonality", "nort"}, {"backlash", "blsh"}, {"settling", "setl"}, {"time_skew", "skew"},
      {"coefficients", "coef"}, {"temperature", "temp"}, {"none", "none"}};
  const ojson j = to_json();
  std::string s = fmt::format("blind test: {} cases\n\nconfusion (rows: truth, columns: diagnosed)\n{:>22}", cases.size(), "");
  for (const auto& p : classes) s += fmt::format(" {:>4}", abbr.at(p));
  s += "\n";
  for (const auto& t : classes) {
    s += fmt::format("{:>22}", t);
    for (const auto& p : classes) {
      const int v = j["confusion"][t][p].get<int>();
      s += v ? fmt::format(" {:>4}", v) : std::string("    .");
    }
    s += "\n";
  }
  s += fmt::format("\n{:>22} {:>5} {:>8} {:>11} {:>11} {:>10} {:>10}  {}\n", "class", "cases", "top-1", "par.err.med",
                   "par.err.max", "shrink.med", "shrink.max", "where (leading factor, cases)");
  for (const auto& t : classes) {
    const ojson& e = j["per_class"][t];
    const bool has_pe = e.contains("param_relative_error") && e["param_relative_error"]["n"].get<size_t>() > 0;
    s += fmt::format("{:>22} {:>5} {:>7.1f}% {:>11} {:>11} {:>10.2f} {:>10.2f}  {} ({})\n", t, e["cases"].get<size_t>(),
                     100 * e["accuracy"].get<double>(),
                     has_pe ? fmt::format("{:.2f}%", 100 * e["param_relative_error"]["median"].get<double>()) : "-",
                     has_pe ? fmt::format("{:.2f}%", 100 * e["param_relative_error"]["max"].get<double>()) : "-",
                     e["shrink_gap_after_over_noise"]["median"].get<double>(),
                     e["shrink_gap_after_over_noise"]["max"].get<double>(), e["where_leading"].get<std::string>(),
                     e["where_leading_cases"].get<int>());
  }
  const ojson& m = j["summary"];
  s += fmt::format(
      "\ntop-1 attribution {:.1f}% overall, lowest class {:.1f}%; false alarms on none {:.1f}%\n"
      "parameters within 10% of the truth: {}/{} (median error {:.2f}%, max {:.2f}%)\n"
      "gap_after within 1.5x noise floor: {}/{} (gap_after / noise floor: median {:.2f}, max {:.2f})\n",
      100 * m["accuracy"].get<double>(), 100 * m["lowest_class_accuracy"].get<double>(),
      100 * (std::isfinite(false_alarm_rate()) ? false_alarm_rate() : 0.0), m["params_within_10_percent"].get<size_t>(),
      m["correct_effect_cases"].get<size_t>(), 100 * m["param_relative_error"]["median"].get<double>(),
      100 * m["param_relative_error"]["max"].get<double>(), m["gap_after_within_1_5_noise"].get<size_t>(), cases.size(),
      m["shrink_gap_after_over_noise"]["median"].get<double>(), m["shrink_gap_after_over_noise"]["max"].get<double>());
  return s;
}

}  // namespace fpss
