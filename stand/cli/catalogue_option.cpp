// The shared --catalogue URL option and the order in which the catalogue is chosen (docs/fleet.md).
#include "stand/cli/catalogue_option.h"

#include <cstdlib>

#include "stand/catalogue/catalogue.h"

namespace fpss::cli {

CLI::Option* add_catalogue_option(CLI::App* sub, std::string& url) {
  return sub->add_option("--catalogue,--db", url,
                         "catalogue: sqlite:PATH or a PATH (default RUNS_DIR/stand.db), or "
                         "postgresql://USER@HOST[:PORT]/DB?sslmode=require; also FPSS_CATALOGUE or the stand "
                         "file's catalogue:");
}

CLI::Option* add_catalogue_wait_option(CLI::App* sub, double& seconds) {
  return sub
      ->add_option("--catalogue-wait", seconds,
                   "seconds the end of a run waits for a catalogue server that was away (docs/fleet.md)")
      ->check(CLI::Range(0.0, 86400.0))
      ->capture_default_str();
}

std::string chosen_catalogue(const std::string& flag, const std::string& stand_value) {
  if (!flag.empty()) return flag;
  if (const char* env = std::getenv("FPSS_CATALOGUE"); env != nullptr && *env != '\0') return env;
  return stand_value;
}

std::string catalogue_url(const std::string& flag, const std::filesystem::path& runs_dir,
                          const std::string& stand_value) {
  const std::string chosen = chosen_catalogue(flag, stand_value);
  return chosen.empty() ? Catalogue::default_path(runs_dir).string() : chosen;
}

std::filesystem::path sqlite_file_of(const std::string& url) {
  if (is_postgres_url(url)) return {};
  if (url.rfind("sqlite:", 0) == 0) {
    std::string p = url.substr(7);
    if (p.rfind("//", 0) == 0) p = p.substr(2);
    return p;
  }
  return url;
}

}  // namespace fpss::cli
