// The correspondence search: descriptors, matches, a covariance-aware consistency graph, cliques
// (include/lmalign/registration/stages/correspondence_search.hpp).
#include "lmalign/registration/stages/correspondence_search.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/registration/estimation_4dof.hpp"
#include "lmalign/registration/stages/complete_search.hpp"
#include "lmalign/registration/stages/landmark_descriptors.hpp"
#include "lmalign/registration/stages/yaw_vote_search.hpp"
#include "lmalign/search/kdtree.hpp"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

namespace lmalign {

bool CorrespondenceSearchOptions::is_valid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why != nullptr) *why = m;
    return false;
  };
  if (keypoints < 3 || target_keypoints < 3) return fail("keypoints must be >= 3");
  if (neighbours < 4 || neighbours > 256) return fail("neighbours must be in [4, 256]");
  if (matches_per_keypoint < 1 || matches_per_keypoint > 16) {
    return fail("matches_per_keypoint must be in [1, 16]");
  }
  if (!(consistency_sigmas > 0.0) || !std::isfinite(consistency_sigmas)) {
    return fail("consistency_sigmas must be > 0 and finite");
  }
  if (seeds < 1 || min_inliers < 3 || hypotheses < 1) {
    return fail("seeds and hypotheses must be >= 1, min_inliers >= 3");
  }
  if (scale_steps < 0 || scale_steps > 64) return fail("scale_steps must be in [0, 64]");
  if (refits < 0 || refits > 16) return fail("refits must be in [0, 16]");
  if (!(scale_ratio > 1.0) || !std::isfinite(scale_ratio)) {
    return fail("scale_ratio must be > 1 and finite");
  }
  return true;
}

namespace {

// The oriented descriptor's radius over the yaw-invariant one's: a wider neighbourhood tells
// more apart, and in it the azimuth bins are wider in metres (measured on the street seeds and
// the real pairs: recall of the true counterpart about that of radii r and 2r together, at half
// the components).
constexpr double kOrientedRadiusFactor = 1.5;
// The weight of the viewing direction's elevation beside the unit-norm shape histogram.
constexpr float kElevationWeight = 0.5f;

// One side of the search: its landmarks, their standard deviations, a tree over them.
struct Side {
  const Points3* points = nullptr;
  const KdTree* tree = nullptr;
  std::vector<double> sigma_m;  // per landmark: sqrt(trace(C) / 3), at least the floor
  const std::vector<Vec3>* views = nullptr;
  bool has_views() const { return views != nullptr && views->size() == points->size(); }
};

std::vector<double> sigmas(const Points3& points, const std::vector<Mat3>* cov, double floor_m) {
  std::vector<double> s(points.size(), floor_m);
  if (cov == nullptr || cov->size() != points.size()) return s;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const double v = (*cov)[i].trace() / 3.0;
    if (std::isfinite(v)) s[i] = std::max(floor_m, std::sqrt(std::max(v, 0.0)));
  }
  return s;
}

// The descriptor of landmark i of a side (landmark_descriptors.hpp): the oriented one when
// `oriented` (the sides know their viewing directions), else the yaw-invariant one; with the
// viewing elevation appended when `elevation`.
bool describe(const Side& side, std::size_t i, const Vec3& up, double radius_m,
              std::size_t neighbours, bool elevation, bool oriented, float* out,
              std::vector<PointIndex>* scratch) {
  if (oriented) {
    const Vec3& view = (*side.views)[i];
    if (!describe_landmark_oriented(*side.points, *side.tree, i, up, view,
                                    kOrientedRadiusFactor * radius_m, out, scratch)) {
      return false;
    }
    out[kOrientedDescriptorDims] = kElevationWeight * static_cast<float>(view.dot(up));
    return true;
  }
  return describe_landmark(*side.points, *side.tree, i, up, radius_m, neighbours, out,
                           elevation ? &(*side.views)[i] : nullptr, kElevationWeight);
}

struct Match {
  PointIndex s, t;
};

// The consistency graph: adjacency as bit rows and as lists.
struct Graph {
  std::vector<std::vector<std::uint64_t>> adj;
  std::vector<std::vector<std::uint32_t>> nbr;
};

// The descriptors' components reordered by decreasing variance over the target's valid
// descriptors (ties by index), so that a partial distance exceeds a bound as early as it can.
std::vector<int> by_variance(const std::vector<float>& td, const std::vector<char>& tok, int dims) {
  std::vector<double> sum(dims, 0.0), sum2(dims, 0.0);
  double n = 0.0;
  for (std::size_t b = 0; b < tok.size(); ++b) {
    if (!tok[b]) continue;
    n += 1.0;
    for (int x = 0; x < dims; ++x) {
      const double v = td[b * dims + x];
      sum[x] += v;
      sum2[x] += v * v;
    }
  }
  std::vector<double> var(dims, 0.0);
  for (int x = 0; x < dims && n > 0.0; ++x) var[x] = sum2[x] / n - (sum[x] / n) * (sum[x] / n);
  std::vector<int> order(dims);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return var[a] > var[b]; });
  return order;
}

// Copies of the descriptors with their components in `order`.
std::vector<float> permuted(const std::vector<float>& d, const std::vector<int>& order) {
  const std::size_t dims = order.size();
  std::vector<float> out(d.size());
  for (std::size_t a = 0; a * dims < d.size(); ++a) {
    for (std::size_t x = 0; x < dims; ++x) out[a * dims + x] = d[a * dims + order[x]];
  }
  return out;
}

// The sums of squared differences between q and `lanes` targets at once, one target per lane,
// from a copy laid out component by component (t[x * lanes + l] is component x of target l),
// each lane's single-precision operations in the scalar loop's order, so that a complete sum is
// bit for bit the scalar one. The sums stop after a block of kBlock components in which every
// lane exceeds `bound` (the partial sums are then all beyond it). Written to sums[0, lanes).
constexpr int kBlock = 16;  // components summed between two tests of the bound
using LaneSums = void (*)(const float* q, const float* t, int dims, float bound, float* sums);

#if defined(__SSE2__)
void lane_sums_sse2(const float* q, const float* t, int dims, float bound, float* sums) {
  const __m128 b = _mm_set1_ps(bound);
  __m128 d = _mm_setzero_ps();
  for (int x0 = 0; x0 < dims; x0 += kBlock) {
    const int x1 = std::min(dims, x0 + kBlock);
    for (int x = x0; x < x1; ++x) {
      const __m128 e = _mm_sub_ps(_mm_set1_ps(q[x]), _mm_loadu_ps(t + 4 * x));
      d = _mm_add_ps(d, _mm_mul_ps(e, e));
    }
    if (_mm_movemask_ps(_mm_cmpgt_ps(d, b)) == 0xF) break;
  }
  _mm_storeu_ps(sums, d);
}
#endif

#if defined(__x86_64__) && defined(__GNUC__)
// Eight lanes where the CPU has AVX (x86-64's baseline has SSE2 only): the same products and
// sums per lane (no fused multiply-add), so the same matches. lane_sums_sse2's loop at twice
// the width; a function of its own because only it may use AVX (its target attribute).
__attribute__((target("avx"))) void lane_sums_avx(const float* q, const float* t, int dims,
                                                  float bound, float* sums) {
  const __m256 b = _mm256_set1_ps(bound);
  __m256 d = _mm256_setzero_ps();
  for (int x0 = 0; x0 < dims; x0 += kBlock) {
    const int x1 = std::min(dims, x0 + kBlock);
    for (int x = x0; x < x1; ++x) {
      const __m256 e = _mm256_sub_ps(_mm256_set1_ps(q[x]), _mm256_loadu_ps(t + 8 * x));
      d = _mm256_add_ps(d, _mm256_mul_ps(e, e));
    }
    if (_mm256_movemask_ps(_mm256_cmp_ps(d, b, _CMP_GT_OQ)) == 0xFF) break;
  }
  _mm256_storeu_ps(sums, d);
}
#endif

// The summing kernel of `lanes` lanes (0: the widest this CPU runs, chosen once), or null when
// this build or CPU has none of that width (1: the scalar loop, always).
LaneSums lane_sums(std::size_t* lanes) {
#if defined(__x86_64__) && defined(__GNUC__)
  static const bool avx = __builtin_cpu_supports("avx");
#else
  static const bool avx = false;
#endif
#if defined(__SSE2__)
  constexpr bool sse2 = true;
#else
  constexpr bool sse2 = false;
#endif
  if (*lanes == 0) *lanes = avx ? 8 : sse2 ? 4 : 1;
#if defined(__x86_64__) && defined(__GNUC__)
  if (*lanes == 8 && avx) return &lane_sums_avx;
#endif
#if defined(__SSE2__)
  if (*lanes == 4) return &lane_sums_sse2;
#endif
  return nullptr;
}

// Each valid source descriptor's `m` nearest valid target descriptors (Euclidean; ties by the
// earlier target keypoint), as matches of landmark indices. Exact: a candidate's sum stops once
// it exceeds the m-th best so far, which it can then never beat (the components are summed in
// decreasing order of their variance, so that this happens early).
std::vector<Match> nearest_descriptors(const std::vector<std::uint32_t>& skeys,
                                       const std::vector<float>& sd_in,
                                       const std::vector<char>& sok,
                                       const std::vector<std::uint32_t>& tkeys,
                                       const std::vector<float>& td_in,
                                       const std::vector<char>& tok, int dims, std::size_t m,
                                       std::size_t W = 0) {
  const LaneSums kernel = lane_sums(&W);
  if (kernel == nullptr && W != 1) {
    throw InvalidArgument("match_descriptors: no " + std::to_string(W) +
                          "-lane kernel in this build or on this CPU");
  }
  const std::vector<int> order = by_variance(td_in, tok, dims);
  const std::vector<float> sd = permuted(sd_in, order), td = permuted(td_in, order);
  std::vector<Match> matches;
  std::vector<std::pair<float, std::uint32_t>> best;
  // Offers target b's distance d (complete, or partial and already beyond the bound it was
  // summed against, which is never below the current one).
  auto offer = [&](float d, std::size_t b) {
    if (best.size() < m || d < best.back().first) {
      const std::pair<float, std::uint32_t> e{d, static_cast<std::uint32_t>(b)};
      best.insert(std::upper_bound(best.begin(), best.end(), e), e);
      if (best.size() > m) best.pop_back();
    }
  };
  auto bound_now = [&] {
    return best.size() < m ? std::numeric_limits<float>::infinity() : best.back().first;
  };
  if (kernel != nullptr) {
    // W targets at a time (4 with SSE2, 8 with AVX), one per lane (lane_sums_sse2). A block of
    // targets stops when every lane exceeds the bound of the block's start; the bound only
    // falls, so a stopped lane could never have been kept (the scalar loop would have stopped it
    // too), and a lane summed further than the scalar loop would go is beyond the bound anyway.
    // The matches are exactly the scalar loop's for every width (issue 39, time).
    const std::size_t blocks = (tkeys.size() + W - 1) / W;
    std::vector<float> lanes(blocks * static_cast<std::size_t>(dims) * W, 0.0f);
    std::vector<char> any_ok(blocks, 0);
    for (std::size_t b = 0; b < tkeys.size(); ++b) {
      for (int x = 0; x < dims; ++x) {
        lanes[((b / W) * static_cast<std::size_t>(dims) + static_cast<std::size_t>(x)) * W +
              b % W] = td[b * dims + x];
      }
      any_ok[b / W] = any_ok[b / W] || tok[b];
    }
    float sums[8];
    for (std::size_t a = 0; a < skeys.size(); ++a) {
      if (!sok[a]) continue;
      best.clear();
      const float* q = &sd[a * dims];
      for (std::size_t j = 0; j < blocks; ++j) {
        if (!any_ok[j]) continue;
        kernel(q, &lanes[j * static_cast<std::size_t>(dims) * W], dims, bound_now(), sums);
        for (std::size_t l = 0; l < W; ++l) {
          const std::size_t b = W * j + l;
          if (b < tkeys.size() && tok[b]) offer(sums[l], b);
        }
      }
      for (const auto& e : best) matches.push_back({skeys[a], tkeys[e.second]});
    }
    return matches;
  }
  for (std::size_t a = 0; a < skeys.size(); ++a) {
    if (!sok[a]) continue;
    best.clear();
    const float* q = &sd[a * dims];
    for (std::size_t b = 0; b < tkeys.size(); ++b) {
      if (!tok[b]) continue;
      const float* t = &td[b * dims];
      const float bound = bound_now();
      float d = 0.0f;
      for (int x0 = 0; x0 < dims && d <= bound; x0 += kBlock) {
        const int x1 = std::min(dims, x0 + kBlock);
        for (int x = x0; x < x1; ++x) {
          const float e = q[x] - t[x];
          d += e * e;
        }
      }
      offer(d, b);
    }
    for (const auto& e : best) matches.push_back({skeys[a], tkeys[e.second]});
  }
  return matches;
}

// Two matches agree when the source pair times a factor and the target pair have the same
// horizontal distance and height difference (about each map's up axis) within `sigmas` standard
// deviations of the four landmarks, plus `relative` times the target's distance (the scale's
// tolerance; 0 when rigid); matches sharing a landmark never agree. One graph per factor, each
// pair's geometry computed once.
//
// Rigid (one factor, no relative tolerance), the height test is a window: f hs - ht is
// u_b - u_a with u = f (p_s . up_s) - (p_t . up_t) per match, and its tolerance is at most
// sqrt(e_a + max e) with e = sigmas^2 (f^2 sd_s^2 + sd_t^2). The matches sorted by u, each is
// tested only against those within that window of it (widened by 1e-9 of the coordinates'
// magnitude for the round-off between the two forms), with the same test as every pair, so the
// graph is the same; the merge's verification spent two thirds of its time here (docs/merge.md).
std::vector<Graph> consistency_graphs(const std::vector<Match>& matches, const Side& src,
                                      const Vec3& us, const Side& tgt, const Vec3& ut,
                                      double sigmas, const std::vector<double>& factors,
                                      double relative) {
  const Points3& P = *src.points;
  const Points3& Q = *tgt.points;
  const std::size_t n = matches.size();
  const std::size_t words = (n + 63) / 64;
  std::vector<Graph> graphs(factors.size());
  for (Graph& g : graphs) {
    g.adj.assign(n, std::vector<std::uint64_t>(words, 0));
    g.nbr.resize(n);
  }
  const double c2 = sigmas * sigmas;
  auto var = [](double s) { return s * s; };
  // Each match's landmarks and variances side by side, so that the loops below read them in
  // sequence rather than through the landmark indices.
  struct Row {
    Vec3 ps, pt;
    double vs = 0.0, vt = 0.0;  // variance of the source and of the target landmark
    PointIndex s = 0, t = 0;
    std::size_t index = 0;  // the match's
  };
  auto row_of = [&](std::size_t a) {
    const Match& m = matches[a];
    return Row{P[m.s], Q[m.t], var(src.sigma_m[m.s]), var(tgt.sigma_m[m.t]), m.s, m.t, a};
  };
  // The test of matches x < y (by index) at every factor. On a ladder (factors ascending), only
  // the factors the horizontal test can pass at are tested: |f rs - rt| <= sqrt(tol2(f)) <= T,
  // T = sqrt(tol2) at the largest factor, puts f within (rt -+ T) / rs, widened by 1e-9 for the
  // round-off; the test itself is unchanged, so are the graphs (the free scale's measurement
  // spent most of its graph time in this loop, docs/scale.md).
  const bool ladder = factors.size() > 1 && std::is_sorted(factors.begin(), factors.end());
  const double f_max = factors.empty() ? 0.0 : factors.back();
  auto test = [&](const Row& x, const Row& y) {
    if (x.s == y.s || x.t == y.t) return;
    const Vec3 ds = y.ps - x.ps, dt = y.pt - x.pt;
    const double hs = ds.dot(us), ht = dt.dot(ut);
    const double vs = x.vs + y.vs;
    const double vtx = x.vt, vty = y.vt;
    const double dt2 = dt.squaredNorm();
    const double rs = std::sqrt(std::max(ds.squaredNorm() - hs * hs, 0.0));
    const double rt = std::sqrt(std::max(dt2 - ht * ht, 0.0));
    std::size_t k_first = 0;
    std::size_t k_end = factors.size();
    if (ladder && rs > 0.0) {
      const double T = std::sqrt(c2 * (f_max * f_max * vs + vtx + vty) + var(relative) * dt2);
      double lo = (rt - T) / rs;
      double hi = (rt + T) / rs;
      lo -= 1e-9 * (1.0 + std::abs(lo));
      hi += 1e-9 * (1.0 + std::abs(hi));
      k_first = static_cast<std::size_t>(std::lower_bound(factors.begin(), factors.end(), lo) -
                                         factors.begin());
      k_end = static_cast<std::size_t>(std::upper_bound(factors.begin(), factors.end(), hi) -
                                       factors.begin());
    }
    for (std::size_t k = k_first; k < k_end; ++k) {
      const double f = factors[k];
      const double noise2 = c2 * (f * f * vs + vtx + vty);
      const double tol2 = relative > 0.0 ? noise2 + var(relative) * dt2 : noise2;
      if ((f * hs - ht) * (f * hs - ht) > tol2) continue;
      if ((f * rs - rt) * (f * rs - rt) > tol2) continue;
      const std::size_t a = x.index, b = y.index;
      Graph& g = graphs[k];
      g.adj[a][b / 64] |= std::uint64_t{1} << (b % 64);
      g.adj[b][a / 64] |= std::uint64_t{1} << (a % 64);
      g.nbr[a].push_back(static_cast<std::uint32_t>(b));
      g.nbr[b].push_back(static_cast<std::uint32_t>(a));
    }
  };
  if (factors.size() != 1 || relative > 0.0) {
    std::vector<Row> rows(n);
    for (std::size_t a = 0; a < n; ++a) rows[a] = row_of(a);
    for (std::size_t a = 0; a < n; ++a) {
      for (std::size_t b = a + 1; b < n; ++b) test(rows[a], rows[b]);
    }
    return graphs;
  }
  const double f = factors[0];
  std::vector<double> u(n), e(n);
  double e_max = 0.0, magnitude = 0.0;
  for (std::size_t a = 0; a < n; ++a) {
    const double hs = P[matches[a].s].dot(us), ht = Q[matches[a].t].dot(ut);
    u[a] = f * hs - ht;
    e[a] = c2 * (f * f * var(src.sigma_m[matches[a].s]) + var(tgt.sigma_m[matches[a].t]));
    e_max = std::max(e_max, e[a]);
    magnitude = std::max(magnitude, std::abs(f * hs) + std::abs(ht));
  }
  const double margin = 1e-9 * (1.0 + magnitude);
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return u[a] < u[b]; });
  std::vector<Row> rows(n);
  std::vector<double> sorted_u(n);
  for (std::size_t i = 0; i < n; ++i) {
    rows[i] = row_of(order[i]);
    sorted_u[i] = u[order[i]];
  }
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t a = order[i];
    const double reach = u[a] + std::sqrt(e[a] + e_max) + margin;
    for (std::size_t j = i + 1; j < n && sorted_u[j] <= reach; ++j) {
      if (rows[i].index < rows[j].index) {
        test(rows[i], rows[j]);
      } else {
        test(rows[j], rows[i]);
      }
    }
  }
  // The neighbour lists in increasing order, as the loop over every pair leaves them.
  for (std::vector<std::uint32_t>& list : graphs[0].nbr) std::sort(list.begin(), list.end());
  return graphs;
}

// The set bits of a & b over `words` words: with the CPU's popcnt instruction where it has one
// (x86-64's baseline lacks it, and the generic bit count was a third of a free-scale alignment's
// time), chosen once at run time.
inline __attribute__((always_inline)) std::size_t count_common_bits(const std::uint64_t* a,
                                                                    const std::uint64_t* b,
                                                                    std::size_t words) {
  std::size_t n = 0;
  for (std::size_t x = 0; x < words; ++x) {
    n += static_cast<std::size_t>(__builtin_popcountll(a[x] & b[x]));
  }
  return n;
}
std::size_t common_bits_generic(const std::uint64_t* a, const std::uint64_t* b, std::size_t words) {
  return count_common_bits(a, b, words);
}
using CommonBits = std::size_t (*)(const std::uint64_t*, const std::uint64_t*, std::size_t);
#if defined(__x86_64__) && defined(__GNUC__)
__attribute__((target("popcnt"))) std::size_t common_bits_popcnt(const std::uint64_t* a,
                                                                 const std::uint64_t* b,
                                                                 std::size_t words) {
  return count_common_bits(a, b, words);
}
CommonBits common_bits_function() {
  return __builtin_cpu_supports("popcnt") ? &common_bits_popcnt : &common_bits_generic;
}
#else
CommonBits common_bits_function() { return &common_bits_generic; }
#endif

// Greedy cliques of the consistency graph (see the header): lists of match indices.
std::vector<std::vector<std::size_t>> cliques(const Graph& graph, std::size_t seeds,
                                              std::size_t min_size) {
  const std::vector<std::vector<std::uint64_t>>& adj = graph.adj;
  const std::vector<std::vector<std::uint32_t>>& nbr = graph.nbr;
  const std::size_t n = adj.size();
  std::vector<std::vector<std::size_t>> out;
  if (n == 0) return out;
  const std::size_t words = adj[0].size();
  // Core numbers (Batagelj-Zaversnik, by repeated removal of a vertex of smallest degree).
  std::vector<std::size_t> degree(n), core(n, 0);
  for (std::size_t v = 0; v < n; ++v) degree[v] = nbr[v].size();
  {
    std::vector<char> removed(n, 0);
    std::vector<std::size_t> deg = degree;
    std::size_t max_deg = 0;
    for (std::size_t d : deg) max_deg = std::max(max_deg, d);
    std::vector<std::vector<std::uint32_t>> bucket(max_deg + 1);
    for (std::size_t v = 0; v < n; ++v) bucket[deg[v]].push_back(static_cast<std::uint32_t>(v));
    std::size_t k = 0;
    // The smallest non-empty bucket: removing a vertex of degree d lowers its neighbours' to at
    // least d - 1, so every bucket below that stays empty and the scan starts there (the same
    // order of removals as scanning from 0, without its cost on a dense graph).
    std::size_t d = 0;
    for (std::size_t done = 0; done < n;) {
      d = d > 0 ? d - 1 : 0;
      while (d <= max_deg && bucket[d].empty()) ++d;
      const std::uint32_t v = bucket[d].back();
      bucket[d].pop_back();
      if (removed[v] || deg[v] != d) continue;
      removed[v] = 1;
      ++done;
      k = std::max(k, d);
      core[v] = k;
      for (std::uint32_t u : nbr[v]) {
        if (!removed[u] && deg[u] > 0) {
          --deg[u];
          bucket[deg[u]].push_back(u);
        }
      }
    }
  }
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return core[a] != core[b] ? core[a] > core[b] : degree[a] > degree[b];
  });
  std::vector<char> used(n, 0);
  std::vector<std::uint64_t> cand(words), removed(words);
  // links[u]: u's neighbours among the candidates, for every candidate u; kept as the candidates
  // shrink (each one removed lowers its candidate neighbours' counts once), so that a clique of
  // C vertices costs the seed's degree times the words once, not C times.
  std::vector<std::uint32_t> links(n, 0);
  static const CommonBits common_bits = common_bits_function();
  auto for_each_bit = [words](const std::vector<std::uint64_t>& set, auto&& f) {
    for (std::size_t w = 0; w < words; ++w) {
      for (std::uint64_t bits = set[w]; bits != 0; bits &= bits - 1) {
        f(w * 64 + static_cast<std::size_t>(__builtin_ctzll(bits)));
      }
    }
  };
  for (std::size_t v : order) {
    if (out.size() >= seeds || core[v] + 1 < min_size) break;
    if (used[v]) continue;
    std::vector<std::size_t> clique{v};
    cand = adj[v];
    for_each_bit(cand, [&](std::size_t u) {
      links[u] = static_cast<std::uint32_t>(common_bits(adj[u].data(), cand.data(), words));
    });
    for (;;) {
      // The candidate with the most links to the others, the first (lowest index) on a tie.
      std::size_t best = n, best_links = 0;
      for_each_bit(cand, [&](std::size_t u) {
        if (best == n || links[u] > best_links) {
          best = u;
          best_links = links[u];
        }
      });
      if (best == n) break;
      clique.push_back(best);
      for (std::size_t x = 0; x < words; ++x) {
        removed[x] = cand[x] & ~adj[best][x];  // best itself among them (no self-loops)
        cand[x] &= adj[best][x];
      }
      for_each_bit(removed, [&](std::size_t r) {
        const std::uint64_t* row = adj[r].data();
        for (std::size_t x = 0; x < words; ++x) {
          for (std::uint64_t bits = row[x] & cand[x]; bits != 0; bits &= bits - 1) {
            --links[x * 64 + static_cast<std::size_t>(__builtin_ctzll(bits))];
          }
        }
      });
    }
    if (clique.size() < min_size) continue;
    for (std::size_t u : clique) used[u] = 1;
    out.push_back(std::move(clique));
  }
  return out;
}

// The poses by decreasing inliers, without near-duplicates (the source's centre moved by less
// than `near_m`, a turn under 5 deg and scales within `same_scale` of each other as a ratio),
// at most `keep`.
std::vector<CorrespondenceHypothesis> distinct_poses(std::vector<CorrespondenceHypothesis> poses,
                                                     const Points3& source, double near_m,
                                                     double same_scale, std::size_t keep) {
  std::stable_sort(poses.begin(), poses.end(),
                   [](const CorrespondenceHypothesis& a, const CorrespondenceHypothesis& b) {
                     return a.inliers > b.inliers;
                   });
  Vec3 centre = Vec3::Zero();
  for (const Vec3& p : source) centre += p;
  centre /= static_cast<double>(source.size());
  std::vector<CorrespondenceHypothesis> out;
  for (const CorrespondenceHypothesis& h : poses) {
    if (out.size() >= keep) break;
    bool dup = false;
    for (const CorrespondenceHypothesis& k : out) {
      const double moved =
          (h.T_target_source * (h.scale * centre) - k.T_target_source * (k.scale * centre)).norm();
      const double turn =
          rotation_angle_deg(h.T_target_source.linear().transpose() * k.T_target_source.linear());
      const bool scale = std::abs(std::log(h.scale / k.scale)) < std::log(same_scale);
      dup = dup || (moved < near_m && turn < 5.0 && scale);
    }
    if (!dup) out.push_back(h);
  }
  return out;
}

// A clique's pose: 4-DoF (estimate_4dof_transform after turning the source's up onto the
// target's) with the source times `factor`; with `measure_scale`, the clique's own scale
// (Umeyama's, from the rotation at `factor`) and the pose again at that scale.
CorrespondenceHypothesis clique_pose(const std::vector<std::size_t>& clique,
                                     const std::vector<Match>& matches, const Points3& P,
                                     const Points3& Q, const Mat3& R_up, const Vec3& ut,
                                     double factor, bool measure_scale) {
  Points3 s_pts, t_pts;
  Correspondences corr;
  for (std::size_t a : clique) {
    corr.push_back(
        {static_cast<PointIndex>(s_pts.size()), static_cast<PointIndex>(t_pts.size()), 0.0});
    s_pts.push_back(R_up * P[matches[a].s]);
    t_pts.push_back(Q[matches[a].t]);
  }
  auto pose_at = [&](double scale) {
    Points3 scaled = s_pts;
    for (Vec3& p : scaled) p *= scale;
    return estimate_4dof_transform(scaled, t_pts, corr, nullptr, ut);
  };
  double scale = factor;
  Isometry3 T = pose_at(scale);
  if (measure_scale) {
    Vec3 ms = Vec3::Zero(), mt = Vec3::Zero();
    for (std::size_t i = 0; i < s_pts.size(); ++i) {
      ms += s_pts[i];
      mt += t_pts[i];
    }
    ms /= static_cast<double>(s_pts.size());
    mt /= static_cast<double>(t_pts.size());
    double num = 0.0, den = 0.0;
    for (std::size_t i = 0; i < s_pts.size(); ++i) {
      num += (t_pts[i] - mt).dot(T.linear() * (s_pts[i] - ms));
      den += (s_pts[i] - ms).squaredNorm();
    }
    if (den > 0.0 && num > 0.0 && std::isfinite(num / den)) {
      scale = num / den;
      T = pose_at(scale);
    }
  }
  T.linear() = T.linear() * R_up;
  return {T, clique.size(), scale};
}

// A rigid clique pose refitted (step 4; LO-RANSAC's local optimisation): the 4-DoF pose (after
// R_up turns the source's up onto the target's, `ut`) from every match whose source landmark the
// pose puts within `sigmas` standard deviations (both landmarks' sigma_m) of its target landmark,
// the nearest such match of each source keypoint (a keypoint's matches are consecutive in
// `matches`); again until those matches repeat (a fixed point), at most `refits` times. Stops,
// keeping the last pose, when fewer than 3 matches agree.
Isometry3 refit_pose(Isometry3 T, const std::vector<Match>& matches, const Side& src,
                     const Side& tgt, const Mat3& R_up, const Vec3& ut, double sigmas, int refits) {
  const Points3& P = *src.points;
  const Points3& Q = *tgt.points;
  const double sigmas2 = sigmas * sigmas;
  Points3 s_pts, t_pts;
  Correspondences corr;
  std::vector<std::size_t> picked, last;
  for (int it = 0; it < refits; ++it) {
    s_pts.clear();
    t_pts.clear();
    corr.clear();
    picked.clear();
    for (std::size_t a = 0; a < matches.size();) {
      const PointIndex si = matches[a].s;
      const Vec3 p = T * P[si];
      const double ss2 = src.sigma_m[si] * src.sigma_m[si];
      std::size_t b = a;
      std::size_t pick = matches.size();
      double best2 = std::numeric_limits<double>::infinity();
      for (; b < matches.size() && matches[b].s == si; ++b) {
        const PointIndex ti = matches[b].t;
        const double d2 = (p - Q[ti]).squaredNorm();
        const double tol2 = sigmas2 * (ss2 + tgt.sigma_m[ti] * tgt.sigma_m[ti]);
        if (d2 < tol2 && d2 < best2) {
          best2 = d2;
          pick = b;
        }
      }
      if (pick < matches.size()) {
        corr.push_back(
            {static_cast<PointIndex>(s_pts.size()), static_cast<PointIndex>(t_pts.size()), 0.0});
        s_pts.push_back(R_up * P[si]);
        t_pts.push_back(Q[matches[pick].t]);
        picked.push_back(pick);
      }
      a = b;
    }
    if (s_pts.size() < 3 || picked == last) break;
    last.swap(picked);
    T = estimate_4dof_transform(s_pts, t_pts, corr, nullptr, ut);
    T.linear() = T.linear() * R_up;
  }
  return T;
}

// One side's descriptors of one kind about one up axis: keys x dims floats, and whether each is
// valid (described, and the landmark not vague).
struct Described {
  std::vector<float> d;
  std::vector<char> ok;
};

// Steps 2-4 for one descriptor kind and one pair of up axes: matches, the consistency graph,
// cliques, their distinct poses. Adds the matches to *matches_total.
std::vector<CorrespondenceHypothesis> poses_of_pair(
    const std::vector<std::uint32_t>& skeys, const Described& sd,
    const std::vector<std::uint32_t>& tkeys, const Described& td, int dims, const Side& src,
    const Vec3& us, const Side& tgt, const Vec3& ut, const CorrespondenceSearchOptions& o,
    double radius, bool oriented, std::size_t* matches_total) {
  // 2. matches, 3. the consistency graph
  const std::vector<Match> matches =
      nearest_descriptors(skeys, sd.d, sd.ok, tkeys, td.d, td.ok, dims, o.matches_per_keypoint);
  *matches_total += matches.size();
  // 4. cliques -> 4-DoF poses, at each factor of the scale ladder (the factor 1 alone when
  // rigid)
  std::vector<CorrespondenceHypothesis> found;
  const Mat3 R_up = rotation_between(us, ut);
  const double relative = o.scale_steps > 0 ? std::sqrt(o.scale_ratio) - 1.0 : 0.0;
  std::vector<double> factors;
  for (int k = -o.scale_steps; k <= o.scale_steps; ++k) {
    factors.push_back(std::pow(o.scale_ratio, k));
  }
  const std::vector<Graph> graphs =
      consistency_graphs(matches, src, us, tgt, ut, o.consistency_sigmas, factors, relative);
  for (std::size_t k = 0; k < factors.size(); ++k) {
    for (const std::vector<std::size_t>& clique : cliques(graphs[k], o.seeds, o.min_inliers)) {
      found.push_back(clique_pose(clique, matches, *src.points, *tgt.points, R_up, ut, factors[k],
                                  o.scale_steps > 0));
      found.back().oriented = oriented;
      if (o.scale_steps == 0 && o.refits > 0) {
        found.back().T_target_source = refit_pose(found.back().T_target_source, matches, src, tgt,
                                                  R_up, ut, o.consistency_sigmas, o.refits);
      }
    }
  }
  return distinct_poses(found, *src.points, radius, std::sqrt(o.scale_ratio), o.hypotheses);
}

// The lists taken in turn (the best of each first), `keep` in all.
void take_in_turn(const std::vector<std::vector<CorrespondenceHypothesis>>& lists, std::size_t keep,
                  std::vector<CorrespondenceHypothesis>* out) {
  for (std::size_t rank = 0; out->size() < keep; ++rank) {
    bool any = false;
    for (const std::vector<CorrespondenceHypothesis>& list : lists) {
      if (rank < list.size() && out->size() < keep) {
        out->push_back(list[rank]);
        any = true;
      }
    }
    if (!any) break;
  }
}

// The checks both searches make of their options and input.
void check_search_input(const CorrespondenceSearchInput& in, const CorrespondenceSearchOptions& o,
                        bool need_ups) {
  std::string why;
  if (!o.is_valid(&why)) throw InvalidArgument("correspondence search: " + why);
  if (in.source.points == nullptr || in.target == nullptr) {
    throw InvalidArgument("correspondence search: no source or target");
  }
  if (need_ups && (in.ups_source.empty() || in.ups_target.empty())) {
    throw InvalidArgument("correspondence search: no up-axis candidates");
  }
  if (!(in.floor_m > 0.0) || !std::isfinite(in.floor_m)) {
    throw InvalidArgument("correspondence search: the covariance floor must be > 0 and finite");
  }
}

// The sample of the target keypoints whose median neighbour distance is the descriptor radius.
double radius_of(const Points3& Q, const KdTree& tree, const CorrespondenceSearchOptions& o) {
  const std::vector<std::uint32_t> tkeys = strided_indices(Q.size(), o.target_keypoints);
  std::vector<std::uint32_t> sample;
  for (std::size_t j = 0; j < tkeys.size(); j += std::max<std::size_t>(1, tkeys.size() / 512)) {
    sample.push_back(tkeys[j]);
  }
  return descriptor_radius(Q, tree, o.neighbours, sample);
}

}  // namespace

std::vector<std::pair<std::uint32_t, std::uint32_t>> match_descriptors(
    const std::vector<std::uint32_t>& source_keys, const std::vector<float>& source,
    const std::vector<char>& source_ok, const std::vector<std::uint32_t>& target_keys,
    const std::vector<float>& target, const std::vector<char>& target_ok, int dims, std::size_t m,
    std::size_t lanes) {
  if (dims < 1 || m < 1) throw InvalidArgument("match_descriptors: dims and m must be >= 1");
  const auto d = static_cast<std::size_t>(dims);
  if (source.size() != source_keys.size() * d || source_ok.size() != source_keys.size() ||
      target.size() != target_keys.size() * d || target_ok.size() != target_keys.size()) {
    throw InvalidArgument("match_descriptors: sizes disagree with the keys and dims");
  }
  std::vector<std::pair<std::uint32_t, std::uint32_t>> out;
  for (const Match& x : nearest_descriptors(source_keys, source, source_ok, target_keys, target,
                                            target_ok, dims, m, lanes)) {
    out.emplace_back(x.s, x.t);
  }
  return out;
}

CorrespondenceSearchResult correspondence_search(const CorrespondenceSearchInput& in,
                                                 const CorrespondenceSearchOptions& o) {
  check_search_input(in, o, true);
  CorrespondenceSearchResult result;
  const Points3& P = *in.source.points;
  const Points3& Q = in.target->points();
  if (P.size() < 3 || Q.size() < 3) return result;

  const KdTree source_tree(P);
  Side src{&P, &source_tree, sigmas(P, in.source.covariances_m2, in.floor_m),
           in.source.view_directions};
  Side tgt{
      &Q, &in.target->tree(),
      sigmas(Q, in.target->has_covariances() ? &in.target->covariances_m2() : nullptr, in.floor_m),
      &in.target->view_directions()};
  const bool elevation = src.has_views() && tgt.has_views();

  // The descriptor radius: the target's median distance to its neighbours-th nearest landmark.
  const std::vector<std::uint32_t> tkeys = strided_indices(Q.size(), o.target_keypoints);
  const std::vector<std::uint32_t> skeys = strided_indices(P.size(), o.keypoints);
  result.radius_m = radius_of(Q, *tgt.tree, o);
  const double radius = result.radius_m;
  if (!(radius > 0.0) || !std::isfinite(radius)) return result;
  const double vague_m = 0.25 * radius;
  const std::size_t neighbourhood = std::min<std::size_t>(4 * o.neighbours, 512);

  // Each descriptor kind (the yaw-invariant one; the oriented one too where both maps know their
  // viewing directions) and each pair of up axes ranks its own distinct poses: a wrong pair's
  // cliques never crowd out the right pair's, nor one kind's the other's.
  std::vector<std::vector<CorrespondenceHypothesis>> per_pair;
  for (const bool oriented : {false, true}) {
    if (oriented && !(elevation && o.oriented)) continue;
    const int dims =
        (oriented ? kOrientedDescriptorDims : kLandmarkDescriptorDims) + (elevation ? 1 : 0);
    // 1. descriptors: once per up axis of each side (a descriptor depends on its own map's up
    // only), valid where the landmark is not vague and has enough neighbours.
    auto describe_all = [&](const Side& side, const std::vector<std::uint32_t>& keys,
                            const Vec3& up) {
      Described out{std::vector<float>(keys.size() * static_cast<std::size_t>(dims)),
                    std::vector<char>(keys.size(), 0)};
      std::vector<PointIndex> scratch;
      for (std::size_t a = 0; a < keys.size(); ++a) {
        out.ok[a] = side.sigma_m[keys[a]] <= vague_m &&
                    describe(side, keys[a], up, radius, neighbourhood, elevation, oriented,
                             &out.d[a * dims], &scratch);
      }
      return out;
    };
    std::vector<Described> by_source_up, by_target_up;
    for (const Vec3& u : in.ups_source) {
      by_source_up.push_back(describe_all(src, skeys, u.normalized()));
    }
    for (const Vec3& u : in.ups_target) {
      by_target_up.push_back(describe_all(tgt, tkeys, u.normalized()));
    }
    for (std::size_t i = 0; i < in.ups_source.size(); ++i) {
      for (std::size_t j = 0; j < in.ups_target.size(); ++j) {
        const Vec3 us = in.ups_source[i].normalized(), ut = in.ups_target[j].normalized();
        per_pair.push_back(poses_of_pair(skeys, by_source_up[i], tkeys, by_target_up[j], dims, src,
                                         us, tgt, ut, o, radius, oriented, &result.matches));
      }
    }
  }
  take_in_turn(per_pair, o.hypotheses, &result.hypotheses);
  return result;
}

double search_descriptor_radius(const Points3& points, const CorrespondenceSearchOptions& options) {
  std::string why;
  if (!options.is_valid(&why)) throw InvalidArgument("correspondence search: " + why);
  if (points.size() < 3) return 0.0;
  const KdTree tree(points);
  return radius_of(points, tree, options);
}

DescribedLandmarks describe_search_landmarks(const Points3& points,
                                             const std::vector<Vec3>* view_directions,
                                             const Vec3& up, double radius_m, bool as_source,
                                             const CorrespondenceSearchOptions& options) {
  std::string why;
  if (!options.is_valid(&why)) throw InvalidArgument("describe_search_landmarks: " + why);
  if (!(radius_m > 0.0) || !std::isfinite(radius_m)) {
    throw InvalidArgument("describe_search_landmarks: the radius must be > 0 and finite, got " +
                          message_number(radius_m));
  }
  if (!up.allFinite() || !(up.norm() > 0.0)) {
    throw InvalidArgument("describe_search_landmarks: the up axis must be finite and non-zero");
  }
  const bool views = view_directions != nullptr && !view_directions->empty();
  if (views && view_directions->size() != points.size()) {
    throw InvalidArgument("describe_search_landmarks: " + std::to_string(view_directions->size()) +
                          " viewing directions for " + std::to_string(points.size()) +
                          " landmarks");
  }
  DescribedLandmarks d;
  d.up = up.normalized();
  d.radius_m = radius_m;
  d.has_views = views;
  if (points.size() < 3) return d;
  d.keys = strided_indices(points.size(), as_source ? options.keypoints : options.target_keypoints);
  constexpr std::size_t W = kLandmarkDescriptorDims + 1;
  d.descriptors.assign(d.keys.size() * W, 0.0f);
  d.described.assign(d.keys.size(), 0);
  const KdTree tree(points);
  const std::size_t neighbourhood = std::min<std::size_t>(4 * options.neighbours, 512);
  for (std::size_t a = 0; a < d.keys.size(); ++a) {
    const std::uint32_t i = d.keys[a];
    d.described[a] =
        describe_landmark(points, tree, i, d.up, radius_m, neighbourhood, &d.descriptors[a * W],
                          views ? &(*view_directions)[i] : nullptr, kElevationWeight);
  }
  return d;
}

CorrespondenceSearchResult correspondence_search_described(const CorrespondenceSearchInput& in,
                                                           const DescribedLandmarks& source,
                                                           const DescribedLandmarks& target,
                                                           const CorrespondenceSearchOptions& o) {
  check_search_input(in, o, false);
  const Points3& P = *in.source.points;
  const Points3& Q = in.target->points();
  constexpr std::size_t W = kLandmarkDescriptorDims + 1;
  for (const auto* side : {&source, &target}) {
    const std::size_t n = side == &source ? P.size() : Q.size();
    if (side->descriptors.size() != side->keys.size() * W ||
        side->described.size() != side->keys.size()) {
      throw InvalidArgument("correspondence search: described landmarks of inconsistent sizes");
    }
    if (!side->up.allFinite() || !(std::abs(side->up.norm() - 1.0) < 1e-6)) {
      throw InvalidArgument("correspondence search: a described side's up axis must be unit");
    }
    for (std::uint32_t k : side->keys) {
      if (k >= n) {
        throw InvalidArgument("correspondence search: a described landmark index " +
                              std::to_string(k) + " is out of range (" + std::to_string(n) +
                              " landmarks)");
      }
    }
  }
  CorrespondenceSearchResult result;
  if (P.size() < 3 || Q.size() < 3) return result;
  result.radius_m = target.radius_m;
  if (!(target.radius_m > 0.0) || !std::isfinite(target.radius_m)) return result;
  const Side src{&P, nullptr, sigmas(P, in.source.covariances_m2, in.floor_m),
                 in.source.view_directions};
  const Side tgt{
      &Q, &in.target->tree(),
      sigmas(Q, in.target->has_covariances() ? &in.target->covariances_m2() : nullptr, in.floor_m),
      &in.target->view_directions()};
  const double vague_m = 0.25 * target.radius_m;
  const bool elevation = source.has_views && target.has_views;
  const int dims = kLandmarkDescriptorDims + (elevation ? 1 : 0);
  auto pack = [&](const DescribedLandmarks& d, const Side& side) {
    Described out{std::vector<float>(d.keys.size() * static_cast<std::size_t>(dims)),
                  std::vector<char>(d.keys.size(), 0)};
    for (std::size_t a = 0; a < d.keys.size(); ++a) {
      out.ok[a] = d.described[a] && side.sigma_m[d.keys[a]] <= vague_m;
      if (out.ok[a]) {
        std::copy_n(&d.descriptors[a * W], dims, &out.d[a * static_cast<std::size_t>(dims)]);
      }
    }
    return out;
  };
  std::vector<std::vector<CorrespondenceHypothesis>> per_pair;
  per_pair.push_back(poses_of_pair(source.keys, pack(source, src), target.keys, pack(target, tgt),
                                   dims, src, source.up, tgt, target.up, o, target.radius_m, false,
                                   &result.matches));
  take_in_turn(per_pair, o.hypotheses, &result.hypotheses);
  return result;
}

}  // namespace lmalign
