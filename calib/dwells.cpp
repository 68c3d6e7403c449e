#include "calib/dwells.h"

#include <fmt/format.h>

#include <cmath>

#include "base/errors.h"

namespace fpss {

std::optional<Dwell> DwellBuilder::add(const Sample& s, OutlierAxes outlier, double temperature_c) {
  if (s.phase != Phase::null && s.phase != Phase::offset) return std::nullopt;
  std::optional<Dwell> done;
  if (open_ && s.step != step_) done = close();
  const double v[4] = {s.counts_alpha, s.counts_beta, s.ref_pitch_arcsec, s.ref_yaw_arcsec};
  if (!open_) {
    open_ = true;
    step_ = s.step;
    phase_ = s.phase;
    sums_ = Sums{};
    sums_.t0 = s.time_s;
  } else if (s.phase != phase_) {
    throw DataError(fmt::format(
        "{}: step {} holds both null and offset rows; each dwell must be one or the other "
        "(cannot tell which reference the sensor saw)",
        origin_.empty() ? "samples" : origin_, s.step));
  }
  sums_.t1 = s.time_s;
  if (std::isfinite(temperature_c)) {
    sums_.temp_sum += temperature_c;
    sums_.temp_n += 1;
  }
  if (outlier.any()) {
    ++sums_.skipped;
    sums_.skipped_axis[0] += outlier.alpha ? 1 : 0;
    sums_.skipped_axis[1] += outlier.beta ? 1 : 0;
    return done;
  }
  if (!sums_.origin_set) {
    for (int i = 0; i < 4; ++i) sums_.o[i] = v[i];
    sums_.origin_set = true;
  }
  sums_.n += 1;
  for (int i = 0; i < 2; ++i) sums_.whole[i] = sums_.whole[i] && v[i] == std::floor(v[i]);
  for (int i = 0; i < 4; ++i) {
    const double d = v[i] - sums_.o[i];
    sums_.s[i] += d;
    sums_.ss[i] += d * d;
  }
  const double t = s.time_s - sums_.t0;
  sums_.st += t;
  sums_.stt += t * t;
  for (int i = 0; i < 2; ++i) sums_.stv[i] += t * (v[i] - sums_.o[i]);
  add_reference(v + 2);
  return done;
}

void DwellBuilder::add_reference(const double* ref) {
  // A frame that shares the frame before's encoder reading (same_reading): the reading counts once
  // in the scatter, and its frames' weight in the mean as one reading.
  const bool same = sums_.readings > 0 && same_reading(ref[0], ref[1], sums_.last_ref[0], sums_.last_ref[1]);
  if (same) {
    sums_.run += 1;
    return;
  }
  sums_.run_ss += sums_.run * sums_.run;
  sums_.run = 1;
  sums_.readings += 1;
  for (int i = 0; i < 2; ++i) {
    const double d = ref[i] - sums_.o[2 + i];
    sums_.rs[i] += d;
    sums_.rss[i] += d * d;
    sums_.last_ref[i] = ref[i];
  }
}

double DwellBuilder::detrended_sd(int axis, double plain_sd) const {
  const double n = sums_.n;
  if (n < 3) return plain_sd;
  // Residual sum of squares of the least-squares line: Svv - Stv^2 / Stt, about the means.
  const double tm = sums_.st / n, vm = sums_.s[axis] / n;
  const double stt = sums_.stt - n * tm * tm;
  const double stv = sums_.stv[axis] - n * tm * vm;
  const double svv = sums_.ss[axis] - n * vm * vm;
  const double rss = stt > 0 ? svv - stv * stv / stt : svv;
  return std::sqrt(std::max(0.0, rss / (n - 2)));
}

std::optional<Dwell> DwellBuilder::flush() { return open_ ? close() : std::nullopt; }

std::optional<Dwell> DwellBuilder::close() {
  open_ = false;
  const double n = sums_.n;
  if (!(n > 0)) return std::nullopt;  // every frame an outlier: no dwell
  double mean[4], sd[4];
  for (int i = 0; i < 4; ++i) {
    const double m = sums_.s[i] / n;
    mean[i] = sums_.o[i] + m;
    sd[i] = n > 1 ? std::sqrt(std::max(0.0, (sums_.ss[i] - n * m * m) / (n - 1))) : 0.0;
  }
  Dwell d;
  d.step = step_;
  d.phase = phase_;
  d.samples = static_cast<size_t>(n);
  d.t_start_s = sums_.t0;
  d.t_end_s = sums_.t1;
  if (sums_.temp_n > 0) d.temperature_c = sums_.temp_sum / sums_.temp_n;
  d.counts_alpha = mean[0];
  d.counts_beta = mean[1];
  d.ref_pitch_arcsec = mean[2];
  d.ref_yaw_arcsec = mean[3];
  d.sd_counts_alpha = sd[0];
  d.sd_counts_beta = sd[1];
  const double k = sums_.readings, runs_ss = sums_.run_ss + sums_.run * sums_.run;
  for (int i = 0; i < 2; ++i) {
    const double m = sums_.rs[i] / k;
    sd[2 + i] = k > 1 ? std::sqrt(std::max(0.0, (sums_.rss[i] - k * m * m) / (k - 1))) : 0.0;
  }
  d.sd_ref_pitch_arcsec = sd[2];
  d.sd_ref_yaw_arcsec = sd[3];
  d.ref_readings = static_cast<size_t>(k);
  d.ref_readings_eff = n * n / runs_ss;
  d.whole_counts_alpha = sums_.whole[0];
  d.whole_counts_beta = sums_.whole[1];
  d.outliers = sums_.skipped;
  d.outliers_alpha = sums_.skipped_axis[0];
  d.outliers_beta = sums_.skipped_axis[1];
  d.sd_detrended_counts_alpha = detrended_sd(0, sd[0]);
  d.sd_detrended_counts_beta = detrended_sd(1, sd[1]);
  return d;
}

std::vector<DwellPair> DwellPairer::add(const Dwell& d) {
  const size_t index = count_++;
  std::vector<DwellPair> out;
  if (d.phase == Phase::null) {
    for (size_t off : waiting_offsets_) out.push_back({index, off, false});
    waiting_offsets_.clear();
    last_null_ = index;
  } else {
    if (last_null_) out.push_back({*last_null_, index, true});
    waiting_offsets_.push_back(index);
  }
  return out;
}

std::vector<Dwell> average_dwells(const SampleTable& t) {
  std::vector<Dwell> out;
  DwellBuilder b(t.origin);
  for (size_t i = 0; i < t.size(); ++i) {
    if (auto d = b.add(t.row(i))) out.push_back(*d);
  }
  if (auto d = b.flush()) out.push_back(*d);
  return out;
}

std::vector<Dwell> average_dwells(const SampleTable& t, const std::vector<OutlierAxes>& skip) {
  return average_dwells(t.frames(), skip);
}

std::vector<Dwell> average_dwells(const FrameColumns& f, const std::vector<OutlierAxes>& skip) {
  std::vector<Dwell> out;
  DwellBuilder b(f.origin);
  for (size_t i = 0; i < f.size(); ++i) {
    const double temp = f.temperature_c ? (*f.temperature_c)[i] : std::numeric_limits<double>::quiet_NaN();
    if (auto d = b.add(f.row(i), i < skip.size() ? skip[i] : OutlierAxes{}, temp)) out.push_back(*d);
  }
  if (auto d = b.flush()) out.push_back(*d);
  return out;
}

std::vector<DwellPair> pair_dwells(const std::vector<Dwell>& dwells) {
  std::vector<DwellPair> out;
  DwellPairer p;
  for (const auto& d : dwells) {
    auto got = p.add(d);
    out.insert(out.end(), got.begin(), got.end());
  }
  return out;
}

}  // namespace fpss
