#include "lmalign/registration/global_init.hpp"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>

#include "lmalign/core/error.hpp"
#include "lmalign/core/first_exception.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/registration/score.hpp"

namespace lmalign {

namespace {

// Every `stride`-th point so that about `want` are taken (all if fewer).
Points3 strided_sample(const Points3& points, std::size_t want) {
  if (points.size() <= want) return points;
  Points3 out;
  out.reserve(want);
  for (std::size_t i = 0; i < want; ++i) out.push_back(points[i * points.size() / want]);
  return out;
}

// The best translation for one rotation: the peak of the 3x3x3-summed vote grid.
struct Peak {
  std::size_t votes = 0;
  Vec3 t = Vec3::Zero();
};

Peak vote_translation(const Points3& rotated_source, const Points3& target, double cell_m,
                      std::size_t max_cells, std::vector<std::uint32_t>& grid,
                      std::vector<std::uint32_t>& tmp) {
  Vec3 s_lo = rotated_source[0], s_hi = s_lo, t_lo = target[0], t_hi = t_lo;
  for (const Vec3& p : rotated_source) {
    s_lo = s_lo.cwiseMin(p);
    s_hi = s_hi.cwiseMax(p);
  }
  for (const Vec3& p : target) {
    t_lo = t_lo.cwiseMin(p);
    t_hi = t_hi.cwiseMax(p);
  }
  // Every vote p_t - R p_s lies in [t_lo - s_hi, t_hi - s_lo]; one cell of margin each side
  // for the 3x3x3 sum.
  const Vec3 lo = t_lo - s_hi;
  const Vec3 extent = (t_hi - s_lo) - lo;
  double cell = cell_m;
  std::size_t dims[3];
  for (;;) {
    std::size_t cells = 1;
    for (int d = 0; d < 3; ++d) {
      dims[d] = static_cast<std::size_t>(std::floor(extent[d] / cell)) + 3;
      cells *= dims[d];
    }
    if (cells <= max_cells) break;
    cell *= 1.5;
  }
  const std::size_t nx = dims[0], ny = dims[1], nz = dims[2];
  grid.assign(nx * ny * nz, 0);
  auto at = [&](std::size_t x, std::size_t y, std::size_t z) { return (z * ny + y) * nx + x; };
  const double inv = 1.0 / cell;
  for (const Vec3& s : rotated_source) {
    for (const Vec3& p : target) {
      const Vec3 v = (p - s - lo) * inv;  // in [0, extent / cell] up to rounding
      auto cell_of = [](double c, std::size_t dim) {
        const double f = std::floor(c);
        const double top = static_cast<double>(dim - 3);
        return static_cast<std::size_t>(f < 0.0 ? 0.0 : f > top ? top : f) + 1;
      };
      ++grid[at(cell_of(v[0], nx), cell_of(v[1], ny), cell_of(v[2], nz))];
    }
  }
  // Separable 3-cell box sums along x, y, z.
  tmp.assign(grid.size(), 0);
  for (std::size_t z = 0; z < nz; ++z)
    for (std::size_t y = 0; y < ny; ++y)
      for (std::size_t x = 1; x + 1 < nx; ++x)
        tmp[at(x, y, z)] = grid[at(x - 1, y, z)] + grid[at(x, y, z)] + grid[at(x + 1, y, z)];
  std::fill(grid.begin(), grid.end(), 0);
  for (std::size_t z = 0; z < nz; ++z)
    for (std::size_t y = 1; y + 1 < ny; ++y)
      for (std::size_t x = 0; x < nx; ++x)
        grid[at(x, y, z)] = tmp[at(x, y - 1, z)] + tmp[at(x, y, z)] + tmp[at(x, y + 1, z)];
  Peak best;
  for (std::size_t z = 1; z + 1 < nz; ++z) {
    for (std::size_t y = 0; y < ny; ++y) {
      for (std::size_t x = 0; x < nx; ++x) {
        const std::size_t v = grid[at(x, y, z - 1)] + grid[at(x, y, z)] + grid[at(x, y, z + 1)];
        if (v > best.votes) {  // strict: the first (lowest index) peak wins ties
          best.votes = v;
          best.t = lo + cell * Vec3(static_cast<double>(x) - 0.5, static_cast<double>(y) - 0.5,
                                    static_cast<double>(z) - 0.5);
        }
      }
    }
  }
  return best;
}

}  // namespace

bool GlobalInitOptions::is_valid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why != nullptr) *why = m;
    return false;
  };
  if (!up.allFinite() || !(up.norm() > 0.0)) return fail("up must be a finite non-zero vector");
  if (!(yaw_step_deg > 0.0 && yaw_step_deg <= 90.0)) {
    return fail("yaw_step_deg must be in (0, 90], got " + message_number(yaw_step_deg));
  }
  if (!(vote_cell_m > 0.0) || !std::isfinite(vote_cell_m)) {
    return fail("vote_cell_m must be > 0 and finite, got " + message_number(vote_cell_m));
  }
  if (max_vote_cells < 27) return fail("max_vote_cells must be >= 27");
  if (vote_source_samples < 3 || vote_target_samples < 3) {
    return fail("vote_source_samples and vote_target_samples must be >= 3");
  }
  if (hypotheses < 1) return fail("hypotheses must be >= 1");
  if (refine_schedule_m.empty()) return fail("refine_schedule_m must have at least one stage");
  for (double d : refine_schedule_m) {
    if (!(d > 0.0))
      return fail("refine_schedule_m: every distance must be > 0, got " + message_number(d));
  }
  if (refine_iterations < 1) return fail("refine_iterations must be >= 1");
  if (!(inlier_distance_m > 0.0) || !std::isfinite(inlier_distance_m)) {
    return fail("inlier_distance_m must be > 0 and finite, got " +
                message_number(inlier_distance_m));
  }
  return true;
}

GlobalInitResult global_align(const Points3& source_points, const PreparedTarget& target,
                              const GlobalInitOptions& options) {
  const auto t_start = std::chrono::steady_clock::now();
  std::string why;
  if (!options.is_valid(&why)) throw InvalidArgument("global initialisation options: " + why);
  if (source_points.size() < 3) {
    throw InvalidArgument("global initialisation: the source has fewer than 3 points");
  }
  if (target.size() < 3) {
    throw InvalidArgument("global initialisation: the target has fewer than 3 points");
  }
  for (std::size_t i = 0; i < source_points.size(); ++i) {
    if (!source_points[i].allFinite()) {
      throw InvalidArgument("global initialisation: source point " + std::to_string(i) +
                            " is not finite");
    }
  }
  const Vec3 up = options.up.normalized();
  const Points3 src = strided_sample(source_points, options.vote_source_samples);
  // (Defaults: 128 x 1024 votes per yaw, 36 yaws: about 0.1 s on 2 cores; the refinement of 4
  // hypotheses dominates. docs/accuracy.md gives the basin figures.)
  const Points3 tgt = strided_sample(target.points(), options.vote_target_samples);

  // 1-2. Vote for the translation at every yaw (one grid per thread; one slot per yaw).
  const int n_yaw = static_cast<int>(std::ceil(360.0 / options.yaw_step_deg - 1e-9));
  std::vector<GlobalHypothesis> all(static_cast<std::size_t>(n_yaw));
  // An exception may not leave the region nor skip its worksharing loop: the allocation and the
  // iterations are captured one by one.
  FirstException error;
#pragma omp parallel proc_bind(close)
  {
    std::vector<std::uint32_t> grid, tmp;
    Points3 rotated;
    bool ready = false;
    error.capture([&] {
      rotated.resize(src.size());
      ready = true;
    });
#pragma omp for schedule(dynamic, 1)
    for (int i = 0; i < n_yaw; ++i) {
      if (!ready) continue;
      error.capture([&] {
        const double yaw_deg = -180.0 + options.yaw_step_deg * i;
        const Mat3 R = Eigen::AngleAxisd(yaw_deg * kPi / 180.0, up).toRotationMatrix();
        for (std::size_t j = 0; j < src.size(); ++j) rotated[j] = R * src[j];
        const Peak peak =
            vote_translation(rotated, tgt, options.vote_cell_m, options.max_vote_cells, grid, tmp);
        GlobalHypothesis& h = all[static_cast<std::size_t>(i)];
        h.yaw_deg = yaw_deg;
        h.votes = peak.votes;
        h.T_coarse.linear() = R;
        h.T_coarse.translation() = peak.t;
      });
    }
  }
  error.rethrow();

  // 3. Refine the yaws whose votes are a local maximum over yaw (circularly), best first.
  std::vector<std::size_t> order;
  for (int i = 0; i < n_yaw; ++i) {
    const std::size_t v = all[static_cast<std::size_t>(i)].votes;
    const std::size_t prev = all[static_cast<std::size_t>((i + n_yaw - 1) % n_yaw)].votes;
    const std::size_t next = all[static_cast<std::size_t>((i + 1) % n_yaw)].votes;
    if (v >= prev && v >= next) order.push_back(static_cast<std::size_t>(i));
  }
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return all[a].votes > all[b].votes; });
  if (order.size() > options.hypotheses) order.resize(options.hypotheses);

  RegistrationOptions ro;  // nearest neighbour, PCL convergence, finite distance per stage
  ro.correspondence = CorrespondenceKind::kNearest;
  ro.convergence.max_iterations = options.refine_iterations;
  const std::size_t n = source_points.size();
  // One hypothesis per thread (each ICP then runs single-threaded inside: fewer barriers than
  // one parallel loop per ICP iteration). Each writes its own slot: deterministic.
  // Each thread sets the distance of its own copy of the options.
#pragma omp parallel for schedule(dynamic, 1)
  for (std::ptrdiff_t oi = 0; oi < static_cast<std::ptrdiff_t>(order.size()); ++oi) {
    error.capture([&] {
      GlobalHypothesis& h = all[order[static_cast<std::size_t>(oi)]];
      RegistrationOptions stage = ro;
      Isometry3 T = h.T_coarse;
      for (double d : options.refine_schedule_m) {
        stage.max_correspondence_distance_m = d;
        const RegistrationResult r = align(source_points, target, stage, T);
        if (r.termination != TerminationReason::kNoCorrespondences) T = r.T_target_source;
      }
      const FitnessScore s =
          fitness_score(source_points, target.tree(), T, options.inlier_distance_m);
      h.refined = true;
      h.T_refined = T;
      h.inlier_fraction = static_cast<double>(s.num_scored) / static_cast<double>(n);
      h.inlier_rms_m = s.num_scored > 0 ? std::sqrt(s.mean_sq_m2) : 0.0;
    });
  }
  error.rethrow();

  // 4. The refined hypothesis with the most inliers (ties: the smaller RMS, then more votes).
  GlobalInitResult result;
  const GlobalHypothesis* best = nullptr;
  for (std::size_t i : order) {
    const GlobalHypothesis& h = all[i];
    if (best == nullptr || h.inlier_fraction > best->inlier_fraction ||
        (h.inlier_fraction == best->inlier_fraction && h.inlier_rms_m < best->inlier_rms_m)) {
      best = &h;
    }
  }
  result.T_target_source = best->T_refined;
  result.inlier_fraction = best->inlier_fraction;
  result.inlier_rms_m = best->inlier_rms_m;
  std::stable_sort(
      all.begin(), all.end(),
      [](const GlobalHypothesis& a, const GlobalHypothesis& b) { return a.votes > b.votes; });
  result.hypotheses = std::move(all);
  result.wall_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return result;
}

}  // namespace lmalign
