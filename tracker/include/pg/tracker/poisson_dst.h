#pragma once
// Fast Poisson solver with a zero (Dirichlet) boundary, by the type-I discrete sine transform
// (DST-I, FFTW's RODFT00). Plans are made once per grid size and kept (a small LRU cache), so a
// tracker that sees similar contact sizes frame after frame plans only at the start.
#include <cstdint>
#include <memory>
#include <vector>

namespace pg {

// The smallest n' >= n for which n' + 1 has no prime factor above 7: a DST-I of size n is an FFT
// of size 2 (n + 1), fastest when that factors into small primes (FFTW: a 320 x 240 DST-I takes
// about 5x longer than 319 x 239).
int dst_fast_size(int n);

// How the DST-I is computed. Both give FFTW's RODFT00, Y_k = 2 sum_j x_j sin(pi (j+1)(k+1) /
// (n+1)).
enum class DstBackend {
  // The odd extension [0, x, 0, -reverse(x)] through FFTW's SIMD real-to-complex FFT of size
  // 2 (n + 1), Y_k = -Im(FFT_{k+1}), rows then (transposed) columns: 2-4x faster than r2r here.
  kRealFft,
  // FFTW's r2r RODFT00 directly (its r2r codelets are not vectorised).
  kFftwR2r,
};

struct PoissonDstOptions {
  DstBackend backend = DstBackend::kRealFft;
  // FFTW_MEASURE plans run faster but take 0.1-0.6 s to make per size (at 250 Hz, only with a
  // warm-up); FFTW_ESTIMATE plans are made in microseconds.
  bool measure_plans = false;
  int max_cached_sizes = 32;  // plans kept; the least recently used is dropped beyond this
};

// Solves the 5-point discrete Poisson equation on an nx x ny grid (row-major, ny rows of nx):
//   w(x+1,y) + w(x-1,y) + w(x,y+1) + w(x,y-1) - 4 w(x,y) = f(x,y)
// with w = 0 on the ring of cells just outside the grid. The DST-I diagonalises the operator:
//   W_kl = F_kl / (2 cos(pi (k+1) / (nx+1)) + 2 cos(pi (l+1) / (ny+1)) - 4).
// Not thread-safe (it owns its buffers); use one per thread. Plan creation is serialised
// process-wide (FFTW's planner is not thread-safe).
class PoissonDstSolver {
 public:
  explicit PoissonDstSolver(PoissonDstOptions options = {});
  ~PoissonDstSolver();
  PoissonDstSolver(const PoissonDstSolver&) = delete;
  PoissonDstSolver& operator=(const PoissonDstSolver&) = delete;

  // The grid of an nx x ny problem (SIMD-aligned, owned by the solver): write f into it, then
  // call solve(). Valid until the next grid() call.
  float* grid(int nx, int ny);
  // Replaces f by w in the grid last returned by grid().
  void solve();

  int cached_sizes() const;
  std::int64_t plans_created() const { return plans_created_; }

 private:
  struct Entry;
  PoissonDstOptions options_;
  std::vector<std::unique_ptr<Entry>> cache_;
  Entry* current_ = nullptr;
  std::int64_t clock_ = 0;
  std::int64_t plans_created_ = 0;
};

}  // namespace pg
