#include "pg/tracker/poisson_dst.h"

#include <fftw3.h>

#include <cassert>
#include <cmath>
#include <mutex>

#include "pg/core/se3.h"

namespace pg {

namespace {

// FFTW's planner (and plan destruction) must not run on two threads at once.
std::mutex& fftw_planner_mutex() {
  static std::mutex m;
  return m;
}

bool is_7_smooth(int n) {
  for (int p : {2, 3, 5, 7}) {
    while (n % p == 0) n /= p;
  }
  return n == 1;
}

struct FftwFloatDeleter {
  void operator()(float* p) const { fftwf_free(p); }
};

// RAII for an FFTW plan (creation and destruction under the planner lock).
class FftwPlan {
 public:
  FftwPlan() = default;
  template <class MakePlan>
  explicit FftwPlan(MakePlan make) {
    std::lock_guard<std::mutex> lock(fftw_planner_mutex());
    plan_ = make();
  }
  ~FftwPlan() {
    if (!plan_) return;
    std::lock_guard<std::mutex> lock(fftw_planner_mutex());
    fftwf_destroy_plan(plan_);
  }
  FftwPlan(const FftwPlan&) = delete;
  FftwPlan& operator=(const FftwPlan&) = delete;
  void execute() const { fftwf_execute(plan_); }
  bool valid() const { return plan_ != nullptr; }

 private:
  fftwf_plan plan_ = nullptr;
};

struct FftwComplexDeleter {
  void operator()(fftwf_complex* p) const { fftwf_free(p); }
};

// DST-I along the rows of `rows` x `n` values through the odd extension and one batched
// real-to-complex FFT of size m = 2 (n + 1), writing the result transposed (n x rows), so that
// two calls give the 2D transform back in the original layout.
class RowDst {
 public:
  RowDst(int n, int rows, unsigned flags) : n_(n), rows_(rows), m_(2 * (n + 1)), half_(n + 2) {
    ext_.reset(fftwf_alloc_real(std::size_t(rows) * m_));
    spec_.reset(fftwf_alloc_complex(std::size_t(rows) * half_));
    plan_ = std::make_unique<FftwPlan>([&] {
      int m = m_;
      return fftwf_plan_many_dft_r2c(1, &m, rows_, ext_.get(), nullptr, 1, m_, spec_.get(),
                                     nullptr, 1, half_, flags);
    });
  }
  bool valid() const { return plan_->valid(); }

  void apply_transposed(const float* in, float* out_transposed) const {
    float* e = ext_.get();
    for (int r = 0; r < rows_; ++r) {
      const float* x = in + std::size_t(r) * n_;
      float* row = e + std::size_t(r) * m_;
      row[0] = 0.0f;
      row[n_ + 1] = 0.0f;
      for (int j = 0; j < n_; ++j) row[1 + j] = x[j];
      for (int j = 0; j < n_; ++j) row[n_ + 2 + j] = -x[n_ - 1 - j];
    }
    plan_->execute();
    const fftwf_complex* c = spec_.get();
    for (int r = 0; r < rows_; ++r) {
      const fftwf_complex* row = c + std::size_t(r) * half_;
      for (int k = 0; k < n_; ++k) out_transposed[std::size_t(k) * rows_ + r] = -row[k + 1][1];
    }
  }

 private:
  int n_, rows_, m_, half_;
  std::unique_ptr<float, FftwFloatDeleter> ext_;
  std::unique_ptr<fftwf_complex, FftwComplexDeleter> spec_;
  std::unique_ptr<FftwPlan> plan_;
};

}  // namespace

int dst_fast_size(int n) {
  int m = std::max(n, 1);
  while (!is_7_smooth(m + 1)) ++m;
  return m;
}

struct PoissonDstSolver::Entry {
  int nx = 0, ny = 0;
  std::int64_t last_used = 0;
  std::unique_ptr<float, FftwFloatDeleter> data;  // the grid, nx * ny
  // 1 / (eigenvalue * 4 (nx + 1) (ny + 1)): the inverse operator with the two unnormalised
  // transforms' scale folded in (RODFT00 applied twice multiplies by 2 (n + 1) per axis).
  std::vector<float> inverse_eigenvalues;
  // kFftwR2r: one in-place 2D RODFT00 plan. kRealFft: row transforms along x and along y, and
  // the transposed intermediate.
  std::unique_ptr<FftwPlan> r2r;
  std::unique_ptr<RowDst> along_x, along_y;
  std::vector<float> transposed;

  Entry(int nx_, int ny_, const PoissonDstOptions& options) : nx(nx_), ny(ny_) {
    const std::size_t n = std::size_t(nx) * ny;
    data.reset(fftwf_alloc_real(n));
    const unsigned flags = options.measure_plans ? FFTW_MEASURE : FFTW_ESTIMATE;
    if (options.backend == DstBackend::kFftwR2r) {
      float* d = data.get();
      r2r = std::make_unique<FftwPlan>([&] {
        return fftwf_plan_r2r_2d(ny, nx, d, d, FFTW_RODFT00, FFTW_RODFT00, flags);
      });
    } else {
      along_x = std::make_unique<RowDst>(nx, ny, flags);
      along_y = std::make_unique<RowDst>(ny, nx, flags);
      transposed.resize(n);
    }
    inverse_eigenvalues.resize(n);
    const double scale = 4.0 * (nx + 1.0) * (ny + 1.0);
    std::vector<double> lx(nx);
    for (int k = 0; k < nx; ++k) lx[k] = 2.0 * std::cos(kPi * (k + 1) / (nx + 1.0)) - 2.0;
    for (int l = 0; l < ny; ++l) {
      const double ly = 2.0 * std::cos(kPi * (l + 1) / (ny + 1.0)) - 2.0;
      for (int k = 0; k < nx; ++k) {
        inverse_eigenvalues[std::size_t(l) * nx + k] = float(1.0 / ((lx[k] + ly) * scale));
      }
    }
  }

  bool valid() const { return r2r ? r2r->valid() : along_x->valid() && along_y->valid(); }

  // The 2D DST-I of the grid, in place.
  void transform() {
    if (r2r) {
      r2r->execute();
    } else {
      along_x->apply_transposed(data.get(), transposed.data());
      along_y->apply_transposed(transposed.data(), data.get());
    }
  }
};

PoissonDstSolver::PoissonDstSolver(PoissonDstOptions options) : options_(options) {
  if (options_.max_cached_sizes < 1) options_.max_cached_sizes = 1;
}

PoissonDstSolver::~PoissonDstSolver() = default;

int PoissonDstSolver::cached_sizes() const { return int(cache_.size()); }

float* PoissonDstSolver::grid(int nx, int ny) {
  assert(nx > 0 && ny > 0);
  ++clock_;
  for (auto& e : cache_) {
    if (e->nx == nx && e->ny == ny) {
      e->last_used = clock_;
      current_ = e.get();
      return e->data.get();
    }
  }
  if (int(cache_.size()) >= options_.max_cached_sizes) {
    std::size_t oldest = 0;
    for (std::size_t i = 1; i < cache_.size(); ++i) {
      if (cache_[i]->last_used < cache_[oldest]->last_used) oldest = i;
    }
    cache_.erase(cache_.begin() + long(oldest));
  }
  cache_.push_back(std::make_unique<Entry>(nx, ny, options_));
  ++plans_created_;
  current_ = cache_.back().get();
  current_->last_used = clock_;
  assert(current_->valid());
  return current_->data.get();
}

void PoissonDstSolver::solve() {
  assert(current_ != nullptr);
  Entry& e = *current_;
  float* w = e.data.get();
  const float* inv = e.inverse_eigenvalues.data();
  const std::size_t n = std::size_t(e.nx) * e.ny;
  e.transform();
  for (std::size_t i = 0; i < n; ++i) w[i] *= inv[i];
  e.transform();
}

}  // namespace pg
