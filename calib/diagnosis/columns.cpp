// The diagnosis's columns: from a sample table or a samples.csv, and several recordings joined
// into one on a shared bench clock where they have one (docs/diagnosis.md, "Several recordings,
// one diagnosis").
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "base/errors.h"
#include "calib/diagnosis/model.h"
#include "calib/samples.h"

namespace fpss {

namespace {

// gimbal_time_s - time_s at the first row from `from` with both finite (NaN when none has).
double bench_clock_of(const SampleTable& t, size_t from) {
  const std::vector<double> g = t.numeric_column("gimbal_time_s");
  for (size_t i = from; i < t.size(); ++i) {
    if (std::isfinite(g[i]) && std::isfinite(t.time_s[i])) return g[i] - t.time_s[i];
  }
  return std::numeric_limits<double>::quiet_NaN();
}

// The shift of each recording onto the first one's bench clock, or empty when they cannot share
// it: a recording without the gimbal's clock, or a gimbal clock that went back (restarted).
std::vector<double> bench_clock_shifts(const std::vector<DiagnosisColumns>& parts) {
  std::vector<double> shift;
  double last_end = -std::numeric_limits<double>::infinity();
  for (const auto& c : parts) {
    if (!std::isfinite(c.bench_clock_s) || c.time_s.empty()) return {};
    const double start = c.bench_clock_s + c.time_s.front(), end = c.bench_clock_s + c.time_s.back();
    if (start < last_end) return {};
    last_end = end;
    shift.push_back(c.bench_clock_s - parts.front().bench_clock_s);
  }
  return shift;
}

}  // namespace

const char* to_string(JointClock c) {
  switch (c) {
    case JointClock::bench: return "bench";
    case JointClock::recorded: return "recorded";
    case JointClock::own: return "own";
  }
  return "own";
}

DiagnosisColumns DiagnosisColumns::of(const SampleTable& t) {
  // The optional columns are filled below, where the table has them.
  DiagnosisColumns c{t.origin, t.time_s, t.ref_pitch_arcsec, t.ref_yaw_arcsec, t.counts_alpha, t.counts_beta,
                     t.step, /*temperature_c=*/{}, /*time_since_move_s=*/{}, /*approach_pitch=*/{},
                     /*approach_yaw=*/{}, /*parts=*/{}};
  if (t.has_column("gimbal_time_s")) c.bench_clock_s = bench_clock_of(t, 0);
  for (auto [name, out] : {std::pair{"temperature_c", &c.temperature_c}, {"time_since_move_s", &c.time_since_move_s},
                           {"approach_pitch", &c.approach_pitch}, {"approach_yaw", &c.approach_yaw}}) {
    if (!t.has_column(name)) continue;
    const std::vector<double> v = t.numeric_column(name);
    out->assign(v.begin(), v.end());
  }
  return c;
}

DiagnosisColumns join_recordings(std::vector<DiagnosisColumns> parts) {
  if (parts.empty()) throw InputError("a joint diagnosis needs at least one recording");
  if (parts.size() > kMaxJointRecordings) {
    throw InputError(fmt::format("a joint diagnosis takes at most {} recordings ({} given)", kMaxJointRecordings,
                                 parts.size()));
  }
  if (parts.size() == 1) return std::move(parts.front());
  const bool since = std::all_of(parts.begin(), parts.end(), [](const DiagnosisColumns& c) {
    return !c.time_since_move_s.empty();
  });
  const bool approach = std::all_of(parts.begin(), parts.end(), [](const DiagnosisColumns& c) {
    return !c.approach_pitch.empty() && !c.approach_yaw.empty();
  });
  const bool temp = std::any_of(parts.begin(), parts.end(), [](const DiagnosisColumns& c) {
    return !c.temperature_c.empty();
  });
  const std::vector<double> shift = bench_clock_shifts(parts);
  // Without the gimbal's clock: do the times as recorded already go on from one recording to the next?
  bool on_one = true;
  for (size_t k = 1; k < parts.size(); ++k) {
    on_one = on_one && !parts[k].time_s.empty() && !parts[k - 1].time_s.empty() &&
             parts[k].time_s.front() >= parts[k - 1].time_s.back();
  }
  DiagnosisColumns j;
  j.bench_clock_s = parts.front().bench_clock_s;
  std::vector<std::string> names;
  for (size_t k = 0; k < parts.size(); ++k) {
    DiagnosisColumns& c = parts[k];
    const size_t n = c.size();
    for (int64_t s : c.step) {
      if (s < 0 || s >= kJointStepStride) {
        throw InputError(fmt::format("{}: step {} outside 0..{}: a joint diagnosis keeps each recording's steps apart "
                                     "by {} per recording",
                                     c.origin, s, kJointStepStride - 1, kJointStepStride));
      }
    }
    auto append = [](auto& to, auto& from) { to.insert(to.end(), from.begin(), from.end()); diag::release(from); };
    if (!shift.empty()) for (double& t : c.time_s) t += shift[k];
    append(j.time_s, c.time_s);
    append(j.ref_pitch_arcsec, c.ref_pitch_arcsec);
    append(j.ref_yaw_arcsec, c.ref_yaw_arcsec);
    append(j.counts_alpha, c.counts_alpha);
    append(j.counts_beta, c.counts_beta);
    for (int64_t s : c.step) j.step.push_back(s + static_cast<int64_t>(k) * kJointStepStride);
    diag::release(c.step);
    if (temp) {
      if (c.temperature_c.empty()) j.temperature_c.insert(j.temperature_c.end(), n, std::numeric_limits<float>::quiet_NaN());
      else append(j.temperature_c, c.temperature_c);
    }
    if (since) append(j.time_since_move_s, c.time_since_move_s);
    if (approach) {
      append(j.approach_pitch, c.approach_pitch);
      append(j.approach_yaw, c.approach_yaw);
    }
    const JointClock clock = !shift.empty() ? JointClock::bench : on_one ? JointClock::recorded : JointClock::own;
    j.parts.push_back({c.origin, n,
                       clock == JointClock::bench      ? shift[k]
                       : clock == JointClock::recorded ? 0.0
                                                       : std::numeric_limits<double>::quiet_NaN(),
                       clock});
    names.push_back(c.origin);
  }
  j.origin = fmt::format("{}", fmt::join(names, " + "));
  return j;
}

DiagnosisColumns read_diagnosis_columns(const std::filesystem::path& path, int64_t last_step) {
  DiagnosisColumns c;
  c.origin = path.string();
  bool first = true, done = false;
  for_each_sample_chunk(
      path,
      [&](const SampleTable& t, size_t from, double fraction_read) {
        if (done) return;
        const bool temp = t.has_column("temperature_c"), since = t.has_column("time_since_move_s");
        const bool side = t.has_column("approach_pitch") && t.has_column("approach_yaw");
        if (!std::isfinite(c.bench_clock_s) && t.has_column("gimbal_time_s")) c.bench_clock_s = bench_clock_of(t, from);
        if (first && t.size() > from) {
          // Reserve once from the first chunk's share of the file (plus a margin), so that growing
          // the columns never holds two copies of them.
          first = false;
          const size_t est = static_cast<size_t>(static_cast<double>(t.size() - from) / fraction_read * 1.02) + 64;
          for (auto* v : {&c.time_s, &c.ref_pitch_arcsec, &c.ref_yaw_arcsec, &c.counts_alpha, &c.counts_beta}) {
            v->reserve(est);
          }
          c.step.reserve(est);
          if (temp) c.temperature_c.reserve(est);
          if (since) c.time_since_move_s.reserve(est);
          if (side) { c.approach_pitch.reserve(est); c.approach_yaw.reserve(est); }
        }
        std::vector<double> tc, sc;
        if (temp) tc = t.numeric_column("temperature_c");
        if (since) sc = t.numeric_column("time_since_move_s");
        std::vector<double> ap, ay;
        if (side) { ap = t.numeric_column("approach_pitch"); ay = t.numeric_column("approach_yaw"); }
        for (size_t i = from; i < t.size(); ++i) {
          if (t.step[i] > last_step) { done = true; return; }
          c.time_s.push_back(t.time_s[i]);
          c.ref_pitch_arcsec.push_back(t.ref_pitch_arcsec[i]);
          c.ref_yaw_arcsec.push_back(t.ref_yaw_arcsec[i]);
          c.counts_alpha.push_back(t.counts_alpha[i]);
          c.counts_beta.push_back(t.counts_beta[i]);
          c.step.push_back(t.step[i]);
          if (temp) c.temperature_c.push_back(static_cast<float>(tc[i]));
          if (since) c.time_since_move_s.push_back(static_cast<float>(sc[i]));
          if (side) {
            c.approach_pitch.push_back(static_cast<float>(ap[i]));
            c.approach_yaw.push_back(static_cast<float>(ay[i]));
          }
        }
      },
      1024);
  return c;
}

}  // namespace fpss
