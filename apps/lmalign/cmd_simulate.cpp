// `lmalign simulate`: write a seeded synthetic map pair with its true transform (the simulators
// of include/lmalign/sim/: the indoor corridor of slam_sim.hpp, the outdoor road of road_sim.hpp).
#include <filesystem>
#include <iostream>
#include <sstream>
#include <string>

#include "cli_util.hpp"
#include "commands.hpp"
#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/io/transform_io.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/sim/road_sim.hpp"
#include "lmalign/sim/slam_sim.hpp"

namespace lmalign::cli {

namespace {

struct SimulateArgs {
  std::string scene = "road";
  unsigned long long seed = 1;
  double overlap = 0.0;  // used only when --overlap is given (else the scene's default)
  unsigned long long landmarks = 3000;
  std::string transform = "0,0,0,0,0,0";
  std::string output;
};

std::string to_text(double value) {
  std::ostringstream os;
  os << value;
  return os.str();
}

int run_simulate(const SimulateArgs& a, const CLI::App& cmd) {
  const bool overlap_given = cmd.count("--overlap") > 0;
  const std::vector<double> t = parse_number_list("--transform", a.transform, 6,
                                                  "x,y,z,roll,pitch,yaw (m, m, m, deg, deg, deg)");
  const Isometry3 T_target_source = pose_from_xyz_rpy_deg(t[0], t[1], t[2], t[3], t[4], t[5]);
  if (a.landmarks < 10 || a.landmarks > 10000000ULL) {
    throw InvalidArgument("--landmarks " + std::to_string(a.landmarks) +
                          ": num_landmarks must be in [10, 10000000]");
  }
  sim::SlamMapPair pair;
  if (a.scene == "road") {
    sim::RoadSimOptions o;
    o.num_landmarks = static_cast<std::size_t>(a.landmarks);
    o.seed = a.seed;
    if (overlap_given) o.overlap = a.overlap;
    o.T_target_source = T_target_source;
    std::string why;
    if (!o.is_valid(&why)) {
      if (!(o.overlap >= 0.0 && o.overlap <= 0.5))
        throw InvalidArgument("--overlap " + to_text(a.overlap) + ": must be in [0, 0.5] (road)");
      throw InvalidArgument("--transform " + a.transform + ": " + why);
    }
    pair = sim::simulate_road_pair(o);
  } else if (a.scene == "corridor") {
    sim::SlamSimOptions o;
    o.num_landmarks = static_cast<std::size_t>(a.landmarks);
    o.seed = a.seed;
    if (overlap_given) o.overlap = a.overlap;
    o.T_target_source = T_target_source;
    std::string why;
    if (!o.is_valid(&why)) {
      if (!(o.overlap > 0.0 && o.overlap <= 1.0))
        throw InvalidArgument("--overlap " + to_text(a.overlap) + ": must be in (0, 1] (corridor)");
      throw InvalidArgument("--transform " + a.transform + ": " + why);
    }
    pair = sim::simulate_map_pair(o);
  } else {
    throw InvalidArgument("--scene '" + a.scene + "': expected road or corridor");
  }

  std::error_code ec;
  std::filesystem::create_directories(a.output, ec);
  if (ec) throw IoError("cannot create output folder '" + a.output + "': " + ec.message());
  const std::filesystem::path dir(a.output);
  // Each file is written atomically; the transform last, so its presence marks a complete pair.
  write_map((dir / "source.txt").string(), pair.source);
  write_map((dir / "target.txt").string(), pair.target);
  write_transform((dir / "T_target_source.txt").string(), pair.T_target_source);
  std::cout << "simulated " << a.scene << " pair, seed " << a.seed << ": source "
            << pair.source.landmarks.size() << " landmarks, target " << pair.target.landmarks.size()
            << " landmarks\n  wrote: " << (dir / "source.txt").string() << ", "
            << (dir / "target.txt").string() << ", " << (dir / "T_target_source.txt").string()
            << " (p_target = T_target_source * p_source)\n";
  return 0;
}

}  // namespace

CommandRunner add_simulate_command(CLI::App& root) {
  auto args = std::make_shared<SimulateArgs>();
  CLI::App* cmd = root.add_subcommand(
      "simulate",
      "Write a seeded synthetic map pair and its true transform into a folder:\n"
      "source.txt, target.txt (method.md section 1 format) and T_target_source.txt (4x4).\n"
      "--scene road: a forward-moving KITTI-like stereo camera on a road (facades, a repetitive\n"
      "ground, range-squared depth noise; include/lmalign/sim/road_sim.hpp); consecutive windows,\n"
      "--overlap in [0, 0.5] (default 0.2). --scene corridor: the indoor RGB-D corridor of\n"
      "slam_sim.hpp, --overlap in (0, 1] (default 0.8). Same seed, same files.");
  cmd->add_option("--scene", args->scene, "road or corridor")->capture_default_str();
  cmd->add_option("--seed", args->seed, "seed of every draw")->capture_default_str();
  cmd->add_option("--overlap", args->overlap, "fraction of the source stretch the target also maps")
      ->type_name("F");
  cmd->add_option("--landmarks", args->landmarks, "landmarks per map (>= 10)")
      ->capture_default_str();
  cmd->add_option("--transform", args->transform,
                  "true T_target_source as x,y,z,roll,pitch,yaw (m, deg; R = Rz Ry Rx)")
      ->capture_default_str()
      ->type_name("X,Y,Z,R,P,Y");
  cmd->add_option("-o,--output", args->output, "output folder (created if missing)")
      ->required()
      ->type_name("DIR");
  return [args, cmd]() { return run_simulate(*args, *cmd); };
}

}  // namespace lmalign::cli
