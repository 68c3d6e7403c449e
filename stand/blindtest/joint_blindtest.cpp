#include "stand/blindtest/joint_blindtest.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <random>

#include "calib/diagnosis/joint.h"
#include "stand/blindtest/blindtest.h"

namespace fpss {

namespace {

const char* const kStand[] = {"backlash", "scale_factor", "axis_nonorthogonality", "settling", "time_skew"};
const char* const kUnit[] = {"bias", "boresight_roll", "coefficients"};

std::vector<std::string> names_of(const std::vector<UnitEffect>& e) {
  std::vector<std::string> n;
  for (const auto& x : e) n.push_back(x.name);
  return n;
}

}  // namespace

JointBlindReport run_joint_blindtest(int cases, uint64_t seed, const std::function<void(const JointBlindCase&)>& progress) {
  JointBlindReport rep;
  std::mt19937_64 g(seed);
  for (int i = 0; i < cases; ++i) {
    JointBlindCase c;
    c.index = i + 1;
    c.stand_effect = kStand[i % 5];
    c.unit_effect = kUnit[(i / 5) % 3];
    const size_t unit = std::uniform_int_distribution<size_t>(0, 1)(g);
    const uint64_t case_seed = g();
    BenchConfig cfg = blindtest_bench(case_seed);
    cfg.sensors = {SensorUnitConfig{"U1", load_published("a-6-fpss1"), {}, {}},
                   SensorUnitConfig{"U2", load_published("a-6-fpss2"), {}, {}}};
    c.unit_serial = cfg.sensors[unit].serial;
    cfg.effects = draw_effects(c.stand_effect, case_seed ^ 0x5354414E44ull, cfg);
    BenchConfig unit_bench = cfg;
    unit_bench.truth = cfg.sensors[unit].truth;  // a change of coefficients is drawn about this unit's own
    cfg.sensors[unit].effects = draw_effects(c.unit_effect, case_seed ^ 0x554E4954ull, unit_bench);
    Bench bench(cfg);
    std::vector<SampleTable> recs = record_units_session(bench, blindtest_plan());
    std::vector<std::pair<std::string, Diagnosis>> diagnosed;
    for (size_t u = 0; u < recs.size(); ++u) {
      CoefficientSet model = cfg.sensors[u].truth;
      BenchConfig alone = cfg;
      alone.truth = model;
      model.extra["expected_scatter_arcsec"] = expected_scatter_arcsec(alone);
      recs[u].origin = fmt::format("joint blindtest case {} unit {}", c.index, cfg.sensors[u].serial);
      diagnosed.emplace_back(cfg.sensors[u].serial, diagnose(recs[u], model, blindtest_diagnosis_options()));
    }
    const JointDiagnosis joint = attribute_effects(diagnosed);
    for (const auto& s : joint.stand_effects) c.found_stand.push_back(s.name);
    for (const auto& [serial, effects] : joint.unit_effects) c.found_units.push_back(names_of(effects));
    c.correct = c.found_stand == std::vector<std::string>{c.stand_effect};
    for (size_t u = 0; u < c.found_units.size(); ++u) {
      const std::vector<std::string> want = u == unit ? std::vector<std::string>{c.unit_effect} : std::vector<std::string>{};
      c.correct = c.correct && c.found_units[u] == want;
    }
    if (progress) progress(c);
    rep.cases.push_back(std::move(c));
  }
  return rep;
}

double JointBlindReport::accuracy() const {
  if (cases.empty()) return 0;
  size_t ok = 0;
  for (const auto& c : cases) ok += c.correct ? 1 : 0;
  return static_cast<double>(ok) / static_cast<double>(cases.size());
}

nlohmann::ordered_json JointBlindReport::to_json() const {
  nlohmann::ordered_json j;
  j["cases"] = cases.size();
  j["accuracy"] = accuracy();
  j["results"] = nlohmann::ordered_json::array();
  for (const auto& c : cases) {
    j["results"].push_back({{"case", c.index},
                            {"stand_effect", c.stand_effect},
                            {"unit_effect", c.unit_effect},
                            {"unit", c.unit_serial},
                            {"found_stand", c.found_stand},
                            {"found_units", c.found_units},
                            {"correct", c.correct}});
  }
  return j;
}

std::string JointBlindReport::to_text() const {
  std::string t = fmt::format("stand or unit: {} of {} cases attributed right ({:.1f} %)\n",
                              static_cast<size_t>(accuracy() * static_cast<double>(cases.size()) + 0.5), cases.size(),
                              100 * accuracy());
  for (const auto& c : cases) {
    if (c.correct) continue;
    std::vector<std::string> per_unit;
    for (const auto& u : c.found_units) per_unit.push_back(fmt::format("{}", fmt::join(u, ",")));
    t += fmt::format("  case {}: stand {} + {} on {} -> stand [{}], units [{}]\n", c.index, c.stand_effect, c.unit_effect,
                     c.unit_serial, fmt::join(c.found_stand, ","), fmt::join(per_unit, " | "));
  }
  return t;
}

}  // namespace fpss
