#include "stand/session/run_record.h"

namespace fpss {

void end_session_record(RunFileSession& s, const std::string& end_utc, const EngineResult& er, const EngineStats& st,
                        const Plan& plan, const Sensor* sensor) {
  s.ended_utc = end_utc;
  s.outcome = to_string(er.outcome);
  if (!er.reason.empty()) s.reason = er.reason;
  s.points_completed = er.points_done;
  s.engine = nlohmann::json{{"wall_s", st.wall_s},         {"device_s", st.device_s},       {"sleep_s", st.sleep_s},
                            {"storage_s", st.storage_s},   {"calibrate_s", st.calibrate_s}, {"own_s", st.own_s()},
                            {"points", st.points},         {"remeasured", st.remeasured},   {"recoveries", st.recoveries},
                            {"bench_s", st.bench_s},       {"physical_s", plan.physical_s},
                            {"estimated_s", plan.estimated_s}, {"scheduled_moves", st.scheduled_moves}};
  if (sensor) {
    const SensorStats ss = sensor->stats();
    s.sensor_stats = nlohmann::json{{"frames", ss.frames},           {"crc_errors", ss.crc_errors},
                                    {"garbage_bytes", ss.garbage_bytes}, {"seq_gaps", ss.seq_gaps},
                                    {"frames_lost", ss.frames_lost}};
  }
}

}  // namespace fpss
