// The merge manifest (include/lmalign/merge/manifest.hpp).
#include "lmalign/merge/manifest.hpp"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>


#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/core/supported_range.hpp"
#include "lmalign/core/symmetric_eigen.hpp"
#include "lmalign/registration/pipeline.hpp"

namespace lmalign {

namespace {

namespace fs = std::filesystem;

std::size_t line_of(const YAML::Node& node) {
  const int line = node.Mark().line;
  return line >= 0 ? static_cast<std::size_t>(line) + 1 : 0;
}

[[noreturn]] void fail(const std::string& file, const YAML::Node& node, const std::string& detail) {
  throw ParseError(file, line_of(node), detail);
}

double number(const std::string& file, const YAML::Node& node, const std::string& field) {
  if (!node.IsScalar()) fail(file, node, field + ": expected a number");
  double v = 0.0;
  try {
    v = node.as<double>();
  } catch (const YAML::Exception&) {
    fail(file, node, field + ": expected a number, got '" + node.Scalar() + "'");
  }
  if (!std::isfinite(v)) fail(file, node, field + ": expected a finite number");
  return v;
}

std::string text(const std::string& file, const YAML::Node& node, const std::string& field) {
  if (!node.IsScalar() || node.Scalar().empty()) {
    fail(file, node, field + ": expected a non-empty string");
  }
  return node.Scalar();
}

// A rows x cols matrix written as a list of rows.
Eigen::MatrixXd matrix(const std::string& file, const YAML::Node& node, const std::string& field,
                       int rows, int cols) {
  const std::string expected = field + ": expected " + std::to_string(rows) + " rows of " +
                               std::to_string(cols) + " numbers";
  if (!node.IsSequence() || static_cast<int>(node.size()) != rows) fail(file, node, expected);
  Eigen::MatrixXd m(rows, cols);
  for (int r = 0; r < rows; ++r) {
    const YAML::Node row = node[r];
    if (!row.IsSequence() || static_cast<int>(row.size()) != cols) fail(file, row, expected);
    for (int c = 0; c < cols; ++c) m(r, c) = number(file, row[c], field);
  }
  return m;
}

// The standard deviations of a prior covariance (rows 0-2 m, 3-5 rad) within the supported
// range, and its smallest eigenvalue at least the smallest variance (a correlation of nearly 1
// is as degenerate as a tiny sigma).
void check_covariance_in_supported_range(const Mat6& C, const std::string& what) {
  for (int i = 0; i < 6; ++i) {
    const bool rotation = i >= 3;
    const double to_unit = rotation ? kRadPerDeg : 1.0;
    check_supported_sigma(
        what + "[" + std::to_string(i) + "][" + std::to_string(i) + "]: standard deviation",
        std::sqrt(C(i, i)), kMinSigma * to_unit,
        (rotation ? kMaxAngleDeg : kMaxCoordinateM) * to_unit, rotation ? "rad" : "m");
  }
  const double smallest = symmetric_eigen(C, false).values.minCoeff();
  const double floor = std::pow(kMinSigma * kRadPerDeg, 2);
  if (!(smallest >= floor)) {
    throw InvalidArgument(
        what + ": smallest eigenvalue " + message_number(smallest) +
        " is below the supported range of a variance (>= " + message_number(floor) + ")");
  }
}

MapPrior parse_prior(const std::string& file, const YAML::Node& entry, const std::string& where) {
  MapPrior prior;
  const YAML::Node tn = entry["T_world_map"];
  const Eigen::MatrixXd T = matrix(file, tn, where + ".T_world_map", 4, 4);
  if ((T.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 0.0) {
    fail(file, tn, where + ".T_world_map: last row must be 0 0 0 1");
  }
  prior.T_world_map.matrix() = T;
  if (!is_rigid_transform(prior.T_world_map)) {
    // A similarity [sR t; 0 1]: the scale of a map without metric scale (pose_graph.hpp).
    const Mat3 A = T.topLeftCorner<3, 3>();
    const double s = std::cbrt(A.determinant());
    if (!std::isfinite(s) || !(s > 0.0)) {
      fail(file, tn,
           where + ".T_world_map: scale (cube root of the 3x3 block's determinant) " +
               message_number(s) + ", expected finite and > 0");
    }
    Isometry3 R_only = Isometry3::Identity();
    R_only.linear() = A / s;
    if (!is_rigid_transform(R_only)) {
      fail(file, tn,
           where +
               ".T_world_map: not a rigid transform (rotation block must be orthonormal to "
               "1e-6 with determinant +1) nor a similarity [sR t; 0 0 0 1]");
    }
    prior.T_world_map.linear() = R_only.linear();
    prior.scale = s;
  }
  // The supported range (core/supported_range.hpp): one line naming the field and the value.
  auto in_range = [&](const YAML::Node& node, auto&& check) {
    try {
      check();
    } catch (const InvalidArgument& e) {
      fail(file, node, e.what());
    }
  };
  in_range(tn, [&] {
    check_supported_translation(where + ".T_world_map", prior.T_world_map.translation());
  });
  const YAML::Node sn = entry["prior_sigma"];
  const YAML::Node cn = entry["prior_covariance"];
  if (sn && cn) fail(file, cn, where + ": give prior_sigma or prior_covariance, not both");
  if (sn) {
    if (!sn.IsSequence() || sn.size() != 2) {
      fail(file, sn, where + ".prior_sigma: expected [rotation_deg, translation_m]");
    }
    const double rot_deg = number(file, sn[0], where + ".prior_sigma[0] (rotation_deg)");
    const double trans_m = number(file, sn[1], where + ".prior_sigma[1] (translation_m)");
    if (rot_deg <= 0.0 || trans_m <= 0.0) {
      fail(file, sn, where + ".prior_sigma: both sigmas must be > 0");
    }
    in_range(sn[0], [&] {
      check_supported_sigma(where + ".prior_sigma[0] (rotation_deg)", rot_deg, kMinSigma,
                            kMaxAngleDeg, "degrees");
    });
    in_range(sn[1], [&] {
      check_supported_sigma(where + ".prior_sigma[1] (translation_m)", trans_m, kMinSigma,
                            kMaxCoordinateM, "m");
    });
    const double r = rot_deg * kRadPerDeg;
    prior.covariance.setZero();
    prior.covariance.diagonal() << trans_m * trans_m, trans_m * trans_m, trans_m * trans_m, r * r,
        r * r, r * r;
  } else if (cn) {
    const Eigen::MatrixXd C = matrix(file, cn, where + ".prior_covariance", 6, 6);
    const double scale = std::max(1e-300, C.cwiseAbs().maxCoeff());
    if ((C - C.transpose()).cwiseAbs().maxCoeff() > 1e-9 * scale) {
      fail(file, cn, where + ".prior_covariance: not symmetric");
    }
    const Mat6 C6 = C;
    const SymmetricEigen<6> eig = symmetric_eigen(C6);
    if (eig.values.minCoeff() <= 0.0) {
      fail(file, cn,
           where + ".prior_covariance: not positive definite (smallest eigenvalue " +
               std::to_string(eig.values.minCoeff()) + ")");
    }
    // Standard deviations within the supported range: rows 0-2 in metres, 3-5 in radians.
    in_range(cn, [&] { check_covariance_in_supported_range(C6, where + ".prior_covariance"); });
    prior.covariance = C;
  } else {
    fail(file, tn, where + ": T_world_map needs prior_sigma or prior_covariance");
  }
  return prior;
}

}  // namespace

void check_prior_in_supported_range(const MapPrior& prior, const std::string& what) {
  check_supported_translation(what + ".T_world_map", prior.T_world_map.translation());
  check_covariance_in_supported_range(prior.covariance, what + ".covariance");
  if (!std::isfinite(prior.scale) || !(prior.scale > 0.0)) {
    throw InvalidArgument(what + ".scale: " + message_number(prior.scale) +
                          ", expected finite and > 0");
  }
}

Manifest parse_manifest(const std::string& yaml_text, const std::string& name,
                        const std::string& base_dir) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::ParserException& e) {
    throw ParseError(name, static_cast<std::size_t>(e.mark.line + 1), "YAML: " + e.msg);
  }
  Manifest manifest;
  manifest.file = name;
  if (!root || root.IsNull()) throw ParseError(name, 0, "empty manifest: expected a 'maps' list");
  if (!root.IsMap()) fail(name, root, "expected a mapping with a 'maps' list");
  for (const auto& kv : root) {
    if (kv.first.Scalar() != "maps") {
      fail(name, kv.first, "unknown key '" + kv.first.Scalar() + "' (expected: maps)");
    }
  }
  const YAML::Node maps = root["maps"];
  if (!maps || maps.IsNull() || (maps.IsSequence() && maps.size() == 0)) {
    throw ParseError(name, maps ? line_of(maps) : 0, "maps: empty manifest (no map listed)");
  }
  if (!maps.IsSequence()) fail(name, maps, "maps: expected a list of maps");
  std::set<std::string> seen;
  static const std::set<std::string> keys{
      "name", "path", "format", "session", "T_world_map", "prior_sigma", "prior_covariance"};
  for (std::size_t i = 0; i < maps.size(); ++i) {
    const YAML::Node e = maps[i];
    const std::string where = "maps[" + std::to_string(i) + "]";
    if (!e.IsMap()) fail(name, e, where + ": expected a mapping with name and path");
    for (const auto& kv : e) {
      if (keys.count(kv.first.Scalar()) == 0) {
        fail(name, kv.first, where + ": unknown key '" + kv.first.Scalar() + "'");
      }
    }
    ManifestEntry entry;
    if (!e["name"]) fail(name, e, where + ".name: missing");
    if (!e["path"]) fail(name, e, where + ".path: missing");
    entry.name = text(name, e["name"], where + ".name");
    if (!seen.insert(entry.name).second) {
      fail(name, e["name"], where + ".name: duplicate map name '" + entry.name + "'");
    }
    const fs::path p = text(name, e["path"], where + ".path");
    entry.path =
        p.is_absolute() ? p.string() : (fs::path(base_dir) / p).lexically_normal().string();
    if (e["format"]) {
      try {
        entry.format = parse_map_format(text(name, e["format"], where + ".format"));
      } catch (const InvalidArgument& ex) {
        fail(name, e["format"], where + ".format: " + ex.what());
      }
    }
    if (e["session"]) entry.session = text(name, e["session"], where + ".session");
    if (e["T_world_map"]) {
      entry.prior = parse_prior(name, e, where);
    } else if (e["prior_sigma"] || e["prior_covariance"]) {
      fail(name, e, where + ": prior_sigma / prior_covariance without T_world_map");
    }
    manifest.maps.push_back(std::move(entry));
  }
  return manifest;
}

Manifest read_manifest(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError("cannot read manifest '" + path + "'");
  std::ostringstream os;
  os << in.rdbuf();
  if (in.bad()) throw IoError("cannot read manifest '" + path + "'");
  const fs::path dir = fs::path(path).parent_path();
  return parse_manifest(os.str(), path, dir.empty() ? "." : dir.string());
}

std::vector<Map> load_manifest_maps(const Manifest& manifest) {
  std::vector<Map> maps;
  maps.reserve(manifest.maps.size());
  for (const ManifestEntry& e : manifest.maps) {
    try {
      AnyMapReadOptions options;
      options.format = e.format;
      maps.push_back(read_any_map(e.path, options));
    } catch (const ParseError& ex) {
      throw ParseError(ex.file(), ex.line(), "map '" + e.name + "': " + ex.detail());
    } catch (const IoError& ex) {
      throw IoError("map '" + e.name + "': " + ex.what());
    } catch (const InvalidArgument& ex) {
      throw InvalidArgument("map '" + e.name + "' (" + e.path + "): " + ex.what());
    }
    if (maps.back().landmarks.empty()) {
      throw InvalidArgument("map '" + e.name + "' (" + e.path + "): no landmark to align");
    }
  }
  return maps;
}

}  // namespace lmalign
