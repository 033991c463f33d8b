// Speed of the learned-normals inference (issue 6 target: U-Net at most 10 ms per 120x160 frame
// on 2 cores): the repository's default model and its per-pixel MLP baseline on a synthetic press
// image, with 1 and 2 Torch threads.
//
//   bench_learn --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <cmath>

#include "pg/learn/normal_model.h"

namespace pg {
namespace {

// A bright ring on a flat grey background: any image of the model's size does for timing.
void make_images(int w, int h, ImageU8& color, ImageU8& background) {
  background = ImageU8(w, h, 3, 120);
  color = background;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const double r = std::hypot(x - w / 2.0, y - h / 2.0);
      if (r < h / 5.0) {
        for (int c = 0; c < 3; ++c) color.at(x, y, c) = std::uint8_t(120 + 60 * std::sin(r + c));
      }
    }
  }
}

void run_model(benchmark::State& state, const char* file) {
  const NormalEstimator model =
      NormalEstimator::load(std::string(PG_SOURCE_DIR) + "/models/" + file, int(state.range(0)));
  ImageU8 color, background;
  make_images(model.info().width, model.info().height, color, background);
  for (auto _ : state) benchmark::DoNotOptimize(model.predict(color, background));
  state.SetLabel(std::to_string(model.info().width) + "x" + std::to_string(model.info().height) +
                 ", " + std::to_string(state.range(0)) + " thread(s)");
}

void BM_DefaultModelInference(benchmark::State& state) { run_model(state, "normals_unet.pt"); }
BENCHMARK(BM_DefaultModelInference)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_MlpInference(benchmark::State& state) { run_model(state, "normals_mlp.pt"); }
BENCHMARK(BM_MlpInference)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace pg

BENCHMARK_MAIN();
