// GAP.json: the diagnosis as JSON (docs/diagnosis.md, "GAP.json"), every field in one place.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "base/text_file.h"
#include "calib/diagnosis/diagnosis.h"
#include "calib/diagnosis/internal.h"

namespace fpss {
namespace {

using ojson = nlohmann::ordered_json;
using diag::where_json;

ojson effect_json(const EffectResult& e) {
  ojson j{{"name", e.name}, {"params", e.params}, {"parameters", e.parameters}, {"fit_rms_arcsec", e.fit_rms_arcsec},
          {"heldout_rms_arcsec", e.heldout_rms_arcsec}, {"score", e.score}};
  if (!e.notes.empty()) j["notes"] = e.notes;
  if (!e.degenerate.empty()) {
    j["degenerate"] = true;
    j["degenerate_why"] = e.degenerate;
  }
  if (!e.detection_limit.empty()) j["detection_limit"] = e.detection_limit;
  if (!e.statistical_limit.empty()) {
    j["statistical_limit"] = e.statistical_limit;
    j["limit_arcsec"] = std::isfinite(e.limit_arcsec) ? ojson(e.limit_arcsec) : ojson();
  }
  return j;
}

}  // namespace

bool Diagnosis::incomplete_recording() const {
  return std::any_of(not_observable.begin(), not_observable.end(), [](const NotObservable& n) { return n.incomplete_recording; });
}

ojson Diagnosis::to_json() const {
  ojson j;
  j["source"] = source;
  j["verdict"] = verdict;
  j["verdict_sentence"] = verdict_sentence;
  j["cause"] = cause;
  ojson cs = ojson::array();
  for (const auto& c : causes) cs.push_back(effect_json(c));
  j["causes"] = cs;
  j["gap_before_arcsec"] = gap_before_arcsec;
  j["gap_after_arcsec"] = gap_after_arcsec;
  j["gap_after_all_arcsec"] = gap_after_all_arcsec;
  j["noise_floor_arcsec"] = noise_floor_arcsec;
  j["materiality_arcsec"] = materiality_arcsec;
  j["calibrated_range_arcsec"] = calibrated_range_arcsec;
  j["where"] = where_json(where);
  j["where_after"] = where_json(where_after);
  ojson ef = ojson::array();
  for (const auto& e : effects) ef.push_back(effect_json(e));
  j["effects"] = ef;
  j["selection"] = {
      {"score", "N ln(MSE / MSE_none) + k ln N on the held-out rows: N = 2 x held-out rows (both axes), MSE the "
                "held-out mean square of residual - effect, k the effect's free parameters; lower is better, none = 0"},
      {"cause", "the best score that also takes at least 0.1 x noise floor^2 off the held-out mean square; none "
                "when no candidate does"},
      {"second_effect", "when the cause leaves more than 1.2x the noise floor: around each of the three best single "
                        "effects by held-out score and the two best by fit-row residual, the others are screened on "
                        "what it leaves and the best three fitted jointly with it (alternating least squares); the best "
                        "pair is kept when its score beats the best single and it takes at least 0.1 x noise floor^2 "
                        "more off the held-out mean square; a refitted transfer function is never paired with a bias "
                        "or a scale factor (it contains both); causes[0] is the member that alone explains more, "
                        "causes[1] carries the joint figures"}};
  ojson no = ojson::array();
  for (const auto& n : not_observable) {
    no.push_back({{"name", n.name}, {"reason", n.reason}, {"incomplete_recording", n.incomplete_recording}});
  }
  j["not_observable"] = no;
  ojson amb = ojson::array();
  for (const auto& m : ambiguous_with) {
    amb.push_back({{"name", m.name}, {"score_difference", m.score_difference}, {"why", m.why}});
  }
  j["ambiguous_with"] = amb;
  ojson sets = ojson::array();
  for (const auto& a : ambiguous) {
    ojson diffs = ojson::object();
    for (size_t k = 0; k < a.members.size(); ++k) {
      diffs[a.members[k]] = std::isfinite(a.score_differences[k]) ? ojson(a.score_differences[k]) : ojson();
    }
    sets.push_back({{"members", a.members},
                    {"score_differences", diffs},
                    {"margin", kAmbiguityMargin},
                    {"separated_by", {{"factor", a.factor}, {"measurement", a.measurement}}},
                    {"why", a.why},
                    {"best_followup", a.best_followup}});
  }
  j["ambiguous"] = sets;
  j["ambiguity_rule"] = fmt::format(
      "a set holds the cause and every candidate whose held-out score lies within {:g} of the cause's (score = -2 ln "
      "likelihood up to constants: a likelihood ratio below e^{:g}), and the look-alikes the recording cannot score "
      "(null score difference); the verdict is unchanged",
      kAmbiguityMargin, kAmbiguityMargin / 2);
  ojson parts = ojson::array();
  for (const auto& p : recordings) {
    parts.push_back({{"source", p.source},
                     {"rows", p.rows},
                     {"step_offset", p.step_offset},
                     {"time_span_s", {p.time_span_s[0], p.time_span_s[1]}},
                     {"clock", to_string(p.clock)},
                     {"time_shift_s", std::isfinite(p.time_shift_s) ? ojson(p.time_shift_s) : ojson()},
                     {"noise_floor_arcsec", std::isfinite(p.noise_floor_arcsec) ? ojson(p.noise_floor_arcsec) : ojson()}});
  }
  j["recordings"] = parts;
  j["candidates"] = candidates;
  j["material_context"] = material_context;
  if (unexplained) {
    j["unexplained"] = {{"heldout_rms_arcsec", unexplained->heldout_rms_arcsec},
                        {"where", where_json(unexplained->where)},
                        {"flexible_shrink", unexplained->flexible_shrink}};
  }
  j["within_step_scatter_arcsec"] = std::isfinite(within_step_scatter_arcsec) ? ojson(within_step_scatter_arcsec) : ojson();
  if (std::isfinite(expected_scatter_arcsec)) {
    j["expected_scatter_arcsec"] = expected_scatter_arcsec;
    j["excess_scatter"] = std::isfinite(excess_scatter()) ? ojson(excess_scatter()) : ojson();
  }
  const auto share = [this](int64_t k) { return frames > 0 ? static_cast<double>(k) / static_cast<double>(frames) : 0.0; };
  j["outliers"] = {{"count", outliers}, {"fraction", outlier_fraction}, {"frames", frames},
                   {"pitch", {{"outlier_frames", outliers_pitch}, {"share", share(outliers_pitch)}}},
                   {"yaw", {{"outlier_frames", outliers_yaw}, {"share", share(outliers_yaw)}}},
                   {"step_ids", outlier_steps},
                   {"rule", "null and offset dwells: the recording's one reduction (calib/reduction.h, as in calibration.json: "
                            "more than 6 robust sigmas of the counts from their dwell's median); slews: more than 6 robust "
                            "sigmas from the median of the frame and up to 3 neighbours on each side in its step "
                            "(calib/outliers.h); either axis; kept out of every fit and score"},
                   {"dwells", dwell_outliers.to_json()}};
  j["split"] = split;
  j["recording"] = recording;
  j["warnings"] = warnings;
  return j;
}

void write_gap_file(const std::filesystem::path& path, const nlohmann::ordered_json& j) {
  write_text_atomic(path, j.dump(1) + "\n");
}

}  // namespace fpss
