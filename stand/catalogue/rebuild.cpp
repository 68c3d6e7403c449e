#include "stand/catalogue/rebuild.h"

#include <fmt/format.h>

#include <algorithm>
#include <set>
#include <system_error>

#include "base/json_file.h"
#include "procedures/recorder.h"
#include "stand/catalogue/run_file.h"

namespace fpss {

namespace fs = std::filesystem;

namespace {

RunStart run_start_of(const RunFile& run, const fs::path& dir) {
  RunStart rs;
  // run.json's run_id (a UUIDv7); runs made before it was one used the folder's name.
  rs.run_id = run.id_or(dir);
  rs.unit = run.unit;
  rs.procedure = run.procedure.name;
  rs.procedure_hash = run.procedure.sha256;
  rs.started_utc = run.started_utc;
  rs.run_dir = fs::absolute(dir);
  rs.emulated = run.emulated;
  if (run.stand && run.stand->settings.is_object()) rs.stand = run.stand->settings.value("stand", "");
  if (run.software) rs.software_version = run.software->version;
  rs.operator_name = run.operator_name.value_or("");
  return rs;
}

// calibration.json, calibration-2.json, ... in the order they were made.
std::vector<fs::path> calibration_files(const fs::path& dir) {
  std::vector<std::pair<int, fs::path>> found;
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string n = e.path().filename().string();
    if (n == "calibration.json") found.emplace_back(1, e.path());
    else if (n.rfind("calibration-", 0) == 0 && n.size() > 17 && n.substr(n.size() - 5) == ".json") {
      try {
        found.emplace_back(std::stoi(n.substr(12, n.size() - 17)), e.path());
      } catch (const std::exception&) {
      }
    }
  }
  std::sort(found.begin(), found.end());
  std::vector<fs::path> out;
  for (auto& f : found) out.push_back(f.second);
  return out;
}

}  // namespace

void index_run_folder(Catalogue& cat, const fs::path& dir, RebuildReport& r) {
  const RunFile run = read_run_file(dir);
  const RunStart rs = run_start_of(run, dir);
  const std::string ended_utc = run.ended_utc.value_or("");
  const std::optional<RunOutcome> outcome = RunRecord::outcome_of(run.outcome, (dir / "run.json").string() + ": outcome");
  const auto known = cat.find_run(rs.run_id);
  if (!known) {
    cat.record_run_start(rs);
    ++r.runs_added;
    if (outcome) cat.record_run_end(rs.run_id, *outcome, ended_utc);
  } else if (known->outcome != outcome && outcome) {
    cat.record_run_end(rs.run_id, *outcome, ended_utc);
    ++r.runs_updated;
  }
  // A run indexed before the catalogue kept operators (or before its prompt named one) takes run.json's.
  if (known && !rs.operator_name.empty() && known->operator_name != rs.operator_name &&
      cat.record_run_operator(rs.run_id, rs.operator_name) > 0) {
    ++r.operators_named;
  }
  std::set<std::string> have;
  for (const auto& c : cat.run_calibrations(rs.run_id)) have.insert(c.coefficients.dump());
  // One unit: the run folder's files; several: each unit's folder, under its serial.
  std::vector<std::pair<std::string, fs::path>> folders;
  if (run.units) {
    for (const RunFileUnit& u : *run.units) {
      if (u.samples) folders.emplace_back(u.serial, (dir / *u.samples).parent_path());
    }
  } else {
    folders.emplace_back(rs.unit, dir);
  }
  for (const auto& [unit, folder] : folders) {
    if (!fs::is_directory(folder)) continue;
    for (const auto& f : calibration_files(folder)) {
      CalibrationRecord cr = CalibrationRecord::from_calibration_json(read_json_file(f, "calibration file"), f.string());
      if (have.count(cr.coefficients.dump())) continue;
      cr.unit = unit;
      cr.source = "run";
      cr.run_id = rs.run_id;
      cr.source_ref = rs.run_id;
      cr.date_utc = cr.coefficients.value("calibrated_at", run.ended_utc.value_or(rs.started_utc));
      cr.stand = rs.stand;
      cr.operator_name = rs.operator_name;
      cat.record_calibration(cr);
      have.insert(cr.coefficients.dump());
      ++r.calibrations_added;
    }
    if (!fs::exists(folder / "acceptance.json")) continue;
    bool indexed = false;
    for (const auto& a : cat.unit_acceptances(unit)) indexed |= a.run_id == rs.run_id;
    if (indexed) continue;
    const nlohmann::json cert = read_json_file(folder / "acceptance.json", "acceptance file");
    AcceptanceRecord rec;
    rec.unit = cert.value("unit", unit);
    rec.run_id = rs.run_id;
    rec.passed = cert.value("passed", false);
    rec.date_utc = cert.value("date_utc", ended_utc);
    rec.certificate = cert;
    rec.stand = rs.stand;
    rec.operator_name = !rs.operator_name.empty() ? rs.operator_name : cert.value("operator", "");
    cat.record_acceptance(rec);
    ++r.acceptances_added;
  }
}

RebuildReport rebuild_catalogue(Catalogue& cat, const fs::path& runs_dir) {
  RebuildReport r;
  std::vector<fs::path> dirs;
  for (const auto& e : fs::directory_iterator(runs_dir)) {
    if (e.is_directory() && !e.is_symlink() && fs::exists(e.path() / "run.json")) dirs.push_back(e.path());
  }
  std::sort(dirs.begin(), dirs.end());  // folder names start with the UTC start time
  for (const auto& d : dirs) {
    ++r.folders;
    try {
      index_run_folder(cat, d, r);
      std::error_code ec;
      fs::remove(d / kCataloguePending, ec);
    } catch (const std::exception& e) {
      r.skipped.push_back(fmt::format("{}: {}", d.string(), e.what()));
    }
  }
  return r;
}

}  // namespace fpss
