// `lmalign build-map`: RGB-D visual odometry on a TUM RGB-D sequence, writing a landmark map
// (method.md §1) and the keyframe trajectory (TUM format). Compiled only with lmalign::vo
// (LMALIGN_HAVE_VO); see docs/map-builder.md.
#ifdef LMALIGN_HAVE_VO

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>

#include "cli_util.hpp"
#include "commands.hpp"
#include "lmalign/core/error.hpp"
#include "lmalign/eval/trajectory.hpp"
#include "lmalign/io/output_file.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/vo/map_builder.hpp"

namespace lmalign::cli {

namespace {

struct BuildArgs {
  std::string sequence;
  std::string output;
  std::string trajectory;
  std::string camera = "fr1";
  std::string camera_file;
  std::string intrinsics;
  double max_difference_s = 0.02;
  bool init_from_groundtruth = false;
  long long max_frames = 0;
  int features = 1000;
  int window = 6;
  unsigned long long seed = 1;
  bool no_progress = false;
};

std::string default_trajectory_path(const std::string& map_path) {
  std::filesystem::path p(map_path);
  const std::string stem = p.extension() == ".txt" ? p.stem().string() : p.filename().string();
  return (p.parent_path() / (stem + "_keyframes.tum.txt")).string();
}

int run_build(const BuildArgs& args, const CLI::App& cmd) {
  if (args.trajectory.empty() && names_standard_output(args.output)) {
    throw InvalidArgument("-o '" + args.output +
                          "' is the standard output: give the trajectory's file with --trajectory");
  }
  const std::string trajectory =
      args.trajectory.empty() ? default_trajectory_path(args.output) : args.trajectory;
  if (same_file(args.output, trajectory)) {
    throw InvalidArgument("-o and --trajectory name the same file '" + args.output + "'");
  }
  if (args.max_frames < 0) throw InvalidArgument("--max-frames must be >= 0");
  if (cmd.count("--camera") + (args.camera_file.empty() ? 0 : 1) +
          (args.intrinsics.empty() ? 0 : 1) >
      1) {
    throw InvalidArgument("give at most one of --camera, --camera-file and --intrinsics");
  }
  vo::TumSequenceOptions seq_options;
  seq_options.max_difference_s = args.max_difference_s;
  const vo::TumSequence seq = vo::load_tum_sequence(args.sequence, seq_options);
  check_outputs({{"-o", args.output}, {"--trajectory", trajectory}},
                {args.sequence + "/rgb.txt", args.sequence + "/depth.txt",
                 args.sequence + "/groundtruth.txt"});

  vo::MapBuilderOptions options;
  if (!args.camera_file.empty()) {
    options.camera = vo::read_camera_yaml(args.camera_file);
  } else if (!args.intrinsics.empty()) {
    options.camera.pinhole = PinholeIntrinsics::parse(args.intrinsics);
  } else {
    options.camera = vo::tum_camera_preset(args.camera);
  }
  options.init_from_ground_truth = args.init_from_groundtruth;
  options.max_frames = static_cast<std::size_t>(args.max_frames);
  options.orb_features = args.features;
  options.window_keyframes = args.window;
  options.seed = args.seed;
  std::string why;
  if (!options.is_valid(&why)) throw InvalidArgument(why);

  const bool bar = !args.no_progress && ::isatty(2);
  const auto start = std::chrono::steady_clock::now();
  const auto result = vo::build_map(seq, options, [&](std::size_t done, std::size_t total) {
    if (!bar) return;
    const int width = 40;
    const int filled = static_cast<int>(width * done / std::max<std::size_t>(total, 1));
    std::fprintf(stderr, "\r[%s%s] %zu/%zu frames", std::string(filled, '#').c_str(),
                 std::string(width - filled, ' ').c_str(), done, total);
    if (done == total) std::fprintf(stderr, "\n");
  });
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  write_map(args.output, result.map);
  write_tum_trajectory(trajectory, result.keyframe_trajectory);

  const auto& s = result.stats;
  say("lmalign build-map: %s (%zu associated RGB-D frames)\n", args.sequence.c_str(),
      seq.frames.size());
  say("  frames processed: %zu (%zu not tracked)\n", s.frames, s.frames_lost);
  say("  keyframes:        %zu\n", s.keyframes);
  say("  landmarks:        %zu (%zu with >= 2 observations; %zu covariances from BA)\n",
      s.landmarks, s.landmarks_two_plus, s.landmarks_ba_covariance);
  say("  observations per landmark: %.2f\n", s.mean_observations);
  say("  time:             %.1f s (%.1f ms per frame)\n", seconds,
      1000.0 * seconds / static_cast<double>(std::max<std::size_t>(s.frames, 1)));
  if (seq.ground_truth && result.keyframe_trajectory.size() >= 3) {
    try {
      const AteResult ate =
          absolute_trajectory_error(result.keyframe_trajectory, *seq.ground_truth);
      say("  keyframe ATE vs groundtruth.txt: rmse %.4f m, max %.4f m (%zu poses)\n",
          ate.translation_m.rmse, ate.translation_m.max, ate.pairs.size());
    } catch (const InvalidArgument&) {
      say("  keyframe ATE: too few keyframes associate with groundtruth.txt\n");
    }
  }
  say("  wrote map:        %s\n  wrote trajectory: %s\n", output_name(args.output).c_str(),
      trajectory.c_str());
  return 0;
}

}  // namespace

CommandRunner add_build_map_command(CLI::App& root) {
  auto args = std::make_shared<BuildArgs>();
  CLI::App* cmd = root.add_subcommand("build-map", kBuildMapDescription);
  cmd->add_option("SEQUENCE", args->sequence, "TUM RGB-D sequence folder")->required();
  cmd->add_option("-o,--output", args->output, "Output map file, written atomically")
      ->required()
      ->type_name("MAP");
  cmd->add_option("--trajectory", args->trajectory,
                  "Keyframe trajectory output, TUM format (default: <MAP stem>_keyframes.tum.txt)")
      ->type_name("FILE");
  cmd->add_option("--camera", args->camera, "TUM intrinsics preset: fr1, fr2 or fr3")
      ->capture_default_str();
  cmd->add_option("--camera-file", args->camera_file,
                  "Small YAML camera file: fx, fy, cx, cy [, width, height, depth_scale]")
      ->type_name("FILE");
  cmd->add_option("--intrinsics", args->intrinsics, "Pinhole intrinsics fx,fy,cx,cy in pixels")
      ->type_name("FX,FY,CX,CY");
  cmd->add_option("--max-difference", args->max_difference_s,
                  "Largest RGB-depth time difference, seconds")
      ->capture_default_str()
      ->type_name("S");
  cmd->add_flag("--init-from-groundtruth", args->init_from_groundtruth,
                "Start at the ground-truth pose of the first frame (map in the mocap frame)");
  cmd->add_option("--max-frames", args->max_frames, "Process at most N frames (0: all)")
      ->capture_default_str()
      ->type_name("N");
  cmd->add_option("--features", args->features, "ORB features per image")->capture_default_str();
  cmd->add_option("--window", args->window, "Keyframes in the sliding-window BA")
      ->capture_default_str();
  cmd->add_option("--seed", args->seed, "Seed of the RANSAC draws")->capture_default_str();
  cmd->add_flag("--no-progress", args->no_progress, "No progress bar");
  return [args, cmd]() { return run_build(*args, *cmd); };
}

}  // namespace lmalign::cli

#endif  // LMALIGN_HAVE_VO
