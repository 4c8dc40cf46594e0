// COLMAP sparse model reader (text and binary) and text writer
// (include/lmalign/map/formats/colmap.hpp; docs/map-format.md "COLMAP").
#include "lmalign/map/formats/colmap.hpp"

#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>
#include <unordered_map>
#include <unordered_set>

#include "lmalign/core/error.hpp"
#include "lmalign/core/text.hpp"
#include "lmalign/io/output_file.hpp"
#include "text_tokens.hpp"

namespace lmalign {

namespace {

// The text readers every format shares (text_tokens.hpp): Bytes, Lines, TokenReader, quoted.
using namespace formats_detail;  // NOLINT(build/namespaces): a private namespace of formats/
using Fail = std::function<void(const std::string&)>;

constexpr long long kMaxId = std::numeric_limits<std::uint32_t>::max();
constexpr std::uint64_t kInvalidPoint3D = std::numeric_limits<std::uint64_t>::max();

struct Point2D {
  double x = 0.0;
  double y = 0.0;
  long long point3d_id = -1;  // -1: none
};

struct ImageRecord {
  Frame frame;
  std::uint32_t camera_id = 0;
  std::vector<Point2D> points;
  std::string where;  // file:line or file: byte N, for later errors
};

// What the readers collect before the model is assembled.
struct Model {
  std::unordered_map<long long, CameraIntrinsics> cameras;
  std::vector<ImageRecord> images;
  std::unordered_map<long long, std::size_t> image_at;
  Map map;
  std::vector<double> errors_px;
  std::unordered_map<long long, std::string> point_where;
};

/// A token without one trailing ',' (COLMAP text written with ", " separators).
std::string_view strip_comma(std::string_view token) {
  if (token.size() > 1 && token.back() == ',') token.remove_suffix(1);
  return token;
}

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError("cannot open COLMAP file '" + path + "'");
  return formats_detail::slurp(in, path);
}

void add_camera(Model& m, long long id, CameraIntrinsics k, const ColmapReadOptions& options,
                const Fail& fail) {
  if (k.width_px > options.max_image_size_px || k.height_px > options.max_image_size_px) {
    fail("image size " + std::to_string(k.width_px) + "x" + std::to_string(k.height_px) +
         " is larger than " + std::to_string(options.max_image_size_px) + " px");
  }
  std::string why;
  if (!k.is_valid(&why)) fail("camera " + std::to_string(id) + ": " + why);
  if (!m.cameras.emplace(id, std::move(k)).second) {
    fail("duplicate CAMERA_ID " + std::to_string(id));
  }
}

void add_image(Model& m, long long id, const double qt[7], long long camera_id,
               std::vector<Point2D> points, const ColmapReadOptions& options, std::string where,
               const Fail& fail) {
  if (m.cameras.find(camera_id) == m.cameras.end()) {
    fail("image " + std::to_string(id) + " names unknown CAMERA_ID " + std::to_string(camera_id));
  }
  Quat q_camera_world(qt[0], qt[1], qt[2], qt[3]);
  const double norm = q_camera_world.norm();
  if (!(std::abs(norm - 1.0) <= options.quaternion_norm_tolerance)) {
    fail("image " + std::to_string(id) + ": quaternion norm is " + std::to_string(norm) +
         ", expected 1 (QW QX QY QZ, scalar first)");
  }
  q_camera_world.normalize();
  const Vec3 t_camera_world(qt[4], qt[5], qt[6]);
  ImageRecord record;
  record.frame.id = id;
  // COLMAP stores world-to-camera; ours is camera-to-world: q^-1 = conjugate, c = -R^T t.
  record.frame.q_world_camera = q_camera_world.conjugate();
  record.frame.p_world_camera = -(q_camera_world.conjugate() * t_camera_world);
  record.frame.camera = m.cameras.at(camera_id);
  record.camera_id = static_cast<std::uint32_t>(camera_id);
  record.points = std::move(points);
  record.where = std::move(where);
  if (!m.image_at.emplace(id, m.images.size()).second) {
    fail("duplicate IMAGE_ID " + std::to_string(id));
  }
  m.images.push_back(std::move(record));
}

// Adds one track element of the landmark being built; checks the image and the index.
void add_track_element(Model& m, Landmark& landmark, long long image_id, long long idx,
                       const Fail& fail) {
  const auto it = m.image_at.find(image_id);
  if (it == m.image_at.end()) {
    fail("point " + std::to_string(landmark.id) + " names unknown IMAGE_ID " +
         std::to_string(image_id));
  }
  const ImageRecord& image = m.images[it->second];
  if (idx < 0 || static_cast<std::size_t>(idx) >= image.points.size()) {
    fail("point " + std::to_string(landmark.id) + ": POINT2D_IDX " + std::to_string(idx) +
         " is out of range for image " + std::to_string(image_id) + " (" +
         std::to_string(image.points.size()) + " 2-D points)");
  }
  const Point2D& p = image.points[static_cast<std::size_t>(idx)];
  landmark.observations.push_back({image_id, p.x, p.y});
}

void add_point(Model& m, Landmark landmark, double error_px, std::string where, const Fail& fail) {
  if (!m.point_where.emplace(landmark.id, std::move(where)).second) {
    fail("duplicate POINT3D_ID " + std::to_string(landmark.id));
  }
  landmark.covariance_unknown = true;
  m.map.landmarks.push_back(std::move(landmark));
  m.errors_px.push_back(error_px);
}

// Every 2-D point naming a 3-D point must name one that exists.
void check_points2d(const Model& m) {
  for (const ImageRecord& image : m.images) {
    for (const Point2D& p : image.points) {
      if (p.point3d_id >= 0 && m.point_where.find(p.point3d_id) == m.point_where.end()) {
        throw ParseError(image.where, 0,
                         "image " + std::to_string(image.frame.id) +
                             " has a 2-D point of unknown POINT3D_ID " +
                             std::to_string(p.point3d_id));
      }
    }
  }
}

// ---- text -----------------------------------------------------------------------------------

// Calls `record(t, lines, path, fail)` for each record (non-comment line) of text file `i`
// (0 cameras, 1 images, 2 points3D); `fail` throws with the record's file and line.
template <typename Record>
void for_each_record(const ColmapFiles& files, int i, Record&& record) {
  const std::string& path = files.names[i];
  Lines lines(files.contents[i], path);
  std::string_view line;
  while (lines.next_record(line)) {
    TokenReader t(line, path, lines.line());
    t.allow_trailing_comma(true);
    const Fail fail = [&t](const std::string& d) { t.fail(d); };
    record(t, lines, path, fail);
  }
}

void read_text(const ColmapFiles& files, const ColmapReadOptions& options, Model& m) {
  const auto read_camera = [&](TokenReader& t, Lines&, const std::string&, const Fail& fail) {
    const long long id = t.integer("CAMERA_ID", 0, kMaxId);
    const std::string_view model_name = t.next();
    const std::optional<CameraModel> model =
        camera_model_from_name(std::string(strip_comma(model_name)));
    if (!model) {
      t.fail("unknown camera model " + quoted(model_name) + " (known: " + camera_model_list() +
             ")");
    }
    CameraIntrinsics k;
    k.model = *model;
    k.width_px = t.integer("WIDTH", 0, options.max_image_size_px);
    k.height_px = t.integer("HEIGHT", 0, options.max_image_size_px);
    const std::size_t n = camera_model_num_params(*model);
    for (std::size_t i = 0; i < n; ++i) {
      k.params.push_back(t.number(camera_model_name(*model) + " parameter " +
                                  std::to_string(i + 1) + " of " + std::to_string(n)));
    }
    if (!t.at_end())
      t.fail("more than " + std::to_string(n) + " parameters for " + camera_model_name(*model));
    add_camera(m, id, std::move(k), options, fail);
  };
  const auto read_image = [&](TokenReader& t, Lines& lines, const std::string& path,
                              const Fail& fail) {
    const long long id = t.integer("IMAGE_ID", 0, kMaxId);
    double qt[7];
    const char* names[7] = {"QW", "QX", "QY", "QZ", "TX", "TY", "TZ"};
    for (int i = 0; i < 7; ++i) qt[i] = t.number(names[i]);
    const long long camera_id = t.integer("CAMERA_ID", 0, kMaxId);
    if (t.next().empty()) t.fail("file ends where NAME was expected");
    if (!t.at_end()) t.fail("extra field after NAME (image names cannot hold spaces)");
    const std::string where = path + ":" + std::to_string(lines.line());
    std::string_view points_line;
    if (!lines.next_raw(points_line)) {
      t.fail("image " + std::to_string(id) +
             ": file ends where its POINTS2D line was expected (truncated?)");
    }
    TokenReader p(points_line, path, lines.line());
    p.allow_trailing_comma(true);
    std::vector<Point2D> points;
    while (!p.at_end()) {
      const std::string what = "POINTS2D[" + std::to_string(points.size()) + "] ";
      Point2D point;
      point.x = p.number(what + "X");
      point.y = p.number(what + "Y");
      point.point3d_id =
          p.integer(what + "POINT3D_ID (-1 for none)", -1, std::numeric_limits<long long>::max());
      points.push_back(point);
    }
    add_image(m, id, qt, camera_id, std::move(points), options, where, fail);
  };
  const auto read_point = [&](TokenReader& t, Lines& lines, const std::string& path,
                              const Fail& fail) {
    Landmark landmark;
    landmark.id = t.integer("POINT3D_ID", 0, std::numeric_limits<long long>::max());
    landmark.p_world.x() = t.number("X");
    landmark.p_world.y() = t.number("Y");
    landmark.p_world.z() = t.number("Z");
    for (const char* c : {"R", "G", "B"}) t.integer(c, 0, 255);
    const double error_px = t.number("ERROR");
    while (!t.at_end()) {
      const std::string what = "TRACK[" + std::to_string(landmark.observations.size()) + "] ";
      const long long image_id = t.integer(what + "IMAGE_ID", 0, kMaxId);
      const long long idx = t.integer(what + "POINT2D_IDX", 0, kMaxId);
      add_track_element(m, landmark, image_id, idx, fail);
    }
    add_point(m, std::move(landmark), error_px, path + ":" + std::to_string(lines.line()), fail);
  };
  for_each_record(files, 0, read_camera);
  for_each_record(files, 1, read_image);
  for_each_record(files, 2, read_point);
}

// ---- binary ---------------------------------------------------------------------------------

void read_binary(const ColmapFiles& files, const ColmapReadOptions& options, Model& m) {
  {
    const std::string& path = files.names[0];
    Bytes b(files.contents[0], path);
    const std::uint64_t n = b.count("num_cameras", 4 + 4 + 8 + 8 + 3 * 8);
    for (std::uint64_t c = 0; c < n; ++c) {
      const std::size_t at = b.offset();
      const Fail fail = [&b, at](const std::string& d) { b.fail_at(at, d); };
      const auto id = b.read<std::uint32_t>("camera_id");
      const auto model_id = b.read<std::int32_t>("model_id");
      const std::optional<CameraModel> model = camera_model_from_id(model_id);
      if (!model) {
        fail("camera " + std::to_string(id) + ": unknown camera model id " +
             std::to_string(model_id) + " (known: " + camera_model_list() + ")");
      }
      CameraIntrinsics k;
      k.model = *model;
      const auto width = b.read<std::uint64_t>("width");
      const auto height = b.read<std::uint64_t>("height");
      if (width > static_cast<std::uint64_t>(options.max_image_size_px) ||
          height > static_cast<std::uint64_t>(options.max_image_size_px)) {
        fail("camera " + std::to_string(id) + ": image size " + std::to_string(width) + "x" +
             std::to_string(height) + " is larger than " +
             std::to_string(options.max_image_size_px) + " px");
      }
      k.width_px = static_cast<long long>(width);
      k.height_px = static_cast<long long>(height);
      for (std::size_t i = 0; i < camera_model_num_params(*model); ++i) {
        k.params.push_back(b.number("camera parameter " + std::to_string(i)));
      }
      add_camera(m, id, std::move(k), options, fail);
    }
    b.expect_end();
  }
  {
    const std::string& path = files.names[1];
    Bytes b(files.contents[1], path);
    const std::uint64_t n = b.count("num_reg_images", 4 + 7 * 8 + 4 + 1 + 8);
    for (std::uint64_t i = 0; i < n; ++i) {
      const std::size_t at = b.offset();
      const Fail fail = [&b, at](const std::string& d) { b.fail_at(at, d); };
      const auto id = b.read<std::uint32_t>("image_id");
      double qt[7];
      const char* names[7] = {"qw", "qx", "qy", "qz", "tx", "ty", "tz"};
      for (int j = 0; j < 7; ++j) qt[j] = b.number(names[j]);
      const auto camera_id = b.read<std::uint32_t>("camera_id");
      b.name_string("image name");
      const std::uint64_t num_points = b.count("num_points2D", 3 * 8);
      std::vector<Point2D> points(num_points);
      for (Point2D& p : points) {
        p.x = b.number("point2D x");
        p.y = b.number("point2D y");
        const auto id3 = b.read<std::uint64_t>("point3D_id");
        p.point3d_id = id3 == kInvalidPoint3D ? -1 : static_cast<long long>(id3);
        if (p.point3d_id < -1) fail("point3D_id " + std::to_string(id3) + " is out of range");
      }
      add_image(m, id, qt, camera_id, std::move(points), options,
                path + ": byte " + std::to_string(at), fail);
    }
    b.expect_end();
  }
  {
    const std::string& path = files.names[2];
    Bytes b(files.contents[2], path);
    const std::uint64_t n = b.count("num_points3D", 8 + 3 * 8 + 3 + 8 + 8);
    m.map.landmarks.reserve(n);
    for (std::uint64_t i = 0; i < n; ++i) {
      const std::size_t at = b.offset();
      const Fail fail = [&b, at](const std::string& d) { b.fail_at(at, d); };
      Landmark landmark;
      const auto id = b.read<std::uint64_t>("point3D_id");
      if (id > static_cast<std::uint64_t>(std::numeric_limits<long long>::max())) {
        fail("point3D_id " + std::to_string(id) + " is out of range");
      }
      landmark.id = static_cast<Id>(id);
      for (int j = 0; j < 3; ++j) landmark.p_world(j) = b.number("xyz"[j] + std::string(""));
      for (int j = 0; j < 3; ++j) b.read<std::uint8_t>("colour");
      const double error_px = b.number("error");
      const std::uint64_t track = b.count("track_length", 8);
      landmark.observations.reserve(track);
      for (std::uint64_t j = 0; j < track; ++j) {
        const auto image_id = b.read<std::uint32_t>("track image_id");
        const auto idx = b.read<std::uint32_t>("track point2D_idx");
        add_track_element(m, landmark, image_id, idx, fail);
      }
      add_point(m, std::move(landmark), error_px, path + ": byte " + std::to_string(at), fail);
    }
    b.expect_end();
  }
}

}  // namespace

Map read_colmap(const std::string& dir, bool binary, const ColmapReadOptions& options,
                std::vector<double>* mean_reprojection_error_px) {
  ColmapFiles files;
  const char* stems[3] = {"cameras", "images", "points3D"};
  for (int i = 0; i < 3; ++i) {
    files.names[i] =
        (std::filesystem::path(dir) / (std::string(stems[i]) + (binary ? ".bin" : ".txt")))
            .string();
    files.contents[i] = read_file(files.names[i]);
  }
  return read_colmap(files, binary, options, mean_reprojection_error_px);
}

Map read_colmap(const ColmapFiles& files, bool binary, const ColmapReadOptions& options,
                std::vector<double>* mean_reprojection_error_px) {
  Model m;
  if (binary) {
    read_binary(files, options, m);
  } else {
    read_text(files, options, m);
  }
  check_points2d(m);
  m.map.header.scale = MapScale::kArbitrary;  // structure from motion
  for (ImageRecord& image : m.images) m.map.frames.push_back(std::move(image.frame));
  if (mean_reprojection_error_px != nullptr) *mean_reprojection_error_px = std::move(m.errors_px);
  return std::move(m.map);
}

void write_colmap_text(const std::string& dir, const Map& map, const PinholeIntrinsics& fallback) {
  map.validate();
  std::vector<CameraIntrinsics> cameras;
  for (const Frame& frame : map.frames) {
    CameraIntrinsics k;
    if (frame.camera && frame.camera->centred_pixels) {
      throw InvalidArgument("frame " + std::to_string(frame.id) +
                            ": its pixels are relative to the image centre (a Bundler map read "
                            "without an image size); COLMAP stores pixels from the top-left "
                            "corner: give the image size (--image-size W,H)");
    }
    if (frame.camera) {
      k = *frame.camera;
    } else {
      k.model = CameraModel::kPinhole;
      k.params = {fallback.fx_px, fallback.fy_px, fallback.cx_px, fallback.cy_px};
      k.width_px = static_cast<long long>(std::ceil(2.0 * fallback.cx_px));
      k.height_px = static_cast<long long>(std::ceil(2.0 * fallback.cy_px));
    }
    std::string why;
    if (!k.is_valid(&why)) {
      throw InvalidArgument("frame " + std::to_string(frame.id) + ": intrinsics: " + why);
    }
    cameras.push_back(std::move(k));
  }
  // POINT2D index of each observation: per frame, in landmark then observation order.
  std::unordered_map<Id, std::size_t> frame_at;
  for (std::size_t i = 0; i < map.frames.size(); ++i) frame_at.emplace(map.frames[i].id, i);
  std::vector<std::vector<std::pair<const Observation*, Id>>> points2d(map.frames.size());
  std::vector<std::vector<std::pair<std::size_t, std::size_t>>> tracks(map.landmarks.size());
  for (std::size_t l = 0; l < map.landmarks.size(); ++l) {
    for (const Observation& obs : map.landmarks[l].observations) {
      const std::size_t f = frame_at.at(obs.frame_id);
      tracks[l].emplace_back(f, points2d[f].size());
      points2d[f].emplace_back(&obs, map.landmarks[l].id);
    }
  }
  create_output_folder(dir);
  const std::filesystem::path folder(dir);
  write_output((folder / "cameras.txt").string(), [&](std::ostream& out) {
    out << "# Camera list with one line of data per camera:\n"
           "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
           "# Number of cameras: "
        << cameras.size() << "\n";
    for (std::size_t i = 0; i < cameras.size(); ++i) {
      out << map.frames[i].id << ' ' << camera_model_name(cameras[i].model) << ' '
          << cameras[i].width_px << ' ' << cameras[i].height_px;
      for (double p : cameras[i].params) out << ' ' << shortest(p);
      out << '\n';
    }
  });
  write_output((folder / "images.txt").string(), [&](std::ostream& out) {
    out << "# Image list with two lines of data per image:\n"
           "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
           "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
           "# Number of images: "
        << map.frames.size() << "\n";
    for (std::size_t i = 0; i < map.frames.size(); ++i) {
      const Frame& frame = map.frames[i];
      const Quat q_camera_world = frame.q_world_camera.normalized().conjugate();
      const Vec3 t = -(q_camera_world * frame.p_world_camera);
      out << frame.id << ' ' << shortest(q_camera_world.w()) << ' ' << shortest(q_camera_world.x())
          << ' ' << shortest(q_camera_world.y()) << ' ' << shortest(q_camera_world.z()) << ' '
          << shortest(t.x()) << ' ' << shortest(t.y()) << ' ' << shortest(t.z()) << ' ' << frame.id
          << " frame_" << frame.id << "\n";
      bool first = true;
      for (const auto& [obs, landmark_id] : points2d[i]) {
        out << (first ? "" : " ") << shortest(obs->u_px) << ' ' << shortest(obs->v_px) << ' '
            << landmark_id;
        first = false;
      }
      out << '\n';
    }
  });
  write_output((folder / "points3D.txt").string(), [&](std::ostream& out) {
    out << "# 3D point list with one line of data per point:\n"
           "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
           "# Number of points: "
        << map.landmarks.size() << "\n";
    for (std::size_t l = 0; l < map.landmarks.size(); ++l) {
      const Landmark& landmark = map.landmarks[l];
      out << landmark.id << ' ' << shortest(landmark.p_world.x()) << ' '
          << shortest(landmark.p_world.y()) << ' ' << shortest(landmark.p_world.z())
          << " 128 128 128 0";
      for (const auto& [f, idx] : tracks[l]) out << ' ' << map.frames[f].id << ' ' << idx;
      out << '\n';
    }
  });
}

}  // namespace lmalign
