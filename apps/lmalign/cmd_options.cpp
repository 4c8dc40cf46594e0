// `lmalign options PRESET`: the preset's stages and its table of settings, one setting per line:
// key, value, unit, bound, doc (docs/cli.md). `lmalign options --markdown`: docs/settings.md,
// every preset's table and the experiment config's keys.
#include <cstdio>
#include <memory>
#include <string>

#include "commands.hpp"
#include "lmalign/core/error.hpp"
#include "lmalign/experiment/config.hpp"
#include "lmalign/registration/presets.hpp"

namespace lmalign::cli {

namespace {

int run_options(const std::string& name, bool markdown) {
  if (markdown) {
    if (!name.empty()) throw InvalidArgument("--markdown prints every preset: give no PRESET");
    std::fputs(settings_reference_markdown().c_str(), stdout);
    return 0;
  }
  if (name.empty()) throw InvalidArgument("options: give a PRESET, or --markdown");
  const Preset preset = find_preset(name);
  const Pipeline pipeline(preset.spec);
  const PipelineSpec& s = preset.spec;
  std::printf("%s: %s\n", preset.name.c_str(), preset.doc.c_str());
  std::string rejectors;
  for (const std::string& r : s.rejectors) rejectors += (rejectors.empty() ? "" : ",") + r;
  std::printf(
      "stages: initialiser %s, matcher %s, rejectors %s, kernel %s, estimator %s, schedule %s, "
      "scorer %s, trust %s (%s)\n",
      s.initialiser.c_str(), s.matcher.c_str(), rejectors.empty() ? "-" : rejectors.c_str(),
      s.kernel.c_str(), s.estimator.c_str(), s.schedule.c_str(), s.scorer.c_str(), s.trust.c_str(),
      preset.file.c_str());
  std::printf("%-40s %-26s %-6s %-40s %s\n", "key", "value", "unit", "bound", "doc");
  const Settings& settings = pipeline.settings();
  for (const SettingRow& row : settings.table()) {
    std::printf("%-40s %-26s %-6s %-40s %s\n", row.key.c_str(),
                row.text(settings.value(row.key)).c_str(), row.unit.c_str(),
                row.bound.text(row.type).c_str(), row.doc.c_str());
  }
  return 0;
}

}  // namespace

CommandRunner add_options_command(CLI::App& root) {
  auto name = std::make_shared<std::string>();
  auto markdown = std::make_shared<bool>(false);
  CLI::App* cmd = root.add_subcommand(
      "options",
      "Print a strategy's stages and its settings, one per line: key, value, unit, bound, doc.\n"
      "Any of them can be changed with `lmalign align --set KEY=VALUE`, an experiment config's\n"
      "`settings:` or Python's settings= (docs/cli.md).");
  cmd->add_option("PRESET", *name,
                  "a strategy name (lmalign align --help lists them) or a preset "
                  "file NAME.yaml");
  cmd->add_flag("--markdown", *markdown,
                "print docs/settings.md instead: every preset's settings and the experiment "
                "config's keys (key, default, unit, bound, doc)");
  return [name, markdown]() { return run_options(*name, *markdown); };
}

}  // namespace lmalign::cli
