// A procedure's plan on an in-process bench (stand/investigate/plan_session.h).
#include "stand/investigate/plan_session.h"

#include "base/errors.h"
#include "procedures/yaml_diag.h"

namespace fpss {

namespace {

SessionOp op_at(SessionOp::Kind kind, double pitch_arcsec, double yaw_arcsec) {
  SessionOp op;
  op.kind = kind;
  op.pitch_arcsec = pitch_arcsec;
  op.yaw_arcsec = yaw_arcsec;
  return op;
}

}  // namespace

std::vector<SessionOp> session_ops(const Plan& plan, const EngineSettings& settings) {
  std::vector<SessionOp> ops;
  for (const Action& a : plan.actions) {
    SessionOp op;
    switch (a.kind) {
      case Action::Kind::home:
        ops.push_back(op_at(SessionOp::Kind::move, 0, 0));
        break;
      case Action::Kind::move:
        op = op_at(SessionOp::Kind::move, a.pitch_arcsec, a.yaw_arcsec);
        op.rate_arcsec_s = a.rate_arcsec_s;
        ops.push_back(op);
        break;
      case Action::Kind::settle:
        op.kind = SessionOp::Kind::settle;
        op.settle_s = a.settle_s;
        ops.push_back(op);
        break;
      case Action::Kind::dwell:
        op = op_at(SessionOp::Kind::dwell, a.pitch_arcsec, a.yaw_arcsec);
        op.settle_s = a.settle_s;
        op.frames = a.frames;
        op.sample_rate_hz = settings.sample_rate_hz;
        op.phase = a.phase;
        ops.push_back(op);
        break;
      case Action::Kind::slew: {
        ops.push_back(op_at(SessionOp::Kind::move, a.start_pitch_arcsec, a.start_yaw_arcsec));
        if (a.settle_s > 0) {
          SessionOp wait;
          wait.kind = SessionOp::Kind::settle;
          wait.settle_s = a.settle_s;
          ops.push_back(wait);
        }
        for (int k = 0; k <= a.reversals; ++k) {
          const auto [p, y] = a.leg_target(k);
          SessionOp leg = op_at(SessionOp::Kind::slew, p, y);
          leg.rate_arcsec_s = a.rate_arcsec_s;
          leg.sample_period_s = a.sample_period_s;
          leg.same_step = k > 0;
          ops.push_back(leg);
        }
        break;
      }
      case Action::Kind::calibrate:
      case Action::Kind::check:
      case Action::Kind::diagnose:
        break;  // off the bench
    }
  }
  return ops;
}

SampleTable simulate_plan(const Plan& plan, const EngineSettings& settings, const BenchConfig& bench, double start_s,
                          const std::string& origin) {
  BenchConfig cfg = bench;
  cfg.sample_rate_hz = settings.sample_rate_hz;
  Bench b(cfg);
  b.advance_to(start_s);
  SampleTable t = record_ops(b, session_ops(plan, settings));
  t.origin = origin;
  return t;
}

SampleTable simulate_procedure(const Procedure& procedure, const EngineSettings& settings, const BenchConfig& bench,
                               double start_s) {
  Diagnostics d(procedure.origin);
  const Plan plan = expand(procedure, settings, d);
  d.throw_if_any();
  return simulate_plan(plan, settings, bench, start_s, procedure.origin);
}

}  // namespace fpss
