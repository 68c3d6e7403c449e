#include "stand/report/plot.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

extern char** environ;

namespace fpss {
namespace {

namespace fs = std::filesystem;

// A private scratch folder for one gnuplot run, removed on scope exit.
class ScratchDir {
 public:
  ScratchDir() {
    std::string tmpl = (fs::temp_directory_path() / "fpss-plot-XXXXXX").string();
    if (!::mkdtemp(tmpl.data())) throw std::runtime_error(fmt::format("mkdtemp: {}", std::strerror(errno)));
    path_ = tmpl;
  }
  ~ScratchDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

std::string read_file(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string last_lines(const std::string& text, size_t n) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) {
    if (!l.empty()) lines.push_back(l);
  }
  std::string out;
  for (size_t i = lines.size() > n ? lines.size() - n : 0; i < lines.size(); ++i) {
    if (!out.empty()) out += " | ";
    out += lines[i];
  }
  return out;
}

}  // namespace

Gnuplot::Gnuplot(std::string program) : program_(std::move(program)) {
  if (program_.empty()) {
    const char* env = std::getenv("FPSS_GNUPLOT");
    program_ = env && *env ? env : "gnuplot";
  }
}

PlotResult Gnuplot::svg(const std::string& script, const std::string& id_prefix, int width_px,
                        int height_px) const {
  PlotResult r;
  ScratchDir dir;
  const auto script_path = dir.path() / "plot.gp";
  const auto out_path = dir.path() / "plot.svg";
  {
    std::ofstream f(script_path);
    // No `mouse`/`standalone` option: gnuplot then embeds no JavaScript and links nothing.
    f << fmt::format("set terminal svg size {},{} dynamic enhanced font 'sans,11' background rgb 'white'\n",
                     width_px, height_px);
    f << "set output\n" << script << "\n";
    if (!f) {
      r.error = fmt::format("cannot write the plot script in {}", dir.path().string());
      return r;
    }
  }

  const GnuplotRun run = run_file(script_path, out_path);
  if (!run.ok()) {
    r.error = run.error;
    r.program_missing = run.program_missing;
    return r;
  }
  const std::string svg = read_file(out_path);
  if (svg.find("<svg") == std::string::npos || svg.find("</svg>") == std::string::npos) {
    r.error = fmt::format("gnuplot (\"{}\") wrote no complete SVG", program_);
    return r;
  }
  r.svg = inline_svg(svg, id_prefix);
  return r;
}

GnuplotRun Gnuplot::run_file(const fs::path& script, const fs::path& stdout_to) const {
  ScratchDir dir;
  const auto err_path = dir.path() / "stderr.txt";
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&fa, STDOUT_FILENO, stdout_to.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
  posix_spawn_file_actions_addopen(&fa, STDERR_FILENO, err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
  std::string arg0 = program_, arg1 = script.string();
  char* argv[] = {arg0.data(), arg1.data(), nullptr};
  pid_t pid = 0;
  const int rc = ::posix_spawnp(&pid, program_.c_str(), &fa, nullptr, argv, environ);
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0) {
    return {fmt::format("cannot run gnuplot (\"{}\": {}); install gnuplot-nox or set FPSS_GNUPLOT", program_,
                        std::strerror(rc)),
            true};
  }
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (WIFEXITED(status) && WEXITSTATUS(status) == 0) return {};
  return {fmt::format("gnuplot (\"{}\") failed ({}): {}", program_,
                      WIFEXITED(status) ? fmt::format("exit {}", WEXITSTATUS(status))
                                        : fmt::format("signal {}", WTERMSIG(status)),
                      last_lines(read_file(err_path), 4)),
          WIFEXITED(status) && WEXITSTATUS(status) == 127};
}

std::string datablock(const std::string& name, const std::vector<std::vector<double>>& rows) {
  std::string out = fmt::format("${} << EOD\n", name);
  for (const auto& row : rows) {
    for (size_t i = 0; i < row.size(); ++i) {
      if (i) out += ' ';
      out += std::isfinite(row[i]) ? fmt::format("{:.10g}", row[i]) : std::string("NaN");
    }
    out += '\n';
  }
  out += "EOD\n";
  return out;
}

std::string gnuplot_quote(const std::string& text) {
  std::string out;
  for (char c : text) {
    if (c == '\'') out += "''";
    else if (c == '\n' || c == '\r') out += ' ';
    else out += c;
  }
  return out;
}

std::string inline_svg(const std::string& svg, const std::string& prefix) {
  const size_t start = svg.find("<svg");
  const size_t end = svg.rfind("</svg>");
  if (start == std::string::npos || end == std::string::npos) return {};
  const std::string body = svg.substr(start, end + 6 - start);
  std::string out;
  out.reserve(body.size() + 1024);
  auto starts = [&](size_t i, const char* s) { return body.compare(i, std::strlen(s), s) == 0; };
  std::map<std::string, int> seen;
  for (size_t i = 0; i < body.size();) {
    // id='x' / id="x" as an attribute (after whitespace), href='#x', url(#x)
    const bool at_attr = i > 0 && std::isspace(static_cast<unsigned char>(body[i - 1]));
    if (at_attr && (starts(i, "id='") || starts(i, "id=\""))) {
      // gnuplot repeats the ids of a key it draws twice (an opaque key): later copies get a suffix.
      const char quote = body[i + 3];
      const size_t close = body.find(quote, i + 4);
      if (close == std::string::npos) {
        out.append(body, i, std::string::npos);
        break;
      }
      const std::string id = body.substr(i + 4, close - (i + 4));
      const int n = ++seen[id];
      out.append(body, i, 4);
      out += prefix + id;
      if (n > 1) out += fmt::format("-{}", n);
      i = close;
    } else if (starts(i, "href='#") || starts(i, "href=\"#")) {
      out.append(body, i, 7);
      out += prefix;
      i += 7;
    } else if (starts(i, "url(#")) {
      out.append(body, i, 5);
      out += prefix;
      i += 5;
    } else {
      out += body[i++];
    }
  }
  return out;
}

}  // namespace fpss
