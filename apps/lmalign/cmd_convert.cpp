// `lmalign convert IN OUT`: read a map in any supported format (docs/map-format.md, "Other
// formats") and write it in ours, or as a COLMAP text model when OUT is a folder.
#include <array>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>

#include "cli_util.hpp"
#include "commands.hpp"
#include "lmalign/core/error.hpp"
#include "lmalign/io/transform_io.hpp"
#include "lmalign/map/formats/formats.hpp"
#include "lmalign/map/transform.hpp"

namespace lmalign::cli {

namespace {

/// A number as `<<` prints it (1, 0.5).
std::string number_text(double value) {
  std::ostringstream out;
  out << value;
  return out.str();
}

struct ConvertArgs {
  std::string input;
  std::string output;
  std::string format = "auto";
  std::string output_format = "auto";
  std::string image_size;  // "W,H"
  double pixel_sigma_px = 0.0;
  double min_parallax_deg = 0.0;
  std::size_t min_observations = 0;
  bool keep_unknown = false;
  std::string transform;  // a 4x4 file: S_out_in
  std::string map_scale;  // metric|arbitrary|unknown: the header's scale, as written
};

int run_convert(const ConvertArgs& args) {
  const MapFormat out_format =
      written_map_format(args.output, parse_map_format(args.output_format));
  if (out_format == MapFormat::kColmapText) {
    refuse_standard_output_folder("OUT", args.output);
    refuse_output_over_input("OUT", args.output, {args.input});
  } else {
    check_outputs({{"OUT", args.output}}, {args.input});
  }
  AnyMapReadOptions options;
  options.format = parse_map_format(args.format);
  options.map.min_observations = args.min_observations;
  if (!args.image_size.empty()) options.image_size_px = parse_image_size(args.image_size);
  options.confidence.pixel_sigma_px = args.pixel_sigma_px;
  options.confidence.min_parallax_deg = args.min_parallax_deg;
  options.keep_unknown_covariance = args.keep_unknown;
  if (args.keep_unknown && out_format == MapFormat::kLmalign) {
    throw InvalidArgument(
        "--keep-unknown-covariance: the lmalign map format cannot hold an unknown covariance; "
        "use it only when OUT is a folder (COLMAP text) or a .ply");
  }
  const MapFormat format =
      options.format == MapFormat::kAuto ? detect_map_format(args.input) : options.format;
  options.format = format;
  std::optional<MapScale> scale;
  if (!args.map_scale.empty()) {
    scale = map_scale_from_name(args.map_scale);
    if (!scale) {
      throw InvalidArgument("--map-scale '" + args.map_scale +
                            "': expected metric, arbitrary or unknown");
    }
  }
  // Read before any map work, so a bad file fails first.
  const std::optional<Similarity3> S_out_in =
      args.transform.empty() ? std::nullopt : std::optional(read_similarity(args.transform));
  MapReadStats stats;
  Map map = read_any_map(args.input, options, &stats);
  if (S_out_in) map = transform_map(map, *S_out_in);
  if (scale) map.header.scale = *scale;
  write_any_map(args.output, map, out_format);
  human() << "convert " << args.input << " (" << map_format_name(format) << ") -> "
          << output_name(args.output) << " (" << map_format_name(out_format) << ")"
          << "\n  frames:    " << map.frames.size() << "\n  landmarks: " << map.landmarks.size()
          << " of " << stats.landmarks_in_file << " kept, " << stats.dropped() << " dropped\n";
  // Every kind that occurs, kept then dropped (MapReadStats).
  const auto line = [](const char* verb, std::size_t n, const std::string& what) {
    if (n > 0) human() << "    " << verb << " " << n << " " << what << "\n";
  };
  const std::string low = number_text(kLowParallaxDeg);
  line("kept", stats.kept_stored, "with the covariance the file stores");
  line("kept", stats.kept_triangulated,
       "with a triangulated covariance (parallax >= " + low + " deg)");
  line("kept", stats.kept_low_parallax,
       "with low parallax (< " + low + " deg): triangulated, their covariance is large");
  line("kept", stats.kept_assumed,
       "with an assumed covariance (a point cloud without any: isotropic, half the local "
       "spacing)");
  line("kept", stats.kept_unknown, "with an unknown covariance (--keep-unknown-covariance)");
  line("dropped", stats.dropped_min_observations,
       "with fewer than " + std::to_string(args.min_observations) +
           " observations (--min-observations)");
  line("dropped", stats.dropped_too_few_views, "seen in fewer than 2 usable views");
  line("dropped", stats.dropped_not_triangulated,
       "that cannot be triangulated (no parallax, or behind a camera)");
  line("dropped", stats.dropped_below_min_parallax,
       "with parallax below " + number_text(args.min_parallax_deg) + " deg (--min-parallax)");
  line("dropped", stats.dropped_unknown, "flagged covariance_known = 0 in the file");
  if (stats.camera_centres_left_out > 0) {
    human() << "  left out " << stats.camera_centres_left_out
            << " vertices that are OpenMVG's camera centres, not landmarks ("
            << stats.camera_centres_rule << ")\n";
  }
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
      "a PLY or an XYZ text point cloud, chosen by content. Formats without covariances get\n"
      "them re-estimated by triangulation (landmarks of low parallax are kept, with their large\n"
      "covariance); landmarks that cannot be triangulated are dropped; point clouds get an\n"
      "assumed covariance from the local spacing. Prints what it kept and dropped, by kind\n"
      "(docs/map-format.md).");
  cmd->add_option("IN", args->input, "input map (file or COLMAP model folder)")->required();
  cmd->add_option("OUT", args->output,
                  "output: a file (lmalign map text), FILE.ply (PLY) or a folder ending in / "
                  "(COLMAP text); '-' writes the map to the standard output (this summary then "
                  "goes to the standard error). A symlink is written through, a FIFO in place")
      ->required();
  cmd->add_option("--output-format", args->output_format,
                  "writer of OUT: auto (by its form, as above), " + written_map_format_names())
      ->capture_default_str();
  cmd->add_option(
      "--format", args->format,
      "reader of IN: " + map_format_names() + " (auto: by content; docs/map-format.md)");
  cmd->add_option(
      "--image-size", args->image_size,
      "Bundler: image size W,H in pixels, needed when OUT stores pixels from the top-left "
      "corner (lmalign text, COLMAP); Bundler's are centred");
  cmd->add_option("--pixel-sigma", args->pixel_sigma_px,
                  "pixel noise for re-estimated covariances, px; 0: COLMAP's stored mean "
                  "reprojection error where present, else 1 px")
      ->capture_default_str();
  cmd->add_option("--min-parallax", args->min_parallax_deg,
                  "drop landmarks whose largest viewing-ray angle is below this (deg); 0: keep "
                  "every landmark that triangulates")
      ->capture_default_str();
  cmd->add_option("--min-observations", args->min_observations,
                  "drop landmarks with fewer observations")
      ->capture_default_str();
  cmd->add_flag("--keep-unknown-covariance", args->keep_unknown,
                "keep landmarks whose covariance cannot be estimated (COLMAP or PLY output only)");
  cmd->add_option("--transform", args->transform,
                  "FILE: move the map by the 4x4 transform in FILE (4 rows of 4 numbers, last "
                  "row 0 0 0 1), rigid [R t; 0 1] or a similarity [sR t; 0 1]: p_out = s R p_in "
                  "+ t, in the map's units; frames move with it and covariances become "
                  "s^2 R C R^T");
  cmd->add_option("--map-scale", args->map_scale,
                  "metric, arbitrary or unknown: the scale the written map's header records "
                  "(default: the one read; docs/map-format.md). A map moved by a similarity is "
                  "no longer metric unless you say so");
  return [args]() { return run_convert(*args); };
}

}  // namespace lmalign::cli
