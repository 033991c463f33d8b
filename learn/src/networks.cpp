#include "networks.h"

#include <algorithm>

namespace pg::learn {

namespace nn = torch::nn;
namespace F = torch::nn::functional;

namespace {

nn::Conv2d conv(int in, int out, int kernel, int stride, int padding, bool bias = true) {
  return nn::Conv2d(nn::Conv2dOptions(in, out, kernel).stride(stride).padding(padding).bias(bias));
}

nn::ConvTranspose2d up_conv(int in, int out) {
  return nn::ConvTranspose2d(nn::ConvTranspose2dOptions(in, out, 4).stride(2).padding(1));
}

nn::LeakyReLU leaky() { return nn::LeakyReLU(nn::LeakyReLUOptions().negative_slope(0.2)); }

// ResNet block: x + (pad conv BN ReLU pad conv BN)(x).
class ResidualBlockImpl : public nn::Module {
 public:
  explicit ResidualBlockImpl(int channels) {
    body_ = register_module(
        "body",
        nn::Sequential(nn::ReflectionPad2d(1), conv(channels, channels, 3, 1, 0, false),
                       nn::BatchNorm2d(channels), nn::ReLU(), nn::ReflectionPad2d(1),
                       conv(channels, channels, 3, 1, 0, false), nn::BatchNorm2d(channels)));
  }
  torch::Tensor forward(const torch::Tensor& x) { return x + body_->forward(x); }

 private:
  nn::Sequential body_{nullptr};
};
TORCH_MODULE(ResidualBlock);

}  // namespace

GeneratorImpl::GeneratorImpl(const NetworkSpec& spec) : spec_(spec) {
  const int w = spec.base_width;
  if (spec.arch == "unet") {
    // pix2pix U-Net: encoder [LeakyReLU] Conv4x4/2 [BN], decoder ReLU ConvT4x4/2 BN, skips by
    // concatenation; channels w, 2w, 4w, 8w, 8w, ...
    const int d = spec.depth;
    multiple_ = 1 << d;
    std::vector<int> c(d);
    for (int i = 0; i < d; ++i) c[i] = w << std::min(i, 3);
    for (int i = 0; i < d; ++i) {
      nn::Sequential block;
      if (i > 0) block->push_back(leaky());
      block->push_back(conv(i == 0 ? 3 : c[i - 1], c[i], 4, 2, 1, /*bias=*/i == 0 || i == d - 1));
      if (i > 0 && i < d - 1) block->push_back(nn::BatchNorm2d(c[i]));
      down_.push_back(register_module("down" + std::to_string(i), block));
    }
    for (int i = 0; i < d; ++i) {
      nn::Sequential block;
      block->push_back(nn::ReLU());
      const int in = i == d - 1 ? c[i] : 2 * c[i];
      if (i == 0) {
        block->push_back(up_conv(in, 3));
        block->push_back(nn::Tanh());
      } else {
        block->push_back(up_conv(in, c[i - 1]));
        block->push_back(nn::BatchNorm2d(c[i - 1]));
      }
      up_.push_back(register_module("up" + std::to_string(i), block));
    }
  } else if (spec.arch == "resnet") {
    // pix2pix ResNet generator: c7s1-w, d2w, d4w, `depth` residual blocks, u2w, uw, c7s1-3.
    multiple_ = 4;
    nn::Sequential b;
    b->push_back(nn::ReflectionPad2d(3));
    b->push_back(conv(3, w, 7, 1, 0, false));
    b->push_back(nn::BatchNorm2d(w));
    b->push_back(nn::ReLU());
    for (int k : {1, 2}) {
      b->push_back(conv(w << (k - 1), w << k, 3, 2, 1, false));
      b->push_back(nn::BatchNorm2d(w << k));
      b->push_back(nn::ReLU());
    }
    for (int i = 0; i < spec.depth; ++i) b->push_back(ResidualBlock(4 * w));
    for (int k : {2, 1}) {
      b->push_back(nn::ConvTranspose2d(nn::ConvTranspose2dOptions(w << k, w << (k - 1), 3)
                                           .stride(2)
                                           .padding(1)
                                           .output_padding(1)
                                           .bias(false)));
      b->push_back(nn::BatchNorm2d(w << (k - 1)));
      b->push_back(nn::ReLU());
    }
    b->push_back(nn::ReflectionPad2d(3));
    b->push_back(conv(w, 3, 7, 1, 0));
    b->push_back(nn::Tanh());
    body_ = register_module("body", b);
  } else if (spec.arch == "mlp") {
    // The paper's per-pixel baseline: (r, g, b, x, y) -> hidden -> hidden -> 3, tanh; as 1x1
    // convolutions over the image with the pixel coordinates appended by forward().
    const int h = spec.mlp_hidden;
    body_ =
        register_module("body", nn::Sequential(conv(5, h, 1, 1, 0), nn::ReLU(), conv(h, h, 1, 1, 0),
                                               nn::ReLU(), conv(h, 3, 1, 1, 0), nn::Tanh()));
  } else {
    throw std::invalid_argument("unknown network architecture '" + spec.arch +
                                "' (unet, resnet or mlp)");
  }
}

torch::Tensor GeneratorImpl::unet(const torch::Tensor& x) {
  std::vector<torch::Tensor> skips;
  torch::Tensor h = x;
  for (auto& block : down_) {
    h = block->forward(h);
    skips.push_back(h);
  }
  const int d = int(down_.size());
  torch::Tensor u = up_[d - 1]->forward(skips[d - 1]);
  for (int i = d - 2; i >= 0; --i) u = up_[i]->forward(torch::cat({u, skips[i]}, 1));
  return u;
}

torch::Tensor GeneratorImpl::forward(torch::Tensor x) {
  const int64_t h = x.size(2), w = x.size(3);
  if (spec_.arch == "mlp") {
    const auto opts = x.options();
    const torch::Tensor ys =
        torch::linspace(-1, 1, h, opts).view({1, 1, h, 1}).expand({x.size(0), 1, h, w});
    const torch::Tensor xs =
        torch::linspace(-1, 1, w, opts).view({1, 1, 1, w}).expand({x.size(0), 1, h, w});
    return body_->forward(torch::cat({x, xs, ys}, 1));
  }
  const int64_t ph = (multiple_ - h % multiple_) % multiple_,
                pw = (multiple_ - w % multiple_) % multiple_;
  if (ph > 0 || pw > 0) {
    x = F::pad(
        x, F::PadFuncOptions({pw / 2, pw - pw / 2, ph / 2, ph - ph / 2}).mode(torch::kReplicate));
  }
  torch::Tensor y = spec_.arch == "unet" ? unet(x) : body_->forward(x);
  if (ph > 0 || pw > 0) y = y.slice(2, ph / 2, ph / 2 + h).slice(3, pw / 2, pw / 2 + w);
  return y;
}

PatchDiscriminatorImpl::PatchDiscriminatorImpl(int w) {
  body_ = register_module(
      "body", nn::Sequential(conv(6, w, 4, 2, 1), leaky(), conv(w, 2 * w, 4, 2, 1, false),
                             nn::BatchNorm2d(2 * w), leaky(), conv(2 * w, 4 * w, 4, 1, 1, false),
                             nn::BatchNorm2d(4 * w), leaky(), conv(4 * w, 1, 4, 1, 1)));
}

torch::Tensor PatchDiscriminatorImpl::forward(const torch::Tensor& input,
                                              const torch::Tensor& normals) {
  return body_->forward(torch::cat({input, normals}, 1));
}

}  // namespace pg::learn
