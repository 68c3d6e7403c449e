// The fleet's measurement-system analysis: crossed studies (units x stands, or operators, x repeats)
// taken from the catalogue, per quantity.
#pragma once
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "calib/msa.h"
#include "stand/catalogue/catalogue.h"

namespace fpss {

// What is crossed with the units: the stands (each record's stand) or the operators (each record's
// run's operator, on whichever stand).
enum class MsaAppraisers { stands, operators };

// The appraisers' name in messages and files: "stands" or "operators".
const char* to_string(MsaAppraisers a);

// The records a study takes: those of the selected units, stands and operators (whichever are the
// appraisers), from `since` on.
struct MsaSelection {
  std::vector<std::string> units;   // empty: every unit with records
  std::vector<std::string> stands;  // empty: every stand with records (an empty stand is named "emulated")
  std::string since;                // ISO 8601 date or time; records before it are left out ("": all)
  std::vector<std::string> operators;  // empty: every operator (a record naming none is "unnamed")
  MsaAppraisers appraisers = MsaAppraisers::stands;
};

// What a study calls a record's stand and operator when the record names none.
inline constexpr const char* kNoStandName = "emulated";
inline constexpr const char* kNoOperatorName = "unnamed";

// A quantity's tolerance (the width the acceptance limits allow: a one-sided limit with a natural
// zero is its value, a two-sided one twice it) and where it comes from.
struct MsaTolerance {
  double value = 0;
  std::string source;
};

// The tolerance of each kind of quantity (none: %GRR of the tolerance is left out).
struct MsaTolerances {
  std::optional<MsaTolerance> residual_mean;    // residual_mean_<axis>_arcsec
  std::optional<MsaTolerance> set_point_angle;  // angle_<axis>_at_<deg>deg_arcsec
  std::optional<MsaTolerance> accuracy;         // accuracy_3sigma_<axis>_arcsec
};

// One quantity's study: y[unit][appraiser][repeat], the latest `repeats` records of each cell.
struct MsaQuantity {
  std::string name, unit;  // "residual_mean_pitch_arcsec", "arcsec"
  std::optional<MsaTolerance> tolerance;
  GaugeStudy study;  // the values studied (MSA.json `values`), for a check by other tools
  GaugeRr result;
};

struct MsaStudy {
  MsaAppraisers appraised_by = MsaAppraisers::stands;
  std::vector<std::string> units, appraisers;  // appraisers: the stands or the operators, as appraised_by says
  size_t repeats = 0, records_used = 0, records_left_out = 0;
  std::vector<MsaQuantity> quantities;
  std::map<std::string, std::string> skipped;  // quantity -> why it could not be studied
  nlohmann::ordered_json to_json(const std::string& catalogue, const MsaSelection& sel) const;
};

// The quantities read of each calibration record (calibration.json): residual_mean_<axis>_arcsec,
// angle_<axis>_at_<-0.4|-0.2|+0.0|+0.2|+0.4>deg_arcsec (the calibrated angle at the counts the
// nominal scale factor puts there; +0.0: at zero counts, the whole transfer function, not C1,
// which trades with the sinusoids' phases); of each acceptance record:
// accuracy_3sigma_<axis>_arcsec. InputError (exit 2) when the selection cannot make a crossed study:
// fewer than two units or appraisers, a unit x appraiser cell without two records (naming the cells).
MsaStudy msa_study(const Catalogue& cat, const MsaSelection& sel, const MsaTolerances& tolerances);

// AIAG's reading of %GRR (of the tolerance, else of the total variation): under 10 % acceptable,
// 10 to 30 % marginal, above unacceptable; and ndc of at least 5.
std::string msa_verdict(const GaugeRr& r);

}  // namespace fpss
