#include "cli_util.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>

#include "lmalign/core/error.hpp"

namespace lmalign::cli {

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

std::filesystem::path repository_root() {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (ec) return {};
  for (fs::path p = exe.parent_path(); !p.empty(); p = p.parent_path()) {
    if (fs::exists(p / "scripts" / "plot_experiment.py", ec)) return p;
    if (p == p.root_path()) break;
  }
  return {};
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
