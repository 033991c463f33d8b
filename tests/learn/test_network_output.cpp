// What the tracker and eval-normals make of a network's output that is not a number. The one
// test file that reaches into the networks (Torch's headers are slow to compile).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "../common/test_support.h"
#include "networks.h"
#include "pg/core/dataset.h"
#include "pg/core/error.h"
#include "pg/learn/normal_model.h"
#include "pg/sim/scene.h"
#include "pg/sim/scene_renderer.h"

namespace pg {
namespace {

using testing_support::TempDir;

// A network whose output is NaN (finite weights that overflow inside it) is not read as the flat
// gel's normals, which it had been: predict passes the NaN on (the tracker counts such normals as
// rejected normals) and eval-normals refuses the model.
TEST(NetworkOutput, NaNIsNotReadAsAFlatGel) {
  TempDir tmp;
  RenderOverrides overrides;
  overrides.width = 40;
  overrides.height = 30;
  overrides.frames = 6;
  overrides.outputs = {"color", "normal", "mask"};
  const SceneRenderer renderer(
      load_scene(std::string(PG_SOURCE_DIR) + "/scenes/normals/sphere_val.json"), overrides);
  const std::string data = tmp.str("presses");
  render_scene_to_dataset(renderer, data);
  TrainOptions o;
  o.train_data = {data};
  o.out = tmp.str("finite.pt");
  o.spec.arch = "unet";
  o.spec.depth = 2;
  o.spec.base_width = 4;
  o.epochs = 1;
  o.threads = 1;
  train_normals(o);

  NormalModelInfo info;
  learn::Generator g = learn::load_model(o.out, info);
  {
    torch::NoGradGuard no_grad;
    g->parameters().front().fill_(3e38f);  // the first convolution's: its sums overflow
  }
  const std::string broken = tmp.str("overflowing.pt");
  learn::save_model(broken, g, info);
  const NormalEstimator model = NormalEstimator::load(broken);  // every weight finite
  const Dataset d = Dataset::open(data);
  const ImageF n = model.predict(d.color(0), d.background());
  const auto nan =
      std::count_if(n.data.begin(), n.data.end(), [](float v) { return std::isnan(v); });
  EXPECT_GT(nan, 0);
  EXPECT_EQ(nan % 3, 0);  // whole pixels
  std::string message;
  try {
    evaluate_normals(model, {data});
  } catch (const InputError& e) {
    message = e.what();
  }
  EXPECT_NE(message.find(broken + ": the network's output is not a finite number at "),
            std::string::npos)
      << message;
}

}  // namespace
}  // namespace pg
