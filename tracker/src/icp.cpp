#include "pg/tracker/icp.h"

#if defined(__AVX512F__) || (defined(__AVX2__) && defined(__FMA__))
#include <immintrin.h>
#endif
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <cmath>

#include "correspondence_cache.h"

namespace pg {

namespace {

// Points per parallel task: enough work to amortise the task overhead.
constexpr std::size_t kGrainSize = 256;
// A step that moves the cloud by less than this turns IcpOptions::max_normal_angle_rad on [m]:
// an eighth of a pixel at 120x160.
constexpr double kNormalLimitStepM = 2e-5;

#if defined(__AVX512F__)
// The float vector of the vectorised paths below, and the two operations they share.
using VectorF = __m512;
inline VectorF broadcast(float v) { return _mm512_set1_ps(v); }
inline VectorF fmadd(VectorF a, VectorF b, VectorF c) { return _mm512_fmadd_ps(a, b, c); }
#elif defined(__AVX2__) && defined(__FMA__)
using VectorF = __m256;
inline VectorF broadcast(float v) { return _mm256_set1_ps(v); }
inline VectorF fmadd(VectorF a, VectorF b, VectorF c) { return _mm256_fmadd_ps(a, b, c); }

// AVX2 has no compress-store: a permutation per 8-bit lane mask moves the lanes that are set to
// the front, in order (the rest of each row is never read).
struct CompressTable {
  alignas(32) int lanes[256][8] = {};
};
constexpr CompressTable make_compress_table() {
  CompressTable t;
  for (int mask = 0; mask < 256; ++mask) {
    int n = 0;
    for (int l = 0; l < 8; ++l) {
      if (mask >> l & 1) t.lanes[mask][n++] = l;
    }
  }
  return t;
}
constexpr CompressTable kCompress = make_compress_table();

__m256i compress_permutation(unsigned mask) {
  return _mm256_load_si256(reinterpret_cast<const __m256i*>(kCompress.lanes[mask]));
}

// Lanes [0, count) of 8 set (all ones), the rest clear.
__m256i first_lanes(int count) {
  return _mm256_cmpgt_epi32(_mm256_set1_epi32(count), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
}
#endif

// The normal equations of one Gauss-Newton iteration (eq. 5/6 linearised), in scaled
// coordinates x = [rho_c; L phi] (degeneracy.h). Sums are kept in kLanes partial sums each: the
// terms of a chunk are added lane by lane, which compiles to vector FMAs with independent
// accumulators (a single running sum cannot be vectorised or reordered without -ffast-math, and
// its latency chain made the accumulation cost more than the rest of the linearisation).
constexpr int kLanes = 8;
struct NormalEquations {
  double H[21][kLanes] = {};        // upper triangle of sum w J J^T, row by row
  double g[6][kLanes] = {};         // sum w r J
  double weighted_sq[kLanes] = {};  // sum w r^2 [m^2]
  double weight[kLanes] = {};       // sum w
  double sq[kLanes] = {};           // sum r^2 over inliers [m^2]
  int inliers = 0;
  long queries = 0;

  // Adds m terms stored by column (J[a][i], w[i], r[i]), of which `kept` have a weight (the
  // others have w = r = 0); the columns m..(m rounded up to kLanes) are overwritten with
  // zero-weight terms.
  template <int kCapacity>
  void add_terms(double (&J)[6][kCapacity], double* w, double* r, int m, int kept) {
    static_assert(kCapacity % kLanes == 0);
    const int padded = (m + kLanes - 1) / kLanes * kLanes;
    for (int i = m; i < padded; ++i) {
      w[i] = r[i] = 0;
      for (int a = 0; a < 6; ++a) J[a][i] = 0;
    }
    for (int i0 = 0; i0 < padded; i0 += kLanes) {
      double wJ[6][kLanes];
      for (int a = 0; a < 6; ++a) {
        for (int l = 0; l < kLanes; ++l) wJ[a][l] = w[i0 + l] * J[a][i0 + l];
      }
      int k = 0;
      for (int a = 0; a < 6; ++a) {
        for (int l = 0; l < kLanes; ++l) g[a][l] += wJ[a][l] * r[i0 + l];
        for (int b = a; b < 6; ++b, ++k) {
          for (int l = 0; l < kLanes; ++l) H[k][l] += wJ[a][l] * J[b][i0 + l];
        }
      }
      for (int l = 0; l < kLanes; ++l) {
        const double wr = w[i0 + l] * r[i0 + l];
        weighted_sq[l] += wr * r[i0 + l];
        weight[l] += w[i0 + l];
        sq[l] += r[i0 + l] * r[i0 + l];
      }
    }
    inliers += kept;
  }
  void add(const NormalEquations& o) {
    for (int l = 0; l < kLanes; ++l) {
      for (int k = 0; k < 21; ++k) H[k][l] += o.H[k][l];
      for (int a = 0; a < 6; ++a) g[a][l] += o.g[a][l];
      weighted_sq[l] += o.weighted_sq[l];
      weight[l] += o.weight[l];
      sq[l] += o.sq[l];
    }
    inliers += o.inliers;
    queries += o.queries;
  }
  static double total(const double (&lanes)[kLanes]) {
    double s = 0;
    for (double v : lanes) s += v;
    return s;
  }
  Matrix6d hessian() const {
    Matrix6d M;
    int k = 0;
    for (int a = 0; a < 6; ++a) {
      for (int b = a; b < 6; ++b) M(a, b) = M(b, a) = total(H[k++]);
    }
    return M;
  }
  Vector6d gradient() const {
    Vector6d v;
    for (int a = 0; a < 6; ++a) v[a] = total(g[a]);
    return v;
  }
};

struct Centroid {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();  // mean of (p - centre)(p - centre)^T
  double rms_radius = 0;
};

Centroid centroid_and_radius(const std::vector<Eigen::Vector3f>& points) {
  Centroid c;
  for (const auto& p : points) c.centre += p.cast<double>();
  c.centre /= double(points.size());
  for (const auto& p : points) {
    const Eigen::Vector3d r = p.cast<double>() - c.centre;
    c.scatter += r * r.transpose();
  }
  c.scatter /= double(points.size());
  c.rms_radius = std::sqrt(c.scatter.trace());
  return c;
}

bool has_normals(const PointCloud& cloud) { return cloud.normals.size() == cloud.points.size(); }

// Whether a pair's residual is along the mean of its two normals (IcpOptions::symmetric), which
// needs the source's normals.
bool uses_source_normals(const PointCloud& source, const IcpOptions& o) {
  return o.symmetric && has_normals(source);
}

// Eq. 5/6 linearised at T: correspondences, robust weights and the normal equations in scaled
// coordinates about c, summed over every stride-th source point in parallel. A oneTBB reduction
// body (the imperative form): a range adds its terms to the body's own sums. The reduction is
// the deterministic one: the ranges are split down to the grain and joined in the same order
// whichever thread ran them, so the sums, and the whole tracking run, are the same bit for bit
// from run to run (with work stealing they differed by ~1e-12, which a lost sequence amplified
// into millimetres). A split zeroes the 2 KB of sums of the new body; with a grain of a quarter
// of the points (at most 256) that is a few per iteration.
class Linearisation {
 public:
  Linearisation(const PointCloud& source, std::size_t stride, const PointCloudTree& target,
                const SE3& T, const Eigen::Vector3d& c, double inv_L, const IcpOptions& o,
                CorrespondenceCache& cache, float radius, float min_dot)
      : src_(source.points),
        src_normals_(uses_source_normals(source, o) || (min_dot > -2.0f && has_normals(source))
                         ? source.normals.data()->data()
                         : nullptr),
        symmetric_(uses_source_normals(source, o)),
        tgt_(target.cloud()),
        target_(target),
        stride_(stride),
        R_(T.rotation_matrix().cast<float>()),
        t_(T.translation().cast<float>()),
        c_(c.cast<float>()),
        inv_L_(float(inv_L)),
        max_corr_(float(o.max_correspondence_m)),
        min_dot_(min_dot),
        radius_(radius),
        options_(o),
        cache_(cache) {}
  Linearisation(Linearisation& other, tbb::split) : Linearisation(other) { eq = {}; }

  void operator()(const tbb::blocked_range<std::size_t>& range) {
    switch (options_.kernel) {
      case RobustKernel::kHuber:
        return run<RobustKernel::kHuber>(range);
      case RobustKernel::kTukey:
        return run<RobustKernel::kTukey>(range);
      case RobustKernel::kNone:
        break;
    }
    run<RobustKernel::kNone>(range);
  }
  void join(const Linearisation& other) { eq.add(other.eq); }

  NormalEquations eq;

 private:
  static constexpr int kChunk = 64;  // correspondences gathered before they are linearised
  // A chunk's moved source points, their indices and their nearest target points, by column.
  struct Chunk {
    float x[kChunk], y[kChunk], z[kChunk];
    int i[kChunk], j[kChunk];
    void set(int m, const Eigen::Vector3f& p, std::size_t source, int nearest) {
      x[m] = p.x();
      y[m] = p.y();
      z[m] = p.z();
      i[m] = int(source);
      j[m] = nearest;
    }
  };

  Linearisation(const Linearisation&) = default;

#if defined(__AVX512F__) || (defined(__AVX2__) && defined(__FMA__))
  struct Row {  // one row of [R t], broadcast
    VectorF r0, r1, r2, t;
    VectorF apply(VectorF x, VectorF y, VectorF z) const {
      return fmadd(r0, x, fmadd(r1, y, fmadd(r2, z, t)));
    }
  };
  // [R t] (points), or [R 0] (directions: normals).
  std::array<Row, 3> broadcast_rows(bool translation) const {
    std::array<Row, 3> rows;
    for (int a = 0; a < 3; ++a) {
      rows[a] = {broadcast(R_(a, 0)), broadcast(R_(a, 1)), broadcast(R_(a, 2)),
                 broadcast(translation ? t_[a] : 0.0f)};
    }
    return rows;
  }

  // The lanes in `stale` of the points from k on, whose cached neighbour no longer holds: each
  // queried from its moved position (xs, ys, zs by lane), and added to the chunk if found.
  void query_stale(unsigned stale, std::size_t k, const float* xs, const float* ys, const float* zs,
                   Chunk& chunk, int& m) {
    for (unsigned bits = stale; bits != 0; bits &= bits - 1) {
      const int l = __builtin_ctz(bits);
      const Eigen::Vector3f p(xs[l], ys[l], zs[l]);
      const std::size_t i = (k + l) * stride_;
      const int j = cache_.query(i, p, target_, radius_, max_corr_, eq.queries);
      if (j >= 0) chunk.set(m++, p, i, j);
    }
  }
#endif

  // The correspondences of a range, gathered in chunks and linearised chunk by chunk (that needs
  // no branch, so it is vectorised: 16 lanes with AVX-512, 8 with AVX2 and FMA, a scalar loop
  // otherwise). Finding them branches only for the points whose cached neighbour no longer
  // holds: the points are moved and tested against the cache a register at a time, and only
  // those are handled one by one.
  template <RobustKernel kKernel>
  void run(const tbb::blocked_range<std::size_t>& range) {
    Chunk chunk;
    int m = 0;
    std::size_t k = range.begin();
#if defined(__AVX512F__)
    const float* src = src_.data()->data();
    const __m512i iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    const __m512i stride = _mm512_set1_epi32(int(stride_)), three = _mm512_set1_epi32(3);
    const std::array<Row, 3> rows = broadcast_rows(true);
    // (32-bit lane indices: clouds of half a billion points and more take the scalar loop.)
    const std::size_t vector_end = src_.size() < (std::size_t(1) << 29) ? range.end() : k;
    for (; k < vector_end; k += 16) {
      const std::size_t count = std::min<std::size_t>(16, vector_end - k);
      const __mmask16 lanes = __mmask16((1u << count) - 1);
      const __m512i index =
          _mm512_mullo_epi32(_mm512_add_epi32(_mm512_set1_epi32(int(k)), iota), stride);
      const __m512i index3 = _mm512_mullo_epi32(index, three);
      const __m512 zero = _mm512_setzero_ps();
      const __m512 sx = _mm512_mask_i32gather_ps(zero, lanes, index3, src, 4);
      const __m512 sy = _mm512_mask_i32gather_ps(zero, lanes, index3, src + 1, 4);
      const __m512 sz = _mm512_mask_i32gather_ps(zero, lanes, index3, src + 2, 4);
      const __m512 x = rows[0].apply(sx, sy, sz), y = rows[1].apply(sx, sy, sz),
                   z = rows[2].apply(sx, sy, sz);
      __m512i answer;
      const __mmask16 valid = cache_.still_valid(index, lanes, x, y, z, answer);
      const __mmask16 found = valid & _mm512_cmpge_epi32_mask(answer, _mm512_setzero_si512());
      _mm512_mask_compressstoreu_ps(chunk.x + m, found, x);
      _mm512_mask_compressstoreu_ps(chunk.y + m, found, y);
      _mm512_mask_compressstoreu_ps(chunk.z + m, found, z);
      _mm512_mask_compressstoreu_epi32(chunk.i + m, found, index);
      _mm512_mask_compressstoreu_epi32(chunk.j + m, found, answer);
      m += __builtin_popcount(unsigned(found));
      if (const unsigned stale = lanes & ~valid) {
        alignas(64) float xs[16], ys[16], zs[16];
        _mm512_store_ps(xs, x);
        _mm512_store_ps(ys, y);
        _mm512_store_ps(zs, z);
        query_stale(stale, k, xs, ys, zs, chunk, m);
      }
      if (m > kChunk - 16) {  // the next 16 might not fit
        linearise_chunk<kKernel>(chunk, m);
        m = 0;
      }
    }
#elif defined(__AVX2__) && defined(__FMA__)
    const float* src = src_.data()->data();
    const __m256i iota = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    const __m256i stride = _mm256_set1_epi32(int(stride_)), three = _mm256_set1_epi32(3);
    const std::array<Row, 3> rows = broadcast_rows(true);
    const std::size_t vector_end = src_.size() < (std::size_t(1) << 29) ? range.end() : k;
    for (; k < vector_end; k += 8) {
      const int count = int(std::min<std::size_t>(8, vector_end - k));
      const __m256i lanes = first_lanes(count);
      const __m256i index =
          _mm256_mullo_epi32(_mm256_add_epi32(_mm256_set1_epi32(int(k)), iota), stride);
      const __m256i index3 = _mm256_mullo_epi32(index, three);
      const __m256 zero = _mm256_setzero_ps(), lanes_ps = _mm256_castsi256_ps(lanes);
      const __m256 sx = _mm256_mask_i32gather_ps(zero, src, index3, lanes_ps, 4);
      const __m256 sy = _mm256_mask_i32gather_ps(zero, src + 1, index3, lanes_ps, 4);
      const __m256 sz = _mm256_mask_i32gather_ps(zero, src + 2, index3, lanes_ps, 4);
      const __m256 x = rows[0].apply(sx, sy, sz), y = rows[1].apply(sx, sy, sz),
                   z = rows[2].apply(sx, sy, sz);
      __m256i answer;
      const __m256i valid = cache_.still_valid(index, lanes, x, y, z, answer);
      const __m256i found =
          _mm256_andnot_si256(_mm256_cmpgt_epi32(_mm256_setzero_si256(), answer), valid);
      const unsigned found_bits = unsigned(_mm256_movemask_ps(_mm256_castsi256_ps(found)));
      // Written whole: m <= kChunk - 8 here, and the lanes past the found ones are overwritten.
      const __m256i to_front = compress_permutation(found_bits);
      _mm256_storeu_ps(chunk.x + m, _mm256_permutevar8x32_ps(x, to_front));
      _mm256_storeu_ps(chunk.y + m, _mm256_permutevar8x32_ps(y, to_front));
      _mm256_storeu_ps(chunk.z + m, _mm256_permutevar8x32_ps(z, to_front));
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(chunk.i + m),
                          _mm256_permutevar8x32_epi32(index, to_front));
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(chunk.j + m),
                          _mm256_permutevar8x32_epi32(answer, to_front));
      m += __builtin_popcount(found_bits);
      const unsigned stale =
          ((1u << count) - 1) & ~unsigned(_mm256_movemask_ps(_mm256_castsi256_ps(valid)));
      if (stale != 0) {
        alignas(32) float xs[8], ys[8], zs[8];
        _mm256_store_ps(xs, x);
        _mm256_store_ps(ys, y);
        _mm256_store_ps(zs, z);
        query_stale(stale, k, xs, ys, zs, chunk, m);
      }
      if (m > kChunk - 8) {  // the next 8 might not fit
        linearise_chunk<kKernel>(chunk, m);
        m = 0;
      }
    }
#endif
    for (; k < range.end(); ++k) {
      const std::size_t i = k * stride_;
      const Eigen::Vector3f p = R_ * src_[i] + t_;
      const int j = cache_.nearest(i, p, target_, radius_, max_corr_, eq.queries);
      if (j < 0) continue;
      chunk.set(m, p, i, j);
      if (++m == kChunk) {
        linearise_chunk<kKernel>(chunk, m);
        m = 0;
      }
    }
    linearise_chunk<kKernel>(chunk, m);
  }

  // Eq. 5/6 for the chunk's m correspondences: a pair farther apart than the correspondence
  // distance, or of zero weight, becomes a zero term (w = r = 0).
  template <RobustKernel kKernel>
  void linearise_chunk(const Chunk& c, int m) {
    double J[6][kChunk], w[kChunk], r[kChunk];
    const float* tp = tgt_.points.data()->data();
    const float* tn = tgt_.normals.data()->data();
    const float max_corr_sq = max_corr_ * max_corr_;
    int kept = 0;
#if defined(__AVX512F__)
    // Sixteen correspondences at a time (GCC does not vectorise the gathers by itself).
    const __m512i three = _mm512_set1_epi32(3);
    const __m512 scale_v = _mm512_set1_ps(float(options_.kernel_scale_m));
    const __m512 max_corr_sq_v = _mm512_set1_ps(max_corr_sq);
    const __m512 inv_L_v = _mm512_set1_ps(inv_L_);
    const __m512 cx = _mm512_set1_ps(c_.x()), cy = _mm512_set1_ps(c_.y()),
                 cz = _mm512_set1_ps(c_.z());
    const std::array<Row, 3> rotation = broadcast_rows(false);
    const auto store = [](double* out, __m512 v) {
      _mm512_storeu_pd(out, _mm512_cvtps_pd(_mm512_castps512_ps256(v)));
      _mm512_storeu_pd(
          out + 8,
          _mm512_cvtps_pd(_mm256_castpd_ps(_mm512_extractf64x4_pd(_mm512_castps_pd(v), 1))));
    };
    for (int e = 0; e < m; e += 16) {
      const __mmask16 valid = m - e >= 16 ? __mmask16(0xFFFF) : __mmask16((1u << (m - e)) - 1);
      const __m512i j3 = _mm512_mullo_epi32(_mm512_maskz_loadu_epi32(valid, c.j + e), three);
      const __m512 zero = _mm512_setzero_ps();
      const auto gather = [&](const float* base) {
        return _mm512_mask_i32gather_ps(zero, valid, j3, base, 4);
      };
      const __m512 px = _mm512_maskz_loadu_ps(valid, c.x + e);
      const __m512 py = _mm512_maskz_loadu_ps(valid, c.y + e);
      const __m512 pz = _mm512_maskz_loadu_ps(valid, c.z + e);
      const __m512 dx = _mm512_sub_ps(px, gather(tp)), dy = _mm512_sub_ps(py, gather(tp + 1)),
                   dz = _mm512_sub_ps(pz, gather(tp + 2));
      __m512 nx = gather(tn), ny = gather(tn + 1), nz = gather(tn + 2);
      __mmask16 compatible = 0xFFFF;
      if (src_normals_) {  // symmetric_pair_normal, sixteen at a time
        const __m512i i3 = _mm512_mullo_epi32(_mm512_maskz_loadu_epi32(valid, c.i + e), three);
        const auto gather_source = [&](const float* base) {
          return _mm512_mask_i32gather_ps(zero, valid, i3, base, 4);
        };
        const __m512 ax = gather_source(src_normals_), ay = gather_source(src_normals_ + 1),
                     az = gather_source(src_normals_ + 2);
        const __m512 sx = rotation[0].apply(ax, ay, az), sy = rotation[1].apply(ax, ay, az),
                     sz = rotation[2].apply(ax, ay, az);
        const __m512 mx = _mm512_add_ps(nx, sx), my = _mm512_add_ps(ny, sy),
                     mz = _mm512_add_ps(nz, sz);
        const __m512 inv_norm = _mm512_div_ps(
            _mm512_set1_ps(1.0f), _mm512_sqrt_ps(_mm512_fmadd_ps(
                                      mx, mx, _mm512_fmadd_ps(my, my, _mm512_mul_ps(mz, mz)))));
        const __m512 dot = _mm512_fmadd_ps(nx, sx, _mm512_fmadd_ps(ny, sy, _mm512_mul_ps(nz, sz)));
        const __mmask16 agree =
            symmetric_ ? _mm512_cmp_ps_mask(dot, zero, _CMP_GT_OQ) : __mmask16(0);
        compatible = _mm512_cmp_ps_mask(dot, _mm512_set1_ps(min_dot_), _CMP_GE_OQ);
        nx = _mm512_mask_mul_ps(nx, agree, mx, inv_norm);
        ny = _mm512_mask_mul_ps(ny, agree, my, inv_norm);
        nz = _mm512_mask_mul_ps(nz, agree, mz, inv_norm);
      }
      const __m512 re = _mm512_fmadd_ps(nx, dx, _mm512_fmadd_ps(ny, dy, _mm512_mul_ps(nz, dz)));
      __m512 we;  // robust_weight's values, without branches
      if constexpr (kKernel == RobustKernel::kHuber) {
        we = _mm512_div_ps(scale_v, _mm512_max_ps(_mm512_abs_ps(re), scale_v));
      } else if constexpr (kKernel == RobustKernel::kTukey) {
        const __m512 u = _mm512_div_ps(re, scale_v);
        const __m512 s = _mm512_max_ps(_mm512_fnmadd_ps(u, u, _mm512_set1_ps(1.0f)), zero);
        we = _mm512_mul_ps(s, s);
      } else {
        we = _mm512_set1_ps(1.0f);
      }
      const __m512 d_sq = _mm512_fmadd_ps(dx, dx, _mm512_fmadd_ps(dy, dy, _mm512_mul_ps(dz, dz)));
      const __mmask16 keep = _mm512_mask_cmp_ps_mask(valid, d_sq, max_corr_sq_v, _CMP_LE_OQ) &
                             _mm512_cmp_ps_mask(we, zero, _CMP_GT_OQ) & compatible;
      kept += __builtin_popcount(unsigned(keep));
      const __m512 ux = _mm512_sub_ps(px, cx), uy = _mm512_sub_ps(py, cy),
                   uz = _mm512_sub_ps(pz, cz);
      store(w + e, _mm512_maskz_mov_ps(keep, we));
      store(r + e, _mm512_maskz_mov_ps(keep, re));
      store(J[0] + e, nx);
      store(J[1] + e, ny);
      store(J[2] + e, nz);
      store(J[3] + e, _mm512_mul_ps(_mm512_fmsub_ps(uy, nz, _mm512_mul_ps(uz, ny)), inv_L_v));
      store(J[4] + e, _mm512_mul_ps(_mm512_fmsub_ps(uz, nx, _mm512_mul_ps(ux, nz)), inv_L_v));
      store(J[5] + e, _mm512_mul_ps(_mm512_fmsub_ps(ux, ny, _mm512_mul_ps(uy, nx)), inv_L_v));
    }
#elif defined(__AVX2__) && defined(__FMA__)
    // The same, eight correspondences at a time, with lane masks of all ones or zeros.
    const __m256i three = _mm256_set1_epi32(3);
    const __m256 zero = _mm256_setzero_ps(), one = _mm256_set1_ps(1.0f);
    const __m256 scale_v = _mm256_set1_ps(float(options_.kernel_scale_m));
    const __m256 max_corr_sq_v = _mm256_set1_ps(max_corr_sq);
    const __m256 inv_L_v = _mm256_set1_ps(inv_L_);
    const __m256 cx = _mm256_set1_ps(c_.x()), cy = _mm256_set1_ps(c_.y()),
                 cz = _mm256_set1_ps(c_.z());
    const std::array<Row, 3> rotation = broadcast_rows(false);
    const auto store = [](double* out, __m256 v) {
      _mm256_storeu_pd(out, _mm256_cvtps_pd(_mm256_castps256_ps128(v)));
      _mm256_storeu_pd(out + 4, _mm256_cvtps_pd(_mm256_extractf128_ps(v, 1)));
    };
    for (int e = 0; e < m; e += 8) {
      const __m256i valid = first_lanes(m - e);
      const __m256 valid_ps = _mm256_castsi256_ps(valid);
      const auto gather_at = [&](__m256i index3, const float* base) {
        return _mm256_mask_i32gather_ps(zero, base, index3, valid_ps, 4);
      };
      const __m256i j3 = _mm256_mullo_epi32(_mm256_maskload_epi32(c.j + e, valid), three);
      const __m256 px = _mm256_maskload_ps(c.x + e, valid);
      const __m256 py = _mm256_maskload_ps(c.y + e, valid);
      const __m256 pz = _mm256_maskload_ps(c.z + e, valid);
      const __m256 dx = _mm256_sub_ps(px, gather_at(j3, tp)),
                   dy = _mm256_sub_ps(py, gather_at(j3, tp + 1)),
                   dz = _mm256_sub_ps(pz, gather_at(j3, tp + 2));
      __m256 nx = gather_at(j3, tn), ny = gather_at(j3, tn + 1), nz = gather_at(j3, tn + 2);
      __m256 compatible = valid_ps;
      if (src_normals_) {  // symmetric_pair_normal, eight at a time
        const __m256i i3 = _mm256_mullo_epi32(_mm256_maskload_epi32(c.i + e, valid), three);
        const __m256 ax = gather_at(i3, src_normals_), ay = gather_at(i3, src_normals_ + 1),
                     az = gather_at(i3, src_normals_ + 2);
        const __m256 sx = rotation[0].apply(ax, ay, az), sy = rotation[1].apply(ax, ay, az),
                     sz = rotation[2].apply(ax, ay, az);
        const __m256 mx = _mm256_add_ps(nx, sx), my = _mm256_add_ps(ny, sy),
                     mz = _mm256_add_ps(nz, sz);
        const __m256 inv_norm =
            _mm256_div_ps(one, _mm256_sqrt_ps(_mm256_fmadd_ps(
                                   mx, mx, _mm256_fmadd_ps(my, my, _mm256_mul_ps(mz, mz)))));
        const __m256 dot = _mm256_fmadd_ps(nx, sx, _mm256_fmadd_ps(ny, sy, _mm256_mul_ps(nz, sz)));
        const __m256 agree = symmetric_ ? _mm256_cmp_ps(dot, zero, _CMP_GT_OQ) : zero;
        compatible = _mm256_cmp_ps(dot, _mm256_set1_ps(min_dot_), _CMP_GE_OQ);
        nx = _mm256_blendv_ps(nx, _mm256_mul_ps(mx, inv_norm), agree);
        ny = _mm256_blendv_ps(ny, _mm256_mul_ps(my, inv_norm), agree);
        nz = _mm256_blendv_ps(nz, _mm256_mul_ps(mz, inv_norm), agree);
      }
      const __m256 re = _mm256_fmadd_ps(nx, dx, _mm256_fmadd_ps(ny, dy, _mm256_mul_ps(nz, dz)));
      __m256 we;  // robust_weight's values, without branches
      if constexpr (kKernel == RobustKernel::kHuber) {
        const __m256 abs_re = _mm256_andnot_ps(_mm256_set1_ps(-0.0f), re);
        we = _mm256_div_ps(scale_v, _mm256_max_ps(abs_re, scale_v));
      } else if constexpr (kKernel == RobustKernel::kTukey) {
        const __m256 u = _mm256_div_ps(re, scale_v);
        const __m256 s = _mm256_max_ps(_mm256_fnmadd_ps(u, u, one), zero);
        we = _mm256_mul_ps(s, s);
      } else {
        we = one;
      }
      const __m256 d_sq = _mm256_fmadd_ps(dx, dx, _mm256_fmadd_ps(dy, dy, _mm256_mul_ps(dz, dz)));
      const __m256 keep =
          _mm256_and_ps(_mm256_and_ps(valid_ps, _mm256_cmp_ps(d_sq, max_corr_sq_v, _CMP_LE_OQ)),
                        _mm256_and_ps(_mm256_cmp_ps(we, zero, _CMP_GT_OQ), compatible));
      kept += __builtin_popcount(unsigned(_mm256_movemask_ps(keep)));
      const __m256 ux = _mm256_sub_ps(px, cx), uy = _mm256_sub_ps(py, cy),
                   uz = _mm256_sub_ps(pz, cz);
      store(w + e, _mm256_and_ps(keep, we));
      store(r + e, _mm256_and_ps(keep, re));
      store(J[0] + e, nx);
      store(J[1] + e, ny);
      store(J[2] + e, nz);
      store(J[3] + e, _mm256_mul_ps(_mm256_fmsub_ps(uy, nz, _mm256_mul_ps(uz, ny)), inv_L_v));
      store(J[4] + e, _mm256_mul_ps(_mm256_fmsub_ps(uz, nx, _mm256_mul_ps(ux, nz)), inv_L_v));
      store(J[5] + e, _mm256_mul_ps(_mm256_fmsub_ps(ux, ny, _mm256_mul_ps(uy, nx)), inv_L_v));
    }
#else
    for (int e = 0; e < m; ++e) {
      const int j3 = 3 * c.j[e];
      const float dx = c.x[e] - tp[j3], dy = c.y[e] - tp[j3 + 1], dz = c.z[e] - tp[j3 + 2];
      float nx = tn[j3], ny = tn[j3 + 1], nz = tn[j3 + 2];
      bool compatible = true;
      if (src_normals_) {
        const int i3 = 3 * c.i[e];
        const Eigen::Vector3f ns =
            R_ * Eigen::Vector3f(src_normals_[i3], src_normals_[i3 + 1], src_normals_[i3 + 2]);
        compatible = nx * ns.x() + ny * ns.y() + nz * ns.z() >= min_dot_;
        if (symmetric_) {
          const Eigen::Vector3f n = symmetric_pair_normal<float>({nx, ny, nz}, ns);
          nx = n.x();
          ny = n.y();
          nz = n.z();
        }
      }
      const float re = nx * dx + ny * dy + nz * dz;  // point-to-plane residual [m]
      const float we = float(robust_weight(kKernel, options_.kernel_scale_m, re));
      const bool keep = (dx * dx + dy * dy + dz * dz <= max_corr_sq) & (we > 0.0f) & compatible;
      kept += keep;
      w[e] = keep ? we : 0.0f;
      r[e] = keep ? re : 0.0f;
      // Jacobian about the centroid, rotation scaled by L: [n; ((p - c) x n) / L].
      const float ux = c.x[e] - c_.x(), uy = c.y[e] - c_.y(), uz = c.z[e] - c_.z();
      J[0][e] = nx;
      J[1][e] = ny;
      J[2][e] = nz;
      J[3][e] = (uy * nz - uz * ny) * inv_L_;
      J[4][e] = (uz * nx - ux * nz) * inv_L_;
      J[5][e] = (ux * ny - uy * nx) * inv_L_;
    }
#endif
    eq.add_terms(J, w, r, m, kept);
  }

  const std::vector<Eigen::Vector3f>& src_;
  // Null when neither the objective (symmetric_) nor the limit on the pairs' normals reads them.
  const float* src_normals_;
  bool symmetric_;  // the residuals are along the pairs' mean normals, else the target's alone
  const PointCloud& tgt_;
  const PointCloudTree& target_;
  std::size_t stride_;
  Eigen::Matrix3f R_;
  Eigen::Vector3f t_, c_;
  float inv_L_, max_corr_, min_dot_, radius_;
  const IcpOptions& options_;
  CorrespondenceCache& cache_;
};

NormalEquations linearise(const PointCloud& source, std::size_t stride,
                          const PointCloudTree& target, const SE3& T, const Eigen::Vector3d& c,
                          double inv_L, const IcpOptions& o, CorrespondenceCache& cache,
                          float radius, bool limit_normals) {
  const std::size_t count = (source.points.size() + stride - 1) / stride;
  // A subsample of a few hundred points is still split in a few ranges: its first queries, far
  // from the target, cost several times a near one.
  const std::size_t grain = std::clamp<std::size_t>(count / 4, 32, kGrainSize);
  // (A pair's normals' cosine is at least -1: -2 keeps every pair.)
  const float min_dot = limit_normals ? float(std::cos(o.max_normal_angle_rad)) : -2.0f;
  Linearisation body(source, stride, target, T, c, inv_L, o, cache, radius, min_dot);
  tbb::parallel_deterministic_reduce(tbb::blocked_range<std::size_t>(0, count, grain), body);
  return body.eq;
}

// Where the last full-cloud iterations started (a ring), for IcpOptions::cycle_extent_m.
class CycleWatch {
 public:
  void record(const SE3& start) { starts_[recorded_++ % kCycleIterations] = start; }
  // Whether the last kCycleIterations starts all lie within `extent` of `last`, measured as the
  // displacement of a cloud's centroid plus its radius times the angle [m].
  bool closed(const SE3& last, const Eigen::Vector3d& centre, double radius, double extent) const {
    return extent > 0.0 && recorded_ >= kCycleIterations &&
           std::all_of(starts_.begin(), starts_.end(), [&](const SE3& s) {
             return (s * centre - last * centre).norm() +
                        radius * s.rotation().angularDistance(last.rotation()) <
                    extent;
           });
  }

 private:
  std::array<SE3, kCycleIterations> starts_;
  int recorded_ = 0;
};

}  // namespace

const char* to_string(IcpStatus status) {
  switch (status) {
    case IcpStatus::kConverged:
      return "converged";
    case IcpStatus::kMaxIterations:
      return "max iterations";
    case IcpStatus::kTooFewPoints:
      return "too few points";
    case IcpStatus::kTooFewCorrespondences:
      return "too few correspondences";
  }
  return "?";
}

PointToPlaneIcp::PointToPlaneIcp(const IcpOptions& options)
    : options_(options), cache_(std::make_unique<CorrespondenceCache>()) {}
PointToPlaneIcp::~PointToPlaneIcp() = default;
PointToPlaneIcp::PointToPlaneIcp(PointToPlaneIcp&&) noexcept = default;
PointToPlaneIcp& PointToPlaneIcp::operator=(PointToPlaneIcp&&) noexcept = default;

IcpResult PointToPlaneIcp::align(const PointCloud& source_in, const PointCloudTree& target,
                                 const SE3& T_target_source_guess) {
  IcpResult result;
  result.T_target_source = T_target_source_guess;
  last_queries_ = 0;
  const IcpOptions& o = options_;
  const PointCloud* source = &source_in;
  // A NaN from the caller's front end would make the centroid and every step NaN: left out.
  const bool with_normals = has_normals(source_in);
  const auto finite = [&](std::size_t i) {
    return source_in.points[i].allFinite() && (!with_normals || source_in.normals[i].allFinite());
  };
  std::size_t kept = 0;
  while (kept < source_in.points.size() && finite(kept)) ++kept;
  if (kept < source_in.points.size()) {
    finite_.clear();
    for (std::size_t i = 0; i < source_in.points.size(); ++i) {
      if (!finite(i)) continue;
      finite_.points.push_back(source_in.points[i]);
      if (with_normals) finite_.normals.push_back(source_in.normals[i]);
    }
    source = &finite_;
  }
  if (o.voxel_size_m > 0.0) {
    voxel_downsample(*source, o.voxel_size_m, downsampled_);
    source = &downsampled_;
  }
  const std::size_t n = source->points.size();
  result.source_points = int(n);
  const PointCloud& tgt = target.cloud();
  if (int(n) < std::max(o.min_points, 1) || int(target.size()) < std::max(o.min_points, 1) ||
      tgt.normals.size() != tgt.points.size()) {
    result.status = IcpStatus::kTooFewPoints;
    return result;
  }

  cache_->reset(n);

  const Centroid cs = centroid_and_radius(source->points);
  // The contact's curvature, for telling its rolls from slivers (DegeneracyReport::shape).
  const ContactShape shape_source = fit_contact_shape(source->points, source->normals);
  const double L = std::max(cs.rms_radius, 1e-6), inv_L = 1.0 / L;
  // Searching a little beyond the correspondence distance lets a point without a partner skip
  // later queries until it has moved by the difference.
  const float radius = 1.5f * float(o.max_correspondence_m);

  // Coarse to fine: the large first steps on every stride-th point. Each step re-queries about
  // every point it moves by more than a point spacing, so the subsample saves most of the
  // queries of a distant guess; the full cloud then starts close to its answer and its points
  // keep their nearest neighbours from one iteration to the next.
  std::size_t stride = 1;
  if (o.coarse_points > 0 && n >= 2 * std::size_t(o.coarse_points)) {
    stride = n / std::size_t(o.coarse_points);
  }
  const int min_inliers = std::max(o.min_points, 6);
  // The pairs' normals are limited (IcpOptions::max_normal_angle_rad) once a step moves the
  // cloud by less than kNormalLimitStepM: near the answer a pair whose normals differ that much
  // straddles a crease, but from a distant guess it is often what pulls the cloud in (across a
  // rounded corner half a millimetre off, say).
  const bool limit_wanted = o.max_normal_angle_rad > 0.0 && has_normals(*source);
  bool limit = false;

  SE3 T = T_target_source_guess;
  CycleWatch cycle;
  for (int iteration = 1; iteration <= o.max_iterations; ++iteration) {
    const Eigen::Vector3d c = T * cs.centre;  // the source centroid in the target frame
    // At most the first half of the iterations are coarse: the full cloud always gets the rest
    // (and a subsample whose correspondences keep flipping cannot use them all up).
    if (iteration > o.max_iterations / 2) stride = 1;

    const bool limited = limit;
    const NormalEquations eq =
        linearise(*source, stride, target, T, c, inv_L, o, *cache_, radius, limited);
    last_queries_ += eq.queries;
    result.iterations = iteration;
    const bool coarse = stride > 1;
    result.coarse_iterations += coarse;
    if (eq.inliers < min_inliers) {
      if (coarse) {  // too sparse to register: the full cloud decides
        stride = 1;
        continue;
      }
      result.status = IcpStatus::kTooFewCorrespondences;
      result.converged = false;
      result.T_target_source = T;
      return result;
    }
    const Matrix6d H_scaled = eq.hessian();
    // The sums are scaled by the one length L; the degeneracy analysis by the cloud's extent
    // about each axis (degeneracy.h): x_Lambda = D^-1 x_L with D = diag(1, 1, 1, L Lambda^-1).
    const Eigen::Matrix3d R = T.rotation_matrix();
    const Eigen::Matrix3d Lambda = rotation_scale(R * cs.scatter * R.transpose());
    Matrix6d D = Matrix6d::Identity();
    D.bottomRightCorner<3, 3>() = L * Lambda.inverse();
    const DegeneracyReport degeneracy =
        analyse_degeneracy(D * H_scaled * D, c, Lambda, o.min_eigenvalue_ratio,
                           shape_source.rotated(R), o.flat_radius_m);
    if (!coarse) {
      result.inliers = eq.inliers;
      result.rms_m = std::sqrt(NormalEquations::total(eq.sq) / eq.inliers);
      result.degeneracy = degeneracy;
      // Hessian and information in the right (source-frame) tangent at this linearisation
      // point: J_c = J_scaled S with S = diag(1, 1, 1, L, L, L), and delta_c = Ad(T_c^-1 T) eps.
      Vector6d s;
      s << 1, 1, 1, L, L, L;
      const Matrix6d H_c = s.asDiagonal() * H_scaled * s.asDiagonal();
      const Matrix6d A = (SE3::Translation(-c) * T).adjoint();
      result.hessian = A.transpose() * H_c * A;
      const double sigma_sq = NormalEquations::total(eq.weighted_sq) /
                              std::max(NormalEquations::total(eq.weight) - 6.0, 1.0);
      result.residual_sigma_m = std::max(std::sqrt(sigma_sq), o.min_residual_sigma_m);
      result.information = result.hessian / (result.residual_sigma_m * result.residual_sigma_m);
      cycle.record(T);
    }

    // Gauss-Newton step about the centroid, only along constrained directions.
    const Vector6d step_c = constrained_step(degeneracy, D * eq.gradient());
    const SE3 T_c = SE3::Translation(c);
    const SE3 linearised = T;
    T = T_c * SE3::exp(step_c) * T_c.inverse() * T;
    const double moved_m = step_c.head<3>().norm() + step_c.tail<3>().norm() * L;
    if (limit_wanted && !limit && moved_m < kNormalLimitStepM) {
      limit = true;
      cycle = CycleWatch();  // a cycle is among limited iterations
    }
    if (coarse) {
      // Fine from the next iteration once the subsample's points move less than coarse_step_m.
      if (moved_m < o.coarse_step_m) stride = 1;
      continue;
    }
    result.T_target_source = T;
    // (Not converged before an iteration with the pairs' normals limited, when they are to be.)
    if (limited == limit_wanted && step_c.head<3>().norm() < o.convergence_translation_m &&
        step_c.tail<3>().norm() < o.convergence_rotation_rad) {
      result.converged = true;
      result.status = IcpStatus::kConverged;
      return result;
    }
    if (limited == limit_wanted && cycle.closed(linearised, cs.centre, L, o.cycle_extent_m)) {
      // The answer is then this iteration's linearisation point, which the Hessian, information
      // and residuals above describe.
      result.T_target_source = linearised;
      result.converged = true;
      result.status = IcpStatus::kConverged;
      return result;
    }
  }
  result.status = IcpStatus::kMaxIterations;
  result.converged = false;
  return result;
}

}  // namespace pg
