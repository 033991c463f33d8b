#include "normals_cli.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "../common/cli_main.h"
#include "../common/progress.h"
#include "pg/core/dataset.h"
#include "pg/core/error.h"
#include "pg/core/file_io.h"
#include "pg/sim/shading_inversion.h"
#include "track_args.h"

namespace pg {
namespace {

// train-normals' bounds on the learning rate and the loss weights (their defaults: 2e-4; L1 100,
// GAN 1, contact 0).
constexpr double kMinLearningRate = 1e-12;
constexpr double kMaxLearningRate = 1;
constexpr double kMaxLossWeight = 1e6;

// A metric as printf's `format` gives it, or "n/a" when it is NaN (no contact pixel to measure).
std::string metric(double value, const char* format) {
  return std::isnan(value) ? "n/a" : format_number(value, format);
}

}  // namespace

CLI::App* add_train_normals_command(CLI::App& app, TrainNormalsArgs& a) {
  TrainOptions& o = a.options;
  CLI::App* cmd = app.add_subcommand(
      "train-normals", "Train a network that maps tactile colour images to surface normals");
  cmd->add_option("--data", o.train_data, "Training dataset folders (color, normal, mask outputs)")
      ->required();
  cmd->add_option("--val", o.val_data,
                  "Validation dataset folders (default: every 10th training frame held out)");
  cmd->add_option("--out,-o", o.out, "Model file to write (OUT.ckpt: the checkpoint)")->required();
  CLI::Option* arch =
      cmd->add_option("--arch", o.spec.arch, "unet (pix2pix, default), resnet or mlp")
          ->check(CLI::IsMember({"unet", "resnet", "mlp"}));
  CLI::Option* depth =
      cmd->add_option("--depth", o.spec.depth,
                      "unet: down-sampling levels (default 5); resnet: residual blocks")
          ->check(range_check(1, kMaxNetworkDepth));
  CLI::Option* width = cmd->add_option("--width", o.spec.base_width,
                                       "unet, resnet: channels of the first layer (default 16)")
                           ->check(range_check(1, kMaxBaseWidth));
  CLI::Option* hidden =
      cmd->add_option("--hidden", o.spec.mlp_hidden, "mlp: hidden layer width (default 32)")
          ->check(range_check(1, kMaxMlpHidden));
  cmd->add_option("--init", o.init_model,
                  "Fine-tune: start from this model's weights, network and input normalisation "
                  "(e.g. the default model, on a real sensor's ball-press labels)")
      ->excludes(arch)
      ->excludes(depth)
      ->excludes(width)
      ->excludes(hidden);
  cmd->add_option("--epochs", o.epochs, "Epochs (default 150)")->check(kPositive);
  cmd->add_option("--batch", o.batch, "Batch size (default 4)")->check(kPositive);
  // Bounded where Torch's float arithmetic holds (a rate of 1e300 failed in LibTorch's words,
  // naming no option; one of 1e-300 was 0 in float, a run that learns nothing) and beyond what
  // any training here uses.
  cmd->add_option("--lr", o.learning_rate, "Adam learning rate (default 2e-4)")
      ->check(range_check(kMinLearningRate, kMaxLearningRate));
  cmd->add_option("--decay-epochs", o.decay_epochs,
                  "Lower the learning rate linearly towards 0 over the last this many epochs "
                  "(pix2pix's schedule; default 0: constant)")
      ->check(kNonNegative);
  cmd->add_option("--l1-weight", o.l1_weight,
                  "Weight of the L1 loss (default 100; the MLP's L2 loss has none)")
      ->check(range_check(0, kMaxLossWeight));
  cmd->add_option("--gan-weight", o.gan_weight,
                  "Weight of the GAN loss (default 1); 0 = no discriminator")
      ->check(range_check(0, kMaxLossWeight));
  cmd->add_option("--contact-weight", o.contact_weight,
                  "Contact pixels' loss counts 1 + this times a background pixel's (default 0)")
      ->check(range_check(0, kMaxLossWeight));
  cmd->add_option("--labels", a.labels,
                  "Frame of the network's normals: sensor (default) or gel (relative to each "
                  "pixel's undeformed gel; the datasets must share one gel shape and camera)")
      ->check(CLI::IsMember({"sensor", "gel"}));
  cmd->add_option("--shift", o.shift_px,
                  "Augmentation: random shifts up to this many pixels (default 8)")
      ->check(range_check(0, 64));
  cmd->add_option("--gain-jitter", o.gain_jitter,
                  "Augmentation: contrast scaled by 1 +- this (default 0.3)")
      ->check(range_check(0, 0.9));
  cmd->add_option("--offset-jitter", o.offset_jitter,
                  "Augmentation: each colour channel shifted by up to +- this many levels (a "
                  "brightness drift since the reference image; default 0)")
      ->check(range_check(0, 64));
  cmd->add_option("--noise-augment", o.noise_augment,
                  "Augmentation: camera noise of a sigma drawn per frame from 0 to this many "
                  "levels, added before the difference with the reference (for renders without "
                  "noise: tacsim render --noise off; default 0)")
      ->check(range_check(0, 64));
  cmd->add_option("--seed", o.seed,
                  "Seed of the initialisation, shuffling and augmentation (default 0)")
      ->check(kSeed);
  cmd->add_option("--threads", o.threads, "Torch threads (default: all cores)")->check(kThreads);
  cmd->add_option("--checkpoint-every", o.checkpoint_every,
                  "Epochs between checkpoints in OUT.ckpt (default 1; the last epoch's always)")
      ->check(kPositive);
  cmd->add_flag("--resume", o.resume,
                "Continue from OUT.ckpt (same settings; --epochs and --decay-epochs may change); "
                "without it, an unfinished run's OUT.ckpt is refused");
  cmd->add_flag("--quiet,-q", a.quiet, "No progress line");
  return cmd;
}

CLI::App* add_eval_normals_command(CLI::App& app, EvalNormalsArgs& a) {
  CLI::App* cmd = app.add_subcommand(
      "eval-normals", "Measure a normals model: MSE of (n+1)/2 and angular error (Table I)");
  cmd->add_option("--model,-m", a.model,
                  "Model file (from train-normals), or shading: the sensor model's shading "
                  "inverted pixel by pixel (track --normals shading), no network")
      ->required();
  cmd->add_option("--data", a.data, "Dataset folders (color, normal, mask outputs)")->required();
  cmd->add_option("--json", a.json, "Also write the results to this JSON file");
  cmd->add_option("--threads", a.threads, "Torch threads (default 1)")->check(kThreads);
  cmd->add_option("--phases", a.phases,
                  "Average the model over the frame shifted by a pixel: 1 (default), 2 or 4 "
                  "passes (as track --normals-phases)")
      ->check(CLI::IsMember({1, 2, 4}));
  cmd->add_option("--blend-shading", a.blend_shading,
                  "Average the model's normals with the shading's inverse, this its weight from "
                  "0 (default: the model alone) to 1 (as track --blend-shading)")
      ->check(range_check(0, 1));
  cmd->add_flag("--quiet,-q", a.quiet, "No progress line");
  return cmd;
}

namespace {

// Fine-tuning takes the --init model's network and weights, not the settings it was trained with:
// a loss weight or augmentation it had and this run leaves at its default (the default model's
// --noise-augment, which its robustness to noise owes to) is said, with how to keep it.
void warn_of_settings_not_carried_over(const TrainOptions& o) {
  const auto recorded = nlohmann::json::parse(
      NormalEstimator::load(o.init_model).info().settings_json, nullptr, false);
  if (!recorded.is_object()) return;  // a model from before the settings were recorded
  const nlohmann::json now = nlohmann::json::parse(training_settings_json(o));
  std::string then_text, now_text;
  for (const char* option :
       {"--contact-weight", "--shift", "--gain-jitter", "--offset-jitter", "--noise-augment"}) {
    const auto it = recorded.find(option);
    if (it == recorded.end() || !it->is_number() || !now.at(option).is_number()) continue;
    if (std::find(o.given.begin(), o.given.end(), option) != o.given.end()) continue;
    const double was = it->get<double>(), is = now.at(option).get<double>();
    if (was == is) continue;
    then_text +=
        (then_text.empty() ? "" : " ") + std::string(option) + " " + format_number(was, "%g");
    now_text += (now_text.empty() ? "" : " ") + std::string(option) + " " + format_number(is, "%g");
  }
  if (then_text.empty()) return;
  std::fprintf(stderr,
               "warning: --init %s was trained with %s; this run trains with %s (fine-tuning "
               "takes the model's network and weights, not its training's settings): give them "
               "again to keep them\n",
               o.init_model.c_str(), then_text.c_str(), now_text.c_str());
}

}  // namespace

int run_train_normals(const TrainNormalsArgs& a) {
  TrainOptions o = a.options;
  as_usage_error([&] {
    check_given_once(o.train_data);
    check_given_once(o.val_data);
  });
  for (const auto* datasets : {&o.train_data, &o.val_data}) {
    for (const std::string& dir : *datasets) {
      check_output_is_not_input(o.out, dir, "the dataset");
      check_output_is_not_input(o.out + ".ckpt", dir, "the dataset", "--out's checkpoint");
    }
  }
  check_output_file(o.out, {FileKind::kZip});
  check_output_file(o.out + ".ckpt", {FileKind::kZip}, "--out's checkpoint");
  if (std::filesystem::is_directory(o.out)) {  // found now, not after the training
    throw InputError("--out " + o.out + ": is a folder; give the model file's name");
  }
  warn_of_validation_in_training(o.val_data, o.train_data, "the training datasets, --data");
  // The model records the first dataset's sensor; another sensor's shading among the data is one
  // network learning two mappings, and track/eval-normals would warn of that sensor's datasets.
  {
    const Dataset first = Dataset::open(o.train_data[0]);
    for (const auto* datasets : {&o.train_data, &o.val_data}) {
      for (const std::string& dir : *datasets) {
        const std::string differ =
            optics_difference(first.info().sensor, Dataset::open(dir).info().sensor);
        if (differ.empty()) continue;
        const bool val = datasets == &o.val_data;
        std::fprintf(stderr,
                     "warning: %s %s: its sensor differs in %s from the sensor of %s (%s), which "
                     "the model records: %s, and track and eval-normals will warn on this "
                     "sensor's datasets\n",
                     val ? "--val" : "--data", dir.c_str(), differ.c_str(), o.train_data[0].c_str(),
                     first.info().sensor.name.c_str(),
                     val ? "its metrics measure the model on another sensor's images"
                         : "the network learns two sensors' shading at once");
      }
    }
  }
  o.gel_relative = a.labels == "gel";
  if (!o.init_model.empty() && !std::filesystem::exists(o.init_model)) {
    throw InputError(o.init_model + ": model file not found (--init)");
  }
  if (!o.init_model.empty() && !std::filesystem::is_regular_file(o.init_model)) {
    throw InputError(o.init_model + ": is not a model file (a folder, device or pipe; --init)");
  }
  std::error_code ec;
  if (!o.init_model.empty() && std::filesystem::equivalent(o.out, o.init_model, ec)) {
    throw InputError("--out " + o.out +
                     " is the --init model; write the fine-tuned model to "
                     "another file (the starting model would be replaced)");
  }
  if (!o.init_model.empty()) warn_of_settings_not_carried_over(o);
  std::unique_ptr<Progress> progress;
  int epoch = 0;              // the one in progress
  int checkpoint_epoch = -1;  // what OUT.ckpt holds by this run: -1 none
  bool reported = false;      // an epoch's line printed
  std::printf("%s on %zu dataset(s) for %d epochs -> %s\n",
              o.init_model.empty() ? ("training " + describe(o.spec)).c_str()
                                   : ("fine-tuning " + o.init_model).c_str(),
              o.train_data.size(), o.epochs, o.out.c_str());
  std::fflush(stdout);
  const std::string checkpoint = o.out + ".ckpt";
  try {
    const StopOnSignals stop;
    train_normals(
        o,
        [&](const EpochReport& r) {
          progress.reset();
          if (!reported) {
            reported = true;
            std::printf("%d training frames in %d batch(es) an epoch, %d validation frames\n",
                        r.train_frames, r.batches, r.val.frames);
            if (o.batch > r.train_frames) {
              std::fprintf(stderr,
                           "warning: --batch %d is more than the %d training frames: each epoch is "
                           "one batch of all of them\n",
                           o.batch, r.train_frames);
            }
          }
          // train_normals writes the checkpoint right after this report.
          if (r.epoch % std::max(1, o.checkpoint_every) == 0) checkpoint_epoch = r.epoch;
          if (r.squared_loss) {  // the MLP: no GAN, no discriminator
            std::printf("epoch %3d/%d  %5.1f s  lr %.2e  L2 %.4f  |  ", r.epoch, r.epochs,
                        r.seconds, r.learning_rate, r.loss_l1);
          } else {
            std::printf("epoch %3d/%d  %5.1f s  lr %.2e  L1 %.4f  GAN %.3f  D %.3f  |  ", r.epoch,
                        r.epochs, r.seconds, r.learning_rate, r.loss_l1, r.loss_gan, r.loss_d);
          }
          if (r.val.frames == 0) {
            std::printf("no validation frames\n");
          } else {
            std::printf("val MSE contact %s image %.2e  angle contact %s deg\n",
                        metric(r.val.mse_contact, "%.2e").c_str(), r.val.mse_image,
                        metric(r.val.angle_contact_deg, "%.2f").c_str());
          }
          std::fflush(stdout);
        },
        [&](int in_epoch, int done, int total) {
          if (o.resume && epoch == 0) {
            std::printf("resumed from %s after epoch %d\n", checkpoint.c_str(), in_epoch - 1);
            std::fflush(stdout);
            checkpoint_epoch = in_epoch - 1;
          }
          epoch = in_epoch;
          // The batches' line on a terminal only: in a log, each epoch's line says enough (the
          // line every tenth of an epoch was ten more lines an epoch).
          if (a.quiet || !isatty(fileno(stderr))) return stop_if_asked();
          if (!progress) {
            progress = std::make_unique<Progress>("epoch " + std::to_string(epoch), total, true,
                                                  "batches");
          }
          progress->update(done);
        });
  } catch (const Stopped& e) {
    progress.reset();
    std::string where = epoch == 0 ? "before the first epoch" : "in epoch " + std::to_string(epoch);
    throw e.with_note(where + "; " + o.out + " not written; " +
                      (checkpoint_epoch > 0
                           ? checkpoint + " holds epoch " + std::to_string(checkpoint_epoch) +
                                 ": --resume continues from it"
                           : "no checkpoint written by this run yet (one every " +
                                 std::to_string(o.checkpoint_every) + " epochs)" +
                                 (std::filesystem::exists(checkpoint)
                                      ? "; " + checkpoint + " is an earlier, finished run's"
                                      : std::string())));
  }
  if (o.resume && epoch == 0) {
    std::printf(
        "nothing left to train: %s holds epoch %d, the last of --epochs; the model is "
        "written from it\n",
        checkpoint.c_str(), o.epochs);
  }
  std::printf("wrote %s\n", o.out.c_str());
  return kExitOk;
}

CLI::App* add_model_info_command(CLI::App& app, ModelInfoArgs& a) {
  CLI::App* cmd = app.add_subcommand(
      "model-info", "Describe a normals model file: network, images, sensor, training, last epoch");
  cmd->add_option("model", a.model, "Model file (from train-normals)")->required();
  return cmd;
}

// Loads the model (its checksums, weights and description checked as track and eval-normals
// do) and prints what it is, what it takes and how it was trained.
int run_model_info(const ModelInfoArgs& a) {
  const NormalEstimator model = NormalEstimator::load(a.model);
  const NormalModelInfo& i = model.info();
  std::error_code ec;
  const auto bytes = std::filesystem::file_size(a.model, ec);
  std::printf("model     %s (%s, checksums and weights ok; digest %s)\n", a.model.c_str(),
              bytes < 1'000'000 ? format_number(double(bytes) / 1e3, "%.0f kB").c_str()
                                : format_number(double(bytes) / 1e6, "%.1f MB").c_str(),
              i.file_digest.c_str());
  std::printf("network   %s, %ld parameters, normals in the %s frame\n", describe(i.spec).c_str(),
              model.parameter_count(), i.gel_relative ? "undeformed gel's" : "sensor");
  std::printf(
      "images    %dx%d (the only size it takes); input mean %.4f %.4f %.4f, std %.4f "
      "%.4f %.4f\n",
      i.width, i.height, double(i.input_mean[0]), double(i.input_mean[1]), double(i.input_mean[2]),
      double(i.input_std[0]), double(i.input_std[1]), double(i.input_std[2]));
  if (i.sensor_known) {
    std::printf(
        "sensor    %s: %zu lights, camera fx %.2f px at %.2f mm (track and eval-normals "
        "warn on other optics)\n",
        i.sensor.name.c_str(), i.sensor.lights.size(), i.sensor.camera.fx,
        i.sensor.camera.distance_m * 1e3);
  } else {
    std::printf("sensor    not recorded (a model file from before 2026-11-27)\n");
  }
  std::string backgrounds;
  for (const std::string& b : i.backgrounds)
    backgrounds += (backgrounds.empty() ? "" : " and ") + b;
  std::printf(
      "frames    %s\n",
      backgrounds.empty()
          ? "background not recorded (a model file from before "
            "2026-11-29, or data that did not say)"
          : ("background " + backgrounds + " (track and eval-normals warn on another)").c_str());
  // The rest of the command that trained it, as its options (alphabetical), for reproducing it.
  const auto settings = nlohmann::json::parse(
      i.settings_json.empty() ? "null" : i.settings_json, nullptr, false);
  if (settings.is_object()) {
    std::string text;
    for (const auto& [option, value] : settings.items()) {
      if (option.rfind("--", 0) != 0 || option == "--val") continue;
      text += (text.empty() ? "" : " ") + option + " " +
              (value.is_number_float() ? format_number(value.get<double>(), "%g") : value.dump());
    }
    const auto val = settings.find("--val");
    const std::size_t validation = val != settings.end() && val->is_array() ? val->size() : 0;
    std::printf("settings  %s; validated on %s\n", text.c_str(),
                validation > 0 ? (std::to_string(validation) + " dataset(s)").c_str()
                               : "every 10th training frame");
  } else {
    std::printf("settings  not recorded (a model file from before 2026-11-29)\n");
  }
  std::printf("trained   %d epoch(s) on %zu dataset(s):\n", i.epochs, i.training_data.size());
  for (const std::string& dir : i.training_data) std::printf("            %s\n", dir.c_str());
  // A fine-tuned model's starting points, back to the one trained from random weights.
  auto base = nlohmann::json::parse(
      i.fine_tuned_from_json.empty() ? "null" : i.fine_tuned_from_json, nullptr, false);
  for (; base.is_object();
       base = base.contains("fine_tuned_from") ? base["fine_tuned_from"] : nlohmann::json()) {
    const auto field = [&](const char* key) {
      return base.contains(key) ? base[key] : nlohmann::json();
    };
    const nlohmann::json model_file = field("model"), epochs = field("epochs"),
                         data = field("training_data");
    std::printf("from      %s, %s epoch(s) on %s dataset(s):\n",
                model_file.is_string() ? model_file.get<std::string>().c_str() : "?",
                epochs.is_number_integer() ? std::to_string(epochs.get<int>()).c_str() : "?",
                data.is_array() ? std::to_string(data.size()).c_str() : "?");
    for (const auto& dir : data.is_array() ? data : nlohmann::json::array()) {
      if (dir.is_string()) std::printf("            %s\n", dir.get<std::string>().c_str());
    }
  }
  const auto history = nlohmann::json::parse(i.history_json, nullptr, false);
  if (history.is_array() && !history.empty()) {
    const nlohmann::json& last = history.back();
    const auto number = [&](const char* key, const char* format) {
      const auto it = last.find(key);
      return it == last.end() || !it->is_number() ? std::string("n/a")
                                                  : format_number(it->get<double>(), format);
    };
    std::printf("last      epoch %s: loss %s, val MSE contact %s, angle contact %s\n",
                number("epoch", "%.0f").c_str(), number("loss_l1", "%.4f").c_str(),
                number("val_mse_contact", "%.2e").c_str(),
                number("val_angle_contact_deg", "%.2f deg").c_str());
  }
  return kExitOk;
}

int run_eval_normals(const EvalNormalsArgs& a) {
  const bool shading = a.model == kShadingNormals;
  as_usage_error([&] { check_given_once(a.data); });
  if (shading && a.phases != 1) {
    throw UsageError("--phases " + std::to_string(a.phases) +
                     ": the shading's inverse reads each pixel by itself, in one pass (1)");
  }
  if (shading && a.blend_shading > 0) {
    throw UsageError("--blend-shading " + format_number(a.blend_shading) +
                     ": averages a model's normals with the shading's inverse; give --model "
                     "MODEL (--model shading is the inverse alone)");
  }
  if (!a.json.empty()) {  // checked before the evaluation, written after it
    const std::filesystem::path folder = std::filesystem::path(a.json).parent_path();
    if (!folder.empty() && !std::filesystem::is_directory(folder)) {
      throw InputError(a.json + ": cannot write: " + folder.string() + " is not a folder");
    }
    if (std::filesystem::is_directory(a.json)) {
      throw InputError("--json " + a.json + ": is a folder; give the JSON file's name");
    }
    if (!shading) check_output_is_not_input(a.json, a.model, "--model", "--json");
    check_output_file(a.json, {FileKind::kJson}, "--json");
    for (const std::string& dir : a.data)
      check_output_is_not_input(a.json, dir, "the dataset", "--json");
    check_can_write(a.json);  // now, not after the evaluation
  }
  std::optional<NormalEstimator> loaded;
  if (shading) {
    check_evaluation_data(a.data);
  } else {
    loaded = NormalEstimator::load(a.model, a.threads);
    loaded->set_phases(a.phases);
    check_evaluation_data(*loaded, a.data);
  }
  for (const std::string& dir : a.data) {
    const Dataset dataset = Dataset::open(dir);
    if (shading || a.blend_shading > 0) check_shading_readable(dataset);
    if (shading) continue;
    const NormalEstimator& model = *loaded;
    warn_of_other_optics(model, dataset.info(), dir);
    // Its own training frames measure the fit, not how the model reads frames it has not seen.
    const auto& trained = model.info().training_data;
    if (std::any_of(trained.begin(), trained.end(), [&](const std::string& t) {
          std::error_code ec;
          return std::filesystem::equivalent(dir, t, ec);
        })) {
      std::fprintf(stderr,
                   "note: %s is among the datasets %s was trained on: its figures measure the "
                   "fit, not how the model reads frames it has not seen\n",
                   dir.c_str(), a.model.c_str());
    }
  }
  nlohmann::json results = nlohmann::json::array();
  std::printf("%-40s %7s %12s %12s %14s %12s %9s\n", "dataset", "frames", "MSE contact",
              "MSE image", "angle contact", "angle image", "ms/frame");
  for (const std::string& dir : a.data) {
    std::unique_ptr<Progress> progress;
    const NormalMetrics m = [&] {
      try {
        const StopOnSignals stop;
        const auto report = [&](int done, int total) {
          if (!progress) progress = std::make_unique<Progress>("evaluating", total, !a.quiet);
          progress->update(done);
        };
        if (!shading && a.blend_shading == 0) return evaluate_normals(*loaded, {dir}, report);
        const DatasetInfo info = Dataset::open(dir).info();
        const ShadingInversion inversion(info.sensor, info.on_real_background());
        if (shading) {
          return evaluate_normals(
              [&](std::size_t, const ImageU8& color, const ImageU8& reference) {
                return inversion.normals(color, reference);
              },
              "--model shading", {dir}, report);
        }
        return evaluate_normals(
            [&](std::size_t, const ImageU8& color, const ImageU8& reference) {
              return blend_normals(loaded->predict(color, reference),
                                   inversion.normals(color, reference), float(a.blend_shading));
            },
            a.model + " blended with the shading's inverse", {dir}, report);
      } catch (const Stopped& e) {
        throw e.with_note("in " + dir +
                          (a.json.empty() ? "" : "; --json " + a.json + " not written") +
                          (results.empty() ? "" : "; the datasets before it are printed above"));
      }
    }();
    std::printf("%-40s %7d %12s %12.3e %10s deg %8.2f deg %9.2f\n", dir.c_str(), m.frames,
                metric(m.mse_contact, "%.3e").c_str(), m.mse_image,
                metric(m.angle_contact_deg, "%.2f").c_str(), m.angle_image_deg, m.ms_per_frame);
    if (m.contact_pixels == 0) {
      std::fprintf(stderr, "warning: %s: no contact pixel in its masks; no contact metrics\n",
                   dir.c_str());
    }
    results.push_back({{"dataset", dir},
                       {"frames", m.frames},
                       {"contact_pixels", m.contact_pixels},
                       {"mse_contact", m.mse_contact},
                       {"mse_image", m.mse_image},
                       {"angle_contact_deg", m.angle_contact_deg},
                       {"angle_image_deg", m.angle_image_deg},
                       {"ms_per_frame", m.ms_per_frame}});
  }
  if (!a.json.empty()) {
    write_text_atomically(
        a.json, nlohmann::json{{"model", a.model},
                               {"arch", shading ? kShadingNormals : loaded->info().spec.arch},
                               {"blend_shading", a.blend_shading},
                               {"phases", a.phases},
                               {"results", results}}
                        .dump(2) +
                    "\n");
  }
  return kExitOk;
}

}  // namespace pg
