// Training of the normals networks: pix2pix (L1 + PatchGAN) for the U-Net and ResNet generators,
// L2 for the per-pixel MLP, as in the paper's Table I.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <random>
#include <stdexcept>
#include <thread>

#include "checkpoint.h"
#include "networks.h"
#include "pg/core/dataset.h"
#include "pg/core/error.h"
#include "pg/core/file_io.h"
#include "pg/core/hash.h"

namespace pg {

namespace fs = std::filesystem;
namespace F = torch::nn::functional;

namespace {

// Frames as tensors: the raw difference input, the true normals and the contact mask; and each
// frame's no-contact reference (its dataset's, shared), which the noise augmentation needs.
struct FrameSet {
  std::vector<torch::Tensor> input, target, mask, reference;
  int width = 0, height = 0;
  // gel_relative: targets in each pixel's gel frame, that of the first dataset's sensor (the
  // others must have the same gel).
  bool gel_relative = false;
  SensorModel sensor;  // the first dataset's (the model records it)
  bool sensor_set = false;
  ImageF gel;  // gel_normals(sensor); empty until the first dataset
  // frame_background of the datasets read, each once; unknown_background: one did not say.
  std::vector<std::string> backgrounds;
  bool unknown_background = false;
  std::size_t size() const { return input.size(); }
};

// An 8-bit colour image as a 3 x H x W tensor in [0, 1].
torch::Tensor colour_tensor(const ImageU8& image) {
  return torch::from_blob(const_cast<std::uint8_t*>(image.data.data()),
                          {image.height, image.width, 3}, torch::kUInt8)
      .permute({2, 0, 1})
      .to(torch::kFloat32)
      .div(255.0)
      .contiguous();
}

void add_frame(FrameSet& set, const Dataset& d, const ImageU8& background,
               const torch::Tensor& reference, const ImageF& gel, int i) {
  set.input.push_back(learn::difference_tensor(d.color(i), background));
  set.reference.push_back(reference);
  ImageF normals = learn::true_normals(d, i);
  if (!gel.empty()) {
    for (std::size_t p = 0; p < gel.data.size(); p += 3) {
      learn::rotate_gel_frame(&gel.data[p], &normals.data[p], true);
    }
  }
  set.target.push_back(learn::image_to_tensor(normals));
  set.mask.push_back(learn::mask_tensor(d.mask(i)));
}

// FNV-1a over the bytes of the training targets and masks, in hex. Its start is not FNV's offset
// (a digit short of it) but stays, so that checkpoints written before still resume.
constexpr std::uint64_t kLabelsHashStart = 1469598103934665603ull;
std::string labels_hash(const FrameSet& set) {
  std::uint64_t h = kLabelsHashStart;
  const auto add = [&h](const torch::Tensor& t) {
    const torch::Tensor c = t.contiguous();
    h = fnv1a(c.data_ptr(), std::size_t(c.numel()) * c.element_size(), h);
  };
  for (std::size_t i = 0; i < set.size(); ++i) {
    add(set.target[i]);
    add(set.mask[i]);
  }
  return hex64(h);
}

// Reads the datasets; every `hold_out_every`-th frame (0: none) goes to `held_out`.
void load_frames(const std::vector<std::string>& dirs, FrameSet& set, FrameSet* held_out,
                 int hold_out_every) {
  for (const std::string& dir : dirs) {
    const Dataset d = Dataset::open(dir);
    for (const char* output : {"color", "normal", "mask"}) {
      if (!(std::string(output) == "normal" ? d.info().has_normals()
                                            : d.info().has_output(output))) {
        throw InputError(dir + ": dataset has no '" + output +
                         "' output, needed for training and validation (a recording of ball "
                         "presses gets them "
                         "from patchgraph label-ball)");
      }
    }
    if (set.width == 0) set.width = d.info().width(), set.height = d.info().height();
    if (held_out) held_out->width = set.width, held_out->height = set.height;
    if (d.info().width() != set.width || d.info().height() != set.height) {
      throw InputError(dir + ": images are " + std::to_string(d.info().width()) + "x" +
                       std::to_string(d.info().height()) + ", the other datasets " +
                       std::to_string(set.width) + "x" + std::to_string(set.height));
    }
    const ImageU8 background = d.background();
    const torch::Tensor reference = colour_tensor(background);
    const std::string kind = frame_background(d.info());
    if (kind.empty()) {
      set.unknown_background = true;
    } else if (std::find(set.backgrounds.begin(), set.backgrounds.end(), kind) ==
               set.backgrounds.end()) {
      set.backgrounds.push_back(kind);
    }
    if (!set.sensor_set) {
      set.sensor = d.info().sensor;
      set.sensor_set = true;
    }
    ImageF gel;
    if (set.gel_relative) {
      // One undeformed gel (camera and gel shape) for all; elasticity, lights and noise may vary.
      gel = learn::gel_normals(d.info().sensor);
      if (set.gel.empty()) {
        set.sensor = d.info().sensor;
        set.gel = gel;
      } else if (!learn::same_gel(gel, set.gel)) {
        throw InputError(dir +
                         ": another camera or gel shape than the other datasets' "
                         "(gel-relative labels need one)");
      }
    }
    for (int i = 0; i < d.frames(); ++i) {
      const bool hold = held_out && hold_out_every > 0 && i % hold_out_every == hold_out_every - 1;
      add_frame(hold ? *held_out : set, d, background, reference, gel, i);
    }
  }
}

// A batch of frames with the augmentation: the same random shift of input and target (replicated
// edges), the difference image scaled by a random gain and, with offset_jitter, each colour
// channel of it shifted by a random offset (a brightness drift since the reference was taken);
// with noise_augment, camera noise of a random sigma (0 to noise_augment levels) added to the
// frame, which is then rounded and clipped to 8 bits as the camera's is, before the difference
// with the reference. None changes the lights' geometry.
struct Batch {
  torch::Tensor input, target, mask;
};

Batch make_batch(const FrameSet& set, const std::vector<int>& index, int shift, double gain_jitter,
                 double offset_jitter, double noise_augment, std::mt19937_64& rng) {
  std::vector<torch::Tensor> in, out, masks;
  std::uniform_int_distribution<int> offset(-shift, shift);
  std::uniform_real_distribution<double> gain(1.0 - gain_jitter, 1.0 + gain_jitter);
  std::uniform_real_distribution<double> level(-offset_jitter, offset_jitter);
  std::uniform_real_distribution<double> sigma(0.0, noise_augment);
  for (int i : index) {
    torch::Tensor x = set.input[i] * gain(rng), y = set.target[i], m = set.mask[i];
    if (offset_jitter > 0) {  // no draws without it: the same run as before the option
      for (int c = 0; c < 3; ++c) x[c] += level(rng) / 255.0;
    }
    if (noise_augment > 0) {  // likewise
      const torch::Tensor frame = (set.reference[i] + x) * 255.0;
      const torch::Tensor noisy =
          (frame + sigma(rng) * torch::randn_like(frame)).round().clamp(0.0, 255.0);
      x = noisy / 255.0 - set.reference[i];
    }
    if (shift > 0) {
      const int dx = offset(rng), dy = offset(rng);
      const auto pad = F::PadFuncOptions({shift, shift, shift, shift}).mode(torch::kReplicate);
      const int h = set.height, w = set.width;
      x = F::pad(x.unsqueeze(0), pad)[0]
              .slice(1, shift + dy, shift + dy + h)
              .slice(2, shift + dx, shift + dx + w);
      y = F::pad(y.unsqueeze(0), pad)[0]
              .slice(1, shift + dy, shift + dy + h)
              .slice(2, shift + dx, shift + dx + w);
      m = F::pad(m.unsqueeze(0), F::PadFuncOptions({shift, shift, shift, shift}))[0]
              .slice(1, shift + dy, shift + dy + h)
              .slice(2, shift + dx, shift + dx + w);
    }
    in.push_back(x);
    out.push_back(y);
    masks.push_back(m);
  }
  return {torch::stack(in), torch::stack(out), torch::stack(masks)};
}

NormalMetrics validate(learn::Generator& g, const FrameSet& set, const torch::Tensor& mean,
                       const torch::Tensor& std) {
  torch::NoGradGuard no_grad;
  g->eval();
  learn::MetricSums sums;
  for (std::size_t i = 0; i < set.size(); i += 8) {
    const std::size_t n = std::min<std::size_t>(8, set.size() - i);
    std::vector<torch::Tensor> x(set.input.begin() + i, set.input.begin() + i + n);
    std::vector<torch::Tensor> y(set.target.begin() + i, set.target.begin() + i + n);
    std::vector<torch::Tensor> m(set.mask.begin() + i, set.mask.begin() + i + n);
    sums.add(learn::as_predicted(g->forward((torch::stack(x) - mean) / std)), torch::stack(y),
             torch::stack(m));
  }
  g->train();
  return sums.metrics(int(set.size()));
}

nlohmann::json epoch_json(const EpochReport& r) {
  // Without validation frames there are no metrics: null, not a perfect 0.
  const auto val = [&](double v) {
    return r.val.frames == 0 ? nlohmann::json() : nlohmann::json(v);
  };
  return {{"epoch", r.epoch},
          {"loss_l1", r.loss_l1},
          {"loss_gan", r.loss_gan},
          {"loss_d", r.loss_d},
          {"learning_rate", r.learning_rate},
          {"val_mse_contact", val(r.val.mse_contact)},
          {"val_mse_image", val(r.val.mse_image)},
          {"val_angle_contact_deg", val(r.val.angle_contact_deg)},
          {"seconds", r.seconds}};
}

void set_learning_rate(torch::optim::Adam& optimizer, double lr) {
  for (auto& group : optimizer.param_groups()) {
    static_cast<torch::optim::AdamOptions&>(group.options()).lr(lr);
  }
}

// The learning rate of epoch `epoch` (0-based) under TrainOptions::decay_epochs' schedule.
double learning_rate_at(const TrainOptions& o, int epoch) {
  const double left = double(o.epochs - epoch) / double(o.decay_epochs + 1);
  return o.learning_rate * std::clamp(left, 0.0, 1.0);
}

}  // namespace

void train_normals(const TrainOptions& options,
                   const std::function<void(const EpochReport&)>& on_epoch,
                   const std::function<void(int, int, int)>& on_step) {
  TrainOptions o = options;
  // Fine-tuning: the network (and its normalisation, below) is the starting model's.
  NormalModelInfo init;
  learn::Generator g(nullptr);
  if (!o.init_model.empty()) {
    g = learn::load_model(o.init_model, init);
    if (init.gel_relative != o.gel_relative) {
      throw InputError("--init " + o.init_model + ": its normals are relative to the " +
                       (init.gel_relative ? "gel" : "sensor") + "; train with --labels " +
                       (init.gel_relative ? "gel" : "sensor") + " to fine-tune it");
    }
    o.spec = init.spec;
  }
  // Settings of the other networks given to the MLP (or its to them) would be silently ignored:
  // refused when given or not at their defaults (checked here, as the arch of an --init model is
  // known only here; a GAN weight of 0 is what the MLP trains with anyway).
  const TrainOptions defaults;
  const auto set = [&](const char* option, bool differs) {
    return differs || std::find(o.given.begin(), o.given.end(), option) != o.given.end();
  };
  const bool mlp = o.spec.arch == "mlp";
  if (mlp && (set("--l1-weight", o.l1_weight != defaults.l1_weight) ||
              (o.gan_weight != 0 && set("--gan-weight", o.gan_weight != defaults.gan_weight)))) {
    throw UsageError(std::string(o.init_model.empty() ? "--arch mlp" : "--init " + o.init_model) +
                     ": the per-pixel MLP trains on an L2 loss alone; --l1-weight and "
                     "--gan-weight do not apply to it");
  }
  if (o.init_model.empty() && mlp &&
      (set("--depth", o.spec.depth != defaults.spec.depth) ||
       set("--width", o.spec.base_width != defaults.spec.base_width))) {
    throw UsageError("--arch mlp: --depth and --width do not apply to it (--hidden: its width)");
  }
  if (o.init_model.empty() && !mlp &&
      set("--hidden", o.spec.mlp_hidden != defaults.spec.mlp_hidden)) {
    throw UsageError("--arch " + o.spec.arch + ": --hidden applies to the MLP only");
  }
  if (o.train_data.empty()) throw InputError("--data: no training datasets given");
  if (o.out.empty()) throw InputError("--out: no model file given");
  if (o.epochs < 1 || o.batch < 1) throw UsageError("--epochs and --batch must be at least 1");
  if (o.decay_epochs < 0 || o.decay_epochs > o.epochs) {
    throw UsageError("--decay-epochs: " + std::to_string(o.decay_epochs) +
                     " is not between 0 and --epochs (" + std::to_string(o.epochs) + ")");
  }
  // Fail now, not after the training, when the model cannot be written.
  {
    const fs::path folder = fs::absolute(o.out).parent_path();
    std::error_code ec;
    fs::create_directories(folder, ec);
    if (ec || !fs::is_directory(folder)) {
      throw InputError(o.out + ": cannot create the folder " + folder.string() + ": " +
                       ec.message());
    }
    // A checkpoint place that is not a file is named by its own check, then the model's.
    learn::check_checkpoint_place(o);
    replaceable_file(o.out + ".ckpt");  // a device or pipe would be replaced by the checkpoint
    check_can_write(replaceable_file(o.out));  // ... or by the model
  }
  const int threads =
      o.threads > 0 ? o.threads : int(std::max(1u, std::thread::hardware_concurrency()));
  torch::set_num_threads(threads);
  torch::manual_seed(o.seed);

  FrameSet train, val;
  train.gel_relative = val.gel_relative = o.gel_relative;
  const int hold_out_every = o.val_data.empty() && o.val_fraction > 0
                                 ? std::max(2, int(std::lround(1.0 / o.val_fraction)))
                                 : 0;
  load_frames(o.train_data, train, o.val_data.empty() ? &val : nullptr, hold_out_every);
  val.sensor = train.sensor;
  val.sensor_set = true;
  val.gel = train.gel;
  if (!o.val_data.empty()) load_frames(o.val_data, val, nullptr, 0);
  if (train.size() == 0) throw InputError("--data: the datasets hold no frames");
  // Without a contact pixel the network would learn the flat gel alone.
  if (std::none_of(train.mask.begin(), train.mask.end(),
                   [](const torch::Tensor& m) { return m.any().item<bool>(); })) {
    throw InputError(
        "--data: no training frame has a contact pixel (every mask is empty): "
        "there is nothing to learn the normals of a press from");
  }
  if (val.size() > 0 && (val.width != train.width || val.height != train.height)) {
    std::string folders;
    for (const std::string& dir : o.val_data) folders += " " + dir;
    throw InputError("--val" + folders + ": images are " + std::to_string(val.width) + "x" +
                     std::to_string(val.height) + ", the training images " +
                     std::to_string(train.width) + "x" + std::to_string(train.height));
  }

  NormalModelInfo info;
  info.spec = o.spec;
  info.width = train.width;
  info.height = train.height;
  info.training_data = o.train_data;
  info.gel_relative = o.gel_relative;
  info.sensor = train.sensor;
  info.sensor_known = true;
  if (!train.unknown_background) info.backgrounds = train.backgrounds;
  if (g) {
    if (init.width != train.width || init.height != train.height) {
      throw InputError("--init " + o.init_model + ": takes " + std::to_string(init.width) + "x" +
                       std::to_string(init.height) + " images, the training data is " +
                       std::to_string(train.width) + "x" + std::to_string(train.height));
    }
    info.input_mean = init.input_mean;
    info.input_std = init.input_std;
    // Fine-tuned, it has seen its starting model's backgrounds as well.
    if (init.backgrounds.empty()) info.backgrounds.clear();
    for (const std::string& b : init.backgrounds) {
      if (!info.backgrounds.empty() &&
          std::find(info.backgrounds.begin(), info.backgrounds.end(), b) == info.backgrounds.end())
        info.backgrounds.push_back(b);
    }
    nlohmann::json base = {{"model", learn::canonical_or_given(o.init_model)},
                           {"epochs", init.epochs},
                           {"training_data", init.training_data}};
    if (!init.fine_tuned_from_json.empty())
      base["fine_tuned_from"] = nlohmann::json::parse(init.fine_tuned_from_json);
    info.fine_tuned_from_json = base.dump();
  } else {
    const torch::Tensor all = torch::stack(train.input);
    const torch::Tensor mean = all.mean({0, 2, 3}), std = all.std({0, 2, 3}).clamp_min(1e-3);
    for (int c = 0; c < 3; ++c) {
      info.input_mean[c] = mean[c].item<float>();
      info.input_std[c] = std[c].item<float>();
    }
    g = learn::Generator(o.spec);
  }
  std::sort(info.backgrounds.begin(), info.backgrounds.end());
  const bool gan = !mlp && o.gan_weight > 0;
  // The PatchGAN's three stride-2 and two 4x4 layers need 12 px a side.
  constexpr int kMinGanSide = 12;
  if (gan && std::min(train.width, train.height) < kMinGanSide) {
    throw InputError("--data: images of " + std::to_string(train.width) + "x" +
                     std::to_string(train.height) +
                     " px are too small for the PatchGAN "
                     "discriminator (at least " +
                     std::to_string(kMinGanSide) + " px a side); --gan-weight 0 trains without it");
  }
  learn::PatchDiscriminator d(nullptr);
  if (gan) d = learn::PatchDiscriminator(o.spec.base_width);
  const auto adam = torch::optim::AdamOptions(o.learning_rate).betas({o.beta1, 0.999});
  torch::optim::Adam opt_g(g->parameters(), adam);
  std::unique_ptr<torch::optim::Adam> opt_d;
  if (gan) opt_d = std::make_unique<torch::optim::Adam>(d->parameters(), adam);

  const std::string checkpoint = o.out + ".ckpt";
  nlohmann::json history = nlohmann::json::array();
  const std::string labels = labels_hash(train);
  learn::TrainingState state{g,       opt_g,           gan ? &d : nullptr, opt_d.get(),
                             history, info.input_mean, info.input_std,     labels};
  const int first_epoch = o.resume ? learn::load_checkpoint(o, state) : 0;
  // Diverged (a learning rate too high for the data, or data out of range): stopped before a
  // NaN network is written as a model.
  const auto diverged = [&](int epoch, const std::string& what) {
    // In the first epoch after a resume, the checkpoint's own numbers are as likely a cause (a
    // file damaged under mended checksums, weights of 1e30) as the settings it was trained with.
    const bool at_resume = o.resume && epoch == first_epoch;
    throw std::runtime_error("training diverged: epoch " + std::to_string(epoch + 1) + ", " + what +
                             (at_resume ? " (the first epoch after resuming " + checkpoint +
                                              ": is it damaged? or try a lower --lr); "
                              : mlp ? " (try a lower --lr or --contact-weight); "
                                    : " (try a lower --lr or lower loss weights); ") +
                             o.out + " not written" +
                             (fs::exists(checkpoint)
                                  ? "; " + checkpoint +
                                        " holds the last epoch before it: remove it to start "
                                        "over with other settings"
                                  : std::string()));
  };

  const torch::Tensor mean =
      torch::tensor(std::vector<float>(info.input_mean.begin(), info.input_mean.end()))
          .view({1, 3, 1, 1});
  const torch::Tensor std =
      torch::tensor(std::vector<float>(info.input_std.begin(), info.input_std.end()))
          .view({1, 3, 1, 1});
  const int batches = int((train.size() + o.batch - 1) / o.batch);
  std::vector<int> order(train.size());
  for (int epoch = first_epoch; epoch < o.epochs; ++epoch) {
    const auto start = std::chrono::steady_clock::now();
    // Seeded per epoch, so that a resumed run continues exactly as an uninterrupted one would.
    std::mt19937_64 rng(o.seed * 0x9E3779B97F4A7C15ull + std::uint64_t(epoch));
    torch::manual_seed(o.seed + std::uint64_t(epoch));
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = int(i);
    std::shuffle(order.begin(), order.end(), rng);
    g->train();
    if (gan) d->train();
    EpochReport r;
    r.epoch = epoch + 1;
    r.epochs = o.epochs;
    r.squared_loss = mlp;
    r.train_frames = int(train.size());
    r.batches = batches;
    // A function of the epoch alone, so a resumed run follows the same schedule.
    r.learning_rate = learning_rate_at(o, epoch);
    set_learning_rate(opt_g, r.learning_rate);
    if (gan) set_learning_rate(*opt_d, r.learning_rate);
    if (on_step) on_step(r.epoch, 0, batches);
    for (int b = 0; b < batches; ++b) {
      const std::vector<int> index(
          order.begin() + b * o.batch,
          order.begin() + std::min<std::size_t>(order.size(), (b + 1) * o.batch));
      const Batch batch = make_batch(train, index, o.shift_px, o.gain_jitter, o.offset_jitter,
                                     o.noise_augment, rng);
      const torch::Tensor x = (batch.input - mean) / std;
      const torch::Tensor fake = g->forward(x);
      if (gan) {
        opt_d->zero_grad();
        const torch::Tensor real_logits = d->forward(x, batch.target);
        const torch::Tensor fake_logits = d->forward(x, fake.detach());
        const torch::Tensor loss_d =
            0.5 *
            (F::binary_cross_entropy_with_logits(real_logits, torch::ones_like(real_logits)) +
             F::binary_cross_entropy_with_logits(fake_logits, torch::zeros_like(fake_logits)));
        loss_d.backward();
        opt_d->step();
        r.loss_d += loss_d.item<double>();
      }
      opt_g.zero_grad();
      torch::Tensor loss;
      const torch::Tensor weight = 1.0 + o.contact_weight * batch.mask;  // N x 1 x H x W
      if (mlp) {
        loss = ((fake - batch.target).pow(2) * weight).mean();
        r.loss_l1 += loss.item<double>();
      } else {
        const torch::Tensor l1 = ((fake - batch.target).abs() * weight).mean();
        loss = o.l1_weight * l1;
        r.loss_l1 += l1.item<double>();
        if (gan) {
          const torch::Tensor logits = d->forward(x, fake);
          const torch::Tensor g_gan =
              F::binary_cross_entropy_with_logits(logits, torch::ones_like(logits));
          loss = loss + o.gan_weight * g_gan;
          r.loss_gan += g_gan.item<double>();
        }
      }
      const double total = loss.item<double>();
      if (!std::isfinite(total)) {
        char text[64];
        std::snprintf(text, sizeof text, "%g", total);
        diverged(epoch, "batch " + std::to_string(b + 1) + ": the loss is " + text);
      }
      loss.backward();
      opt_g.step();
      if (on_step) on_step(r.epoch, b + 1, batches);
    }
    // The loss can stay finite while weights or BatchNorm's running statistics overflow (--lr
    // 1e5): such a network reads every pixel as NaN, and the model readers refuse it.
    for (const auto& list : {g->parameters(), g->buffers()}) {
      for (const torch::Tensor& t : list) {
        if (!torch::isfinite(t).all().item<bool>()) {
          diverged(epoch, "the network's weights or running statistics are not finite numbers");
        }
      }
    }
    r.loss_l1 /= batches;
    r.loss_gan /= batches;
    r.loss_d /= batches;
    if (val.size() > 0) {
      r.val = validate(g, val, mean, std);
      if (!std::isfinite(r.val.mse_image)) {
        diverged(epoch, "the network's output on the validation frames is not a finite number");
      }
    }
    r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    history.push_back(epoch_json(r));
    if (on_epoch) on_epoch(r);
    if ((epoch + 1) % std::max(1, o.checkpoint_every) == 0 || epoch + 1 == o.epochs) {
      learn::save_checkpoint(o, epoch + 1, state);
    }
  }
  g->eval();
  info.epochs = o.epochs;
  info.history_json = history.dump();
  nlohmann::json settings = learn::run_settings(o);
  settings.erase("--data");  // training_data
  settings.erase("--init");  // fine_tuned_from
  settings["--decay-epochs"] = o.decay_epochs;
  if (mlp) {  // trains on its L2 loss alone
    settings.erase("--l1-weight");
    settings.erase("--gan-weight");
  }
  info.settings_json = settings.dump();
  learn::save_model(o.out, g, info);
}

}  // namespace pg
