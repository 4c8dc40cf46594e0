#include "lmalign/registration/correspondence.hpp"

#include <algorithm>
#include <atomic>
#include <cfloat>
#include <cmath>
#include <limits>
#include <utility>

#include <omp.h>

#include "lmalign/core/error.hpp"
#include "lmalign/core/first_exception.hpp"

namespace lmalign {

namespace {

constexpr PointIndex kNoMatch = std::numeric_limits<PointIndex>::max();
constexpr int kMaxK = 4096;
// A workspace keeps at most this many reference poses; beyond, its cache is emptied (bounded
// memory for workspaces used over very many calls).
constexpr std::size_t kMaxPoses = 1u << 16;
// Relative slack of the reuse test: rounding errors of the distances involved are below 1e-15
// relative; 1e-9 leaves six orders of magnitude of room (docs/performance.md).
constexpr double kSlack = 1e-9;
// State::fast_pick's two values that are not a set of slots (k <= 7 uses bits 0-6).
constexpr std::uint32_t kPickUnknown = 0;
constexpr std::uint32_t kPickAll = 0x80;

// The total order of candidates, the kd-tree's: (squared distance, target index). Every choice
// "the nearer one" below uses it, so that reused and fresh results agree, ties included.
inline bool nearer_in_total_order(double d2_a, PointIndex a, double d2_b, PointIndex b) {
  return d2_a < d2_b || (d2_a == d2_b && a < b);
}

// A float <= r (r >= 0) within 2^-19 relative of it: a conservative copy of the reuse radius.
// (Scaling down before the round-to-nearest conversion keeps it below r without a data-dependent
// branch, which the processor would mispredict half the time. Below FLT_MIN the conversion's
// error is absolute, so such radii become 0: no reuse, which is always safe.)
float round_down_to_float(double r) {
  if (!(r < static_cast<double>(FLT_MAX))) return FLT_MAX;
  if (!(r >= static_cast<double>(FLT_MIN))) return 0.0f;
  return static_cast<float>(r * (1.0 - 0x1p-20));
}

// A per-thread slice of n 8-byte elements padded to whole 64-byte cache lines, plus one: threads
// never write to the same line (false sharing made two threads slower than one).
std::size_t padded_stride(std::size_t n) { return (n + 7) / 8 * 8 + 8; }

// Interleaves the low 21 bits of v with two zero bits between each.
std::uint64_t spread_bits(std::uint64_t v) {
  v &= 0x1fffff;
  v = (v | v << 32) & 0x1f00000000ffffULL;
  v = (v | v << 16) & 0x1f0000ff0000ffULL;
  v = (v | v << 8) & 0x100f00f00f00f00fULL;
  v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
  v = (v | v << 2) & 0x1249249249249249ULL;
  return v;
}

// Source indices sorted along a Morton (Z-order) curve of their positions: queries that follow
// each other touch the same parts of the tree. Only the speed depends on this order.
std::vector<PointIndex> morton_order(const Points3& points) {
  const std::size_t n = points.size();
  std::vector<PointIndex> order(n);
  if (n == 0) return order;
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const Vec3& p : points) {
    if (!p.allFinite()) continue;
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  std::vector<std::uint64_t> code(n);
  for (std::size_t i = 0; i < n; ++i) {
    code[i] = ~0ULL;  // non-finite points last
    if (!points[i].allFinite()) continue;
    code[i] = 0;
    for (int d = 0; d < 3; ++d) {
      const double extent = hi[d] - lo[d];
      const double u = extent > 0.0 ? (points[i][d] - lo[d]) / extent : 0.0;
      const auto cell = static_cast<std::uint64_t>(std::clamp(u, 0.0, 1.0) * 2097151.0);
      code[i] |= spread_bits(cell) << d;
    }
  }
  for (std::size_t i = 0; i < n; ++i) order[i] = static_cast<PointIndex>(i);
  std::sort(order.begin(), order.end(), [&code](PointIndex a, PointIndex b) {
    return code[a] < code[b] || (code[a] == code[b] && a < b);
  });
  return order;
}

// Sorts (d2, idx) by the kd-tree's total order: distance, then index. Insertion: the lists are
// short and, from one iteration to the next, nearly sorted already.
void sort_candidates(PointIndex* idx, double* d2, std::size_t n) {
  for (std::size_t j = 1; j < n; ++j) {
    const double d = d2[j];
    const PointIndex i = idx[j];
    std::size_t p = j;
    while (p > 0 && (d2[p - 1] > d || (d2[p - 1] == d && idx[p - 1] > i))) {
      d2[p] = d2[p - 1];
      idx[p] = idx[p - 1];
      --p;
    }
    d2[p] = d;
    idx[p] = i;
  }
}

}  // namespace

std::string to_string(CorrespondenceKind kind) {
  return kind == CorrespondenceKind::kNearest ? "nearest" : "weighted_knn";
}

bool CorrespondenceOptions::is_valid(std::string* why) const {
  auto fail = [&](const std::string& msg) {
    if (why != nullptr) *why = msg;
    return false;
  };
  if (k < 1 || k > kMaxK) {
    return fail("k must be in [1, " + std::to_string(kMaxK) + "], got " + std::to_string(k));
  }
  if (std::isnan(max_distance_m) || max_distance_m <= 0.0) {
    return fail("max_distance_m must be > 0 (or infinite), got " + std::to_string(max_distance_m));
  }
  return true;
}

// ---------------------------------------------------------------------------------------------
// Workspace

struct CorrespondenceWorkspace::State {
  struct Pose {
    Mat3 R;
    Vec3 t;
  };
  // What the cache refers to.
  const KdTree* tree = nullptr;
  const Points3* source = nullptr;
  std::size_t n = 0;
  std::size_t width = 0;  // candidates kept per source point (k + margin)

  // Entries are kept by position in the Morton order of the source points, so that each
  // thread's block of queries reads and writes a contiguous block of entries (no false sharing).
  std::vector<PointIndex> order;  // Morton position -> source index
  std::vector<PointIndex> inv;    // source index -> Morton position
  double coord_max = 0.0;         // largest absolute target coordinate (rounding allowance)
  double source_norm_max = 0.0;   // largest |s| (m) over the finite source points
  // Bounds every coordinate of P.R * s + P.t for every registered pose P and finite source point
  // s: max over the poses of ||P.R||_F * source_norm_max + |P.t|_inf (rounding allowance).
  double pose_bound_max = 0.0;
  // Per source point s: candidates cand[s * width, s * width + min(width, tree size)), the
  // conservative distance `reach` of the last one at the reference pose (< 0: no entry; +inf:
  // every target point is a candidate) and the reference pose `poses[ref[s]]`.
  std::vector<PointIndex> cand;
  std::vector<float> reach;
  std::vector<std::uint16_t> ref;
  std::vector<PointIndex> ref_source;  // the reference position is poses[ref] * source[ref_source]
  std::vector<Pose> poses;
  // The fast path (docs/performance.md): per entry, a conservative half of the gap between the
  // gap_k-th and (gap_k + 1)-th neighbour distances at the reference position (+inf: the entry
  // holds every target point; < 0: unknown). While the point stays within it of the reference,
  // its gap_k first candidates (entry positions [0, gap_k), in any order) are its gap_k nearest.
  std::vector<float> half_gap;
  std::vector<std::uint16_t> fast_ref;  // the pose of the fast reference position
  std::size_t gap_k = 1;                // the finder's k
  // With the fast path, Eq. 6 needs only the candidates of the largest weight: bit j set when
  // entry slot j < gap_k holds a target point of the largest weight among the gap_k (kPickAll:
  // use them all; kPickUnknown: not found yet). Kept for weighted k <= 7 without a distance
  // limit, for the finder `pick_serial`.
  std::vector<std::uint8_t> fast_pick;
  std::uint64_t pick_serial = 0;
  // Per-thread scratch: `scratch_width` entries for each thread, `scratch_stride` apart
  // (padded_stride(): no two threads write to one cache line).
  std::vector<PointIndex> scratch_idx;
  std::vector<double> scratch_d2;
  std::size_t scratch_width = 0;
  std::size_t scratch_stride = 0;
  // Per-thread bit sets for the seeded searches (KdTree::knn_seeded's seed_marks: one bit per
  // target point, all zero between searches), `marks_stride` words apart, whole cache lines.
  std::vector<std::uint64_t> seed_marks;
  std::size_t marks_stride = 0;

  std::size_t searched = 0;
  std::size_t reused = 0;
  std::size_t fast = 0;

  void clear_cache() {
    std::fill(reach.begin(), reach.end(), -1.0f);
    poses.clear();
    pose_bound_max = 0.0;
  }
  void ensure_cache() {
    if (reach.size() == n) return;
    cand.assign(n * width, 0);
    reach.assign(n, -1.0f);
    half_gap.assign(n, -1.0f);
    fast_ref.assign(n, 0);
    fast_pick.assign(n, 0);
    ref.assign(n, 0);
    ref_source.assign(n, 0);
    poses.clear();
  }
  void ensure_scratch(std::size_t w) {
    const std::size_t threads = static_cast<std::size_t>(std::max(1, omp_get_max_threads()));
    if (scratch_width >= w && scratch_idx.size() >= threads * scratch_stride) return;
    scratch_width = std::max(scratch_width, w);
    scratch_stride = padded_stride(scratch_width);
    scratch_idx.assign(threads * scratch_stride, 0);
    scratch_d2.assign(threads * scratch_stride, 0.0);
  }
  void ensure_marks() {
    const std::size_t threads = static_cast<std::size_t>(std::max(1, omp_get_max_threads()));
    const std::size_t stride = padded_stride(tree->seed_mark_words());
    if (marks_stride == stride && seed_marks.size() >= threads * stride) return;
    marks_stride = stride;
    seed_marks.assign(threads * stride, 0);
  }
  std::uint64_t* marks_of_this_thread() {
    return seed_marks.data() + static_cast<std::size_t>(omp_get_thread_num()) * marks_stride;
  }
  // The id of pose (R, t) for entries made in this call; *pushed tells whether it was added.
  std::uint32_t register_pose(const Mat3& R, const Vec3& t, bool* pushed) {
    *pushed = false;
    // |R s + t|_inf <= |R s|_2 + |t|_inf <= ||R||_F |s|_2 + |t|_inf.
    const double bound = R.norm() * source_norm_max + t.cwiseAbs().maxCoeff();
    if (!poses.empty() && poses.back().R == R && poses.back().t == t) {
      return static_cast<std::uint32_t>(poses.size() - 1);
    }
    if (poses.size() >= kMaxPoses) clear_cache();
    poses.push_back({R, t});
    // (NaN from 0 * inf, huge source points: no bound, then nothing is reused.)
    if (!(bound <= pose_bound_max)) {
      pose_bound_max = std::isnan(bound) ? std::numeric_limits<double>::infinity() : bound;
    }
    *pushed = true;
    return static_cast<std::uint32_t>(poses.size() - 1);
  }
};

CorrespondenceWorkspace::CorrespondenceWorkspace() : state_(new State) {}
CorrespondenceWorkspace::~CorrespondenceWorkspace() { delete state_; }
CorrespondenceWorkspace::CorrespondenceWorkspace(CorrespondenceWorkspace&& o) noexcept
    : state_(o.state_) {
  o.state_ = new State;
}
CorrespondenceWorkspace& CorrespondenceWorkspace::operator=(CorrespondenceWorkspace&& o) noexcept {
  std::swap(state_, o.state_);
  return *this;
}
void CorrespondenceWorkspace::clear() { state_->clear_cache(); }
std::size_t CorrespondenceWorkspace::last_searched() const { return state_->searched; }
std::size_t CorrespondenceWorkspace::last_reused() const { return state_->reused; }
std::size_t CorrespondenceWorkspace::last_fast() const { return state_->fast; }
std::size_t CorrespondenceWorkspace::memory_bytes() const {
  const State& s = *state_;
  return s.order.capacity() * sizeof(PointIndex) + s.inv.capacity() * sizeof(PointIndex) +
         s.cand.capacity() * sizeof(PointIndex) + s.reach.capacity() * sizeof(float) +
         s.ref.capacity() * sizeof(std::uint16_t) + s.ref_source.capacity() * sizeof(PointIndex) +
         s.half_gap.capacity() * sizeof(float) + s.fast_ref.capacity() * sizeof(std::uint16_t) +
         s.fast_pick.capacity() * sizeof(std::uint8_t) + s.poses.capacity() * sizeof(State::Pose) +
         s.scratch_idx.capacity() * sizeof(PointIndex) + s.scratch_d2.capacity() * sizeof(double) +
         s.seed_marks.capacity() * sizeof(std::uint64_t);
}

// ---------------------------------------------------------------------------------------------
// The search kernel shared by find() and nearest_sq_distances().

namespace {

struct Kernel {
  const KdTree* tree;
  const Vec3* target;
  std::size_t target_size;
  const Vec3* source;
  CorrespondenceWorkspace::State* st;  // the cache (nullptr: plain search)
  std::size_t width;                   // == st->width
  std::uint32_t pose_id;
  // The target weights when the fast path may keep only the largest-weight candidates
  // (State::fast_pick), else nullptr.
  const double* pick_weights = nullptr;
  // Absolute allowance for the rounding of distances computed from coordinates this large
  // (relative slack alone does not cover the cancellation in q - p far from the origin): one
  // bound for the whole call, over the target's coordinates and every position a registered
  // pose can produce (set by with_tolerance()).
  double tol = 0.0;

  void with_tolerance() {
    // 1e-9: room for the rounding of the bound itself.
    tol = 1e-13 * (st->coord_max + 2.0 * st->pose_bound_max * (1.0 + 1e-9));
  }

  // The reference position of entry e for the wide test: where its candidates were searched.
  Vec3 reference(std::size_t e) const {
    const CorrespondenceWorkspace::State::Pose& P = st->poses[st->ref[e]];
    return P.R * source[st->ref_source[e]] + P.t;
  }
  // Re-evaluates the entry of source point e at q (sorted into idx/d2) and tells whether it
  // provably holds the `want` first neighbours of q: the reuse test (docs/performance.md).
  // *outside_m receives a lower bound on the distance from q of every target point that is not
  // a candidate (+inf when every target point is one). With a positive `give_up_below` (used
  // for borrowed entries, whose values are not needed when they fail), an entry whose bound is
  // below it is not re-evaluated: false, idx/d2 and *outside_m untouched.
  bool entry_holds(std::size_t e, const Vec3& q, std::size_t want, PointIndex* idx, double* d2,
                   double* outside_m, double give_up_below = 0.0) const {
    const std::size_t have = std::min(width, target_size);  // held by every entry
    const float reach = st->reach[e];
    const std::size_t got = std::min(want, have);
    double outside = std::numeric_limits<double>::infinity();
    if (!std::isinf(reach) && got > 0) {
      const Vec3 q_ref = reference(e);
      const double moved = std::sqrt(squared_distance(q, q_ref));
      outside = static_cast<double>(reach) * (1.0 - kSlack) - moved * (1.0 + kSlack) - tol;
      if (give_up_below > 0.0 && !(outside > give_up_below)) return false;
    }
    const PointIndex* entry = st->cand.data() + e * width;
    for (std::size_t j = 0; j < have; ++j) {
      idx[j] = entry[j];
      d2[j] = squared_distance(q, target[entry[j]]);
    }
    sort_candidates(idx, d2, have);
    *outside_m = outside;
    if (std::isinf(reach)) return true;  // every target point is a candidate
    if (got == 0) return false;
    const double kth = std::sqrt(d2[got - 1]);
    return kth * (1.0 + kSlack) < *outside_m;
  }

  // The fast path: entry e's half gap was measured at its fast reference position (the pose
  // poses[fast_ref[e]] applied to source point s). If q has moved from there by less than the
  // half gap, its gap_k nearest are the entry's gap_k first candidates (triangle inequality:
  // each of them is nearer than d_k + moved, every other point farther than d_(k+1) - moved).
  // Writes them into idx/d2 in the entry's order, not sorted (select_match<false> needs no
  // order), and returns how many (0: the test failed). Given `chosen`, and pick_weights, where
  // the entry has the candidates of the largest weight among them marked (State::fast_pick),
  // Eq. 6 chooses among those, the nearer on equal weights (the total order): that choice is
  // written into idx[0]/d2[0], *chosen set, and 1 returned.
  std::size_t fast(std::size_t e, std::size_t s, const Vec3& q, PointIndex* idx, double* d2,
                   bool* chosen = nullptr) const {
    const float half_gap = st->half_gap[e];
    if (!(half_gap > 0.0f) || !(st->reach[e] >= 0.0f)) return 0;
    if (!std::isinf(half_gap)) {
      const CorrespondenceWorkspace::State::Pose& P = st->poses[st->fast_ref[e]];
      const Vec3 q_ref = P.R * source[s] + P.t;
      const double moved = std::sqrt(squared_distance(q, q_ref));
      if (!(moved * (1.0 + kSlack) + tol < static_cast<double>(half_gap) * (1.0 - kSlack))) {
        return 0;
      }
    }
    const PointIndex* entry = st->cand.data() + e * width;
    if (chosen != nullptr && pick_weights != nullptr) {
      std::uint32_t mask = st->fast_pick[e];
      if (mask == kPickUnknown) {
        // The slots of the largest weight among the first gap_k (the k nearest since the fast
        // reference was set; candidates beyond a target of fewer points are never marked).
        mask = 0;
        double best_w = 0.0;
        for (std::size_t j = 0; j < std::min(st->gap_k, target_size); ++j) {
          const double w = pick_weights[entry[j]];
          if (w > best_w) {
            best_w = w;
            mask = 0;
          }
          if (w == best_w && w > 0.0) mask |= 1u << j;
        }
        if (mask == 0) mask = kPickAll;
        st->fast_pick[e] = static_cast<std::uint8_t>(mask);
      }
      if (mask != kPickAll) {
        // All of one (positive) weight: the nearest of them, as select_match would choose.
        PointIndex best_i = entry[__builtin_ctz(mask)];
        double best_d2 = squared_distance(q, target[best_i]);
        for (mask &= mask - 1; mask != 0; mask &= mask - 1) {
          const PointIndex i = entry[__builtin_ctz(mask)];
          const double d = squared_distance(q, target[i]);
          if (nearer_in_total_order(d, i, best_d2, best_i)) {
            best_i = i;
            best_d2 = d;
          }
        }
        idx[0] = best_i;
        d2[0] = best_d2;
        *chosen = true;
        return 1;
      }
    }
    const std::size_t got = std::min(st->gap_k, target_size);
    for (std::size_t j = 0; j < got; ++j) {
      idx[j] = entry[j];
      d2[j] = squared_distance(q, target[entry[j]]);
    }
    return got;
  }

  // Makes q (this call's pose applied to source point s) entry e's fast reference: d2 holds the
  // entry's `have` candidates sorted at q, and every other target point is at least `outside_m`
  // from q. The half gap is half of (min(d_(k+1), outside) - d_k), rounded down.
  void rebase_fast(std::size_t e, const double* d2, std::size_t have, double outside_m) const {
    const std::size_t k = st->gap_k;
    float half_gap = -1.0f;
    if (have <= k) {
      if (have >= target_size) half_gap = std::numeric_limits<float>::infinity();
    } else {
      const double next = std::min(std::sqrt(d2[k]), outside_m);
      const double gap = 0.5 * (next - std::sqrt(d2[k - 1]) * (1.0 + kSlack));
      if (gap > 0.0) half_gap = round_down_to_float(gap);
    }
    st->half_gap[e] = half_gap;
    st->fast_ref[e] = static_cast<std::uint16_t>(pose_id);
    st->fast_pick[e] = kPickUnknown;  // found by the first fast() that needs it
  }

  // The `want` first neighbours of q = T * source[s] in the tree's total order, written sorted
  // into idx/d2 (capacity >= 2 width); returns how many (min(want, target size)). Tries, in
  // turn: s's cache entry e; the entry `*lender` (the one this thread served last, usually of a
  // neighbour of s in the Morton order: its reference position may be nearer q than s's own);
  // a fresh search, seeded with entry e. Sets *searched if the tree was searched, and *lender
  // to e. Whatever serves, entry e's fast reference becomes q.
  std::size_t neighbours(std::size_t e, std::size_t s, const Vec3& q, std::size_t want,
                         PointIndex* idx, double* d2, bool* searched, std::ptrdiff_t* lender,
                         std::uint64_t* seed_marks) const {
    const std::size_t have = std::min(width, target_size);
    const std::size_t got = std::min(want, have);
    const bool own = st->reach[e] >= 0.0f;
    *searched = false;
    double outside_m = 0.0;
    if (own && entry_holds(e, q, want, idx, d2, &outside_m)) {
      // Keep the entry sorted as of now (cheaper to sort next time, and its first gap_k are
      // the k nearest at the new fast reference).
      PointIndex* entry = st->cand.data() + e * width;
      for (std::size_t j = 0; j < have; ++j) {
        if (entry[j] != idx[j]) entry[j] = idx[j];
      }
      rebase_fast(e, d2, have, outside_m);
      *lender = static_cast<std::ptrdiff_t>(e);
      return got;
    }
    if (*lender >= 0) {
      const auto l = static_cast<std::size_t>(*lender);
      // A lender whose bound is under 0.8 times the k-th distance of the point's own (failed)
      // candidates almost never holds: skip its re-evaluation (measured on the real pair: 1.5%
      // fewer instructions, 1.3% more searches; only the speed depends on this).
      const double give_up_below = own && got > 0 ? 0.8 * std::sqrt(d2[got - 1]) : 0.0;
      if (entry_holds(l, q, want, idx + width, d2 + width, &outside_m, give_up_below)) {
        std::copy(idx + width, idx + width + have, st->cand.data() + e * width);
        rebase_fast(e, d2 + width, have, outside_m);
        std::copy(idx + width, idx + width + got, idx);
        std::copy(d2 + width, d2 + width + got, d2);
        st->reach[e] = st->reach[l];
        st->ref[e] = st->ref[l];
        st->ref_source[e] = st->ref_source[l];
        *lender = static_cast<std::ptrdiff_t>(e);
        return got;
      }
    }
    // Search again, seeded with the old candidates re-evaluated at q (already sorted in idx/d2):
    // a tight bound from the start.
    const std::size_t found = own ? tree->knn_seeded(q, width, idx, d2, have, idx, d2, seed_marks)
                                  : tree->knn(q, width, idx, d2);
    *searched = true;
    if (found == 0) {
      st->reach[e] = -1.0f;
      st->half_gap[e] = -1.0f;
      return 0;
    }
    std::copy(idx, idx + found, st->cand.data() + e * width);
    st->reach[e] = found >= target_size ? std::numeric_limits<float>::infinity()
                                        : round_down_to_float(std::sqrt(d2[found - 1]));
    st->ref[e] = static_cast<std::uint16_t>(pose_id);
    st->ref_source[e] = static_cast<PointIndex>(s);
    // Beyond the found candidates, every target point is at least their last distance away.
    rebase_fast(e, d2, found,
                found >= target_size ? std::numeric_limits<double>::infinity()
                                     : std::sqrt(d2[found - 1]) * (1.0 - kSlack));
    *lender = static_cast<std::ptrdiff_t>(e);
    return std::min(want, found);
  }
};

}  // namespace

// ---------------------------------------------------------------------------------------------
// Finder

CorrespondenceFinder::CorrespondenceFinder(const KdTree& target, std::vector<double> target_weights,
                                           const CorrespondenceOptions& options)
    : target_(&target), weights_(std::move(target_weights)), options_(options) {
  init();
}

CorrespondenceFinder::CorrespondenceFinder(Borrow, const KdTree& target,
                                           const std::vector<double>& target_weights,
                                           const CorrespondenceOptions& options)
    : target_(&target), borrowed_weights_(&target_weights), options_(options) {
  init();
}

CorrespondenceFinder CorrespondenceFinder::borrowing(const KdTree& target,
                                                     const std::vector<double>& target_weights,
                                                     const CorrespondenceOptions& options) {
  return CorrespondenceFinder(Borrow{}, target, target_weights, options);
}

void CorrespondenceFinder::init() {
  static std::atomic<std::uint64_t> next_serial{1};
  serial_ = next_serial.fetch_add(1);
  std::string why;
  if (!options_.is_valid(&why)) throw InvalidArgument("correspondence options: " + why);
  const std::vector<double>& w = weights();
  if (options_.kind == CorrespondenceKind::kWeightedKnn && w.size() != target_->size()) {
    throw InvalidArgument("correspondence: " + std::to_string(w.size()) + " target weights for " +
                          std::to_string(target_->size()) + " target points");
  }
  for (std::size_t i = 0; i < w.size(); ++i) {
    if (!std::isfinite(w[i]) || w[i] < 0.0) {
      throw InvalidArgument("correspondence: target weight " + std::to_string(i) +
                            " must be finite and >= 0");
    }
  }
  // Squared threshold; an infinite (or huge) distance stays infinite.
  max_distance_sq_m2_ = std::isinf(options_.max_distance_m) || options_.max_distance_m > 1e150
                            ? std::numeric_limits<double>::infinity()
                            : options_.max_distance_m * options_.max_distance_m;
}

std::size_t CorrespondenceFinder::cache_width() const {
  const std::size_t k =
      options_.kind == CorrespondenceKind::kWeightedKnn ? static_cast<std::size_t>(options_.k) : 1;
  // k + m candidates: a wider cache survives larger motions but costs more per search and per
  // re-evaluation. Converged points take the fast path, which re-evaluates only k, so on the
  // real pair m = 5..8 costs the fewest instructions (k = 5: 79,240 searches at m = 3, 56,845 at
  // m = 5; docs/performance.md); 5 keeps the memory per landmark low.
  return k + std::max<std::size_t>(5, (k + 1) / 2);
}

namespace {

// The strategy applied to the k first neighbours. Returns the chosen correspondence, or one with
// target_index == kNoMatch. "Nearer" is the tree's total order (distance, then index): with
// kSorted the candidates come in that order (the searches' output), otherwise in any order (the
// fast path's); the choice is the same.
template <bool kSorted>
inline Correspondence select_match(PointIndex s, const PointIndex* idx, const double* d2,
                                   std::size_t found, bool weighted, const double* weights,
                                   double max_sq) {
  Correspondence c{s, kNoMatch, 0.0};
  std::size_t best = found;
  auto nearer = [&](std::size_t a, std::size_t b) {
    return nearer_in_total_order(d2[a], idx[a], d2[b], idx[b]);
  };
  if (!weighted) {
    if (kSorted) {
      best = found >= 1 ? 0 : found;
    } else {
      for (std::size_t j = 0; j < found; ++j) {
        if (best == found || nearer(j, best)) best = j;
      }
    }
    if (best < found && d2[best] <= max_sq) {
      c.target_index = idx[best];
      c.distance_sq_m2 = d2[best];
    }
    return c;
  }
  // Eq. 6: argmax of the target weight over candidates within range, the nearer one on equal
  // weights (sorted: a strict '>' keeps the earlier one); weight 0 never matches.
  // (Branch-free selection: the comparisons' outcomes are unpredictable.)
  double best_w = 0.0;
  for (std::size_t j = 0; j < found; ++j) {
    const double w = d2[j] <= max_sq ? weights[idx[j]] : 0.0;
    const bool better = w > best_w || (!kSorted && w == best_w && best < found && nearer(j, best));
    best_w = better ? w : best_w;
    best = better ? j : best;
  }
  if (best < found) {
    c.target_index = idx[best];
    c.distance_sq_m2 = d2[best];
  }
  return c;
}

// Removes the kNoMatch slots, keeping source order.
void compact(Correspondences& out) {
  std::size_t w = 0;
  for (std::size_t r = 0; r < out.size(); ++r) {
    if (out[r].target_index != kNoMatch) out[w++] = out[r];
  }
  out.resize(w);
}

}  // namespace

void CorrespondenceFinder::find(const Points3& source_points, Correspondences& out) const {
  const std::size_t n = source_points.size();
  const bool weighted = options_.kind == CorrespondenceKind::kWeightedKnn;
  const std::size_t k = weighted ? static_cast<std::size_t>(options_.k) : 1;
  const double* w = weights().data();
  out.resize(n);

  // One slot per source point, filled in parallel, then compacted in source order: the result
  // does not depend on the thread count or schedule.
  // An exception may not leave the region nor skip its worksharing loop: the allocations and
  // the iterations are captured one by one.
  FirstException error;
#pragma omp parallel
  {
    std::vector<PointIndex> idx;
    std::vector<double> dist;
    bool ready = false;
    error.capture([&] {
      idx.resize(k);
      dist.resize(k);
      ready = true;
    });
#pragma omp for schedule(static)
    for (std::ptrdiff_t s = 0; s < static_cast<std::ptrdiff_t>(n); ++s) {
      if (!ready) continue;
      error.capture([&] {
        const auto si = static_cast<std::size_t>(s);
        const std::size_t found = target_->knn(source_points[si], k, idx.data(), dist.data());
        out[si] = select_match<true>(static_cast<PointIndex>(si), idx.data(), dist.data(), found,
                                     weighted, w, max_distance_sq_m2_);
      });
    }
  }
  error.rethrow();
  compact(out);
}

void CorrespondenceFinder::bind(const Points3& source_points,
                                CorrespondenceWorkspace& workspace) const {
  CorrespondenceWorkspace::State& st = *workspace.state_;
  const std::size_t width = cache_width();
  const std::size_t k =
      options_.kind == CorrespondenceKind::kWeightedKnn ? static_cast<std::size_t>(options_.k) : 1;
  if (st.tree != target_ || st.source != &source_points || st.n != source_points.size() ||
      st.width != width || st.gap_k != k) {
    st.gap_k = k;
    st.tree = target_;
    st.source = &source_points;
    st.n = source_points.size();
    st.width = width;
    st.order = morton_order(source_points);
    st.inv.resize(st.n);
    for (std::size_t j = 0; j < st.n; ++j) st.inv[st.order[j]] = static_cast<PointIndex>(j);
    st.coord_max = 0.0;
    for (const Vec3& p : target_->points()) {
      st.coord_max = std::max(st.coord_max, p.cwiseAbs().maxCoeff());
    }
    st.source_norm_max = 0.0;
    for (const Vec3& p : source_points) {
      if (p.allFinite()) st.source_norm_max = std::max(st.source_norm_max, p.norm());
    }
    st.pose_bound_max = 0.0;
    st.searched = st.reused = st.fast = 0;
    st.cand.clear();
    st.reach.clear();
    st.ref.clear();
    st.ref_source.clear();
    st.half_gap.clear();
    st.fast_ref.clear();
    st.fast_pick.clear();
    st.poses.clear();
  }
}

void CorrespondenceFinder::find(const Points3& source_points, const Isometry3& T_target_source,
                                Points3& moved, Correspondences& out,
                                CorrespondenceWorkspace& workspace, bool reuse) const {
  bind(source_points, workspace);
  CorrespondenceWorkspace::State& st = *workspace.state_;
  const std::size_t n = source_points.size();
  const bool weighted = options_.kind == CorrespondenceKind::kWeightedKnn;
  const std::size_t k = weighted ? static_cast<std::size_t>(options_.k) : 1;
  const double* w = weights().data();
  const double max_sq = max_distance_sq_m2_;
  moved.resize(n);
  out.resize(n);

  Kernel kernel{
      target_, target_->points().data(), target_->size(), source_points.data(), &st, st.width, 0};
  bool pushed = false;
  if (reuse) {
    st.ensure_cache();
    kernel.pose_id =
        st.register_pose(T_target_source.linear(), T_target_source.translation(), &pushed);
    kernel.with_tolerance();
    // The fast path keeps only the largest-weight candidates where the choice cannot depend on
    // a distance limit; the marks are this finder's (another one's weights may differ).
    if (weighted && k <= 7 && std::isinf(max_sq)) {
      if (st.pick_serial != serial_) {
        std::fill(st.fast_pick.begin(), st.fast_pick.end(), std::uint8_t{kPickUnknown});
        st.pick_serial = serial_;
      }
      kernel.pick_weights = w;
    }
  }
  st.ensure_scratch(std::max(2 * st.width, k));
  if (reuse) st.ensure_marks();
  const std::size_t sw = st.scratch_stride;
  // Exactly transform_points(): R * p + t with R and t copied out of the isometry.
  const Mat3 R = T_target_source.linear();
  const Vec3 t = T_target_source.translation();
  const PointIndex* order = st.order.data();
  std::size_t searched = 0, reused = 0, fast = 0, unmatched = 0;
  // When the last pass on this workspace served nearly every point by the fast path (a
  // converged estimate), this one costs a few nanoseconds per point, less than waking the
  // thread pool (tens of microseconds with OMP_WAIT_POLICY=passive): it runs on this thread.
  // Measured on the real pair: 49 us per converged iteration on one thread against 93 us on
  // two (docs/performance.md). The result does not depend on it.
  const bool parallel = !(reuse && st.fast + st.reused > 0 && st.searched * 32 < n);

  // proc_bind(close): threads that migrate between cores lose their caches (measured on the
  // benchmark machine: docs/performance.md). An exception may not leave the region: each
  // iteration is captured.
  FirstException error;
#pragma omp parallel proc_bind(close) reduction(+ : searched, reused, fast, unmatched) if (parallel)
  {
    PointIndex* idx = st.scratch_idx.data() + static_cast<std::size_t>(omp_get_thread_num()) * sw;
    double* d2 = st.scratch_d2.data() + static_cast<std::size_t>(omp_get_thread_num()) * sw;
    std::ptrdiff_t lender = -1;  // this thread's last served entry (Morton order)
    std::uint64_t* marks = reuse ? st.marks_of_this_thread() : nullptr;
    // In Morton order: queries that follow each other touch the same parts of the tree.
#pragma omp for schedule(dynamic, 256)
    for (std::ptrdiff_t j = 0; j < static_cast<std::ptrdiff_t>(n); ++j) {
      error.capture([&] {
        const auto e = static_cast<std::size_t>(j);
        const PointIndex s = order[e];
        const Vec3 q = R * source_points[s] + t;
        std::size_t found = 0;
        bool sorted = true;   // the fast path leaves its candidates in the entry's order
        bool chosen = false;  // the fast path chose the match (idx[0])
        if (!q.allFinite()) {
          if (reuse) st.reach[e] = -1.0f;
          if (lender == j) lender = -1;
        } else if (reuse && (found = kernel.fast(e, s, q, idx, d2, &chosen)) > 0) {
          ++reused;
          ++fast;
          lender = j;
          sorted = false;
        } else if (reuse) {
          bool did_search = false;
          found = kernel.neighbours(e, s, q, k, idx, d2, &did_search, &lender, marks);
          if (did_search) {
            ++searched;
          } else {
            ++reused;
          }
        } else {
          found = target_->knn(q, k, idx, d2);
          ++searched;
        }
        // Straight into source order: Morton neighbours are mostly index neighbours in a SLAM
        // map (landmarks numbered along the trajectory), so the threads' writes rarely share a
        // cache line, and no staging buffer is needed.
        moved[s] = q;
        out[s] = chosen   ? Correspondence{static_cast<PointIndex>(s), idx[0], d2[0]}
                 : sorted ? select_match<true>(s, idx, d2, found, weighted, w, max_sq)
                          : select_match<false>(s, idx, d2, found, weighted, w, max_sq);
        unmatched += out[s].target_index == kNoMatch ? 1 : 0;
      });
    }
  }
  error.rethrow();
  // No entry refers to this pose unless a point was searched or re-based (not all took the fast
  // path).
  if (pushed && searched + reused == fast) st.poses.pop_back();
  st.searched = searched;
  st.reused = reused;
  st.fast = fast;
  if (unmatched > 0) compact(out);  // (never, without a distance limit or zero weights)
}

void CorrespondenceFinder::nearest_sq_distances(const Points3& source_points,
                                                const Isometry3& T_target_source, std::size_t begin,
                                                std::size_t end, double* d2_out,
                                                CorrespondenceWorkspace& workspace) const {
  bind(source_points, workspace);
  CorrespondenceWorkspace::State& st = *workspace.state_;
  end = std::min(end, source_points.size());
  if (begin >= end) return;
  st.ensure_cache();
  st.ensure_scratch(2 * st.width);
  st.ensure_marks();
  bool pushed = false;
  Kernel kernel{
      target_, target_->points().data(), target_->size(), source_points.data(), &st, st.width, 0};
  kernel.pose_id =
      st.register_pose(T_target_source.linear(), T_target_source.translation(), &pushed);
  kernel.with_tolerance();
  const std::size_t sw = st.scratch_stride;
  const Mat3 R = T_target_source.linear();
  const Vec3 t = T_target_source.translation();
  std::size_t searched = 0, reused = 0, fast = 0;

  FirstException error;  // an exception may not leave the region: each iteration is captured
#pragma omp parallel proc_bind(close) reduction(+ : searched, reused, fast)
  {
    PointIndex* idx = st.scratch_idx.data() + static_cast<std::size_t>(omp_get_thread_num()) * sw;
    double* d2 = st.scratch_d2.data() + static_cast<std::size_t>(omp_get_thread_num()) * sw;
    std::ptrdiff_t lender = -1;
    std::uint64_t* marks = st.marks_of_this_thread();
#pragma omp for schedule(static)
    for (std::ptrdiff_t i = static_cast<std::ptrdiff_t>(begin);
         i < static_cast<std::ptrdiff_t>(end); ++i) {
      error.capture([&] {
        const auto s = static_cast<std::size_t>(i);
        const Vec3 q = R * source_points[s] + t;
        double value = std::numeric_limits<double>::infinity();
        const std::size_t e = st.inv[s];
        // The fast path serves any want <= k: the nearest is among an unchanged k nearest.
        const std::size_t fast_found = q.allFinite() ? kernel.fast(e, s, q, idx, d2) : 0;
        if (fast_found >= 1) {
          value = *std::min_element(d2, d2 + fast_found);
          ++reused;
          ++fast;
          lender = static_cast<std::ptrdiff_t>(e);
        } else if (q.allFinite()) {
          bool did_search = false;
          if (kernel.neighbours(e, s, q, 1, idx, d2, &did_search, &lender, marks) == 1) {
            value = d2[0];
          }
          if (did_search) {
            ++searched;
          } else {
            ++reused;
          }
        } else {
          st.reach[e] = -1.0f;
          if (lender == static_cast<std::ptrdiff_t>(e)) lender = -1;
        }
        d2_out[s - begin] = value;
      });
    }
  }
  error.rethrow();
  if (pushed && searched + reused == fast) st.poses.pop_back();
  st.searched = searched;
  st.reused = reused;
  st.fast = fast;
}

}  // namespace lmalign
