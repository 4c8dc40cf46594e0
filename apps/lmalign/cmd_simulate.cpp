// `lmalign simulate`: write a seeded synthetic map pair with its true transform (the simulators
// of include/lmalign/sim/: the indoor corridor of slam_sim.hpp, the outdoor road of road_sim.hpp).
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <string>

#include "cli_util.hpp"
#include "commands.hpp"
#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/io/output_file.hpp"
#include "lmalign/io/transform_io.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/sim/fleet_sim.hpp"
#include "lmalign/sim/road_sim.hpp"
#include "lmalign/sim/slam_sim.hpp"
#include "lmalign/sim/street_sim.hpp"

namespace lmalign::cli {

namespace {

struct SimulateArgs {
  std::string scene = "road";
  unsigned long long seed = 1;
  double overlap = 0.0;  // used only when --overlap is given (else the scene's default)
  unsigned long long landmarks = 3000;
  std::string transform = "0,0,0,0,0,0";
  std::string output;
  unsigned long long maps = 50;
  unsigned long long twins = 2;
  std::string prior_sigma = "3,0.5";
  unsigned long long frames = 30;  // street: keyframes per window
  unsigned long long windows = 0;  // street: 0 = a pair; else that many windows + a manifest
  std::string views = "ring";      // fleet: the keyframes' layout (FleetViews)
};

std::string to_text(double value) {
  std::ostringstream os;
  os << value;
  return os.str();
}

// A matrix as YAML flow rows, doubles to round-trip precision.
template <typename Matrix>
std::string yaml_rows(const Matrix& M) {
  std::string s = "[";
  char buf[64];
  for (int r = 0; r < M.rows(); ++r) {
    s += r ? ", [" : "[";
    for (int c = 0; c < M.cols(); ++c) {
      std::snprintf(buf, sizeof(buf), "%s%.17g", c ? ", " : "", M(r, c));
      s += buf;
    }
    s += "]";
  }
  return s + "]";
}

// --scene fleet: N mini-maps of one world (fleet_sim.hpp) with a manifest and the truth.
int run_simulate_fleet(const SimulateArgs& a) {
  sim::FleetSimOptions o;
  o.num_maps = static_cast<std::size_t>(a.maps);
  o.seed = a.seed;
  o.num_twins = static_cast<std::size_t>(a.twins);
  if (a.maps < 2 || a.maps > 100000ULL) {
    throw InvalidArgument("--maps " + std::to_string(a.maps) + ": must be in [2, 100000]");
  }
  if (a.twins > 1000ULL) throw InvalidArgument("--twins: must be <= 1000");
  if (a.views != "ring" && a.views != "roaming") {
    throw InvalidArgument("--views " + a.views + ": expected 'ring' or 'roaming'");
  }
  o.views = a.views == "roaming" ? sim::FleetViews::kRoaming : sim::FleetViews::kRing;
  if (a.prior_sigma != "none") {
    const std::vector<double> ps =
        parse_number_list("--prior-sigma", a.prior_sigma, 2, "ROT_DEG,TRANS_M, e.g. 3,0.5");
    if (!(ps[0] > 0.0 && ps[1] > 0.0)) {
      throw InvalidArgument("--prior-sigma " + a.prior_sigma + ": both sigmas must be > 0");
    }
    o.prior_sigma_deg = ps[0];
    o.prior_sigma_m = ps[1];
  }
  const sim::FleetScene scene = sim::simulate_fleet(o);
  const std::filesystem::path dir(a.output);
  create_output_folder((dir / "maps").string());
  const bool priors = !scene.prior_T_world_map.empty();
  for (std::size_t i = 0; i < scene.maps.size(); ++i) {
    write_map((dir / "maps" / (scene.names[i] + ".txt")).string(), scene.maps[i]);
  }
  write_output((dir / "ground_truth.yaml").string(), [&](std::ostream& os) {
    os << "# lmalign simulate --scene fleet --seed " << a.seed << ": true T_world_map (m)\nmaps:\n";
    for (std::size_t i = 0; i < scene.maps.size(); ++i) {
      os << "  " << scene.names[i] << ": " << yaml_rows(scene.T_world_map[i].matrix()) << "\n";
    }
  });
  write_output((dir / "overlaps.csv").string(), [&](std::ostream& os) {
    os << "source,target,kind,shared_fraction\n";
    for (const sim::FleetOverlap& v : scene.overlaps) {
      os << scene.names[v.i] << "," << scene.names[v.j] << ",overlap," << v.shared_fraction << "\n";
    }
    for (const auto& t : scene.twins) {
      os << scene.names[t.first] << "," << scene.names[t.second] << ",twin,0\n";
    }
  });
  // The manifest last: its presence marks a complete scene.
  write_output((dir / "manifest.yaml").string(), [&](std::ostream& os) {
    os << "# lmalign simulate --scene fleet --maps " << a.maps << " --seed " << a.seed
       << (a.views == "ring" ? "" : " --views " + a.views) << " (docs/merge.md)\nmaps:\n";
    for (std::size_t i = 0; i < scene.maps.size(); ++i) {
      os << "  - name: " << scene.names[i] << "\n    path: maps/" << scene.names[i] << ".txt\n";
      if (priors) {
        os << "    T_world_map: " << yaml_rows(scene.prior_T_world_map[i].matrix())
           << "\n    prior_covariance: " << yaml_rows(scene.prior_covariance[i]) << "\n";
      }
    }
  });
  std::size_t landmarks = 0;
  for (const Map& m : scene.maps) landmarks += m.landmarks.size();
  human() << "simulated fleet, seed " << a.seed << ": " << scene.maps.size() << " maps ("
          << landmarks / scene.maps.size() << " landmarks on average), " << scene.overlaps.size()
          << " truly overlapping pairs, " << scene.twins.size() << " planted look-alike pairs"
          << (priors ? ", noisy priors" : ", no priors")
          << "\n  wrote: " << (dir / "manifest.yaml").string() << ", "
          << (dir / "ground_truth.yaml").string() << ", " << (dir / "overlaps.csv").string() << ", "
          << (dir / "maps").string() << "/\n";
  return 0;
}

// The road's or the corridor's options from the command line (landmarks, seed, the overlap when
// given, the true transform); one-line errors naming the option: --overlap when `overlap_ok`
// refuses it (`overlap_range` says what it takes), else --transform.
template <typename Options, typename OverlapOk>
Options pair_options(const SimulateArgs& a, bool overlap_given, const Isometry3& T_target_source,
                     const OverlapOk& overlap_ok, const char* overlap_range) {
  Options o;
  o.num_landmarks = static_cast<std::size_t>(a.landmarks);
  o.seed = a.seed;
  if (overlap_given) o.overlap = a.overlap;
  o.T_target_source = T_target_source;
  std::string why;
  if (!o.is_valid(&why)) {
    if (!overlap_ok(o.overlap)) {
      throw InvalidArgument("--overlap " + to_text(a.overlap) + ": must be in " + overlap_range);
    }
    throw InvalidArgument("--transform " + a.transform + ": " + why);
  }
  return o;
}

// The street simulator's options from the command line; one-line errors naming the option.
sim::StreetSimOptions street_options(const SimulateArgs& a, bool overlap_given,
                                     const Isometry3& T_target_source) {
  sim::StreetSimOptions o;
  o.num_landmarks = static_cast<std::size_t>(a.landmarks);
  o.seed = a.seed;
  if (overlap_given) o.overlap = a.overlap;
  if (a.frames < 2 || a.frames > 100000ULL) {
    throw InvalidArgument("--frames " + std::to_string(a.frames) + ": must be in [2, 100000]");
  }
  o.window_frames = static_cast<std::size_t>(a.frames);
  o.T_target_source = T_target_source;
  std::string why;
  if (!o.is_valid(&why)) {
    if (!(o.overlap >= 0.0 && o.overlap <= 0.75))
      throw InvalidArgument("--overlap " + to_text(a.overlap) + ": must be in [0, 0.75] (street)");
    if (o.num_landmarks > 1000000)
      throw InvalidArgument("--landmarks " + std::to_string(a.landmarks) +
                            ": must be <= 1000000 (street)");
    throw InvalidArgument("--transform " + a.transform + ": " + why);
  }
  return o;
}

// --scene street --windows N: N windows of one drive, each in its own first keyframe's frame,
// with a manifest (no priors) and the truth, for lmalign merge.
int run_simulate_street_windows(const SimulateArgs& a, bool overlap_given) {
  if (a.windows < 2 || a.windows > 10000ULL) {
    throw InvalidArgument("--windows " + std::to_string(a.windows) + ": must be in [2, 10000]");
  }
  const sim::StreetSimOptions o = street_options(a, overlap_given, Isometry3::Identity());
  const sim::StreetWindows w = sim::simulate_street_windows(o, static_cast<std::size_t>(a.windows));
  const std::filesystem::path dir(a.output);
  create_output_folder((dir / "maps").string());
  std::vector<std::string> names;
  for (std::size_t i = 0; i < w.maps.size(); ++i) {
    names.push_back("w" + std::to_string(i));
    write_map((dir / "maps" / (names[i] + ".txt")).string(), w.maps[i]);
  }
  write_output((dir / "ground_truth.yaml").string(), [&](std::ostream& os) {
    os << "# lmalign simulate --scene street --windows " << a.windows << " --seed " << a.seed
       << ": true T_world_map (m)\nmaps:\n";
    for (std::size_t i = 0; i < w.maps.size(); ++i) {
      os << "  " << names[i] << ": " << yaml_rows(w.T_world_map[i].matrix()) << "\n";
    }
  });
  // The manifest last: its presence marks a complete scene.
  write_output((dir / "manifest.yaml").string(), [&](std::ostream& os) {
    os << "# lmalign simulate --scene street --windows " << a.windows << " --seed " << a.seed
       << " (docs/merge.md): no priors\nmaps:\n";
    for (const std::string& n : names)
      os << "  - name: " << n << "\n    path: maps/" << n << ".txt\n";
  });
  human() << "simulated street, seed " << a.seed << ": " << w.maps.size() << " windows of "
          << o.window_frames << " keyframes (" << std::llround(o.overlap * o.window_frames)
          << " shared with the next), " << o.num_landmarks
          << " landmarks each\n  wrote: " << (dir / "manifest.yaml").string() << ", "
          << (dir / "ground_truth.yaml").string() << ", " << (dir / "maps").string() << "/\n";
  return 0;
}

int run_simulate(const SimulateArgs& a, const CLI::App& cmd) {
  refuse_standard_output_folder("--out", a.output);
  if (a.scene == "fleet") return run_simulate_fleet(a);
  const bool overlap_given = cmd.count("--overlap") > 0;
  if (a.scene != "street" && (cmd.count("--windows") > 0 || cmd.count("--frames") > 0)) {
    throw InvalidArgument("--windows and --frames only apply to --scene street");
  }
  if (a.scene == "street" && cmd.count("--windows") > 0) {
    return run_simulate_street_windows(a, overlap_given);
  }
  const std::vector<double> t = parse_number_list("--transform", a.transform, 6,
                                                  "x,y,z,roll,pitch,yaw (m, m, m, deg, deg, deg)");
  const Isometry3 T_target_source = pose_from_xyz_rpy_deg(t[0], t[1], t[2], t[3], t[4], t[5]);
  if (a.landmarks < 10 || a.landmarks > 10000000ULL) {
    throw InvalidArgument("--landmarks " + std::to_string(a.landmarks) +
                          ": num_landmarks must be in [10, 10000000]");
  }
  sim::SlamMapPair pair;
  if (a.scene == "road") {
    const auto overlap_ok = [](double f) { return f >= 0.0 && f <= 0.5; };
    pair = sim::simulate_road_pair(pair_options<sim::RoadSimOptions>(
        a, overlap_given, T_target_source, overlap_ok, "[0, 0.5] (road)"));
  } else if (a.scene == "corridor") {
    const auto overlap_ok = [](double f) { return f > 0.0 && f <= 1.0; };
    pair = sim::simulate_map_pair(pair_options<sim::SlamSimOptions>(
        a, overlap_given, T_target_source, overlap_ok, "(0, 1] (corridor)"));
  } else if (a.scene == "street") {
    pair = sim::simulate_street_pair(street_options(a, overlap_given, T_target_source));
  } else {
    throw InvalidArgument("--scene '" + a.scene + "': expected road, street, corridor or fleet");
  }

  create_output_folder(a.output);
  const std::filesystem::path dir(a.output);
  // Each file is written atomically; the transform last, so its presence marks a complete pair.
  write_map((dir / "source.txt").string(), pair.source);
  write_map((dir / "target.txt").string(), pair.target);
  write_transform((dir / "T_target_source.txt").string(), pair.T_target_source);
  human() << "simulated " << a.scene << " pair, seed " << a.seed << ": source "
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
      "--overlap in [0, 0.5] (default 0.2): periodic facades and ground, the aliasing case.\n"
      "--scene street: aperiodic streets (buildings of random widths and setbacks, trees, poles,\n"
      "parked cars, gaps, curves and turns; street_sim.hpp) seen by a KITTI-like stereo rig,\n"
      "windows of --frames keyframes about 1 m apart sharing --overlap of them (default 0.25,\n"
      "at most 0.75); --windows N writes N windows for lmalign merge instead of a pair\n"
      "(DIR/maps/w*.txt, DIR/manifest.yaml without priors, DIR/ground_truth.yaml).\n"
      "--scene corridor: the indoor RGB-D corridor of slam_sim.hpp, --overlap in (0, 1]\n"
      "(default 0.8). --scene fleet: --maps N mini-maps of one\n"
      "world (fleet_sim.hpp) in random frames, with look-alike pairs planted (--twins), written\n"
      "as DIR/maps/*.txt, DIR/manifest.yaml (for lmalign merge; --prior-sigma adds noisy priors),\n"
      "DIR/ground_truth.yaml (merge --ground-truth) and DIR/overlaps.csv. Same seed, same files.");
  cmd->add_option("--scene", args->scene, "road, street, corridor or fleet")->capture_default_str();
  cmd->add_option("--seed", args->seed, "seed of every draw")->capture_default_str();
  cmd->add_option("--overlap", args->overlap, "fraction of the source stretch the target also maps")
      ->type_name("F");
  cmd->add_option("--landmarks", args->landmarks, "landmarks per map (>= 10)")
      ->capture_default_str();
  cmd->add_option("--transform", args->transform,
                  "true T_target_source as x,y,z,roll,pitch,yaw (m, deg; R = Rz Ry Rx)")
      ->capture_default_str()
      ->type_name("X,Y,Z,R,P,Y");
  cmd->add_option("--frames", args->frames, "street: keyframes per window (about 1 m apart)")
      ->capture_default_str();
  cmd->add_option("--windows", args->windows,
                  "street: write this many consecutive windows with a manifest (>= 2) instead of "
                  "a pair")
      ->type_name("N");
  cmd->add_option("--maps", args->maps, "fleet: number of mini-maps")->capture_default_str();
  cmd->add_option("--twins", args->twins, "fleet: look-alike map pairs planted")
      ->capture_default_str();
  cmd->add_option("--views", args->views,
                  "fleet: 'ring' (8 keyframes on a ring about each map's centre, looking out; a "
                  "box's wall is seen from behind too) or 'roaming' (24 keyframes anywhere within "
                  "0.7 map radii, any heading; surfaces seen from the front only)")
      ->capture_default_str()
      ->type_name("ring|roaming");
  cmd->add_option(
         "--prior-sigma", args->prior_sigma,
         "fleet: noisy priors in the manifest (GPS-like), ROT_DEG,TRANS_M, or 'none' (global "
         "alignment and the candidate pre-filter)")
      ->capture_default_str()
      ->type_name("ROT_DEG,TRANS_M|none");
  cmd->add_option("-o,--output,--out", args->output, "output folder (created if missing)")
      ->required()
      ->type_name("DIR");
  return [args, cmd]() { return run_simulate(*args, *cmd); };
}

}  // namespace lmalign::cli
