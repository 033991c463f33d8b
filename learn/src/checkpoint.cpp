#include "checkpoint.h"

#include <filesystem>

#include "pg/core/error.h"
#include "pg/core/json_fields.h"
#include "zip_check.h"

namespace pg::learn {
namespace {

namespace fs = std::filesystem;

constexpr const char* kCheckpointFormat = "patchgraph-normals-checkpoint-1";

std::string checkpoint_path(const TrainOptions& o) { return o.out + ".ckpt"; }

}  // namespace

// The settings that make a training run what it is, recorded in the checkpoint so that a resumed
// run can be held to them: resuming with another learning rate, batch, seed, loss weight,
// augmentation, training or validation data or starting model would silently continue a
// different run. --epochs and --decay-epochs may change on resuming (to train longer); the
// schedule is a function of the epoch, so it then continues as the new values say.
nlohmann::json run_settings(const TrainOptions& o) {
  nlohmann::json data = nlohmann::json::array(), val = nlohmann::json::array();
  for (const std::string& folder : o.train_data) data.push_back(canonical_or_given(folder));
  // Without --val every 10th training frame is held out: dropping it changes the training set.
  for (const std::string& folder : o.val_data) val.push_back(canonical_or_given(folder));
  return {{"--lr", o.learning_rate},
          {"beta1", o.beta1},
          {"--batch", o.batch},
          {"--seed", o.seed},
          {"--l1-weight", o.l1_weight},
          {"--gan-weight", o.gan_weight},
          {"--contact-weight", o.contact_weight},
          {"--shift", o.shift_px},
          {"--gain-jitter", o.gain_jitter},
          {"--offset-jitter", o.offset_jitter},
          {"--noise-augment", o.noise_augment},
          {"--data", data},
          {"--val", val},
          {"--init", o.init_model.empty() ? std::string() : canonical_or_given(o.init_model)}};
}

namespace {

// Throws InputError naming the first setting of `o` that differs from the checkpoint's record
// (a checkpoint written before the record existed is not checked).
void check_run_settings(const nlohmann::json& recorded, const TrainOptions& o,
                        const std::string& checkpoint) {
  const nlohmann::json now = run_settings(o);
  for (const auto& [option, value] : now.items()) {
    if (!recorded.contains(option) || recorded.at(option) == value) continue;
    throw InputError(checkpoint + ": trained with " + option + " " + recorded.at(option).dump() +
                     ", resumed with " + value.dump() +
                     "; resume with the same value, or remove it (or train into another --out) "
                     "to start a new run");
  }
}

// The checkpoint archive, its description and its epoch; throws InputError naming it when it is
// damaged or not a checkpoint.
struct Opened {
  torch::serialize::InputArchive archive;
  nlohmann::json info;
  int epoch = 0;
};
void open_checkpoint(const std::string& checkpoint, Opened& c) {
  check_zip_checksums(checkpoint, "checkpoint");
  c10::IValue format, text, epoch;
  try {
    c.archive.load_from(checkpoint);
  } catch (const std::exception&) {  // c10::Error, or TorchScript's on a damaged entry name
    throw InputError(checkpoint + ": corrupt checkpoint");
  }
  if (!c.archive.try_read("format", format) || !format.isString() ||
      format.toStringRef() != kCheckpointFormat || !c.archive.try_read("info", text) ||
      !text.isString() || !c.archive.try_read("epoch", epoch) || !epoch.isInt()) {
    throw InputError(checkpoint + ": not a normals training checkpoint");
  }
  c.epoch = int(epoch.toInt());
  try {
    c.info = nlohmann::json::parse(text.toStringRef());
  } catch (const nlohmann::json::exception& e) {
    throw InputError(checkpoint +
                     ": malformed checkpoint description: " + without_json_tag(e.what()));
  }
}

}  // namespace

// A path as one file is always named (symbolic links and ".." resolved), or as given.
std::string canonical_or_given(const std::string& path) {
  std::error_code ec;
  const std::filesystem::path canonical = std::filesystem::weakly_canonical(path, ec);
  return ec ? path : canonical.string();
}

void check_checkpoint_place(const TrainOptions& o) {
  const std::string checkpoint = checkpoint_path(o);
  std::error_code ec;
  if (fs::exists(checkpoint, ec) && !fs::is_regular_file(checkpoint, ec)) {
    throw InputError(checkpoint +
                     ": is not a file (a folder, device or pipe?), where the run keeps its "
                     "checkpoint; remove it or train into another --out");
  }
  if (o.resume || !fs::is_regular_file(checkpoint, ec)) return;
  Opened c;
  try {
    open_checkpoint(checkpoint, c);
  } catch (const InputError& e) {
    throw InputError(std::string(e.what()) + "; remove it to start a new run into " + o.out);
  }
  const int epochs = c.info.is_object() ? c.info.value("epochs", 0) : 0;
  if (epochs == 0) {  // written before the run's length was recorded
    throw InputError(checkpoint + ": holds a training run at epoch " + std::to_string(c.epoch) +
                     " whose length it does not record (an older checkpoint): --resume "
                     "continues it; remove it to start a new run into " +
                     o.out);
  }
  if (c.epoch < epochs) {
    throw InputError(checkpoint + ": holds an unfinished training run (epoch " +
                     std::to_string(c.epoch) + " of " + std::to_string(epochs) +
                     "): --resume continues it; remove it to start a new run into " + o.out);
  }
}

void save_checkpoint(const TrainOptions& o, int epochs_done, const TrainingState& s) {
  const std::string checkpoint = checkpoint_path(o);
  const bool gan = s.discriminator != nullptr;
  torch::serialize::OutputArchive a;
  a.write("format", c10::IValue(std::string(kCheckpointFormat)));
  nlohmann::json j = {{"arch", o.spec.arch},
                      {"depth", o.spec.depth},
                      {"base_width", o.spec.base_width},
                      {"mlp_hidden", o.spec.mlp_hidden},
                      {"gan", gan},
                      {"gel_relative", o.gel_relative},
                      {"epochs", o.epochs},
                      {"run", run_settings(o)},
                      {"input_mean", s.input_mean},
                      {"input_std", s.input_std},
                      {"labels_hash", s.labels_hash},
                      {"history", s.history}};
  a.write("info", c10::IValue(j.dump()));
  a.write("epoch", c10::IValue(int64_t(epochs_done)));
  torch::serialize::OutputArchive gw, og;
  s.generator->save(gw);
  s.generator_optimizer.save(og);
  a.write("generator", gw);
  a.write("opt_g", og);
  if (gan) {
    torch::serialize::OutputArchive dw, od;
    (*s.discriminator)->save(dw);
    s.discriminator_optimizer->save(od);
    a.write("discriminator", dw);
    a.write("opt_d", od);
  }
  save_archive(a, checkpoint, "checkpoint");
}

int load_checkpoint(const TrainOptions& o, TrainingState& s) {
  const std::string checkpoint = checkpoint_path(o);
  const bool gan = s.discriminator != nullptr;
  if (!fs::is_regular_file(checkpoint)) throw InputError(checkpoint + ": no checkpoint to resume");
  Opened c;
  open_checkpoint(checkpoint, c);
  try {
    const nlohmann::json& j = c.info;
    // The run's settings first: a run resumed without its --init would otherwise be told only
    // that the network differs.
    if (j.contains("run")) check_run_settings(j.at("run"), o, checkpoint);
    NetworkSpec trained;
    trained.arch = j.at("arch").get<std::string>();
    trained.depth = j.at("depth").get<int>();
    trained.base_width = j.at("base_width").get<int>();
    trained.mlp_hidden = j.at("mlp_hidden").get<int>();
    const bool trained_gan = j.at("gan").get<bool>();
    const bool trained_gel = j.value("gel_relative", false);
    if (trained.arch != o.spec.arch || trained.depth != o.spec.depth ||
        trained.base_width != o.spec.base_width || trained.mlp_hidden != o.spec.mlp_hidden ||
        trained_gan != gan || trained_gel != o.gel_relative) {
      const auto what = [](const NetworkSpec& spec, bool with_gan, bool gel) {
        return describe(spec) + (with_gan ? " with" : " without") + " the GAN loss, labels " +
               (gel ? "gel" : "sensor");
      };
      throw InputError(checkpoint + ": holds " + what(trained, trained_gan, trained_gel) +
                       ", this run asks for " + what(o.spec, gan, o.gel_relative) +
                       "; resume with the checkpoint's --arch, --depth, --width, --hidden, "
                       "--gan-weight and --labels, or train into another --out");
    }
    // A run that went further than asked would write a model of more epochs than --epochs.
    if (c.epoch > o.epochs) {
      throw InputError(checkpoint + ": holds epoch " + std::to_string(c.epoch) +
                       ", past --epochs " + std::to_string(o.epochs) + "; give --epochs " +
                       std::to_string(c.epoch) + " to write its model, or more to train on");
    }
    // The same folders may hold other frames now (re-rendered), or --init another model: the
    // weights would go on under another input normalisation (a checkpoint written before it
    // was recorded is not checked).
    if (j.contains("input_mean") &&
        (j.at("input_mean").get<std::array<float, 3>>() != s.input_mean ||
         j.at("input_std").get<std::array<float, 3>>() != s.input_std)) {
      throw InputError(checkpoint +
                       ": was trained under another input normalisation than this run's data "
                       "gives (" +
                       (o.init_model.empty() ? std::string("--data's frames")
                                             : "the --init model " + o.init_model) +
                       " changed since); resume with the data it was trained on, or remove it "
                       "(or train into another --out) to start a new run");
    }
    // (A checkpoint written before the labels' hash was recorded is not checked.)
    if (j.contains("labels_hash") && j.at("labels_hash").get<std::string>() != s.labels_hash) {
      throw InputError(checkpoint +
                       ": was trained on other labels than --data holds now (its normal or mask "
                       "images changed since: labelled again?); resume with the labels it was "
                       "trained on, or remove it (or train into another --out) to start a new "
                       "run");
    }
    s.history = j.at("history");
    torch::serialize::InputArchive sub;
    c.archive.read("generator", sub);
    s.generator->load(sub);
    c.archive.read("opt_g", sub);
    s.generator_optimizer.load(sub);
    if (gan) {
      c.archive.read("discriminator", sub);
      (*s.discriminator)->load(sub);
      c.archive.read("opt_d", sub);
      s.discriminator_optimizer->load(sub);
    }
    // The archive's checksums hold, yet its weights may not fit the network or be numbers (a
    // file written so by other means): training on would fail in Torch's words, or "diverge"
    // at once and blame the learning rate.
    const auto module_problem = [](const torch::nn::Module& loaded,
                                   const torch::nn::Module& described) {
      const std::string shape = weights_shape_problem(loaded, described);
      return shape.empty() ? weights_number_problem(loaded) : shape;
    };
    std::string problem = module_problem(*s.generator, *Generator(o.spec));
    if (problem.empty() && gan) {
      problem = module_problem(**s.discriminator, *PatchDiscriminator(o.spec.base_width));
    }
    if (problem.empty()) problem = optimizer_state_problem(s.generator_optimizer);
    if (problem.empty() && gan) problem = optimizer_state_problem(*s.discriminator_optimizer);
    if (!problem.empty()) throw InputError(checkpoint + ": corrupt checkpoint: " + problem);
  } catch (const InputError&) {
    throw;
  } catch (const nlohmann::json::exception& e) {
    throw InputError(checkpoint +
                     ": malformed checkpoint description: " + without_json_tag(e.what()));
  } catch (const std::exception&) {  // c10::Error, or TorchScript's on a damaged entry name
    throw InputError(checkpoint + ": corrupt checkpoint");
  }
  return c.epoch;
}

}  // namespace pg::learn

namespace pg {

std::string training_settings_json(const TrainOptions& options) {
  return learn::run_settings(options).dump();
}

}  // namespace pg
