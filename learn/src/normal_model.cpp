// Model files, the input encoding, inference and evaluation.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>

#include "networks.h"
#include "pg/core/dataset.h"
#include "pg/core/error.h"
#include "pg/core/file_io.h"
#include "pg/core/gel_rays.h"
#include "pg/core/json_fields.h"
#include "pg/core/memory.h"
#include "pg/core/statistics.h"
#include "zip_check.h"

namespace pg {

namespace fs = std::filesystem;

std::string describe(const NetworkSpec& spec) {
  if (spec.arch == "mlp") return "mlp (hidden " + std::to_string(spec.mlp_hidden) + ")";
  return spec.arch + " (depth " + std::to_string(spec.depth) + ", width " +
         std::to_string(spec.base_width) + ")";
}

namespace learn {

namespace {

constexpr const char* kFormat = "patchgraph-normals-1";

nlohmann::json info_to_json(const NormalModelInfo& info) {
  nlohmann::json j;
  j["arch"] = info.spec.arch;
  j["depth"] = info.spec.depth;
  j["base_width"] = info.spec.base_width;
  j["mlp_hidden"] = info.spec.mlp_hidden;
  j["input_mean"] = info.input_mean;
  j["input_std"] = info.input_std;
  j["width"] = info.width;
  j["height"] = info.height;
  j["epochs"] = info.epochs;
  j["training_data"] = info.training_data;
  if (info.gel_relative) j["labels"] = "gel";
  if (!info.fine_tuned_from_json.empty())
    j["fine_tuned_from"] = nlohmann::json::parse(info.fine_tuned_from_json);
  if (info.sensor_known) j["sensor"] = sensor_to_json(info.sensor);
  if (!info.backgrounds.empty()) j["backgrounds"] = info.backgrounds;
  if (!info.settings_json.empty()) j["settings"] = nlohmann::json::parse(info.settings_json);
  j["history"] = info.history_json.empty() ? nlohmann::json::array()
                                           : nlohmann::json::parse(info.history_json);
  return j;
}

NormalModelInfo info_from_json(const nlohmann::json& j, const std::string& path) {
  NormalModelInfo info;
  info.spec.arch = j.at("arch").get<std::string>();
  info.spec.depth = j.at("depth").get<int>();
  info.spec.base_width = j.at("base_width").get<int>();
  info.spec.mlp_hidden = j.at("mlp_hidden").get<int>();
  info.input_mean = j.at("input_mean").get<std::array<float, 3>>();
  info.input_std = j.at("input_std").get<std::array<float, 3>>();
  info.width = j.at("width").get<int>();
  info.height = j.at("height").get<int>();
  info.epochs = j.at("epochs").get<int>();
  info.training_data = j.at("training_data").get<std::vector<std::string>>();
  info.history_json = j.at("history").dump();
  if (j.contains("fine_tuned_from")) {
    const nlohmann::json& base = j.at("fine_tuned_from");
    if (!base.is_object()) {
      throw nlohmann::json::other_error::create(501, "fine_tuned_from is not an object", &j);
    }
    info.fine_tuned_from_json = base.dump();
  }
  if (j.contains("settings")) {
    const nlohmann::json& settings = j.at("settings");
    if (!settings.is_object()) {
      throw nlohmann::json::other_error::create(501, "settings is not an object", &j);
    }
    info.settings_json = settings.dump();
  }
  const std::string labels = j.value("labels", std::string("sensor"));
  if (labels != "sensor" && labels != "gel") {
    throw nlohmann::json::other_error::create(501, "unknown labels '" + labels + "'", &j);
  }
  info.gel_relative = labels == "gel";
  info.sensor_known = j.contains("sensor");
  if (info.sensor_known || info.gel_relative) {
    info.sensor = sensor_from_json(j.at("sensor"), path + ": sensor");
  }
  if (j.contains("backgrounds")) {
    info.backgrounds = j.at("backgrounds").get<std::vector<std::string>>();
    for (const std::string& b : info.backgrounds) {
      if (b != "synthetic" && b != "real") {
        throw nlohmann::json::other_error::create(501, "unknown background '" + b + "'", &j);
      }
    }
  }
  return info;
}

}  // namespace

ImageF gel_normals(const SensorModel& sensor) {
  return undeformed_gel_normals(make_gel_rays(sensor.camera, sensor.gel));
}

bool same_gel(const ImageF& a, const ImageF& b) {
  if (a.data.size() != b.data.size()) return false;
  for (std::size_t k = 0; k < a.data.size(); ++k) {
    if (std::abs(a.data[k] - b.data[k]) > 1e-6f) return false;
  }
  return true;
}

void rotate_gel_frame(const float* g, float* n, bool to_gel) {
  // R: the minimal rotation taking +z to g, I + [v]x + [v]x^2 / (1 + c) with v = z x g, c = g.z.
  const float vx = -g[1], vy = g[0], s = vx * vx + vy * vy, k = 1.0f / (1.0f + g[2]);
  const float r[3][3] = {{1.0f + k * (vx * vx - s), k * vx * vy, vy},
                         {k * vx * vy, 1.0f + k * (vy * vy - s), -vx},
                         {-vy, vx, g[2]}};
  const float a = n[0], b = n[1], c = n[2];
  for (int i = 0; i < 3; ++i) {
    n[i] =
        to_gel ? r[0][i] * a + r[1][i] * b + r[2][i] * c : r[i][0] * a + r[i][1] * b + r[i][2] * c;
  }
}

torch::Tensor difference_tensor(const ImageU8& color, const ImageU8& background) {
  const int w = color.width, h = color.height;
  torch::Tensor t = torch::empty({3, h, w}, torch::kFloat32);
  float* out = t.data_ptr<float>();
  const std::size_t plane = std::size_t(w) * h;
  for (std::size_t p = 0; p < plane; ++p) {
    for (int c = 0; c < 3; ++c) {
      out[c * plane + p] =
          (float(color.data[p * 3 + c]) - float(background.data[p * 3 + c])) / 255.0f;
    }
  }
  return t;
}

torch::Tensor image_to_tensor(const ImageF& image) {
  const std::size_t plane = std::size_t(image.width) * image.height;
  torch::Tensor t = torch::empty({image.channels, image.height, image.width}, torch::kFloat32);
  float* out = t.data_ptr<float>();
  for (std::size_t p = 0; p < plane; ++p) {
    for (int c = 0; c < image.channels; ++c)
      out[c * plane + p] = image.data[p * image.channels + c];
  }
  return t;
}

ImageF true_normals(const Dataset& dataset, int frame) {
  ImageF n = dataset.normal(frame);
  if (const auto bad = first_non_finite(n)) {
    throw InputError(dataset_frame_path(dataset.dir(), "normal", frame) + ": pixel (" +
                     std::to_string((*bad)[0]) + ", " + std::to_string((*bad)[1]) +
                     ") is not finite; the ground-truth normals training and evaluation compare "
                     "with must be finite");
  }
  return n;
}

torch::Tensor mask_tensor(const ImageU8& mask) {
  torch::Tensor t = torch::empty({1, mask.height, mask.width}, torch::kFloat32);
  float* out = t.data_ptr<float>();
  for (std::size_t k = 0; k < mask.data.size(); ++k) out[k] = mask.data[k] > 0 ? 1.0f : 0.0f;
  return t;
}

ImageF tensor_to_image(const torch::Tensor& chw) {
  const torch::Tensor t = chw.contiguous().to(torch::kFloat32);
  const int c = int(t.size(0)), h = int(t.size(1)), w = int(t.size(2));
  ImageF image(w, h, c);
  const float* in = t.data_ptr<float>();
  const std::size_t plane = std::size_t(w) * h;
  for (std::size_t p = 0; p < plane; ++p) {
    for (int k = 0; k < c; ++k) image.data[p * c + k] = in[k * plane + p];
  }
  return image;
}

void save_model(const std::string& path, Generator& generator, const NormalModelInfo& info) {
  torch::serialize::OutputArchive archive;
  archive.write("format", c10::IValue(std::string(kFormat)));
  archive.write("info", c10::IValue(info_to_json(info).dump()));
  torch::serialize::OutputArchive weights;
  generator->save(weights);
  archive.write("generator", weights);
  save_archive(archive, path, "model file");
}

void save_archive(torch::serialize::OutputArchive& archive, const std::string& path,
                  const std::string& what) {
  replaceable_file(path);  // refuses a device or pipe, which a whole-file write would stream into
  // Serialised in memory first: Torch's own file writer, on a disk that fills, throws from its
  // destructor, which ends the program (SIGABRT, its temporary file left behind).
  std::ostringstream bytes;
  try {
    archive.save_to(bytes);
  } catch (const c10::Error& e) {
    const std::string why = e.what_without_backtrace();
    throw InputError(path + ": cannot write the " + what + " (" + why.substr(0, why.find('\n')) +
                     ")");
  }
  write_text_atomically(path, bytes.str(), what);
}

std::string weights_shape_problem(const torch::nn::Module& loaded,
                                  const torch::nn::Module& described) {
  for (const bool buffers : {false, true}) {
    const auto want = buffers ? described.named_buffers() : described.named_parameters();
    const auto got = buffers ? loaded.named_buffers() : loaded.named_parameters();
    for (const auto& item : want) {
      const torch::Tensor* t = got.find(item.key());
      if (!t) return item.key() + " is missing";
      if (t->sizes() != item.value().sizes()) return item.key() + " has another shape";
    }
  }
  return {};
}

std::string weights_number_problem(const torch::nn::Module& module) {
  for (const bool buffers : {false, true}) {
    for (const auto& item : buffers ? module.named_buffers() : module.named_parameters()) {
      const torch::Tensor& t = item.value();
      if (t.is_floating_point() && !torch::isfinite(t).all().item<bool>()) {
        return item.key() + " holds numbers that are not finite";
      }
    }
  }
  return {};
}

std::string optimizer_state_problem(torch::optim::Adam& optimizer) {
  for (const auto& group : optimizer.param_groups()) {
    for (const torch::Tensor& p : group.params()) {
      const auto it = optimizer.state().find(c10::guts::to_string(p.unsafeGetTensorImpl()));
      if (it == optimizer.state().end()) continue;  // no step taken for it yet
      const auto& state = static_cast<const torch::optim::AdamParamState&>(*it->second);
      for (const torch::Tensor* moment : {&state.exp_avg(), &state.exp_avg_sq()}) {
        if (moment->sizes() != p.sizes()) return "an optimizer moment has another shape";
        if (!torch::isfinite(*moment).all().item<bool>()) {
          return "an optimizer moment holds numbers that are not finite";
        }
      }
    }
  }
  return {};
}

namespace {

// The description's numbers within what train-normals makes (a depth of 0 had crashed the
// U-Net's first pass; an input_std of 0 made every pixel a fallback normal).
void check_description(const NormalModelInfo& info, const std::string& path) {
  const auto refuse = [&](const std::string& what) {
    throw InputError(path + ": malformed model description: " + what);
  };
  const NetworkSpec& n = info.spec;
  const auto within = [&](const char* name, int value, int largest) {
    if (value < 1 || value > largest) {
      refuse(std::string(name) + " " + std::to_string(value) + " not in 1-" +
             std::to_string(largest));
    }
  };
  within("depth", n.depth, kMaxNetworkDepth);
  within("base_width", n.base_width, kMaxBaseWidth);
  within("mlp_hidden", n.mlp_hidden, kMaxMlpHidden);
  for (int c = 0; c < 3; ++c) {
    if (!std::isfinite(info.input_mean[c])) refuse("input_mean is not finite");
    if (!(info.input_std[c] > 0.0f) || !std::isfinite(info.input_std[c]))
      refuse("input_std is not a positive number");
  }
  if (std::min(info.width, info.height) < kMinImageSide ||
      std::max(info.width, info.height) > kMaxImageSide) {
    refuse("image size " + std::to_string(info.width) + "x" + std::to_string(info.height) +
           " not in " + std::to_string(kMinImageSide) + "-" + std::to_string(kMaxImageSide));
  }
}

}  // namespace

Generator load_model(const std::string& path, NormalModelInfo& info) {
  if (!fs::exists(path)) throw InputError(path + ": model file not found");
  if (!fs::is_regular_file(path)) {
    throw InputError(path + ": is not a model file (a folder, device or pipe)");
  }
  learn::check_zip_checksums(path, "model file");
  torch::serialize::InputArchive archive;
  try {
    archive.load_from(path);
  } catch (const std::exception&) {  // c10::Error, or TorchScript's on a damaged entry name
    throw InputError(path + ": not a readable model file (corrupt or not a Torch archive)");
  }
  c10::IValue format, text;
  if (archive.try_read("format", format) && format.isString() &&
      format.toStringRef().rfind("patchgraph-normals-checkpoint", 0) == 0) {
    throw InputError(path +
                     ": is a training checkpoint, not a model; train-normals writes the model "
                     "at its end (or, stopped, the same command with `--resume --epochs E`, E "
                     "the checkpoint's epoch and --decay-epochs at most E, writes it now; a later "
                     "--resume trains on)");
  }
  if (!archive.try_read("format", format) || !format.isString() ||
      format.toStringRef() != kFormat || !archive.try_read("info", text) || !text.isString()) {
    throw InputError(path + ": not a patchgraph normals model (expected format '" +
                     std::string(kFormat) + "')");
  }
  try {
    info = info_from_json(nlohmann::json::parse(text.toStringRef()), path);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(path + ": malformed model description: " + without_json_tag(e.what()));
  }
  check_description(info, path);
  Generator generator(nullptr);
  try {
    generator = Generator(info.spec);
    torch::serialize::InputArchive weights;
    if (!archive.try_read("generator", weights)) throw InputError(path + ": no generator weights");
    generator->load(weights);
  } catch (const InputError&) {
    throw;
  } catch (const std::invalid_argument& e) {
    throw InputError(path + ": " + e.what());
  } catch (const std::exception&) {
    throw InputError(path + ": the weights do not match the network it describes (" +
                     info.spec.arch + ")");
  }
  // A description that says this one ran as that network, described wrongly.
  if (const std::string problem = weights_shape_problem(*generator, *Generator(info.spec));
      !problem.empty()) {
    throw InputError(path + ": the weights do not match the network it describes (" +
                     info.spec.arch + ", depth " + std::to_string(info.spec.depth) + ", width " +
                     std::to_string(info.spec.base_width) + "): " + problem);
  }
  // Weights written so by a diverged run of some other tool: every prediction would be noise.
  if (const std::string problem = weights_number_problem(*generator); !problem.empty()) {
    throw InputError(path + ": corrupt model file: " + problem);
  }
  generator->eval();
  return generator;
}

torch::Tensor as_predicted(const torch::Tensor& raw) {
  const torch::Tensor unit = raw / raw.norm(2, 1, true).clamp_min(1e-6);
  torch::Tensor up = torch::zeros_like(unit);
  up.select(1, 2).fill_(1.0f);
  // A NaN stays NaN (it had become the flat gel's normal, hiding a broken network).
  const torch::Tensor keep = (unit.narrow(1, 2, 1) > kMinFacingZ)
                                 .logical_or(torch::isfinite(unit).all(1, true).logical_not());
  return torch::where(keep, unit, up);
}

void MetricSums::add(const torch::Tensor& predicted, const torch::Tensor& truth,
                     const torch::Tensor& mask) {
  const torch::Tensor p = predicted / predicted.norm(2, 1, true).clamp_min(1e-6);
  const torch::Tensor t = truth / truth.norm(2, 1, true).clamp_min(1e-6);
  const torch::Tensor se = ((p - t) * 0.5).pow(2).mean(1, true);  // encoded as (n + 1) / 2
  const torch::Tensor angle = torch::acos((p * t).sum(1, true).clamp(-1.0, 1.0)) * (180.0 / kPi);
  se_image += se.sum().item<double>();
  angle_image += angle.sum().item<double>();
  se_contact += (se * mask).sum().item<double>();
  angle_contact += (angle * mask).sum().item<double>();
  contact_px += mask.sum().item<double>();
  image_px += double(se.numel());
}

NormalMetrics MetricSums::metrics(int frames) const {
  NormalMetrics m;
  m.frames = frames;
  const double c = std::max(contact_px, 1.0), i = std::max(image_px, 1.0);
  // No contact pixel: no contact error to report (0 would read as a perfect model).
  const double no_contact = std::numeric_limits<double>::quiet_NaN();
  m.contact_pixels = long(contact_px);
  m.mse_contact = contact_px > 0 ? se_contact / c : no_contact;
  m.angle_contact_deg = contact_px > 0 ? angle_contact / c : no_contact;
  m.mse_image = se_image / i;
  m.angle_image_deg = angle_image / i;
  return m;
}

}  // namespace learn

namespace {
// Pixel offsets of the frame for phase averaging, in the order they join: the stride-2 layers see
// a frame shifted by one pixel on another sampling grid, so each offset is another phase of them.
constexpr int kPhaseShifts[4][2] = {{0, 0}, {1, 1}, {1, 0}, {0, 1}};
}  // namespace

struct NormalEstimator::Impl {
  std::string path;
  NormalModelInfo info;
  learn::Generator generator{nullptr};
  ImageF gel;  // the undeformed gel's normals, for a gel-relative model
  int phases = 1;
};

NormalEstimator::NormalEstimator(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
NormalEstimator::NormalEstimator(NormalEstimator&&) noexcept = default;
NormalEstimator& NormalEstimator::operator=(NormalEstimator&&) noexcept = default;
NormalEstimator::~NormalEstimator() = default;

// A forward pass allocates and frees a few MB of tensors; kept in the heap (keep_freed_memory)
// they are reused, where every frame had faulted them in again: about 540 page faults a frame at
// 120x160, a fifth to a quarter of the U-Net's inference time and more than half of the MLP's on
// a 2-core AMD EPYC (docs/learned_normals.md, "Freed memory kept").

NormalEstimator NormalEstimator::load(const std::string& path, int threads) {
  keep_freed_memory();
  auto impl = std::make_unique<Impl>();
  impl->path = path;
  impl->generator = learn::load_model(path, impl->info);
  impl->info.file_digest = file_digest(path);
  if (impl->info.gel_relative) {
    impl->gel = learn::gel_normals(impl->info.sensor);
    if (!impl->gel.same_shape(impl->info.width, impl->info.height, 3)) {
      throw InputError(path + ": its sensor's image size does not match the model's");
    }
  }
  if (threads <= 0) threads = int(std::max(1u, std::thread::hardware_concurrency()));
  torch::set_num_threads(threads);
  // Trained weights leave some activations denormal; flushing them to zero keeps the CPU's
  // fast path (no visible change to the normals).
  at::globalContext().setFlushDenormal(true);
  return NormalEstimator(std::move(impl));
}

void NormalEstimator::set_phases(int phases) {
  if (phases != 1 && phases != 2 && phases != 4) {
    throw InputError("normals phases must be 1, 2 or 4, not " + std::to_string(phases));
  }
  // A per-pixel network has no stride to average over; a shifted frame would read each pixel's
  // colour at its neighbour's place.
  if (phases != 1 && impl_->info.spec.arch == "mlp") {
    throw InputError(impl_->path + ": a per-pixel MLP has no phases to average (1 only, not " +
                     std::to_string(phases) + ")");
  }
  impl_->phases = phases;
}

int NormalEstimator::phases() const { return impl_->phases; }

const NormalModelInfo& NormalEstimator::info() const { return impl_->info; }
const std::string& NormalEstimator::path() const { return impl_->path; }
long NormalEstimator::parameter_count() const {
  long n = 0;
  for (const torch::Tensor& t : impl_->generator->parameters()) n += long(t.numel());
  return n;
}

void NormalEstimator::check_sensor(const SensorModel& sensor, const std::string& where) const {
  const NormalModelInfo& m = impl_->info;
  const int w = sensor.camera.width, h = sensor.camera.height;
  if (w != m.width || h != m.height) {
    throw InputError(impl_->path + ": the model takes " + std::to_string(m.width) + "x" +
                     std::to_string(m.height) + " images; " + where + " has " + std::to_string(w) +
                     "x" + std::to_string(h) +
                     " (render at the model's size or train a model at the dataset's)");
  }
  if (m.gel_relative && !learn::same_gel(learn::gel_normals(sensor), impl_->gel)) {
    throw InputError(impl_->path + ": a gel-relative model of another camera or gel shape than " +
                     where + "'s sensor");
  }
}

std::string NormalEstimator::sensor_difference(const SensorModel& sensor) const {
  const NormalModelInfo& m = impl_->info;
  return m.sensor_known ? optics_difference(m.sensor, sensor) : "";
}

std::string frame_background(const DatasetInfo& info) {
  if (info.render_known) return info.background.empty() ? "synthetic" : "real";
  // Neither rendered from a scene nor saying how it was rendered: a recording (patchgraph
  // recording, or label-ball's labels of one).
  return info.scene.empty() ? "real" : "";
}

std::string NormalEstimator::background_difference(const DatasetInfo& info) const {
  const std::vector<std::string>& known = impl_->info.backgrounds;
  const std::string b = frame_background(info);
  if (known.empty() || b.empty() || std::find(known.begin(), known.end(), b) != known.end()) {
    return "";
  }
  const auto frames = [](const std::string& background) {
    return background == "real" ? std::string(
                                      "a real sensor's background (a recording, or a "
                                      "render over a real no-contact image)")
                                : std::string("the renderer's synthetic background");
  };
  return "its frames have " + frames(b) + ", and " + impl_->path +
         " was trained only on frames with " + frames(known.front()) +
         ": a network reads another background's contrast as other slopes (the default model "
         "reads a press over the real DIGIT background 6.2 deg off, against 2.3 deg on the "
         "synthetic one)";
}

std::string optics_difference(const SensorModel& t, const SensorModel& sensor) {
  std::vector<std::string> differ;
  bool lights = t.lights.size() != sensor.lights.size();
  for (std::size_t k = 0; !lights && k < t.lights.size(); ++k) {
    const PointLight &a = t.lights[k], &b = sensor.lights[k];
    lights = !a.position_m.isApprox(b.position_m, 1e-6) || !a.color.isApprox(b.color, 1e-6) ||
             std::abs(a.intensity - b.intensity) > 1e-6 * a.intensity;
  }
  if (lights) differ.push_back("lights");
  const ShadingModel &s = t.shading, &o = sensor.shading;
  if (s.ambient != o.ambient || s.diffuse != o.diffuse || s.specular != o.specular ||
      s.shininess != o.shininess || s.exposure != o.exposure) {
    differ.push_back("shading");
  }
  const CameraModel &c = t.camera, &d = sensor.camera;
  const auto near = [](double x, double y) { return std::abs(x - y) <= 1e-6 * std::abs(x); };
  if (!near(c.fx, d.fx) || !near(c.fy, d.fy) || !near(c.cx + 1, d.cx + 1) ||
      !near(c.cy + 1, d.cy + 1) || !near(c.distance_m, d.distance_m)) {
    differ.push_back("camera");
  }
  std::string text;
  for (std::size_t k = 0; k < differ.size(); ++k) {
    text += (k == 0 ? "" : k + 1 == differ.size() ? " and " : ", ") + differ[k];
  }
  return text;
}

ImageF NormalEstimator::predict(const ImageU8& color, const ImageU8& background) const {
  const NormalModelInfo& info = impl_->info;
  auto check = [&](const ImageU8& image, const char* what) {
    if (!image.same_shape(info.width, info.height, 3)) {
      throw InputError(std::string(what) + " image is " + std::to_string(image.width) + "x" +
                       std::to_string(image.height) + "x" + std::to_string(image.channels) +
                       "; the model " + impl_->path + " takes " + std::to_string(info.width) + "x" +
                       std::to_string(info.height) + "x3 (RGB)");
    }
  };
  check(color, "colour");
  check(background, "background");
  // Flushing denormals (load's) is the calling thread's setting: this may be another thread
  // (track_dataset's, reading the next frame while the tracker updates).
  at::globalContext().setFlushDenormal(true);
  // The input encoding, normalisation and forward()'s edge padding in one pass: the network then
  // runs on an image whose sides are already multiples of what it needs. With phase averaging
  // the batch holds the frame shifted by each phase's pixel offset.
  const int w = info.width, h = info.height, m = impl_->generator->multiple();
  const int pw = (m - w % m) % m, ph = (m - h % m) % m;
  const int wp = w + pw, hp = h + ph, left = pw / 2, top = ph / 2;
  const int phases = impl_->phases;
  const std::size_t plane = std::size_t(wp) * hp;
  torch::Tensor x = torch::empty({phases, 3, hp, wp}, torch::kFloat32);
  {
    float scale[3], offset[3];
    for (int c = 0; c < 3; ++c) {
      scale[c] = 1.0f / (255.0f * info.input_std[c]);
      offset[c] = -info.input_mean[c] / info.input_std[c];
    }
    for (int k = 0; k < phases; ++k) {
      float* in = x.data_ptr<float>() + std::size_t(k) * 3 * plane;
      const int dx = kPhaseShifts[k][0], dy = kPhaseShifts[k][1];
      for (int yp = 0; yp < hp; ++yp) {
        const int y = std::clamp(yp - top - dy, 0, h - 1);
        for (int xp = 0; xp < wp; ++xp) {
          const std::size_t p = (std::size_t(y) * w + std::clamp(xp - left - dx, 0, w - 1)) * 3;
          for (int c = 0; c < 3; ++c) {
            const float d = float(color.data[p + c]) - float(background.data[p + c]);
            in[c * plane + std::size_t(yp) * wp + xp] = d * scale[c] + offset[c];
          }
        }
      }
    }
  }
  torch::NoGradGuard no_grad;
  const torch::Tensor n = impl_->generator->forward(x).contiguous();
  // The phases' mean, of unit length, facing the camera's side of the gel (z > 0) where the
  // network is unsure. (A shifted frame's last column or row, beyond the padding, is its
  // neighbour's.)
  ImageF normals(w, h, 3);
  const float* out = n.data_ptr<float>();
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      float nx = 0.0f, ny = 0.0f, nz = 0.0f;
      for (int k = 0; k < phases; ++k) {
        const int xs = std::min(x + left + kPhaseShifts[k][0], wp - 1);
        const int ys = std::min(y + top + kPhaseShifts[k][1], hp - 1);
        const float* o = out + std::size_t(k) * 3 * plane + std::size_t(ys) * wp + xs;
        nx += o[0], ny += o[plane], nz += o[2 * plane];
      }
      const float inv = 1.0f / std::max(std::sqrt(nx * nx + ny * ny + nz * nz), 1e-6f);
      float* o = &normals.data[(std::size_t(y) * w + x) * 3];
      if (!std::isfinite(nx * inv + ny * inv + nz * inv)) {
        // A broken network's NaN is passed on, for the tracker to count as rejected normals
        // (it had read as the flat gel's normal).
        o[0] = o[1] = o[2] = std::numeric_limits<float>::quiet_NaN();
        continue;
      } else if (nz * inv > learn::kMinFacingZ) {
        o[0] = nx * inv, o[1] = ny * inv, o[2] = nz * inv;
      } else {
        o[0] = 0.0f, o[1] = 0.0f, o[2] = 1.0f;
      }
      if (!impl_->gel.empty()) {
        learn::rotate_gel_frame(&impl_->gel.data[(std::size_t(y) * w + x) * 3], o, false);
      }
    }
  }
  return normals;
}

namespace {

// `model`: null for none (NormalsReader).
std::vector<Dataset> open_evaluation_data(const NormalEstimator* model,
                                          const std::vector<std::string>& datasets) {
  std::vector<Dataset> sets;
  for (const auto& dir : datasets) {
    sets.push_back(Dataset::open(dir));
    for (const char* output : {"color", "normal", "mask"}) {
      if (!(std::string(output) == "normal" ? sets.back().info().has_normals()
                                            : sets.back().info().has_output(output))) {
        throw InputError(dir + ": dataset has no '" + output +
                         "' output, needed to evaluate normals");
      }
    }
    if (model) model->check_sensor(sets.back().info().sensor, dir);
  }
  return sets;
}

// evaluate_normals over opened datasets; `what` names the reader's output in errors, `why` what
// a non-finite one means.
NormalMetrics evaluate_opened(const std::vector<Dataset>& sets, const NormalsReader& read,
                              const std::string& what, const std::string& why,
                              const std::function<void(int, int)>& progress) {
  int total = 0;
  for (const Dataset& d : sets) total += d.frames();
  learn::MetricSums sums;
  std::vector<double> times;
  int done = 0;
  for (std::size_t k = 0; k < sets.size(); ++k) {
    const Dataset& d = sets[k];
    const ImageU8 background = d.background();
    for (int i = 0; i < d.frames(); ++i) {
      const ImageU8 color = d.color(i);
      const auto start = std::chrono::steady_clock::now();
      const ImageF predicted = read(k, color, background);
      times.push_back(
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
              .count());
      const auto not_finite = std::count_if(predicted.data.begin(), predicted.data.end(),
                                            [](float v) { return !std::isfinite(v); });
      if (not_finite > 0) {
        throw InputError(what + " is not a finite number at " + std::to_string(not_finite / 3) +
                         " pixels of " + d.dir() + " frame " + std::to_string(i) + " (" + why +
                         ")");
      }
      sums.add(learn::image_to_tensor(predicted).unsqueeze(0),
               learn::image_to_tensor(learn::true_normals(d, i)).unsqueeze(0),
               learn::mask_tensor(d.mask(i)).unsqueeze(0));
      ++done;
      if (progress) progress(done, total);
    }
  }
  NormalMetrics m = sums.metrics(done);
  if (!times.empty()) m.ms_per_frame = upper_median(times);
  return m;
}

}  // namespace

void check_evaluation_data(const NormalEstimator& model, const std::vector<std::string>& datasets) {
  for (const Dataset& d : open_evaluation_data(&model, datasets)) d.background();
}

void check_evaluation_data(const std::vector<std::string>& datasets) {
  for (const Dataset& d : open_evaluation_data(nullptr, datasets)) d.background();
}

NormalMetrics evaluate_normals(const NormalEstimator& model,
                               const std::vector<std::string>& datasets,
                               const std::function<void(int, int)>& progress) {
  return evaluate_opened(
      open_evaluation_data(&model, datasets),
      [&](std::size_t, const ImageU8& color, const ImageU8& reference) {
        return model.predict(color, reference);
      },
      model.path() + ": the network's output", "a diverged or damaged model", progress);
}

NormalMetrics evaluate_normals(const NormalsReader& read, const std::string& name,
                               const std::vector<std::string>& datasets,
                               const std::function<void(int, int)>& progress) {
  return evaluate_opened(open_evaluation_data(nullptr, datasets), read, name + "'s output",
                         "a fault of " + name, progress);
}

}  // namespace pg
