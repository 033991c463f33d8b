#pragma once
// Learned surface normals (paper section IV-A): a network maps a tactile colour image to the gel's
// surface-normal image in the sensor frame. Torch stays inside learn/src; this header does not
// include it.
//
// Input encoding: the frame minus the sensor's no-contact reference image (DIR/background.png),
// per channel, scaled to [-1, 1] and normalised by the training set's mean and standard
// deviation (stored in the model file). Subtracting the reference is what real GelSight and DIGIT
// pipelines do; it removes the sensor's own illumination pattern and most of the background, so a
// model generalises across gels and backgrounds.
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "pg/core/dataset.h"
#include "pg/core/image.h"
#include "pg/core/sensor.h"

namespace pg {

// The network architectures of the paper's Table I.
struct NetworkSpec {
  std::string arch = "unet";  // unet (pix2pix U-Net), resnet (pix2pix ResNet), mlp (per pixel)
  int depth = 5;              // unet: down-sampling levels; resnet: residual blocks
  int base_width = 16;        // channels of the first layer (pix2pix: 64)
  int mlp_hidden = 32;        // mlp: width of its two hidden layers (5-32-32-3 in the paper)
};
// The sizes train-normals makes (its options' ranges), which a model file's description is held
// to: depth 1-kMaxNetworkDepth, base_width 1-kMaxBaseWidth, mlp_hidden 1-kMaxMlpHidden.
constexpr int kMaxNetworkDepth = 8, kMaxBaseWidth = 256, kMaxMlpHidden = 1024;
// "unet (depth 5, width 16)", "mlp (hidden 32)": the network in a message.
std::string describe(const NetworkSpec& spec);

// What a model file holds besides the weights.
struct NormalModelInfo {
  NetworkSpec spec;
  std::array<float, 3> input_mean{0, 0, 0}, input_std{1, 1, 1};  // of the difference image
  int width = 0, height = 0;  // image size it was trained on (and accepts)
  int epochs = 0;
  std::vector<std::string> training_data;  // dataset folders
  std::string history_json;                // per-epoch losses and validation metrics (JSON array)
  // The run's train-normals settings, a JSON object by option name ("--lr", "--batch", "--seed",
  // the loss weights, the augmentation, "--decay-epochs", "--val"): what else the command that
  // made it said. Empty for a file from before 2026-11-29, which did not record them.
  std::string settings_json;
  // A fine-tuned model's starting point (train-normals --init), as a JSON object: "model" (its
  // file), "epochs", "training_data" and, when that model was fine-tuned too, its own
  // "fine_tuned_from". Empty for a model trained from random weights (or a file from before
  // 2026-11-27, which did not record it).
  std::string fine_tuned_from_json;
  // The network's output frame: false = the sensor frame S; true = each pixel's undeformed gel
  // (+z along the gel's normal there, the minimal rotation from S), composed with the gel of
  // `sensor` at inference.
  bool gel_relative = false;
  // The sensor the model was trained on (its first dataset's): composes a gel-relative output,
  // and tells images of other optics. Recorded in model files since 2026-11-27 (and before in
  // gel-relative ones); sensor_known is false for an older file.
  SensorModel sensor;
  bool sensor_known = false;
  // The backgrounds of its training frames (frame_background), sorted, each once; empty when a
  // training dataset did not say (and in a file from before 2026-11-29, which did not record
  // them). With --init, the starting model's too.
  std::vector<std::string> backgrounds;
  // Not stored in the file: the FNV-1a of its bytes as NormalEstimator::load read them
  // (file_digest), which summary.json records and eval --resume compares, so that a model trained
  // again into the same path is told from the one before. Empty when not loaded from a file.
  std::string file_digest;
};

// What lies behind a dataset's imprints, as a network that reads the frame minus the no-contact
// reference sees it: "synthetic" (a render on the renderer's own no-contact image) or "real" (a
// render blended over a real sensor's no-contact image, TACTO's blend, which halves and blurs an
// imprint's contrast; or a recording of a real sensor); "" when the dataset does not say (a
// render from before dataset.json recorded its render settings).
std::string frame_background(const DatasetInfo& info);

// A trained model for inference. Not thread-safe: use one per thread.
class NormalEstimator {
 public:
  // Loads MODEL; threads = the intra-op threads Torch may use (0 = all cores). Throws InputError
  // naming the path when the file is missing, corrupt or not a normals model.
  static NormalEstimator load(const std::string& path, int threads = 1);
  NormalEstimator(NormalEstimator&&) noexcept;
  NormalEstimator& operator=(NormalEstimator&&) noexcept;
  ~NormalEstimator();

  // Unit normals in the sensor frame (width x height x 3). `color` and `background` must be
  // 8-bit RGB of the size the model was trained on; throws InputError otherwise.
  ImageF predict(const ImageU8& color, const ImageU8& background) const;
  // Phase averaging: `predict` runs the network on the frame shifted by 0 and 1 pixel (phases 2:
  // diagonally; 4: each of the stride-2 layers' four sampling phases) in one batch and averages
  // the outputs, which cuts the contact region's error by about a tenth for 2-4x the inference
  // time (docs/learned_normals.md). 1 (the default) is the single pass. Throws InputError for
  // anything but 1, 2 or 4.
  void set_phases(int phases);
  int phases() const;
  const NormalModelInfo& info() const;
  const std::string& path() const;
  // The network's trainable weights (scalars).
  long parameter_count() const;
  // Throws InputError (naming `where` and the model) when images of `sensor` do not suit the
  // model: another image size, or, for a gel-relative model, another undeformed gel (camera or
  // gel shape) than the one it composes its output with.
  void check_sensor(const SensorModel& sensor, const std::string& where) const;
  // "" when images of `sensor` look like the training sensor's (or the model does not say what
  // that was); else which of its optics differ ("lights", "shading", "camera"): the network
  // reads another sensor's shading as other slopes (a model of sensor A on a sensor of permuted
  // light colours: 23.6 deg contact error against 9.5).
  std::string sensor_difference(const SensorModel& sensor) const;
  // "" when the frames of `info` have a background the model was trained on (or either does not
  // say); else a sentence for a warning naming both (the default model, trained on synthetic
  // renders, reads a sphere press rendered over the real DIGIT background 6.2 deg off in the
  // contact, against 2.3 deg on its synthetic render).
  std::string background_difference(const DatasetInfo& info) const;

 private:
  struct Impl;
  explicit NormalEstimator(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// The paper's metric: MSE of the normal image encoded as (n + 1) / 2, averaged over channels and
// pixels, in the contact region (the dataset's mask) and over the whole image; and the mean
// angle between predicted and true normals [deg].
struct NormalMetrics {
  int frames = 0;
  long contact_pixels = 0;  // the contact metrics are NaN when there is none
  double mse_contact = 0, mse_image = 0;
  double angle_contact_deg = 0, angle_image_deg = 0;
  double ms_per_frame = 0;  // median inference time
};

// Which optics of sensor `b` differ from `a`'s for a network that reads shading ("lights",
// "shading" and "camera", joined with commas and "and"; "" if none): NormalEstimator's
// sensor_difference, and train-normals on datasets of several sensors.
std::string optics_difference(const SensorModel& a, const SensorModel& b);

// Throws InputError naming the dataset unless each can be evaluated with `model`: color, normal
// and mask outputs, images the model takes, a no-contact reference. Before any work, so that a
// bad last dataset does not cost the results of the others.
void check_evaluation_data(const NormalEstimator& model, const std::vector<std::string>& datasets);
// Evaluates on every frame of each dataset (checked as check_evaluation_data says).
NormalMetrics evaluate_normals(const NormalEstimator& model,
                               const std::vector<std::string>& datasets,
                               const std::function<void(int, int)>& progress = nullptr);

// Normals from something other than a network (the shading's inverse, pg/sim/
// shading_inversion.h): the index of the dataset in evaluate_normals' list, a frame's colour
// image and that dataset's no-contact reference -> unit normals, width x height x 3.
using NormalsReader =
    std::function<ImageF(std::size_t dataset, const ImageU8& color, const ImageU8& reference)>;
// check_evaluation_data without a model's own checks: the outputs and the reference.
void check_evaluation_data(const std::vector<std::string>& datasets);
// The same metrics for `read`, named `name` in errors (InputError where it gives a value that is
// not a finite number).
NormalMetrics evaluate_normals(const NormalsReader& read, const std::string& name,
                               const std::vector<std::string>& datasets,
                               const std::function<void(int, int)>& progress = nullptr);

struct TrainOptions {
  std::vector<std::string> train_data;  // dataset folders with color, normal and mask outputs
  std::vector<std::string> val_data;    // validation folders; empty: hold out val_fraction
  double val_fraction = 0.1;
  NetworkSpec spec;
  std::string out;  // model file; OUT.ckpt holds the resumable checkpoint
  int epochs = 150;
  int batch = 4;
  double learning_rate = 2e-4, beta1 = 0.5;  // Adam, as pix2pix
  // The last decay_epochs epochs lower the learning rate linearly towards zero (pix2pix's
  // schedule): epoch e (0-based) of E trains at lr * min(1, (E - e) / (decay_epochs + 1)).
  int decay_epochs = 0;
  double l1_weight = 100.0;  // unet/resnet: L1 on the normals x this + the GAN loss x gan_weight
  double gan_weight = 1.0;   // 0 trains without the PatchGAN discriminator; mlp: L2 only
  // The L1 (mlp: L2) loss of a contact pixel counts 1 + contact_weight times a background
  // pixel's (0: pix2pix's plain loss). Contact pixels are a few percent of the image, and they
  // are the ones the tracker integrates.
  double contact_weight = 0.0;
  // Train on normals relative to the undeformed gel (NormalModelInfo::gel_relative); the
  // datasets must share one undeformed gel (camera and gel shape).
  bool gel_relative = false;
  int shift_px = 8;          // augmentation: random image shifts up to this [px]
  double gain_jitter = 0.3;  // augmentation: the difference image scaled by 1 +- this
  // Augmentation: each colour channel of the difference image shifted by up to +- this many
  // levels (a brightness drift of the sensor since its reference image); 0 = off.
  double offset_jitter = 0.0;
  // Augmentation: camera noise of a sigma drawn per frame from 0 to this many levels, added to
  // the frame (rounded and clipped to 8 bits, as the camera's) before the difference with the
  // reference: for training renders without noise (tacsim render --noise off), so that the
  // network meets fresh noise each epoch and cameras quieter than the renders'; 0 = off.
  double noise_augment = 0.0;
  std::uint64_t seed = 0;
  int threads = 0;            // 0 = all cores
  int checkpoint_every = 1;   // epochs
  bool resume = false;        // continue from OUT.ckpt
  // Fine-tuning: start from this model's weights, with its network and its input normalisation
  // (`spec` is then taken from it; the training images must be of its size and its label frame,
  // `gel_relative`). The discriminator starts afresh. "" = from random weights.
  std::string init_model;
  // The network options given explicitly ("--l1-weight", "--gan-weight", "--depth", "--width",
  // "--hidden"), so that one the chosen network ignores is refused even at its default value;
  // and the loss weight and augmentation ("--contact-weight", "--shift", "--gain-jitter",
  // "--offset-jitter", "--noise-augment"), whose fine-tuning values given are not warned of.
  std::vector<std::string> given;
};

struct EpochReport {
  int epoch = 0, epochs = 0;
  double learning_rate = 0;
  double loss_l1 = 0, loss_gan = 0, loss_d = 0;  // means over the epoch (mlp: loss_l1 = L2)
  bool squared_loss = false;                     // loss_l1 is the MLP's L2
  int train_frames = 0, batches = 0;             // per epoch
  NormalMetrics val;
  double seconds = 0;
};

// The settings that make a training run of `options` what it is, by their train-normals option
// names, as a JSON object (what a model's NormalModelInfo::settings_json records, with the data).
std::string training_settings_json(const TrainOptions& options);

// Trains and writes OUT (and OUT.ckpt every checkpoint_every epochs). Throws InputError for bad
// data (naming the folder or file). `on_step(epoch, done, total)` reports batches within an
// epoch (counted from 1, as EpochReport::epoch; a resumed run starts after its checkpoint's).
void train_normals(const TrainOptions& options,
                   const std::function<void(const EpochReport&)>& on_epoch = nullptr,
                   const std::function<void(int, int, int)>& on_step = nullptr);

}  // namespace pg
