// The arithmetic of designing a follow-up run: how well a planned run would separate rival effects
// (T-optimality) and how far it would bound the effects a recording could not see.
#pragma once
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "calib/coefficients.h"
#include "calib/diagnosis/diagnosis.h"

namespace fpss {

// A fitted candidate from GAP.json's `effects[]` (name and numeric params); throws InputError for
// an unknown name. A refitted transfer function (coefficients) carries its C1..C8 per axis from
// params `alpha` and `beta`.
EffectParams effect_from_json(const nlohmann::ordered_json& effect);

// A candidate against the end state of an investigation (docs/diagnosis.md, "Investigation"):
// named (a cause); bounded (not seen, and its limit_arcsec at most the materiality); ambiguous (in
// a set of look-alikes); or unbounded (not observable, seen but not named, or its limit above).
struct CandidateStatus {
  std::string name;
  std::string status;  // named | bounded | ambiguous | unbounded
  std::string why;
  double limit_arcsec = std::numeric_limits<double>::infinity();
};
std::vector<CandidateStatus> candidate_status(const Diagnosis& d, double materiality_arcsec);

// A planned run as the diagnosis would see it (noise-free columns from a simulated bench), with
// the diagnosis's split and features. Predictions use the candidates' forward models.
class PlannedRun {
 public:
  // `noise_arcsec`: the noise floor of one frame, as the first recording measured it.
  PlannedRun(DiagnosisColumns planned, const CoefficientSet& model, const DiagnosisOptions& opts, double noise_arcsec);
  ~PlannedRun();
  PlannedRun(PlannedRun&&) noexcept;

  // The expected log-likelihood ratio in favour of `truth` against `rival` on the plan's held-out
  // rows (what the joint diagnosis scores): the rival is fitted on the plan's fit rows to what the
  // truth predicts there (noise-free), and what it cannot follow, over 2 sigma^2, is the expected
  // log-likelihood ratio (T-optimality, Atkinson and Fedorov 1975). Conservative: the rival may
  // take parameters here that the first recording would refuse.
  double expected_log_lr(const EffectParams& truth, const std::string& rival) const;
  // Against several rivals at once (a pair of causes), fitted together.
  double expected_log_lr(const EffectParams& truth, const std::vector<std::string>& rivals) const;
  // The smaller of the two directions: whichever of the two is true, how strongly the plan tells.
  double separation(const EffectParams& a, const EffectParams& b) const;
  // The candidate's limit_arcsec (EffectResult) when this plan's held-out rows join
  // `other_heldout_rows` held-out rows of earlier recordings that say nothing of the effect.
  double limit_arcsec(const std::string& effect, size_t other_heldout_rows) const;
  // The sixths of the calibrated range the plan's rows reach on each axis (pitch, yaw).
  RangeSections range_sections() const;
  size_t rows() const;
  size_t heldout_rows() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace fpss
