// `lmalign eval-trajectory`: absolute trajectory error and relative pose error of an estimated
// trajectory against ground truth, as the TUM RGB-D benchmark defines them (docs/map-builder.md).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <limits>
#include <memory>
#include <sstream>
#include <string>

#include "cli_util.hpp"
#include "commands.hpp"
#include "lmalign/core/error.hpp"
#include "lmalign/eval/trajectory.hpp"
#include "lmalign/io/output_file.hpp"
#include "lmalign/map/map_io.hpp"

namespace lmalign::cli {

namespace {

struct EvalArgs {
  std::string estimate;
  std::string ground_truth;
  std::string frame_times;
  double max_difference_s = 0.02;
  double offset_s = 0.0;
  double delta_s = 1.0;
  bool no_align = false;
  std::string plot;
  std::string aligned_out;
};

std::string fmt(double v, int precision = 4) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", precision, v);
  return buf;
}

// Top view (x, y) of the ground truth over the estimate's time span and of the aligned estimate.
void write_svg_plot(const std::string& path, const Trajectory& gt, const Trajectory& aligned) {
  double x0 = std::numeric_limits<double>::infinity(), y0 = x0, x1 = -x0, y1 = -x0;
  const double t_begin = aligned.front().timestamp_s, t_end = aligned.back().timestamp_s;
  Trajectory gt_span;
  for (const auto& p : gt) {
    if (p.timestamp_s >= t_begin - 0.5 && p.timestamp_s <= t_end + 0.5) gt_span.push_back(p);
  }
  for (const Trajectory* t : {static_cast<const Trajectory*>(&gt_span), &aligned}) {
    for (const auto& p : *t) {
      x0 = std::min(x0, p.T_world_camera.translation().x());
      x1 = std::max(x1, p.T_world_camera.translation().x());
      y0 = std::min(y0, p.T_world_camera.translation().y());
      y1 = std::max(y1, p.T_world_camera.translation().y());
    }
  }
  const double size = 600.0, margin = 40.0;
  const double span = std::max({x1 - x0, y1 - y0, 1e-6});
  auto px = [&](double x) { return margin + (x - x0) / span * size; };
  auto py = [&](double y) { return margin + size - (y - y0) / span * size; };
  auto polyline = [&](const Trajectory& t, const char* colour) {
    std::ostringstream os;
    os << "<polyline fill=\"none\" stroke=\"" << colour << "\" stroke-width=\"1.5\" points=\"";
    for (const auto& p : t) {
      os << fmt(px(p.T_world_camera.translation().x()), 2) << ','
         << fmt(py(p.T_world_camera.translation().y()), 2) << ' ';
    }
    os << "\"/>\n";
    return os.str();
  };
  write_output(path, [&](std::ostream& os) {
    const double w = size + 2 * margin;
    os << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << w << "\" height=\"" << w + 20
       << "\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
       << polyline(gt_span, "black") << polyline(aligned, "red")
       << "<text x=\"10\" y=\"20\" font-family=\"sans-serif\" font-size=\"14\">top view (x, y), "
       << "scale " << fmt(span, 3) << " m per " << size
       << " px: black = ground truth, red = aligned estimate</text>\n"
       << "</svg>\n";
  });
}

int run_eval(const EvalArgs& args) {
  if (!std::isfinite(args.max_difference_s) || args.max_difference_s < 0.0) {
    throw InvalidArgument("--max-difference " + fmt(args.max_difference_s) + ": must be >= 0 s");
  }
  if (!std::isfinite(args.delta_s) || args.delta_s <= 0.0) {
    throw InvalidArgument("--delta " + fmt(args.delta_s) + ": must be > 0 s");
  }
  if (!std::isfinite(args.offset_s)) throw InvalidArgument("--offset must be finite");
  const std::vector<std::string> inputs{args.estimate, args.ground_truth, args.frame_times};
  check_outputs({{"--aligned-out", args.aligned_out}, {"--plot", args.plot}}, inputs);

  Trajectory estimate;
  if (!args.frame_times.empty()) {
    MapReadOptions read_options;
    read_options.min_observations = 0;
    const Map map = read_map(args.estimate, read_options);
    estimate = trajectory_from_map(map, read_frame_times(args.frame_times), args.frame_times);
  } else {
    estimate = read_tum_trajectory(args.estimate);
  }
  const Trajectory gt = read_tum_trajectory(args.ground_truth);

  AteOptions ate_options;
  ate_options.max_difference_s = args.max_difference_s;
  ate_options.offset_s = args.offset_s;
  ate_options.align = !args.no_align;
  const AteResult ate = absolute_trajectory_error(estimate, gt, ate_options);
  RpeOptions rpe_options;
  rpe_options.max_difference_s = args.max_difference_s;
  rpe_options.offset_s = args.offset_s;
  rpe_options.delta_s = args.delta_s;
  rpe_options.delta_tolerance_s = std::min(0.1, 0.5 * args.delta_s);
  const RpeResult rpe = relative_pose_error(estimate, gt, rpe_options);

  human() << "lmalign eval-trajectory: estimate " << args.estimate;
  if (!args.frame_times.empty()) human() << " (map, times from " << args.frame_times << ")";
  human() << " (" << estimate.size() << " poses) vs ground truth " << args.ground_truth << " ("
          << gt.size() << " poses)\n"
          << "associated pairs: " << ate.pairs.size() << " (max difference "
          << args.max_difference_s << " s)\n";
  auto row = [](const std::string& name, const ErrorStats& s, const char* unit, double scale,
                int precision) {
    human() << "  " << name << " rmse " << fmt(s.rmse * scale, precision) << "  mean "
            << fmt(s.mean * scale, precision) << "  median " << fmt(s.median * scale, precision)
            << "  std " << fmt(s.std_dev * scale, precision) << "  max "
            << fmt(s.max * scale, precision) << " " << unit << "\n";
  };
  human() << "ATE (" << (args.no_align ? "no alignment" : "after rigid alignment, no scale") << ", "
          << ate.pairs.size() << " poses):\n";
  row("translation", ate.translation_m, "m", 1.0, 4);
  row("rotation   ", ate.rotation_deg, "deg", 1.0, 3);
  if (!args.no_align) {
    const Quat q(ate.T_gt_est.rotation());
    const double angle = 2.0 * std::atan2(q.vec().norm(), std::abs(q.w())) * 180.0 / M_PI;
    human() << "  alignment T_gt_est: rotation " << fmt(angle, 3) << " deg, translation "
            << fmt(ate.T_gt_est.translation().norm(), 4) << " m\n";
  }
  human() << "RPE (delta " << args.delta_s << " s, " << rpe.translation_m.count << " pairs):\n";
  if (rpe.translation_m.count == 0) {
    human() << "  no pose pair spans " << args.delta_s << " s\n";
  } else {
    row("translation", rpe.translation_m, "m", 1.0, 4);
    row("rotation   ", rpe.rotation_deg, "deg", 1.0, 3);
  }

  Trajectory aligned;
  for (const auto& p : ate.pairs) {
    aligned.push_back({estimate[p.estimate_index].timestamp_s,
                       ate.T_gt_est * estimate[p.estimate_index].T_world_camera});
  }
  if (!args.aligned_out.empty()) {
    write_tum_trajectory(args.aligned_out, aligned);
    human() << "wrote aligned estimate: " << output_name(args.aligned_out) << "\n";
  }
  if (!args.plot.empty()) {
    write_svg_plot(args.plot, gt, aligned);
    human() << "wrote plot: " << output_name(args.plot) << "\n";
  }
  return 0;
}

}  // namespace

CommandRunner add_eval_trajectory_command(CLI::App& root) {
  auto args = std::make_shared<EvalArgs>();
  CLI::App* cmd = root.add_subcommand(
      "eval-trajectory",
      "Absolute trajectory error (RMSE of positions after rigid alignment, Horn/Umeyama, no "
      "scale)\nand relative pose error of an estimate against ground truth, as the TUM RGB-D "
      "benchmark\ndefines them. Both files are TUM trajectories (timestamp tx ty tz qx qy qz qw),"
      "\nor EST is a map file with --frame-times FILE ('frame_id timestamp' per line).");
  cmd->add_option("EST", args->estimate, "Estimated trajectory (TUM format), or a map file")
      ->required();
  cmd->add_option("GT", args->ground_truth, "Ground-truth trajectory (TUM format)")->required();
  cmd->add_option("--frame-times", args->frame_times,
                  "EST is a map: stamp its FRAME poses with these times ('frame_id timestamp')")
      ->type_name("FILE");
  cmd->add_option("--max-difference", args->max_difference_s,
                  "Largest time difference of an associated pose pair, seconds")
      ->capture_default_str()
      ->type_name("S");
  cmd->add_option("--offset", args->offset_s, "Time offset added to the ground truth, seconds")
      ->capture_default_str()
      ->type_name("S");
  cmd->add_option("--delta", args->delta_s, "RPE time step, seconds")
      ->capture_default_str()
      ->type_name("S");
  cmd->add_flag("--no-align", args->no_align,
                "ATE without alignment (both trajectories in the same world frame)");
  cmd->add_option("--plot", args->plot, "Write a top-view SVG plot of both trajectories")
      ->type_name("FILE.svg");
  cmd->add_option("--aligned-out", args->aligned_out,
                  "Write the aligned estimate as a TUM trajectory")
      ->type_name("FILE");
  return [args]() { return run_eval(*args); };
}

}  // namespace lmalign::cli
