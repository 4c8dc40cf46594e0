// `lmalign convert IN OUT`: read a map in any supported format (docs/map-format.md, "Other
// formats") and write it in ours, or as a COLMAP text model when OUT is a folder.
#include <array>
#include <iostream>
#include <memory>
#include <string>

#include "cli_util.hpp"
#include "commands.hpp"
#include "lmalign/core/error.hpp"
#include "lmalign/map/formats/formats.hpp"

namespace lmalign::cli {

namespace {

struct ConvertArgs {
  std::string input;
  std::string output;
  std::string format = "auto";
  std::string image_size;  // "W,H"
  double pixel_sigma_px = 0.0;
  double min_parallax_deg = 1.0;
  std::size_t min_observations = 0;
  bool keep_unknown = false;
};

int run_convert(const ConvertArgs& args) {
  refuse_output_over_input("OUT", args.output, {args.input});
  AnyMapReadOptions options;
  options.format = parse_map_format(args.format);
  options.map.min_observations = args.min_observations;
  if (!args.image_size.empty()) options.image_size_px = parse_image_size(args.image_size);
  options.confidence.pixel_sigma_px = args.pixel_sigma_px;
  options.confidence.min_parallax_deg = args.min_parallax_deg;
  options.keep_unknown_covariance = args.keep_unknown;
  if (args.keep_unknown && written_map_format(args.output) == MapFormat::kLmalign) {
    throw InvalidArgument(
        "--keep-unknown-covariance: the lmalign map format cannot hold an unknown covariance; "
        "use it only when OUT is a folder (COLMAP text) or a .ply");
  }
  const MapFormat format =
      options.format == MapFormat::kAuto ? detect_map_format(args.input) : options.format;
  options.format = format;
  const Map map = read_any_map(args.input, options);
  write_any_map(args.output, map);
  std::cout << "convert " << args.input << " (" << map_format_name(format) << ") -> " << args.output
            << " (" << map_format_name(written_map_format(args.output)) << ")"
            << "\n  frames:    " << map.frames.size() << "\n  landmarks: " << map.landmarks.size()
            << "\n";
  return 0;
}

}  // namespace

CommandRunner add_convert_command(CLI::App& root) {
  auto args = std::make_shared<ConvertArgs>();
  CLI::App* cmd = root.add_subcommand(
      "convert",
      "Convert a map to the lmalign map text format (or, if OUT is a folder, to a COLMAP text\n"
      "model; if OUT ends in .ply, to PLY with the covariances). IN may be an lmalign map, a\n"
      "Bundler v0.3 .out file, a COLMAP model folder (text or binary), a stella_vslam .msg or\n"
      "a PLY, chosen by content. Formats without covariances get them re-estimated by\n"
      "triangulation; landmarks where that is impossible are dropped (docs/map-format.md).");
  cmd->add_option("IN", args->input, "input map (file or COLMAP model folder)")->required();
  cmd->add_option("OUT", args->output,
                  "output: a file (lmalign map text), FILE.ply (PLY) or a folder ending in / "
                  "(COLMAP text)")
      ->required();
  cmd->add_option("--format", args->format,
                  "reader of IN: auto (by content), lmalign, bundler, colmap-text, colmap-bin, "
                  "ply, stella-vslam");
  cmd->add_option(
      "--image-size", args->image_size,
      "Bundler: image size W,H in pixels, needed when OUT stores pixels from the top-left "
      "corner (lmalign text, COLMAP); Bundler's are centred");
  cmd->add_option("--pixel-sigma", args->pixel_sigma_px,
                  "pixel noise for re-estimated covariances, px; 0: COLMAP's stored mean "
                  "reprojection error where present, else 1 px")
      ->capture_default_str();
  cmd->add_option("--min-parallax", args->min_parallax_deg,
                  "below this largest viewing-ray angle (deg) a covariance is not estimated")
      ->capture_default_str();
  cmd->add_option("--min-observations", args->min_observations,
                  "drop landmarks with fewer observations")
      ->capture_default_str();
  cmd->add_flag("--keep-unknown-covariance", args->keep_unknown,
                "keep landmarks whose covariance cannot be estimated (COLMAP or PLY output only)");
  return [args]() { return run_convert(*args); };
}

}  // namespace lmalign::cli
