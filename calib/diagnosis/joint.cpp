#include "calib/diagnosis/joint.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>

namespace fpss {

// A refitted transfer function contains a scale factor (its linear term): a unit whose diagnosis
// names a change of its coefficients may show the gimbal's scale factor only inside that change.
bool absorbed_by_coefficients(const std::string& name) { return name == "scale_factor"; }

bool is_gimbal_effect(const std::string& name) {
  return name == "backlash" || name == "scale_factor" || name == "axis_nonorthogonality" || name == "settling";
}

namespace {

// The units' mean of each numeric parameter, and the largest departure from it.
nlohmann::ordered_json mean_params(const std::vector<const EffectResult*>& found, double& spread_share) {
  nlohmann::ordered_json mean = nlohmann::ordered_json::object();
  spread_share = 0;
  for (const auto& [key, value] : found.front()->params.items()) {
    if (!value.is_number()) continue;
    double sum = 0;
    size_t n = 0;
    for (const EffectResult* e : found) {
      if (e->params.contains(key) && e->params[key].is_number()) {
        sum += e->params[key].get<double>();
        ++n;
      }
    }
    const double m = n ? sum / static_cast<double>(n) : 0.0;
    mean[key] = m;
    for (const EffectResult* e : found) {
      if (e->params.contains(key) && e->params[key].is_number() && std::abs(m) > 0) {
        spread_share = std::max(spread_share, std::abs(e->params[key].get<double>() - m) / std::abs(m));
      }
    }
  }
  return mean;
}

}  // namespace

JointDiagnosis attribute_effects(const std::vector<std::pair<std::string, Diagnosis>>& units) {
  JointDiagnosis j;
  std::vector<std::string> names;  // every cause named, in first-seen order
  for (const auto& [serial, d] : units) {
    for (const EffectResult& c : d.causes) {
      if (std::find(names.begin(), names.end(), c.name) == names.end()) names.push_back(c.name);
    }
  }
  std::map<std::string, bool> common;
  for (const std::string& name : names) {
    std::vector<const EffectResult*> found;
    std::vector<std::string> serials, absorbed;
    for (const auto& [serial, d] : units) {
      const EffectResult* named = nullptr;
      bool refitted = false;
      for (const EffectResult& c : d.causes) {
        if (c.name == name && !named) named = &c;
        refitted = refitted || c.name == "coefficients";
      }
      if (named) {
        found.push_back(named);
        serials.push_back(serial);
      } else if (refitted && absorbed_by_coefficients(name)) {
        absorbed.push_back(serial);
      }
    }
    common[name] = units.size() >= 2 && !found.empty() && found.size() + absorbed.size() == units.size() &&
                   name != "coefficients";
    if (!common[name]) continue;
    StandEffect s;
    s.name = name;
    double spread = 0;
    s.params = mean_params(found, spread);
    s.units = serials;
    s.units.insert(s.units.end(), absorbed.begin(), absorbed.end());
    s.evidence = nlohmann::ordered_json::object();
    s.evidence["rule"] =
        absorbed.empty()
            ? fmt::format("named in the diagnosis of every unit ({} of {}): the stand's", found.size(), units.size())
            : fmt::format("named in {} of {} units; the others' refitted coefficients contain it: the stand's",
                          found.size(), units.size());
    if (!absorbed.empty()) {
      s.evidence["absorbed_by_coefficients"] = absorbed;
      s.evidence["note"] = "these units' change of coefficients holds the stand's effect too: its size is the other "
                           "units' alone";
    }
    s.evidence["largest_departure_from_mean"] = spread;
    nlohmann::ordered_json per = nlohmann::ordered_json::object();
    for (size_t k = 0; k < found.size(); ++k) {
      per[serials[k]] = {{"params", found[k]->params}, {"heldout_rms_arcsec", found[k]->heldout_rms_arcsec}};
    }
    s.evidence["units"] = per;
    if (spread > 0.5 && absorbed.empty()) {
      s.evidence["note"] = "the units disagree on its size by more than half: part of it may be each unit's own";
    }
    j.stand_effects.push_back(std::move(s));
  }
  for (const auto& [serial, d] : units) {
    std::vector<UnitEffect> own;
    for (const EffectResult& c : d.causes) {
      if (common[c.name]) continue;
      UnitEffect u{c.name, c.params, {}};
      if (is_gimbal_effect(c.name)) {
        u.note = "an effect of the gimbal that the other units do not show: look at this unit's mount";
      }
      own.push_back(std::move(u));
    }
    j.unit_effects.emplace_back(serial, std::move(own));
  }
  if (units.size() < 2) j.notes.push_back("one unit: nothing tells the stand's effects from the unit's");
  return j;
}

nlohmann::ordered_json JointDiagnosis::to_json() const {
  nlohmann::ordered_json j;
  j["format"] = "fpss-stand joint-diagnosis/1";
  nlohmann::ordered_json serials = nlohmann::ordered_json::array();
  for (const auto& [serial, _] : unit_effects) serials.push_back(serial);
  j["units"] = serials;
  j["stand_effects"] = nlohmann::ordered_json::array();
  for (const StandEffect& s : stand_effects) {
    j["stand_effects"].push_back({{"name", s.name}, {"params", s.params}, {"units", s.units}, {"evidence", s.evidence}});
  }
  j["unit_effects"] = nlohmann::ordered_json::object();
  for (const auto& [serial, effects] : unit_effects) {
    nlohmann::ordered_json list = nlohmann::ordered_json::array();
    for (const UnitEffect& u : effects) {
      nlohmann::ordered_json e{{"name", u.name}, {"params", u.params}};
      if (!u.note.empty()) e["note"] = u.note;
      list.push_back(e);
    }
    j["unit_effects"][serial] = list;
  }
  j["notes"] = notes;
  return j;
}

}  // namespace fpss
