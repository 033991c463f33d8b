#pragma once
// The networks (Torch modules) and the tensors they consume. Internal to pg_learn.
#include <torch/torch.h>

#include <string>
#include <vector>

#include "gel_frame.h"
#include "pg/core/dataset.h"
#include "pg/core/image.h"
#include "pg/learn/normal_model.h"

namespace pg::learn {

// Any of the generators: 3 input channels (the encoded difference image) -> 3 (normals, tanh).
// Accepts any image size: inputs are padded to what the architecture needs and the output is
// cropped back.
class GeneratorImpl : public torch::nn::Module {
 public:
  explicit GeneratorImpl(const NetworkSpec& spec);
  torch::Tensor forward(torch::Tensor x);
  // forward() pads each side up to a multiple of this (replicating the edge; the extra split
  // evenly, the odd pixel after) and crops the output back.
  int multiple() const { return multiple_; }

 private:
  torch::Tensor unet(const torch::Tensor& x);
  NetworkSpec spec_;
  int multiple_ = 1;                              // input sizes must be multiples of this
  std::vector<torch::nn::Sequential> down_, up_;  // unet
  torch::nn::Sequential body_{nullptr};           // resnet and mlp
};
TORCH_MODULE(Generator);

// pix2pix PatchGAN discriminator (two stride-2 layers: a ~34 px receptive field, which suits
// 120x160 tactile images) on the concatenated input and normal images; outputs logits.
class PatchDiscriminatorImpl : public torch::nn::Module {
 public:
  explicit PatchDiscriminatorImpl(int base_width);
  torch::Tensor forward(const torch::Tensor& input, const torch::Tensor& normals);

 private:
  torch::nn::Sequential body_{nullptr};
};
TORCH_MODULE(PatchDiscriminator);

// The input encoding (see normal_model.h): the raw difference (color - background) / 255,
// 3 x H x W, before normalisation by the stored mean and std.
torch::Tensor difference_tensor(const ImageU8& color, const ImageU8& background);
// Image (H x W x C, float) <-> tensor (C x H x W).
torch::Tensor image_to_tensor(const ImageF& image);
ImageF tensor_to_image(const torch::Tensor& chw);
// A 0/255 contact mask as a 1 x H x W tensor of 0/1.
torch::Tensor mask_tensor(const ImageU8& mask);
// A dataset's ground-truth normal image of `frame`, for training and evaluation: throws
// InputError naming the file and pixel when a value is not finite (the tracker, which only
// integrates normals, copes with such pixels; a loss or a metric would turn NaN).
ImageF true_normals(const Dataset& dataset, int frame);

// The network's output as the tracker gets it: of unit length, and +z (the undeformed gel) where
// it does not face the camera's side of the gel by more than kMinFacingZ (the network is unsure
// there). NormalEstimator::predict applies it per pixel after averaging the phases; the
// validation metrics of training through `as_predicted` (N x 3 x H x W), so that they are the
// metrics eval-normals reports.
constexpr float kMinFacingZ = 0.05f;
torch::Tensor as_predicted(const torch::Tensor& raw);

// Writes `archive` to `path` through a temporary file (a symbolic link's file replaced, a device
// or pipe refused: replaceable_file); InputError "PATH: cannot write the WHAT (CAUSE)" leaves no
// temporary file and the previous file as it was.
void save_archive(torch::serialize::OutputArchive& archive, const std::string& path,
                  const std::string& what);

// What is wrong with the weights `loaded` read from a file, against `described`, a fresh module of
// the network the file says it holds: a parameter or buffer missing or of another shape (Torch's
// load takes each stored tensor as it is, whatever its shape). Empty when nothing; else "KEY has
// another shape", for the loaders' errors.
std::string weights_shape_problem(const torch::nn::Module& loaded,
                                  const torch::nn::Module& described);
// A parameter or buffer of `module` that holds numbers that are not finite (a file written so, its
// checksums intact): "KEY holds numbers that are not finite"; empty when none.
std::string weights_number_problem(const torch::nn::Module& module);
// Shapes and numbers as above, for an Adam optimizer's state read from a file: each moment of the
// shape of its parameter, and finite.
std::string optimizer_state_problem(torch::optim::Adam& optimizer);

// Model files: a Torch archive with the generator's weights and NormalModelInfo as JSON.
void save_model(const std::string& path, Generator& generator, const NormalModelInfo& info);
// Throws InputError naming the path.
Generator load_model(const std::string& path, NormalModelInfo& info);

// The metrics of normal_model.h on a batch: predicted and true normals (N x 3 x H x W, unit or
// near unit), mask (N x 1 x H x W, 0/1). Sums over the batch, for averaging by the caller.
struct MetricSums {
  double se_contact = 0, se_image = 0, angle_contact = 0, angle_image = 0;
  double contact_px = 0, image_px = 0;
  void add(const torch::Tensor& predicted, const torch::Tensor& truth, const torch::Tensor& mask);
  NormalMetrics metrics(int frames) const;
};

}  // namespace pg::learn
