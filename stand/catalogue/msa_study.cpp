#include "stand/catalogue/msa_study.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "base/errors.h"
#include "calib/residuals.h"
#include "calib/transfer_function.h"
#include "calib/units.h"

namespace fpss {

namespace {

// One measurement of every quantity it has, from one record.
struct Observation {
  std::string unit, stand, operator_name, date;
  std::map<std::string, double> values;
};

std::string stand_name(const std::string& s) { return s.empty() ? kNoStandName : s; }
std::string shown_operator(const std::string& s) { return s.empty() ? kNoOperatorName : s; }

constexpr double kSetPointsDeg[] = {-0.4, -0.2, 0.0, 0.2, 0.4};

std::string set_point_name(const char* axis, double deg) { return fmt::format("angle_{}_at_{:+.1f}deg_arcsec", axis, deg); }

void add_number(Observation& o, const std::string& name, const nlohmann::json& v) {
  if (v.is_number() && std::isfinite(v.get<double>())) o.values[name] = v.get<double>();
}

Observation from_calibration(const CalibrationRecord& c) {
  Observation o{c.unit, stand_name(c.stand), shown_operator(c.operator_name), c.date_utc, {}};
  const nlohmann::json& j = c.coefficients;
  for (const auto& [axis, key] : {std::pair{"pitch", "alpha"}, std::pair{"yaw", "beta"}}) {
    if (j.contains("residuals") && j["residuals"].contains(axis)) {
      add_number(o, fmt::format("residual_mean_{}_arcsec", axis), j["residuals"][axis].value("mean_abs_arcsec", nlohmann::json()));
    }
    if (!j.contains(key) || !j[key].is_array() || j[key].size() != 8) continue;
    AxisCoeffs cf{};
    bool ok = true;
    for (size_t i = 0; i < 8; ++i) {
      ok = ok && j[key][i].is_number();
      if (ok) cf[i] = j[key][i].get<double>();
    }
    if (!ok) continue;
    for (double deg : kSetPointsDeg) {
      const double counts = deg * kArcsecPerDeg / (fit::kNominalC2 * kArcsecPerRad);
      const double a = rad_to_arcsec(transfer_angle(cf.data(), counts));
      if (std::isfinite(a)) o.values[set_point_name(axis, deg)] = a;
    }
  }
  return o;
}

Observation from_acceptance(const AcceptanceRecord& a) {
  Observation o{a.unit, stand_name(a.stand), shown_operator(a.operator_name), a.date_utc, {}};
  if (!a.certificate.contains("criteria") || !a.certificate["criteria"].is_array()) return o;
  for (const auto& k : a.certificate["criteria"]) {
    for (const char* axis : {"pitch", "yaw"}) {
      if (k.value("id", std::string()) == fmt::format("accuracy_3sigma_{}", axis)) {
        add_number(o, fmt::format("accuracy_3sigma_{}_arcsec", axis), k.value("measured", nlohmann::json()));
      }
    }
  }
  return o;
}

bool selected(const std::vector<std::string>& list, const std::string& v) {
  return list.empty() || std::find(list.begin(), list.end(), v) != list.end();
}

// How the cells are named: "on stand S" or "by operator O", and in a list "U on S" or "U by operator O".
std::string cell_name(MsaAppraisers by, const std::string& unit, const std::string& appraiser, bool in_list) {
  if (by == MsaAppraisers::operators) return fmt::format("{}{} by operator {}", in_list ? "" : "unit ", unit, appraiser);
  return fmt::format("{}{} on {}{}", in_list ? "" : "unit ", unit, in_list ? "" : "stand ", appraiser);
}

// The cells' observations, latest last; the study's units and appraisers.
struct Cells {
  MsaAppraisers by = MsaAppraisers::stands;
  std::vector<std::string> units, appraisers;
  std::map<std::pair<std::string, std::string>, std::vector<Observation>> cell;
};

Cells sort_into_cells(std::vector<Observation> obs, const MsaSelection& sel, size_t& left_out) {
  Cells c;
  c.by = sel.appraisers;
  std::set<std::string> units, appraisers;
  for (Observation& o : obs) {
    if (!selected(sel.units, o.unit) || !selected(sel.stands, o.stand) || !selected(sel.operators, o.operator_name) ||
        (!sel.since.empty() && o.date < sel.since)) {
      ++left_out;
      continue;
    }
    units.insert(o.unit);
    const std::string& appraiser = c.by == MsaAppraisers::operators ? o.operator_name : o.stand;
    appraisers.insert(appraiser);
    c.cell[{o.unit, appraiser}].push_back(std::move(o));
  }
  c.units.assign(units.begin(), units.end());
  c.appraisers.assign(appraisers.begin(), appraisers.end());
  for (auto& [k, v] : c.cell) {
    std::stable_sort(v.begin(), v.end(), [](const Observation& a, const Observation& b) { return a.date < b.date; });
  }
  return c;
}

// The study of one quantity over the latest `repeats` records of each cell that have it.
std::optional<GaugeStudy> study_of(const Cells& c, const std::string& q, size_t repeats, std::string& why) {
  GaugeStudy s;
  for (const std::string& u : c.units) {
    s.y.emplace_back();
    for (const std::string& st : c.appraisers) {
      std::vector<double> ys;
      const auto it = c.cell.find({u, st});
      if (it != c.cell.end()) {
        for (const Observation& o : it->second) {
          if (const auto v = o.values.find(q); v != o.values.end()) ys.push_back(v->second);
        }
      }
      if (ys.size() < repeats) {
        why = fmt::format("{}: {} record(s) with it, {} needed", cell_name(c.by, u, st, false), ys.size(), repeats);
        return std::nullopt;
      }
      s.y.back().emplace_back(ys.end() - static_cast<std::ptrdiff_t>(repeats), ys.end());
    }
  }
  return s;
}

}  // namespace

MsaStudy msa_study(const Catalogue& cat, const MsaSelection& sel, const MsaTolerances& tolerances) {
  for (const std::string& u : sel.units) {
    if (!cat.has_unit(u)) throw InputError(fmt::format("--units: unit {} is not in the catalogue", u));
  }
  std::vector<Observation> cal_obs, acc_obs;
  for (const std::string& u : cat.units()) {
    if (!selected(sel.units, u)) continue;
    for (const CalibrationRecord& r : cat.unit_history(u)) cal_obs.push_back(from_calibration(r));
    for (const AcceptanceRecord& r : cat.unit_acceptances(u)) acc_obs.push_back(from_acceptance(r));
  }
  MsaStudy out;
  out.appraised_by = sel.appraisers;
  const Cells cals = sort_into_cells(std::move(cal_obs), sel, out.records_left_out);
  const Cells accs = sort_into_cells(std::move(acc_obs), sel, out.records_left_out);
  out.units = cals.units;
  out.appraisers = cals.appraisers;
  const bool by_operators = sel.appraisers == MsaAppraisers::operators;
  const char* const who = by_operators ? "operator" : "stand";
  // Records of runs that named no operator, or indexed by a catalogue that kept none (before schema version 3).
  const bool unnamed = by_operators && std::count(out.appraisers.begin(), out.appraisers.end(), kNoOperatorName) > 0;
  const std::string hint = unnamed ? fmt::format(" ({}: records naming no operator; `fpss-stand catalogue rebuild` "
                                                 "names those of an older catalogue from their run.json)",
                                                 kNoOperatorName)
                                   : "";
  if (out.units.size() < 2 || out.appraisers.size() < 2) {
    throw InputError(fmt::format("msa: a crossed study needs at least two units and two {}s; the selection has "
                                 "{} unit(s) ({}) and {} {}(s) ({}){}",
                                 who, out.units.size(), fmt::join(out.units, ", "), out.appraisers.size(), who,
                                 fmt::join(out.appraisers, ", "), hint));
  }
  // Repeats: as many as every cell has (balanced, the latest of each), at least two.
  size_t repeats = SIZE_MAX;
  std::vector<std::string> thin;
  for (const std::string& u : out.units) {
    for (const std::string& st : out.appraisers) {
      const auto it = cals.cell.find({u, st});
      const size_t n = it == cals.cell.end() ? 0 : it->second.size();
      repeats = std::min(repeats, n);
      if (n < 2) thin.push_back(fmt::format("{} ({})", cell_name(sel.appraisers, u, st, true), n));
    }
  }
  if (!thin.empty()) {
    throw InputError(fmt::format("msa: every unit needs at least two calibrations {} every {} (repeatability is "
                                 "their scatter); short: {}{}",
                                 by_operators ? "by" : "on", who, fmt::join(thin, "; "), hint));
  }
  out.repeats = repeats;
  for (const auto& [k, v] : cals.cell) out.records_used += std::min(v.size(), repeats);
  // One quantity's study, or why not (`from` names where its records are when not calibrations).
  const auto add = [&](const Cells& c, const std::string& q, size_t r, const std::optional<MsaTolerance>& tol,
                       const std::string& from) {
    std::string why;
    const auto s = study_of(c, q, r, why);
    if (!s) {
      out.skipped[q] = from + why;
      return;
    }
    MsaQuantity m{q, "arcsec", tol, *s, {}};
    m.result = gauge_rr(m.study, tol ? std::optional<double>(tol->value) : std::nullopt);
    out.quantities.push_back(std::move(m));
  };
  for (const char* axis : {"pitch", "yaw"}) {
    add(cals, fmt::format("residual_mean_{}_arcsec", axis), repeats, tolerances.residual_mean, "");
    for (double deg : kSetPointsDeg) add(cals, set_point_name(axis, deg), repeats, tolerances.set_point_angle, "");
  }
  // Accuracy comes from acceptances: a study of its own cells, when they are crossed too.
  Cells crossed = accs;
  crossed.units = out.units;
  crossed.appraisers = out.appraisers;
  for (const char* axis : {"pitch", "yaw"}) {
    add(crossed, fmt::format("accuracy_3sigma_{}_arcsec", axis), 2, tolerances.accuracy, "acceptances: ");
  }
  return out;
}

std::string msa_verdict(const GaugeRr& r) {
  const double pct = r.grr_percent_tolerance.value_or(r.grr_percent_tv);
  const char* of = r.grr_percent_tolerance ? "of the tolerance" : "of the total variation";
  const char* word = pct < 10 ? "acceptable" : pct <= 30 ? "marginal" : "unacceptable";
  return fmt::format("{} (%GRR {:.1f} % {}; ndc {}{})", word, pct, of, r.ndc, r.ndc >= 5 ? "" : ", below 5");
}

const char* to_string(MsaAppraisers a) { return a == MsaAppraisers::operators ? "operators" : "stands"; }

nlohmann::ordered_json MsaStudy::to_json(const std::string& catalogue, const MsaSelection& sel) const {
  nlohmann::ordered_json j;
  j["format"] = "fpss-stand msa/1";
  j["method"] = "AIAG MSA 4th edition, ANOVA method (crossed, the interaction kept)";
  j["catalogue"] = catalogue;
  j["appraisers"] = to_string(appraised_by);
  j["selection"] = {{"units", sel.units}, {"stands", sel.stands}, {"operators", sel.operators},
                    {"since", sel.since.empty() ? nlohmann::json() : nlohmann::json(sel.since)}};
  j["units"] = units;
  j[to_string(appraised_by)] = appraisers;  // "stands" or "operators"
  j["repeats"] = repeats;
  j["records_used"] = records_used;
  j["records_left_out"] = records_left_out;
  nlohmann::ordered_json qs = nlohmann::ordered_json::object();
  for (const MsaQuantity& q : quantities) {
    nlohmann::ordered_json e;
    e["unit"] = q.unit;
    e["tolerance"] = q.tolerance ? nlohmann::ordered_json(q.tolerance->value) : nlohmann::ordered_json();
    e["tolerance_source"] = q.tolerance ? nlohmann::ordered_json(q.tolerance->source) : nlohmann::ordered_json();
    const nlohmann::ordered_json r = q.result.to_json();
    for (const auto& [k, v] : r.items()) e[k] = v;
    e["verdict"] = msa_verdict(q.result);
    e["values"] = q.study.y;  // [unit][appraiser][repeat], in the order of `units` and `stands` (or `operators`)
    qs[q.name] = std::move(e);
  }
  j["quantities"] = qs;
  j["skipped"] = skipped;
  return j;
}

}  // namespace fpss
