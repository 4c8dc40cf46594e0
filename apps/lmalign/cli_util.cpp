#include "cli_util.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include "lmalign/core/error.hpp"
#include "lmalign/io/output_file.hpp"

namespace lmalign::cli {

void add_set_options(const std::vector<std::string>& assignments, AlignRequest* request) {
  for (const std::string& s : assignments) {
    try {
      request->add_assignment(s);
    } catch (const InvalidArgument& e) {
      throw InvalidArgument(std::string("--set ") + e.what());
    }
  }
}

std::vector<double> parse_number_list(const std::string& option, const std::string& text,
                                      std::size_t count, const std::string& expected) {
  std::vector<double> values;
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = text.find(',', start);
    const std::string tok =
        text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    double v = 0.0;
    const auto r = std::from_chars(tok.data(), tok.data() + tok.size(), v);
    if (tok.empty() || r.ec != std::errc() || r.ptr != tok.data() + tok.size() ||
        !std::isfinite(v)) {
      throw InvalidArgument(option + " \"" + text + "\": '" + tok +
                            "' is not a finite number; expected " + expected);
    }
    values.push_back(v);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  if (values.size() != count) {
    throw InvalidArgument(option + " \"" + text + "\": " + std::to_string(values.size()) +
                          " values, expected " + expected);
  }
  return values;
}

bool same_file(const std::string& a, const std::string& b) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::equivalent(a, b, ec) && !ec) return true;
  ec.clear();
  const fs::path ca = fs::weakly_canonical(a, ec);
  if (ec) return false;
  const fs::path cb = fs::weakly_canonical(b, ec);
  if (ec) return false;
  return ca == cb;
}

void refuse_output_over_input(const std::string& option, const std::string& output,
                              const std::vector<std::string>& inputs) {
  for (const std::string& in : inputs) {
    if (same_file(output, in)) {
      throw InvalidArgument(option + " '" + output +
                            "' is an input file; refusing to overwrite it");
    }
  }
}

namespace {
bool g_stdout_claimed = false;
}  // namespace

bool standard_output_claimed() { return g_stdout_claimed; }
std::FILE* human_file() { return g_stdout_claimed ? stderr : stdout; }
std::ostream& human() { return g_stdout_claimed ? std::cerr : std::cout; }

void say(const char* format, ...) {
  std::va_list args;
  va_start(args, format);
  std::vfprintf(human_file(), format, args);
  va_end(args);
}

std::string output_name(const std::string& path) {
  return path == "-" ? "the standard output" : path;
}

void check_outputs(const std::vector<OutputOption>& outputs,
                   const std::vector<std::string>& inputs) {
  std::string on_stdout;
  for (const auto& [option, path] : outputs) {
    if (path.empty()) continue;
    const OutputTarget t = check_output_path(path);
    if (t.kind == OutputKind::kStandardOutput) {
      if (!on_stdout.empty()) {
        throw InvalidArgument(option + " '" + path + "': " + on_stdout +
                              " already writes to the standard output; at most one output "
                              "may be '-'");
      }
      on_stdout = option;
      continue;
    }
    refuse_output_over_input(option, path, inputs);
  }
  if (!on_stdout.empty()) {
    std::cout.flush();
    std::fflush(stdout);
    g_stdout_claimed = true;
  }
}

void refuse_standard_output_folder(const std::string& option, const std::string& folder) {
  if (folder == "-" || names_standard_output(folder)) {
    throw InvalidArgument(option + " '" + folder +
                          "': an output folder cannot be the standard output");
  }
}

nlohmann::json json_number(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json();
}

nlohmann::json json_matrix(const Isometry3& T) {
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) {
    nlohmann::json row = nlohmann::json::array();
    for (int c = 0; c < 4; ++c) row.push_back(T.matrix()(r, c));
    rows.push_back(row);
  }
  return rows;
}

std::array<long long, 2> parse_image_size(const std::string& text) {
  const auto comma = text.find(',');
  try {
    if (comma == std::string::npos) throw std::invalid_argument(text);
    std::size_t used_w = 0;
    std::size_t used_h = 0;
    const std::string w_text = text.substr(0, comma);
    const std::string h_text = text.substr(comma + 1);
    const long long w = std::stoll(w_text, &used_w);
    const long long h = std::stoll(h_text, &used_h);
    if (used_w != w_text.size() || used_h != h_text.size() || w <= 0 || h <= 0) {
      throw std::invalid_argument(text);
    }
    return {w, h};
  } catch (const std::logic_error&) {
    throw InvalidArgument("--image-size '" + text +
                          "': expected W,H, two positive integers in pixels (e.g. 640,427)");
  }
}

}  // namespace lmalign::cli

namespace lmalign::cli {

namespace {
std::atomic<bool> g_stop{false};
static_assert(std::atomic<bool>::is_always_lock_free, "the signal handler needs a lock-free flag");

extern "C" void on_stop_signal(int sig) {
  if (g_stop.exchange(true)) {
    ::signal(sig, SIG_DFL);
    ::raise(sig);
  }
}
}  // namespace

std::atomic<bool>& stop_flag() { return g_stop; }

StopSignals::StopSignals() {
  struct sigaction sa {};
  sa.sa_handler = on_stop_signal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_RESTART;
  ::sigaction(SIGINT, &sa, &old_int_);
  ::sigaction(SIGTERM, &sa, &old_term_);
}

StopSignals::~StopSignals() {
  ::sigaction(SIGINT, &old_int_, nullptr);
  ::sigaction(SIGTERM, &old_term_, nullptr);
}

std::filesystem::path source_checkout() {
#ifdef LMALIGN_SOURCE_DIR
  std::error_code ec;
  const std::filesystem::path root(LMALIGN_SOURCE_DIR);
  if (std::filesystem::is_directory(root / "scripts", ec)) return root;
#endif
  return {};
}

std::string find_script(const std::string& name, const char* env_var) {
  namespace fs = std::filesystem;
  if (const char* env = std::getenv(env_var); env != nullptr && *env != '\0') return env;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const fs::path installed =
        exe.parent_path().parent_path() / "share" / "lmalign" / "scripts" / name;
    if (fs::is_regular_file(installed, ec)) return installed.string();
  }
  if (const fs::path root = source_checkout(); !root.empty()) {
    if (fs::is_regular_file(root / "scripts" / name, ec)) return (root / "scripts" / name).string();
  }
  return {};
}

int draw_plots(const std::string& script, const std::vector<std::string>& args,
               const std::string& plots_dir) {
  namespace fs = std::filesystem;
  create_output_folder(plots_dir);
  std::string pattern = (fs::path(plots_dir) / ".lmalign-plots.XXXXXX").string();
  if (::mkdtemp(pattern.data()) == nullptr) {
    throw IoError("cannot write into '" + plots_dir + "': " + std::strerror(errno));
  }
  const fs::path temp(pattern);
  struct Remove {
    fs::path path;
    ~Remove() {
      std::error_code ec;
      fs::remove_all(path, ec);
    }
  } remove{temp};
  std::vector<std::string> argv{python_interpreter(), script};
  argv.insert(argv.end(), args.begin(), args.end());
  argv.insert(argv.end(), {"--plots-dir", temp.string()});
  const int rc = run_process(argv);
  if (rc != 0) return rc;
  std::vector<fs::path> drawn;
  for (const auto& entry : fs::directory_iterator(temp)) {
    if (entry.is_regular_file()) drawn.push_back(entry.path());
  }
  std::sort(drawn.begin(), drawn.end());
  for (const fs::path& file : drawn) {
    std::ifstream in(file, std::ios::binary);
    std::ostringstream bytes;
    bytes << in.rdbuf();
    if (!in && !in.eof()) throw IoError("cannot read the plot '" + file.string() + "'");
    const std::string data = bytes.str();
    write_output((fs::path(plots_dir) / file.filename()).string(), [&](std::ostream& out) {
      out.write(data.data(), static_cast<std::streamsize>(data.size()));
    });
  }
  return 0;
}

std::string python_interpreter() {
  if (const char* env = std::getenv("LMALIGN_PYTHON"); env != nullptr && *env != '\0') return env;
  if (::access("/usr/bin/python3", X_OK) == 0) return "/usr/bin/python3";
  return "python3";
}

int run_process(const std::vector<std::string>& argv) {
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  std::cout.flush();
  std::fflush(stdout);
  const pid_t pid = ::fork();
  if (pid < 0) return -1;
  if (pid == 0) {
    // The child's own output belongs to the human summary: on standard error when an output
    // file has standard output.
    if (g_stdout_claimed) ::dup2(STDERR_FILENO, STDOUT_FILENO);
    ::execvp(args[0], args.data());
    std::fprintf(stderr, "lmalign: cannot run %s\n", args[0]);
    ::_exit(127);
  }
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) return -1;
  }
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  return -1;
}

}  // namespace lmalign::cli
