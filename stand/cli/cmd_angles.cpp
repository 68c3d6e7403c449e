// fpss-stand angles: the two transfer functions of a coefficient file at given counts.
#include <fmt/format.h>

#include <cmath>
#include <cstdio>
#include <utility>

#include <nlohmann/json.hpp>

#include "base/errors.h"
#include "calib/coefficients.h"
#include "calib/units.h"
#include "stand/cli/commands.h"
#include "stand/cli/file_hints.h"
#include "stand/cli/help.h"

namespace fpss::cli {

void add_angles(CLI::App& app, Runner& run) {
  struct Opts { std::string model; double alpha = 0, beta = 0; };
  auto o = std::make_shared<Opts>();
  auto* sub = app.add_subcommand("angles", "Pitch (alpha) and yaw (beta) angles, arcsec, at given counts");
  expect_file(sub, sub->add_option("--model", o->model, "coefficient file (JSON)")->required(), o->model,
              FileKind::coefficients);
  sub->add_option("--alpha", o->alpha, "counts_alpha")->required();
  sub->add_option("--beta", o->beta, "counts_beta")->required();
  examples(sub, {"fpss-stand angles --model calib/data/published/a-6-fpss1.json --alpha 1200 --beta -800",
                 "fpss-stand angles --model RUN_DIR/calibration.json --alpha 0 --beta 0"});
  sub->callback([o, &run] {
    run = [o] {
      // CLI11 reads "nan" and "inf" as numbers, and its Range check lets NaN through.
      for (const auto& [name, v] : {std::pair{"--alpha", o->alpha}, std::pair{"--beta", o->beta}}) {
        if (!std::isfinite(v) || v < kCountsMin || v > kCountsMax) {
          throw InputError(fmt::format("{} {}: expected counts, a finite number in [{}, {}]", name, v, kCountsMin,
                                       kCountsMax));
        }
      }
      const CoefficientSet set = load_coefficients(o->model);
      nlohmann::ordered_json j;
      j["alpha_arcsec"] = set.alpha_model().angle_arcsec(o->alpha);
      j["beta_arcsec"] = set.beta_model().angle_arcsec(o->beta);
      std::printf("%s\n", j.dump().c_str());
      return 0;
    };
  });
}

}  // namespace fpss::cli
