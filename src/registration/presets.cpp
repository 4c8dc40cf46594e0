// The presets (include/lmalign/registration/presets.hpp): parsed from configs/presets/*.yaml, built
// into the library by cmake/lmalign_embed_presets.cmake, and from users' preset files.
#include "lmalign/registration/presets.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/core/supported_range.hpp"
#include "lmalign/registration/supported_landmarks.hpp"

namespace lmalign {

namespace detail {
/// (name, text) of every configs/presets/*.yaml (presets_embedded.cpp, generated at build time).
const std::vector<std::pair<std::string, std::string>>& embedded_presets();
}  // namespace detail

namespace {

std::size_t line_of(const YAML::Node& n) {
  if (!n.IsDefined()) return 0;
  const YAML::Mark m = n.Mark();
  return m.is_null() ? 0 : static_cast<std::size_t>(m.line) + 1;
}

std::string known_stages(Seam seam) {
  std::string s;
  for (const StageInfo& i : stage_registry()) {
    if (i.seam == seam) s += (s.empty() ? "" : ", ") + i.name;
  }
  return s;
}

std::string scalar_text(const YAML::Node& n) {
  if (n.IsScalar()) return n.Scalar();
  if (n.IsSequence()) {
    std::string s;
    for (std::size_t i = 0; i < n.size(); ++i) {
      if (!n[i].IsScalar()) return std::string();
      s += (i ? "," : "") + n[i].Scalar();
    }
    return s;
  }
  return std::string();
}

// A preset key naming a stage: its seam, or nullopt.
std::optional<Seam> seam_of_key(const std::string& key) {
  static const std::vector<std::pair<std::string, Seam>> seams{
      {"initialiser", Seam::kInitialiser}, {"matcher", Seam::kMatcher},
      {"rejectors", Seam::kRejector},      {"kernel", Seam::kKernel},
      {"estimator", Seam::kEstimator},     {"schedule", Seam::kSchedule},
      {"scorer", Seam::kScorer},           {"trust", Seam::kTrustJudge}};
  for (const auto& [k, seam] : seams) {
    if (k == key) return seam;
  }
  return std::nullopt;
}

// A stage key's value (the rejectors: a list of stages) into the preset's spec.
void read_stages(const std::string& key, Seam seam, const YAML::Node& v, const std::string& file,
                 PipelineSpec* spec) {
  auto stage = [&](const YAML::Node& n) {
    if (!n.IsScalar()) throw ParseError(file, line_of(n), key + ": expected a stage name");
    if (find_stage(seam, n.Scalar()) == nullptr) {
      throw ParseError(file, line_of(n),
                       "unknown " + to_string(seam) + " stage '" + n.Scalar() +
                           "' (known: " + known_stages(seam) + ")");
    }
    return n.Scalar();
  };
  if (seam == Seam::kRejector) {
    if (!v.IsSequence()) throw ParseError(file, line_of(v), "rejectors: expected a list");
    for (const YAML::Node& r : v) spec->rejectors.push_back(stage(r));
    return;
  }
  const std::string s = stage(v);
  switch (seam) {
    case Seam::kInitialiser:
      spec->initialiser = s;
      break;
    case Seam::kMatcher:
      spec->matcher = s;
      break;
    case Seam::kKernel:
      spec->kernel = s;
      break;
    case Seam::kEstimator:
      spec->estimator = s;
      break;
    case Seam::kSchedule:
      spec->schedule = s;
      break;
    case Seam::kScorer:
      spec->scorer = s;
      break;
    default:
      spec->trust = s;
      break;
  }
}

// One of the preset's own keys (doc, group, order, header, recommended, aliases).
void read_preset_key(const std::string& key, const YAML::Node& v, const std::string& file,
                     Preset* p) {
  auto text = [&](const char* what) {
    if (!v.IsScalar()) throw ParseError(file, line_of(v), key + ": expected " + what);
    return v.Scalar();
  };
  if (key == "doc") {
    p->doc = text("a line of text");
  } else if (key == "group") {
    p->group = text("paper or lmalign");
    if (p->group != "paper" && p->group != "lmalign") {
      throw ParseError(file, line_of(v),
                       "group: expected paper or lmalign, got '" + p->group + "'");
    }
  } else if (key == "order") {
    try {
      p->order = std::stoi(text("an integer"));
    } catch (const std::exception&) {
      throw ParseError(file, line_of(v), "order: expected an integer");
    }
  } else if (key == "header") {
    p->header = text("a short text");
  } else if (key == "recommended") {
    const std::string t = text("true or false");
    if (t != "true" && t != "false") {
      throw ParseError(file, line_of(v), "recommended: expected true or false");
    }
    p->recommended = t == "true";
  } else if (key == "aliases") {
    if (!v.IsSequence()) throw ParseError(file, line_of(v), "aliases: expected a list of names");
    for (const YAML::Node& a : v) {
      if (!a.IsScalar()) throw ParseError(file, line_of(a), "aliases: expected names");
      p->aliases.push_back(a.Scalar());
    }
  }
}

// The preset's settings, each checked against its row of the pipeline's table, then the whole.
void read_preset_settings(const YAML::Node& settings, const std::string& file, Preset* p) {
  // The stages must fit together, and the settings be theirs.
  std::optional<Pipeline> pipeline;
  try {
    pipeline.emplace(p->spec);
  } catch (const InvalidArgument& e) {
    throw ParseError(file, 1, e.what());
  }
  if (!settings.IsMap()) return;
  for (auto it = settings.begin(); it != settings.end(); ++it) {
    const YAML::Node k = it->first;
    const YAML::Node v = it->second;
    const std::string key = k.IsScalar() ? k.Scalar() : std::string();
    const std::string value = scalar_text(v);
    try {
      const SettingRow& row = pipeline->settings().row(key);
      if (value.empty() && !v.IsScalar()) {
        throw InvalidArgument(key + ": expected a value or a list of numbers");
      }
      p->spec.settings.emplace_back(key, row.parse(value));
    } catch (const InvalidArgument& e) {
      throw ParseError(file, line_of(k), std::string("settings: ") + e.what());
    }
  }
  try {
    Pipeline check(p->spec);
  } catch (const InvalidArgument& e) {
    throw ParseError(file, line_of(settings), e.what());
  }
}

Preset parse(const std::string& text, const std::string& name, const std::string& file) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::ParserException& e) {
    throw ParseError(file, e.mark.is_null() ? 0 : static_cast<std::size_t>(e.mark.line) + 1,
                     "YAML syntax error: " + e.msg);
  }
  if (!root.IsMap()) throw ParseError(file, line_of(root), "expected a mapping of a preset's keys");
  static const std::vector<std::string> keys{"doc",       "group",       "order",       "header",
                                             "aliases",   "recommended", "initialiser", "matcher",
                                             "rejectors", "kernel",      "estimator",   "schedule",
                                             "scorer",    "trust",       "settings"};
  Preset p;
  p.name = name;
  p.header = name;
  p.file = file;
  p.spec.name = name;
  std::vector<std::string> seen;
  YAML::Node settings;
  for (auto it = root.begin(); it != root.end(); ++it) {
    const YAML::Node k = it->first;
    const YAML::Node v = it->second;
    const std::string key = k.IsScalar() ? k.Scalar() : std::string();
    if (std::find(keys.begin(), keys.end(), key) == keys.end()) {
      std::string list;
      for (const std::string& s : keys) list += (list.empty() ? "" : ", ") + s;
      throw ParseError(file, line_of(k),
                       "unknown key '" + key + "' (expected one of " + list + ")");
    }
    if (std::find(seen.begin(), seen.end(), key) != seen.end()) {
      throw ParseError(file, line_of(k), "duplicate key '" + key + "'");
    }
    seen.push_back(key);
    if (key == "settings") {
      if (!v.IsMap() && !v.IsNull()) {
        throw ParseError(file, line_of(v), "settings: expected a mapping of KEY: VALUE");
      }
      settings = v;
    } else if (const std::optional<Seam> seam = seam_of_key(key)) {
      read_stages(key, *seam, v, file, &p.spec);
    } else {
      read_preset_key(key, v, file, &p);
    }
  }
  for (const char* required : {"initialiser", "matcher", "kernel", "estimator", "schedule"}) {
    if (std::find(seen.begin(), seen.end(), required) == seen.end()) {
      throw ParseError(file, 1, std::string("missing key '") + required + "'");
    }
  }
  read_preset_settings(settings, file, &p);
  return p;
}

std::vector<Preset> load_builtin() {
  std::vector<Preset> out;
  for (const auto& [name, text] : detail::embedded_presets()) {
    out.push_back(parse(text, name, "configs/presets/" + name + ".yaml"));
  }
  std::stable_sort(out.begin(), out.end(),
                   [](const Preset& a, const Preset& b) { return a.order < b.order; });
  std::size_t recommended = 0;
  for (const Preset& p : out) recommended += p.recommended ? 1 : 0;
  if (recommended != 1) {
    throw Error("configs/presets: exactly one preset must be recommended, found " +
                std::to_string(recommended));
  }
  return out;
}

bool ends_with(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

}  // namespace

bool Preset::uses_k() const { return spec.matcher == "weighted_knn"; }

const std::vector<Preset>& presets() {
  static const std::vector<Preset> all = load_builtin();
  return all;
}

std::vector<std::string> preset_names(const std::string& group) {
  std::vector<std::string> out;
  for (const Preset& p : presets()) {
    if (group.empty() || p.group == group) out.push_back(p.name);
  }
  return out;
}

const Preset& recommended_preset() {
  for (const Preset& p : presets()) {
    if (p.recommended) return p;
  }
  throw Error("no recommended preset");
}

bool is_preset_name(const std::string& name) {
  for (const Preset& p : presets()) {
    if (p.name == name || std::find(p.aliases.begin(), p.aliases.end(), name) != p.aliases.end()) {
      return true;
    }
  }
  return false;
}

Preset find_preset(const std::string& name) {
  for (const Preset& p : presets()) {
    if (p.name == name || std::find(p.aliases.begin(), p.aliases.end(), name) != p.aliases.end()) {
      return p;
    }
  }
  if (ends_with(name, ".yaml") || ends_with(name, ".yml")) return read_preset_file(name);
  std::string known;
  std::string nearest;
  std::size_t best = std::numeric_limits<std::size_t>::max();
  for (const Preset& p : presets()) {
    known += (known.empty() ? "" : ", ") + p.name;
    // A name the given one begins (cov -> covariance) counts as near as a one-letter typo.
    const std::size_t d =
        p.name.rfind(name, 0) == 0 && !name.empty() ? std::size_t{1} : edit_distance(name, p.name);
    if (d < best) {
      best = d;
      nearest = p.name;
    }
  }
  const bool close = best <= std::max<std::size_t>(2, name.size() / 3);
  throw InvalidArgument("unknown strategy '" + name + "'" +
                        (close ? " (nearest: '" + nearest + "')" : std::string()) +
                        "; known: " + known + ", or a preset file NAME.yaml");
}

Preset parse_preset(const std::string& yaml_text, const std::string& name,
                    const std::string& file) {
  return parse(yaml_text, name, file);
}

Preset read_preset_file(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    throw IoError("cannot read preset '" + path + "': " + std::strerror(EISDIR));
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError("cannot open preset '" + path + "': " + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw IoError("cannot read preset '" + path + "': read error");
  return parse(text.str(), std::filesystem::path(path).stem().string(), path);
}

void AlignRequest::describe_maps(const MapHeader& source, const MapHeader& target) {
  source_metric = source.scale == MapScale::kMetric;
  target_metric = target.scale == MapScale::kMetric;
  covariances_assumed = source.covariance_assumed || target.covariance_assumed;
}

void AlignRequest::add_assignment(const std::string& key_value) {
  const std::size_t eq = key_value.find('=');
  if (eq == std::string::npos || eq == 0) {
    throw InvalidArgument("'" + key_value + "': expected KEY=VALUE");
  }
  settings.emplace_back(key_value.substr(0, eq), SettingValue(key_value.substr(eq + 1)));
}

void AlignRequest::resolve(const Preset& preset) {
  const Pipeline base(preset.spec);
  const std::string strategy = " (strategy '" + preset.name + "')";
  for (auto& [key, value] : settings) {
    try {
      const SettingRow& row = base.settings().row(key);  // an unknown key names the nearest
      if (const std::string* text = std::get_if<std::string>(&value)) value = row.parse(*text);
    } catch (const InvalidArgument& e) {
      throw InvalidArgument("settings: " + std::string(e.what()) + strategy);
    }
  }
  if (prior) {
    std::string why;
    if (!prior->is_valid(&why)) throw InvalidArgument("prior sigma: " + why);
    if (!base.initialiser().uses_prior()) {
      throw InvalidArgument("prior sigma: the strategy '" + preset.name +
                            "' uses no prior (its initialiser '" + preset.spec.initialiser +
                            "' does not search)");
    }
  }
  if (initial_guess) {
    if (!is_rigid_transform(*initial_guess)) {
      throw InvalidArgument(
          "initial guess: not a rigid transform (expected a finite 4x4 [R t; 0 0 0 1] with R "
          "orthonormal and det R = +1)");
    }
    check_supported_translation("initial guess", initial_guess->translation());
  }
  try {
    const Pipeline resolved(resolve_spec(preset, *this));  // the whole table, within its bounds
  } catch (const InvalidArgument& e) {
    throw InvalidArgument("settings: " + std::string(e.what()) + strategy);
  }
}

PipelineSpec resolve_spec(const Preset& preset, const AlignRequest& request) {
  PipelineSpec spec = preset.spec;
  auto add = [&](const std::string& key, SettingValue v) {
    spec.settings.emplace_back(key, std::move(v));
  };
  if (request.k && preset.uses_k()) add("match.k", static_cast<long long>(*request.k));
  if (request.max_iterations || request.max_distance_m) {
    const Pipeline base(spec);
    for (auto& kv :
         base.schedule().limits(base.settings(), request.max_iterations, request.max_distance_m)) {
      add(kv.first, std::move(kv.second));
    }
  }
  for (const auto& kv : request.settings) add(kv.first, kv.second);
  return spec;
}

Summary align(const Preset& preset, const SourceView& source, const PreparedTarget& target,
              const AlignRequest& given) {
  AlignRequest request = given;
  request.resolve(preset);
  const Pipeline pipeline(resolve_spec(preset, request));
  // The supported range (core/supported_range.hpp): landmarks beyond it are left out, counted,
  // and named in the verdict's reason.
  const SupportedLandmarks kept = keep_supported_landmarks(source, target);
  PipelineRequest r;
  r.initial_guess = request.initial_guess;
  r.prior = request.prior;
  r.record_history = request.record_history;
  r.history_scores = request.record_history;
  r.free_scale = resolve_scale_mode(request.scale, request.source_metric, request.target_metric) ==
                 ScaleMode::kFree;
  r.source_left_out = kept.source_left_out;
  r.target_left_out = kept.target_left_out;
  r.covariances_assumed = request.covariances_assumed;
  return pipeline.run(kept.source ? kept.source->view() : source,
                      kept.target ? *kept.target : target, r);
}

}  // namespace lmalign
