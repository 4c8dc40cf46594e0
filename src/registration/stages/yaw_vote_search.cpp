#include "lmalign/registration/stages/yaw_vote_search.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>

#include "lmalign/core/error.hpp"
#include "lmalign/core/first_exception.hpp"
#include "lmalign/core/geometry.hpp"

namespace lmalign {

namespace {

constexpr std::int64_t kCellLimit = std::int64_t{1} << 20;  // 21 bits per axis in a key
constexpr std::uint64_t kEmpty = ~std::uint64_t{0};

Points3 strided(const Points3& points, std::size_t want) {
  if (points.size() <= want) return points;
  Points3 out;
  out.reserve(want);
  for (std::size_t i = 0; i < want; ++i) out.push_back(points[i * points.size() / want]);
  return out;
}

// The coordinate-wise median of `points` (not empty): a centre that one far landmark cannot move.
Vec3 median_point(const Points3& points) {
  Vec3 out;
  std::vector<double> v(points.size());
  for (int d = 0; d < 3; ++d) {
    for (std::size_t i = 0; i < points.size(); ++i) v[i] = points[i][d];
    const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    out[d] = *mid;
  }
  return out;
}

// std::floor(v) as an integer, when it lies strictly between -limit and limit (an integer below
// 2^52); else false. Exact: the truncation of v, one less when that is above v. Inline because the
// votes below take three floors each, and the library's floor is a call.
inline bool floor_within(double v, double limit, std::int64_t* out) {
  if (!(v < limit && v >= 1.0 - limit)) return false;
  const auto i = static_cast<std::int64_t>(v);
  *out = i - static_cast<std::int64_t>(static_cast<double>(i) > v);
  return true;
}

std::uint64_t pack(std::int64_t x, std::int64_t y, std::int64_t z) {
  return (static_cast<std::uint64_t>(x + kCellLimit) << 42) |
         (static_cast<std::uint64_t>(y + kCellLimit) << 21) |
         static_cast<std::uint64_t>(z + kCellLimit);
}

// Sparse vote counts over packed cell keys: open addressing, linear probing, sized for the
// number of votes; cells are listed in slot order.
class HashCounts {
 public:
  void reset(std::size_t max_votes) {
    std::size_t size = 64;
    while (size < 2 * max_votes) size <<= 1;
    keys_.assign(size, kEmpty);
    counts_.assign(size, 0);
    mask_ = size - 1;
  }
  void add(std::uint64_t key) {
    std::size_t i = hash(key);
    while (keys_[i] != kEmpty && keys_[i] != key) i = (i + 1) & mask_;
    keys_[i] = key;
    ++counts_[i];
  }
  std::uint32_t count(std::uint64_t key) const {
    std::size_t i = hash(key);
    while (keys_[i] != kEmpty) {
      if (keys_[i] == key) return counts_[i];
      i = (i + 1) & mask_;
    }
    return 0;
  }
  /// visit(count, key) for every cell with votes.
  template <typename Visit>
  void for_each_cell(Visit&& visit) const {
    for (std::size_t i = 0; i < keys_.size(); ++i) {
      if (keys_[i] != kEmpty) visit(counts_[i], keys_[i]);
    }
  }

 private:
  std::size_t hash(std::uint64_t key) const {
    return static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> 20) & mask_;
  }
  std::vector<std::uint64_t> keys_;
  std::vector<std::uint32_t> counts_;
  std::size_t mask_ = 0;
};

// The vote grid over horizontal cells (a, b). Dense over the box of cells the votes can reach
// when that box is no larger than the hash table would be (the usual case: the translations
// between two maps span a few hundred cells per axis), else sparse: open addressing, linear
// probing, sized for the number of votes. Both modes list their cells with the same keys, so the
// peak (ties broken by key) is the same whichever is used.
class VoteGrid {
 public:
  void reset(std::size_t max_votes, std::int64_t a_min, std::int64_t a_max, std::int64_t b_min,
             std::int64_t b_max) {
    std::size_t size = 64;
    while (size < 2 * max_votes) size <<= 1;
    const double na = static_cast<double>(a_max - a_min + 1);
    const double nb = static_cast<double>(b_max - b_min + 1);
    dense_ = na >= 1.0 && nb >= 1.0 && na * nb <= static_cast<double>(size);
    if (dense_) {
      a0_ = a_min;
      b0_ = b_min;
      na_ = static_cast<std::int64_t>(na);
      nb_ = static_cast<std::int64_t>(nb);
      dense_counts_.assign(static_cast<std::size_t>(na_ * nb_), 0);
    } else {
      sparse_.reset(max_votes);
    }
  }
  void add(std::int64_t a, std::int64_t b) {
    if (dense_) {
      ++dense_counts_[static_cast<std::size_t>((a - a0_) * nb_ + (b - b0_))];
    } else {
      sparse_.add(pack(a, b, 0));
    }
  }
  std::uint32_t count(std::int64_t a, std::int64_t b) const {
    if (!dense_) return sparse_.count(pack(a, b, 0));
    if (a < a0_ || b < b0_ || a >= a0_ + na_ || b >= b0_ + nb_) return 0;
    return dense_counts_[static_cast<std::size_t>((a - a0_) * nb_ + (b - b0_))];
  }
  /// visit(count, key) for every cell with votes.
  template <typename Visit>
  void for_each_cell(Visit&& visit) const {
    if (!dense_) {
      sparse_.for_each_cell(visit);
      return;
    }
    for (std::int64_t i = 0; i < na_; ++i) {
      for (std::int64_t j = 0; j < nb_; ++j) {
        const std::uint32_t c = dense_counts_[static_cast<std::size_t>(i * nb_ + j)];
        if (c != 0) visit(c, pack(a0_ + i, b0_ + j, 0));
      }
    }
  }

 private:
  bool dense_ = false;
  std::int64_t a0_ = 0, b0_ = 0, na_ = 0, nb_ = 0;
  std::vector<std::uint32_t> dense_counts_;
  HashCounts sparse_;
};

// The 3-D vote grid over cells (a, b, c): dense over the box of cells the votes can reach when
// it has at most kDenseLimit cells, else sparse. Both list the same cells with the same counts;
// peaks are found by count, then key.
class VoteGrid3 {
 public:
  void reset(std::size_t max_votes, const std::int64_t* lo, const std::int64_t* hi) {
    double cells = 1.0;
    for (int k = 0; k < 3; ++k)
      cells *= static_cast<double>(std::max<std::int64_t>(0, hi[k] - lo[k] + 1));
    // Only the cells the last vote touched are cleared.
    for (std::size_t t = 0; t < touched_count_; ++t) dense_counts_[touched_[t]] = 0;
    touched_count_ = 0;
    dense_ = cells >= 1.0 && cells <= kDenseLimit;
    if (!dense_) {
      sparse_.reset(max_votes);
      return;
    }
    for (int k = 0; k < 3; ++k) {
      lo_[k] = lo[k];
      n_[k] = hi[k] - lo[k] + 1;
    }
    if (dense_counts_.size() < static_cast<std::size_t>(cells)) {
      dense_counts_.resize(static_cast<std::size_t>(cells), 0);
    }
    // At most one entry per distinct cell, and one spare: add() writes before it counts.
    const std::size_t most = std::min(max_votes, static_cast<std::size_t>(cells)) + 1;
    if (touched_.size() < most) touched_.resize(most);
  }
  void add(std::int64_t a, std::int64_t b, std::int64_t c) {
    if (!dense_) {
      sparse_.add(pack(a, b, c));
      return;
    }
    const std::int64_t i = a - lo_[0], j = b - lo_[1], k = c - lo_[2];
    if (i < 0 || j < 0 || k < 0 || i >= n_[0] || j >= n_[1] || k >= n_[2]) return;
    const auto idx = static_cast<std::uint32_t>((i * n_[1] + j) * n_[2] + k);
    // Without a branch: a cell's first vote keeps the entry written here, later ones overwrite it.
    touched_[touched_count_] = idx;
    touched_count_ += static_cast<std::size_t>(dense_counts_[idx]++ == 0);
  }
  std::uint32_t count(std::int64_t a, std::int64_t b, std::int64_t c) const {
    if (!dense_) return sparse_.count(pack(a, b, c));
    const std::int64_t i = a - lo_[0], j = b - lo_[1], k = c - lo_[2];
    if (i < 0 || j < 0 || k < 0 || i >= n_[0] || j >= n_[1] || k >= n_[2]) return 0;
    return dense_counts_[static_cast<std::size_t>((i * n_[1] + j) * n_[2] + k)];
  }
  /// The `keep` cells with the most votes (fewer if fewer have votes) as (count, key), by
  /// decreasing count, equal counts by increasing key.
  std::vector<std::pair<std::uint32_t, std::uint64_t>> top(std::size_t keep) const {
    std::vector<std::pair<std::uint32_t, std::uint64_t>> out;
    if (!dense_) {
      sparse_.for_each_cell([&](std::uint32_t n, std::uint64_t key) { out.emplace_back(n, key); });
      keep = std::min(keep, out.size());
      std::partial_sort(out.begin(), out.begin() + static_cast<std::ptrdiff_t>(keep), out.end(),
                        [](const auto& l, const auto& r) {
                          return l.first != r.first ? l.first > r.first : l.second < r.second;
                        });
      out.resize(keep);
      return out;
    }
    // The dense index orders cells as their keys do (both are lexicographic in (a, b, c)), so
    // one integer, the count above the complemented index, sorts them: larger is better.
    std::vector<std::uint64_t> ranked(touched_count_);
    for (std::size_t t = 0; t < touched_count_; ++t) {
      const std::uint32_t idx = touched_[t];
      ranked[t] = (std::uint64_t{dense_counts_[idx]} << 32) | std::uint64_t{~idx};
    }
    keep = std::min(keep, ranked.size());
    std::partial_sort(ranked.begin(), ranked.begin() + static_cast<std::ptrdiff_t>(keep),
                      ranked.end(), std::greater<>());
    for (std::size_t t = 0; t < keep; ++t) {
      const auto idx = static_cast<std::int64_t>(~static_cast<std::uint32_t>(ranked[t]));
      const std::int64_t k = idx % n_[2];
      const std::int64_t j = (idx / n_[2]) % n_[1];
      const std::int64_t i = idx / (n_[2] * n_[1]);
      out.emplace_back(static_cast<std::uint32_t>(ranked[t] >> 32),
                       pack(lo_[0] + i, lo_[1] + j, lo_[2] + k));
    }
    return out;
  }

 private:
  static constexpr double kDenseLimit = 8.0e6;
  bool dense_ = false;
  std::int64_t lo_[3] = {0, 0, 0}, n_[3] = {0, 0, 0};
  std::vector<std::uint32_t> dense_counts_;
  std::vector<std::uint32_t> touched_;  // the first touched_count_ are the cells with votes
  std::size_t touched_count_ = 0;
  HashCounts sparse_;
};

struct Peak {
  std::size_t votes = 0;
  Vec3 t = Vec3::Zero();
};

// Where a prior lets the source centre's image be: within radius_h of `centre` across the up
// axis and within radius_v along it (infinite: anywhere).
struct VoteWindow {
  Vec3 centre = Vec3::Zero();
  double radius_h = std::numeric_limits<double>::infinity();
  double radius_v = std::numeric_limits<double>::infinity();
};

// The translation with the most votes among translations t = q - x for the rotated, centred
// source samples x; within `window` when its radii are finite. The vote is over the
// horizontal part of t (in the plane normal to `up`, 3x3 cells): an error in either map's up axis
// (a hand-held camera gives it to a few degrees) tilts the source, which moves its landmarks
// mostly vertically. The vertical part of t is then the median of the peak's votes.
std::vector<Peak> vote(const Points3& rotated, const Points3& target, double cell, const Vec3& up,
                       const VoteWindow& window, std::size_t max_peaks, VoteGrid& grid,
                       std::vector<double>& heights,
                       std::vector<std::pair<double, std::size_t>>& by_e1) {
  const Vec3 e1 = up.unitOrthogonal();
  const Vec3 e2 = up.cross(e1);
  const double inv = 1.0 / cell;
  {
    // The cells t = q - x can reach: from the extents of both sides along e1 and e2, one cell
    // wider on each side for the rounding of t's components.
    auto extent = [](const Points3& pts, const Vec3& e) {
      double lo = std::numeric_limits<double>::infinity(), hi = -lo;
      for (const Vec3& p : pts) {
        lo = std::min(lo, p.dot(e));
        hi = std::max(hi, p.dot(e));
      }
      return std::pair<double, double>{lo, hi};
    };
    const auto [x1_lo, x1_hi] = extent(rotated, e1);
    const auto [x2_lo, x2_hi] = extent(rotated, e2);
    const auto [q1_lo, q1_hi] = extent(target, e1);
    const auto [q2_lo, q2_hi] = extent(target, e2);
    const double limit = static_cast<double>(kCellLimit);
    auto cell_of = [&](double v) {
      return static_cast<std::int64_t>(std::clamp(std::floor(v * inv), -limit, limit));
    };
    grid.reset(rotated.size() * target.size(), cell_of(q1_lo - x1_hi) - 1,
               cell_of(q1_hi - x1_lo) + 1, cell_of(q2_lo - x2_hi) - 1, cell_of(q2_hi - x2_lo) + 1);
  }
  const bool bounded = std::isfinite(window.radius_h);
  const double rh2 = window.radius_h * window.radius_h;
  // Every vote t = q - x within the window, with its horizontal cell (a, b); both passes below
  // (the vote, then the peak's heights) see the same votes.
  auto vote_of = [&](const Vec3& x, const Vec3& q, auto&& visit) {
    const Vec3 t = q - x;
    if (bounded) {
      const Vec3 d = t - window.centre;
      const double v = d.dot(up);
      if (std::abs(v) > window.radius_v || (d - v * up).squaredNorm() > rh2) return;
    }
    const double a = std::floor(t.dot(e1) * inv);
    const double b = std::floor(t.dot(e2) * inv);
    if (std::abs(a) >= static_cast<double>(kCellLimit - 2) ||
        std::abs(b) >= static_cast<double>(kCellLimit - 2)) {
      return;
    }
    visit(t, a, b);
  };
  auto for_each_vote = [&](auto&& visit) {
    for (const Vec3& x : rotated) {
      for (const Vec3& q : target) vote_of(x, q, visit);
    }
  };
  for_each_vote([&](const Vec3&, double a, double b) {
    grid.add(static_cast<std::int64_t>(a), static_cast<std::int64_t>(b));
  });
  // The fullest cells (32 for each peak wanted), then their 3x3 sums; peaks best first, each
  // at least 3 cells (Chebyshev) from a better one.
  std::vector<std::pair<std::uint32_t, std::uint64_t>> top;
  grid.for_each_cell([&](std::uint32_t c, std::uint64_t key) { top.emplace_back(c, key); });
  const std::size_t keep = std::min<std::size_t>(32 * max_peaks, top.size());
  std::partial_sort(top.begin(), top.begin() + static_cast<std::ptrdiff_t>(keep), top.end(),
                    [](const auto& l, const auto& r) {
                      return l.first != r.first ? l.first > r.first : l.second < r.second;
                    });
  struct Cand {
    std::size_t votes;
    double a, b;
    std::int64_t x, y;
  };
  std::vector<Cand> cands;
  for (std::size_t j = 0; j < keep; ++j) {
    const std::uint64_t key = top[j].second;
    const std::int64_t x = static_cast<std::int64_t>(key >> 42) - kCellLimit;
    const std::int64_t y = static_cast<std::int64_t>((key >> 21) & ((1u << 21) - 1)) - kCellLimit;
    std::size_t sum = 0;
    double wa = 0.0, wb = 0.0;
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        const std::uint32_t c = grid.count(x + dx, y + dy);
        sum += c;
        wa += c * (static_cast<double>(x + dx) + 0.5);
        wb += c * (static_cast<double>(y + dy) + 0.5);
      }
    }
    if (sum == 0) continue;
    cands.push_back(
        {sum, cell * wa / static_cast<double>(sum), cell * wb / static_cast<double>(sum), x, y});
  }
  // Best first; among equal sums the fuller cell (earlier in `top`) first.
  std::stable_sort(cands.begin(), cands.end(),
                   [](const Cand& l, const Cand& r) { return l.votes > r.votes; });
  std::vector<Cand> chosen;
  for (const Cand& c : cands) {
    if (chosen.size() >= max_peaks) break;
    bool near = false;
    for (const Cand& o : chosen) {
      if (std::max(std::abs(o.x - c.x), std::abs(o.y - c.y)) < 3) near = true;
    }
    if (!near) chosen.push_back(c);
  }
  std::vector<Peak> peaks;
  if (chosen.empty()) return peaks;
  // The vertical part: median over the votes in the peak's 3x3 cells. Only the target
  // landmarks whose projection on e1 puts them within a cell of those cells can vote there
  // (found by bisection in the targets sorted by that projection); each is then tested exactly as
  // in the vote, so the heights are the same as from every pair.
  by_e1.clear();
  for (std::size_t j = 0; j < target.size(); ++j) by_e1.emplace_back(target[j].dot(e1), j);
  std::sort(by_e1.begin(), by_e1.end());
  for (const Cand& c : chosen) {
    heights.clear();
    const double band_lo = (static_cast<double>(c.x) - 2.0) * cell;
    const double band_hi = (static_cast<double>(c.x) + 3.0) * cell;
    auto in_peak = [&](const Vec3& t, double a, double b) {
      if (std::abs(a - static_cast<double>(c.x)) <= 1.0 &&
          std::abs(b - static_cast<double>(c.y)) <= 1.0) {
        heights.push_back(t.dot(up));
      }
    };
    for (const Vec3& x : rotated) {
      const double x1 = x.dot(e1);
      auto it = std::lower_bound(by_e1.begin(), by_e1.end(),
                                 std::pair<double, std::size_t>{x1 + band_lo, 0});
      for (; it != by_e1.end() && it->first <= x1 + band_hi; ++it) {
        vote_of(x, target[it->second], in_peak);
      }
    }
    if (heights.empty()) continue;  // not reached: the peak's own votes are among them
    const std::size_t mid = heights.size() / 2;
    std::nth_element(heights.begin(), heights.begin() + static_cast<std::ptrdiff_t>(mid),
                     heights.end());
    Peak p;
    p.votes = c.votes;
    p.t = c.a * e1 + c.b * e2 + heights[mid] * up;
    peaks.push_back(p);
  }
  return peaks;
}

// The votes of `cell` above its surroundings: its count minus the mean count of the 98 cells two
// cells away (the 5x5x5 block without the 3x3x3 one), at least 0. Every source sample votes for
// every target sample, so the counts carry a smooth background, the overlap of the two maps'
// extents at that translation: on a street it is a ridge along the road, highest where the maps
// overlap most, and the truth of a short overlap sits on its flank. The matched landmarks add a
// spike of one or two cells (their covariances are smaller than a cell) on top of it; the mean of
// a symmetric shell cancels a background that is linear across it.
double prominence(const VoteGrid3& grid, const std::int64_t* cell) {
  double shell = 0.0;
  int n = 0;
  for (int dx = -2; dx <= 2; ++dx) {
    for (int dy = -2; dy <= 2; ++dy) {
      for (int dz = -2; dz <= 2; ++dz) {
        if (std::max({std::abs(dx), std::abs(dy), std::abs(dz)}) < 2) continue;
        shell += grid.count(cell[0] + dx, cell[1] + dy, cell[2] + dz);
        ++n;
      }
    }
  }
  return std::max(0.0, grid.count(cell[0], cell[1], cell[2]) - shell / n);
}

// The most prominent translations in 3-D cells (prominence() of the cells with the most votes,
// each peak at least 3 cells from a better one), best first; each peak's translation is the mean
// of its 3x3x3 block's votes. The vote of vote() without its horizontal projection, for up axes
// that agree (a tilt moves far landmarks across cells).
std::vector<Peak> vote3d(const Points3& rotated, const Points3& target, double cell, const Vec3& up,
                         const VoteWindow& window, std::size_t max_peaks, VoteGrid3& grid) {
  const double inv = 1.0 / cell;
  const double limit = static_cast<double>(kCellLimit - 2);
  const bool bounded = std::isfinite(window.radius_h);
  const double rh2 = window.radius_h * window.radius_h;
  {
    // The cells t = q - x can reach, from both sides' robust extents (2nd to 98th percentile
    // per axis, one cell wider for rounding): a dense grid drops the votes outside, which only
    // the farthest landmarks cast; a peak is made of many.
    std::int64_t lo[3], hi[3];
    std::vector<double> xs(rotated.size()), qs(target.size());
    auto pct = [](std::vector<double>& v, double f) {
      const std::size_t k = static_cast<std::size_t>(f * static_cast<double>(v.size() - 1));
      std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
      return v[k];
    };
    for (int k = 0; k < 3; ++k) {
      for (std::size_t i = 0; i < rotated.size(); ++i) xs[i] = rotated[i][k];
      for (std::size_t i = 0; i < target.size(); ++i) qs[i] = target[i][k];
      const double xl = pct(xs, 0.02), xh = pct(xs, 0.98), ql = pct(qs, 0.02), qh = pct(qs, 0.98);
      lo[k] = static_cast<std::int64_t>(std::clamp(std::floor((ql - xh) * inv), -limit, limit)) - 1;
      hi[k] = static_cast<std::int64_t>(std::clamp(std::floor((qh - xl) * inv), -limit, limit)) + 1;
    }
    grid.reset(rotated.size() * target.size(), lo, hi);
  }
  for (const Vec3& x : rotated) {
    for (const Vec3& q : target) {
      const Vec3 t = q - x;
      if (bounded) {
        const Vec3 d = t - window.centre;
        const double v = d.dot(up);
        if (std::abs(v) > window.radius_v || (d - v * up).squaredNorm() > rh2) continue;
      }
      std::int64_t a, b, c;
      if (!floor_within(t[0] * inv, limit, &a) || !floor_within(t[1] * inv, limit, &b) ||
          !floor_within(t[2] * inv, limit, &c)) {
        continue;
      }
      grid.add(a, b, c);
    }
  }
  const std::vector<std::pair<std::uint32_t, std::uint64_t>> top = grid.top(64 * max_peaks);
  const std::size_t keep = top.size();
  struct Cand {
    std::size_t votes;
    Vec3 t;
    std::int64_t i[3];
  };
  auto unpack = [](std::uint64_t key, std::int64_t* i) {
    i[0] = static_cast<std::int64_t>(key >> 42) - kCellLimit;
    i[1] = static_cast<std::int64_t>((key >> 21) & ((1u << 21) - 1)) - kCellLimit;
    i[2] = static_cast<std::int64_t>(key & ((1u << 21) - 1)) - kCellLimit;
  };
  std::vector<Cand> cands;
  for (std::size_t j = 0; j < keep; ++j) {
    Cand c;
    unpack(top[j].second, c.i);
    std::size_t sum = 0;
    Vec3 w = Vec3::Zero();
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = -1; dz <= 1; ++dz) {
          const std::uint32_t n = grid.count(c.i[0] + dx, c.i[1] + dy, c.i[2] + dz);
          sum += n;
          w += n * Vec3(static_cast<double>(c.i[0] + dx) + 0.5,
                        static_cast<double>(c.i[1] + dy) + 0.5,
                        static_cast<double>(c.i[2] + dz) + 0.5);
        }
      }
    }
    c.votes = static_cast<std::size_t>(prominence(grid, c.i));
    c.t = cell * w / static_cast<double>(sum);
    cands.push_back(c);
  }
  std::stable_sort(cands.begin(), cands.end(),
                   [](const Cand& l, const Cand& r) { return l.votes > r.votes; });
  std::vector<Peak> peaks;
  std::vector<const Cand*> chosen;
  for (const Cand& c : cands) {
    if (chosen.size() >= max_peaks) break;
    bool near = false;
    for (const Cand* o : chosen) {
      std::int64_t d = 0;
      for (int k = 0; k < 3; ++k) d = std::max(d, std::abs(o->i[k] - c.i[k]));
      if (d < 3) near = true;
    }
    if (near) continue;
    chosen.push_back(&c);
    Peak p;
    p.votes = c.votes;
    p.t = c.t;
    peaks.push_back(p);
  }
  return peaks;
}

}  // namespace

bool YawVoteOptions::is_valid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why != nullptr) *why = m;
    return false;
  };
  if (!(yaw_step_deg > 0.0 && yaw_step_deg <= 90.0)) {
    return fail("yaw_step_deg must be in (0, 90], got " + std::to_string(yaw_step_deg));
  }
  if (source_samples < 3 || target_samples < 3) {
    return fail("source_samples and target_samples must be >= 3");
  }
  if (hypotheses < 1) return fail("hypotheses must be >= 1");
  if (peaks_per_yaw < 1 || peaks_per_yaw > 64) return fail("peaks_per_yaw must be in [1, 64]");
  return true;
}

YawHypothesis local_vote(const Points3& points, const KdTree& target_tree, const Vec3& up_in,
                         const Vec3& source_centre, const Isometry3& T0,
                         const LocalVoteOptions& o) {
  YawHypothesis out;
  out.T_target_source = T0;
  if (points.empty() || target_tree.size() == 0) return out;
  const Vec3 up = up_in.normalized();
  const Vec3 pivot = T0 * source_centre;
  const int half_n =
      o.yaw_step_rad > 0.0
          ? static_cast<int>(std::floor(o.yaw_half_width_rad / o.yaw_step_rad + 1e-9))
          : 0;
  const double inv = 1.0 / o.cell_m;
  const std::int64_t n = 2 * static_cast<std::int64_t>(std::ceil(o.half_width_m * inv)) + 3;
  const std::int64_t off = n / 2;
  const double cell_limit = static_cast<double>(kCellLimit);
  const std::size_t k = std::min(o.neighbours, target_tree.size());
  const Points3& q = target_tree.points();
  // A vote lands in the grid only if each component of t is within reach_m of 0; at yaw y a moved
  // landmark turns by at most |y| |moved - pivot| about the pivot. So a target landmark farther
  // than sqrt(3) reach_m + max |y| |moved - pivot| from a moved landmark never votes, and a
  // moved landmark that far from the targets' bounding box has no neighbour that votes: its query
  // is skipped, and the others' searches stop at that distance (the same votes). The margin covers
  // the rounding of coordinates up to 1e15 m.
  const double reach_m = static_cast<double>(std::max(off - 1, n - 1 - off)) * o.cell_m;
  const double yaw_max_rad = half_n * o.yaw_step_rad;
  Vec3 box_min = q.front(), box_max = q.front();
  for (const Vec3& p : q) {
    box_min = box_min.cwiseMin(p);
    box_max = box_max.cwiseMax(p);
  }
  const double box_abs_m = std::max(box_min.cwiseAbs().maxCoeff(), box_max.cwiseAbs().maxCoeff());
  // The neighbours of each moved landmark, once: wide enough for every yaw of the window.
  std::vector<Vec3> moved(points.size());
  std::vector<PointIndex> nbr(points.size() * k);
  std::vector<double> d2(k);
  std::vector<std::size_t> counts(points.size(), 0);
  for (std::size_t i = 0; i < points.size(); ++i) {
    moved[i] = T0 * points[i];
    const double votes_within_m = std::sqrt(3.0) * reach_m +
                                  yaw_max_rad * (moved[i] - pivot).norm() +
                                  1e-9 * (box_abs_m + moved[i].cwiseAbs().maxCoeff() + reach_m);
    const Vec3 outside = (box_min - moved[i]).cwiseMax(moved[i] - box_max).cwiseMax(0.0);
    if (outside.norm() > votes_within_m) continue;
    // Only the neighbours within votes_within_m can vote: the k nearest of those are the leading
    // entries of the k nearest, and the search need not visit what lies beyond.
    counts[i] = target_tree.knn_within(moved[i], k, votes_within_m, &nbr[i * k], d2.data());
  }
  std::vector<std::uint32_t> grid(static_cast<std::size_t>(n * n * n));
  std::vector<std::uint32_t> box1, box2;
  std::size_t best_votes = 0;
  for (int y = -half_n; y <= half_n; ++y) {
    const Mat3 R = Eigen::AngleAxisd(y * o.yaw_step_rad, up).toRotationMatrix();
    std::fill(grid.begin(), grid.end(), 0u);
    for (std::size_t i = 0; i < points.size(); ++i) {
      const Vec3 x = R * (moved[i] - pivot) + pivot;
      for (std::size_t j = 0; j < counts[i]; ++j) {
        const Vec3 t = q[nbr[i * k + j]] - x;
        // A floor beyond +-kCellLimit is outside the grid (n^3 cells fit in memory) anyway.
        std::int64_t a, b, c;
        if (!floor_within(t[0] * inv, cell_limit, &a) ||
            !floor_within(t[1] * inv, cell_limit, &b) ||
            !floor_within(t[2] * inv, cell_limit, &c)) {
          continue;
        }
        a += off;
        b += off;
        c += off;
        if (a < 1 || b < 1 || c < 1 || a >= n - 1 || b >= n - 1 || c >= n - 1) continue;
        ++grid[static_cast<std::size_t>((a * n + b) * n + c)];
      }
    }
    // 3x3x3 box sums, separably (exact integer sums), then the best cell; its position is the
    // vote-weighted mean of its 27 cells.
    auto at = [n](std::int64_t a, std::int64_t b, std::int64_t c) {
      return static_cast<std::size_t>((a * n + b) * n + c);
    };
    box1.assign(grid.size(), 0u);
    box2.assign(grid.size(), 0u);
    for (std::int64_t a = 0; a < n; ++a)
      for (std::int64_t b = 0; b < n; ++b)
        for (std::int64_t c = 1; c < n - 1; ++c)
          box1[at(a, b, c)] = grid[at(a, b, c - 1)] + grid[at(a, b, c)] + grid[at(a, b, c + 1)];
    for (std::int64_t a = 0; a < n; ++a)
      for (std::int64_t b = 1; b < n - 1; ++b)
        for (std::int64_t c = 1; c < n - 1; ++c)
          box2[at(a, b, c)] = box1[at(a, b - 1, c)] + box1[at(a, b, c)] + box1[at(a, b + 1, c)];
    std::size_t yaw_best = 0;
    std::int64_t ba = 0, bb = 0, bc = 0;
    for (std::int64_t a = 1; a < n - 1; ++a) {
      for (std::int64_t b = 1; b < n - 1; ++b) {
        for (std::int64_t c = 1; c < n - 1; ++c) {
          const std::size_t sum = box2[at(a - 1, b, c)] + box2[at(a, b, c)] + box2[at(a + 1, b, c)];
          if (sum > yaw_best) {
            yaw_best = sum;
            ba = a;
            bb = b;
            bc = c;
          }
        }
      }
    }
    if (yaw_best > best_votes) {
      best_votes = yaw_best;
      Vec3 w = Vec3::Zero();
      for (int da = -1; da <= 1; ++da) {
        for (int db = -1; db <= 1; ++db) {
          for (int dc = -1; dc <= 1; ++dc) {
            const std::uint32_t v = grid[at(ba + da, bb + db, bc + dc)];
            w += v * Vec3(static_cast<double>(ba + da - off) + 0.5,
                          static_cast<double>(bb + db - off) + 0.5,
                          static_cast<double>(bc + dc - off) + 0.5);
          }
        }
      }
      const Vec3 t = o.cell_m * w / static_cast<double>(yaw_best);
      Isometry3 T = Isometry3::Identity();
      T.linear() = R;
      T.translation() = pivot - R * pivot + t;  // x -> R (x - pivot) + pivot + t
      out.T_target_source = T * T0;
      out.yaw_rad = y * o.yaw_step_rad;
    }
  }
  out.votes = best_votes;
  return out;
}

Mat3 rotation_between(const Vec3& from, const Vec3& to) {
  const Vec3 a = from.normalized();
  const Vec3 b = to.normalized();
  const Vec3 axis = a.cross(b);
  const double s = axis.norm();
  const double c = a.dot(b);
  if (s < 1e-12) {
    if (c > 0.0) return Mat3::Identity();
    // Opposite: a half turn about any axis perpendicular to a.
    Vec3 perp = a.cross(Vec3::UnitX());
    if (perp.norm() < 1e-6) perp = a.cross(Vec3::UnitY());
    return Eigen::AngleAxisd(kPi, perp.normalized()).toRotationMatrix();
  }
  return Eigen::AngleAxisd(std::atan2(s, c), axis / s).toRotationMatrix();
}

namespace {

void check_yaw_vote_input(const Points3& source_points, const Points3& target_points,
                          const Vec3& up_source, const Vec3& up_target, double cell_m,
                          const YawVoteOptions& options, const PoseWindow* window) {
  std::string why;
  if (!options.is_valid(&why)) throw InvalidArgument("yaw-vote search: " + why);
  if (source_points.size() < 3 || target_points.size() < 3) {
    throw InvalidArgument("yaw-vote search: each map needs at least 3 landmarks");
  }
  if (!(up_source.norm() > 0.0) || !(up_target.norm() > 0.0) || !up_source.allFinite() ||
      !up_target.allFinite()) {
    throw InvalidArgument("yaw-vote search: the up axes must be finite and non-zero");
  }
  if (!(cell_m > 0.0) || !std::isfinite(cell_m)) {
    throw InvalidArgument("yaw-vote search: cell_m must be > 0 and finite");
  }
  if (window != nullptr &&
      (!(window->rotation_sd_rad > 0.0) || !(window->translation_sd_m > 0.0) ||
       !std::isfinite(window->rotation_sd_rad) || !std::isfinite(window->translation_sd_m) ||
       !window->T_target_source_guess.matrix().allFinite())) {
    throw InvalidArgument("yaw-vote search: the prior's sigmas must be > 0 and finite");
  }
  for (std::size_t i = 0; i < source_points.size(); ++i) {
    if (!source_points[i].allFinite()) {
      throw InvalidArgument("yaw-vote search: source landmark " + std::to_string(i) +
                            " is not finite");
    }
  }
  for (std::size_t i = 0; i < target_points.size(); ++i) {
    if (!target_points[i].allFinite()) {
      throw InvalidArgument("yaw-vote search: target landmark " + std::to_string(i) +
                            " is not finite");
    }
  }
}

// The samples the votes are cast with: the source samples about their centre (they turn about
// it), the target samples less `target_centre`.
struct VoteSamples {
  Points3 src, tgt;
  Vec3 centre = Vec3::Zero();
  Vec3 target_centre = Vec3::Zero();
};

VoteSamples vote_samples(const Points3& source_points, const Points3& target_points, double cell_m,
                         const YawVoteOptions& options) {
  VoteSamples v;
  v.src = strided(source_points, options.source_samples);
  v.tgt = strided(target_points, options.target_samples);
  const Points3& src = v.src;
  Points3& tgt = v.tgt;
  Vec3& centre = v.centre;
  Vec3& target_centre = v.target_centre;
  // The source samples turn about their centroid, and vote for t = q - R (p - centre). Every
  // vote must fit the grid's +-kCellLimit cells per axis; a vote beyond it is dropped. For maps
  // near their origins they do. When they do not (maps whose coordinates are far from their
  // origin, or a few far landmarks that pull the centroid away from the others), both sides are
  // centred on the coordinate-wise medians of their samples instead: the votes then span the
  // maps' sizes, whatever their coordinates (up to the supported 1e15 m) and whatever a few far
  // landmarks do (theirs are dropped).
  for (const Vec3& p : src) centre += p;
  centre /= static_cast<double>(src.size());
  {
    double reach_m = 0.0;
    for (const Vec3& p : src) reach_m = std::max(reach_m, (p - centre).norm());
    double target_reach_m = 0.0;
    for (const Vec3& q : tgt) target_reach_m = std::max(target_reach_m, q.norm());
    if (!((reach_m + target_reach_m) / cell_m < 0.25 * static_cast<double>(kCellLimit))) {
      centre = median_point(src);
      target_centre = median_point(tgt);
      for (Vec3& q : tgt) q -= target_centre;
    }
  }
  if (options.vote_3d) {
    // The 3-D vote's counts do not depend on the order of the target samples; in the order of
    // their cells (the grid's memory order), one source sample's votes walk the grid nearly in
    // order, which the cache rewards.
    const double inv = 1.0 / cell_m;
    std::stable_sort(tgt.begin(), tgt.end(), [inv](const Vec3& l, const Vec3& r) {
      const double l0 = std::floor(l[0] * inv), r0 = std::floor(r[0] * inv);
      if (l0 != r0) return l0 < r0;
      const double l1 = std::floor(l[1] * inv), r1 = std::floor(r[1] * inv);
      if (l1 != r1) return l1 < r1;
      return l[2] < r[2];
    });
  }

  return v;
}

// The yaws voted over: about the up axes' alignment, every yaw (no prior), else those within 3
// sigma of the guess, with the vote window about the guess's image of the source centre.
struct YawGrid {
  Mat3 base = Mat3::Identity();
  double yaw_from = -kPi;
  int n_yaw = 0;
  bool circular = true;
  Vec3 t_centre = Vec3::Zero();
  double radius_h = std::numeric_limits<double>::infinity();
  double radius_v = std::numeric_limits<double>::infinity();
};

// The azimuth about `up` of the principal horizontal axis of `points` turned by R, in
// (-pi/2, pi/2], from the unit e1 towards up x e1: the angle of the 2x2 scatter's major axis.
// Turning the points about `up` by b adds b to it (modulo pi).
double principal_azimuth(const Points3& points, const Mat3& R, const Vec3& up, const Vec3& e1) {
  const Vec3 e2 = up.cross(e1);
  double ma = 0.0, mb = 0.0;
  for (const Vec3& p : points) {
    const Vec3 q = R * p;
    ma += q.dot(e1);
    mb += q.dot(e2);
  }
  const double n = static_cast<double>(std::max<std::size_t>(points.size(), 1));
  ma /= n;
  mb /= n;
  double saa = 0.0, sbb = 0.0, sab = 0.0;
  for (const Vec3& p : points) {
    const Vec3 q = R * p;
    const double a = q.dot(e1) - ma, b = q.dot(e2) - mb;
    saa += a * a;
    sbb += b * b;
    sab += a * b;
  }
  return 0.5 * std::atan2(2.0 * sab, saa - sbb);
}

YawGrid yaw_grid(const Vec3& up_source, const Vec3& up, const Vec3& centre, double cell_m,
                 const YawVoteOptions& options, const PoseWindow* window,
                 const VoteSamples& samples) {
  YawGrid g;
  Mat3& base = g.base;
  double& yaw_from = g.yaw_from;
  int& n_yaw = g.n_yaw;
  Vec3& t_centre = g.t_centre;
  double& radius_h = g.radius_h;
  double& radius_v = g.radius_v;
  bool& circular = g.circular;
  const double step = options.yaw_step_deg * kPi / 180.0;
  if (window == nullptr) {
    base = rotation_between(up_source, up);
    n_yaw = static_cast<int>(std::ceil(2.0 * kPi / step - 1e-9));
    // The grid's phase: the yaw that turns the source samples' principal horizontal axis onto
    // the target samples', modulo the step. A map turned about its up axis then gets the same
    // candidates, turned with it (when the step divides 180 deg, as the default's 3 deg does:
    // an axis has two directions); with a fixed phase the grid met the truth at another offset
    // and, on a real KITTI pair, the answer changed with the turn (docs/accuracy.md).
    const Vec3 e1 = rotation_between(Vec3::UnitZ(), up) * Vec3::UnitX();
    const double turn = principal_azimuth(samples.tgt, Mat3::Identity(), up, e1) -
                        principal_azimuth(samples.src, base, up, e1);
    const double phase = turn - step * std::floor(turn / step);  // [0, step)
    yaw_from = -kPi + (std::isfinite(phase) ? phase : 0.0);
  } else {
    base = window->T_target_source_guess.linear();
    const double half = 3.0 * window->rotation_sd_rad;
    if (half >= kPi) {
      n_yaw = static_cast<int>(std::ceil(2.0 * kPi / step - 1e-9));
    } else {
      circular = false;
      // Within 3 sigma (the tolerance absorbs the rounding of an exact multiple of the step).
      const int per_side = static_cast<int>(std::floor(half / step + 1e-9));
      n_yaw = 2 * per_side + 1;
      yaw_from = -per_side * step;
    }
    // Where the guess puts the source centre; the votes are for that point's image. The
    // sigmas are of the left perturbation about the target origin (uncertainty.hpp): a yaw
    // about the up axis through the origin moves that image along a circle (each yaw's window
    // is centred on it, below), a tilt moves it by the rotation's sigma times its lever arm:
    // across the up axis by its height, along it by its horizontal distance.
    const Vec3 image = window->T_target_source_guess * centre;
    const double height = std::abs(image.dot(up));
    const double across = (image - image.dot(up) * up).norm();
    // The vote window's centre relative to the target's centre (the votes are), turned by each
    // yaw about the target origin below: R_yaw image - target_centre.
    t_centre = image;
    radius_h = 3.0 * (window->translation_sd_m + window->rotation_sd_rad * height) + 2.0 * cell_m;
    radius_v = 3.0 * (window->translation_sd_m + window->rotation_sd_rad * across) + 2.0 * cell_m;
  }

  return g;
}

// Each yaw's peaks (one thread per yaw, each its own slot).
std::vector<std::vector<YawHypothesis>> vote_every_yaw(const VoteSamples& v, const YawGrid& g,
                                                       const Vec3& up, double cell_m,
                                                       const YawVoteOptions& options,
                                                       std::size_t per_yaw) {
  const Points3& src = v.src;
  const Points3& tgt = v.tgt;
  const Vec3& centre = v.centre;
  const Vec3& target_centre = v.target_centre;
  const int n_yaw = g.n_yaw;
  const double step = options.yaw_step_deg * kPi / 180.0;
  std::vector<std::vector<YawHypothesis>> all(static_cast<std::size_t>(n_yaw));
  FirstException error;
#pragma omp parallel
  {
    // Every thread reaches the worksharing loop (an exception may not skip it, nor leave an
    // iteration): allocations and iterations are captured one by one.
    VoteGrid grid;
    VoteGrid3 grid3;
    std::vector<double> heights;
    std::vector<std::pair<double, std::size_t>> by_e1;
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
        const double yaw = g.yaw_from + step * i;
        const Mat3 R_yaw = Eigen::AngleAxisd(yaw, up).toRotationMatrix();
        const Mat3 R = R_yaw * g.base;
        for (std::size_t j = 0; j < src.size(); ++j) rotated[j] = R * (src[j] - centre);
        const VoteWindow w{R_yaw * g.t_centre - target_centre, g.radius_h, g.radius_v};
        const std::vector<Peak> peaks =
            options.vote_3d ? vote3d(rotated, tgt, cell_m, up, w, per_yaw, grid3)
                            : vote(rotated, tgt, cell_m, up, w, per_yaw, grid, heights, by_e1);
        for (const Peak& peak : peaks) {
          YawHypothesis h;
          h.yaw_rad = yaw;
          h.votes = peak.votes;
          h.T_target_source.linear() = R;
          // p -> R (p - centre) + t_peak + target_centre
          h.T_target_source.translation() = (peak.t + target_centre) - R * centre;
          all[static_cast<std::size_t>(i)].push_back(h);
        }
      });
    }
  }
  error.rethrow();
  return all;
}

// Local maxima over yaw (circular without a window) of each yaw's best peak, best first; with
// several peaks per yaw, every peak of every yaw.
std::vector<YawHypothesis> yaw_maxima(const std::vector<std::vector<YawHypothesis>>& all,
                                      bool circular, std::size_t per_yaw) {
  const int n_yaw = static_cast<int>(all.size());
  std::vector<YawHypothesis> out;
  auto best_votes = [&](int i) -> std::size_t {
    const auto& v = all[static_cast<std::size_t>(i)];
    return v.empty() ? 0 : v.front().votes;
  };
  for (int i = 0; i < n_yaw; ++i) {
    const std::size_t v = best_votes(i);
    if (v == 0) continue;
    if (per_yaw > 1) {
      for (const YawHypothesis& h : all[static_cast<std::size_t>(i)]) out.push_back(h);
      continue;
    }
    const bool has_prev = circular || i > 0;
    const bool has_next = circular || i + 1 < n_yaw;
    const std::size_t prev = has_prev ? best_votes((i + n_yaw - 1) % n_yaw) : 0;
    const std::size_t next = has_next ? best_votes((i + 1) % n_yaw) : 0;
    if (v >= prev && v >= next) out.push_back(all[static_cast<std::size_t>(i)].front());
  }
  std::stable_sort(out.begin(), out.end(), [](const YawHypothesis& a, const YawHypothesis& b) {
    return a.votes > b.votes;
  });
  return out;
}

}  // namespace

std::vector<YawHypothesis> yaw_vote_hypotheses(const Points3& source_points,
                                               const Points3& target_points, const Vec3& up_source,
                                               const Vec3& up_target, double cell_m,
                                               const YawVoteOptions& options,
                                               const PoseWindow* window) {
  check_yaw_vote_input(source_points, target_points, up_source, up_target, cell_m, options, window);
  const VoteSamples v = vote_samples(source_points, target_points, cell_m, options);
  const Vec3 up = up_target.normalized();
  const YawGrid g = yaw_grid(up_source, up, v.centre, cell_m, options, window, v);
  const std::size_t per_yaw = std::max<std::size_t>(1, options.peaks_per_yaw);
  std::vector<YawHypothesis> out =
      yaw_maxima(vote_every_yaw(v, g, up, cell_m, options, per_yaw), g.circular, per_yaw);
  if (out.size() > options.hypotheses) out.resize(options.hypotheses);
  return out;
}

}  // namespace lmalign
