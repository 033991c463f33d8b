#include "pg/sim/shading_fit.h"

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "change_filter.h"
#include "pg/core/error.h"
#include "pg/core/gel_rays.h"
#include "shading.h"

namespace pg {

namespace {

// The fitted parameters, per light: its position [m] and its colour times intensity; then the
// specular and the ambient share (the last only where the frames show the shading itself: in
// its change the ambient light cancels). Forward-difference steps: 0.01 mm, and 1e-3 of a unit
// colour or share.
constexpr int kPerLight = 6;
constexpr double kPositionStep = 1e-5, kScaleStep = 1e-3;
// The fit stops when an iteration lowers the cost by less than this share of it.
constexpr double kConvergedDecrease = 1e-7;

// Pixels in structure-of-arrays form, as shade_span takes them.
struct Samples {
  std::vector<float> px, py, pz;  // the undeformed gel's point [m]
  std::vector<float> nx, ny, nz;  // the labelled normal
  std::vector<float> gx, gy, gz;  // the undeformed gel's normal
  std::vector<float> seen;        // per channel: the frame's value [levels]
  std::vector<float> base;        // per channel: blended, the reference's value, else 0 [levels]

  std::size_t size() const { return px.size(); }
  void push(const Eigen::Vector3f& p, const Eigen::Vector3f& n, const Eigen::Vector3f& g,
            const float* seen3, const float* base3) {
    px.push_back(p.x()), py.push_back(p.y()), pz.push_back(p.z());
    nx.push_back(n.x()), ny.push_back(n.y()), nz.push_back(n.z());
    gx.push_back(g.x()), gy.push_back(g.y()), gz.push_back(g.z());
    seen.insert(seen.end(), seen3, seen3 + 3);
    base.insert(base.end(), base3, base3 + 3);
  }
  void push(const Samples& from, std::size_t i) {
    push({from.px[i], from.py[i], from.pz[i]}, {from.nx[i], from.ny[i], from.nz[i]},
         {from.gx[i], from.gy[i], from.gz[i]}, &from.seen[3 * i], &from.base[3 * i]);
  }
};

std::vector<double> parameters_of(const SensorModel& s) {
  std::vector<double> theta;
  for (const PointLight& l : s.lights) {
    for (int a = 0; a < 3; ++a) theta.push_back(l.position_m[a]);
    for (int a = 0; a < 3; ++a) theta.push_back(l.color[a] * l.intensity);
  }
  theta.push_back(s.shading.specular);
  theta.push_back(s.shading.ambient);
  return theta;
}

// The start's sensor with the parameters theta: each light's colour is its largest channel's
// share, its intensity that channel.
SensorModel sensor_of(SensorModel s, const std::vector<double>& theta) {
  for (std::size_t k = 0; k < s.lights.size(); ++k) {
    const double* t = &theta[kPerLight * k];
    PointLight& l = s.lights[k];
    l.position_m = Eigen::Vector3d(t[0], t[1], t[2]);
    const Eigen::Vector3d scaled(t[3], t[4], t[5]);
    l.intensity = scaled.maxCoeff();
    l.color = l.intensity > 0 ? Eigen::Vector3d(scaled / l.intensity) : Eigen::Vector3d::Ones();
  }
  s.shading.specular = theta[kPerLight * s.lights.size()];
  s.shading.ambient = theta[kPerLight * s.lights.size() + 1];
  return s;
}

// The parameters kept to what a sensor file may hold: colours and intensities from 0 to 1000,
// the shares from 0 to 10, and each light between the camera and the deepest-pressed gel with
// kLightRoom to spare. The gel's surface curves away from the camera beyond the gel, so a light
// may not stray sideways without bound: at most twice as far from the axis as the start's
// farthest or the gel's corner, and nearer where the surface there leaves it no room.
constexpr double kLightRoom = 5e-4;        // [m]
constexpr double kLargestIntensity = 1e3;  // a sensor file's largest
constexpr double kLargestShare = 10.0;     // a sensor file's largest ambient or specular share
void keep_feasible(std::vector<double>& theta, const SensorModel& sensor) {
  double reach = std::hypot(0.5 * sensor.gel.width_m, 0.5 * sensor.gel.height_m);
  for (const PointLight& l : sensor.lights) reach = std::max(reach, l.position_m.head<2>().norm());
  reach *= 2.0;
  const double nearest = -sensor.camera.distance_m + kLightRoom;
  auto farthest = [&](double x, double y) {
    return sensor.gel.surface_z(x, y) - sensor.gel.max_indentation_m - kLightRoom;
  };
  for (std::size_t k = 0; k < sensor.lights.size(); ++k) {
    double* t = &theta[kPerLight * k];
    const double radius = std::hypot(t[0], t[1]);
    double scale = radius > reach ? reach / radius : 1.0;
    for (int i = 0; i < 60 && farthest(scale * t[0], scale * t[1]) < nearest; ++i) scale *= 0.9;
    t[0] *= scale, t[1] *= scale;
    t[2] = std::clamp(t[2], nearest, std::max(nearest, farthest(t[0], t[1])));
    for (int a = 3; a < 6; ++a) t[a] = std::clamp(t[a], 0.0, kLargestIntensity);
  }
  for (std::size_t a = kPerLight * sensor.lights.size(); a < theta.size(); ++a)
    theta[a] = std::clamp(theta[a], 0.0, kLargestShare);
}

// The frame's value per channel of every sample as the model has it [levels]: blended onto a real
// background, the reference plus the shading's change, base + gain 255 (shade(n) - shade(n_gel));
// else the shading itself, 255 shade(n); clipped to 8 bits as the camera does (so a channel
// clipped in the frame only bounds the model).
void predict(const SensorModel& sensor, bool blended, float gain, const Samples& s,
             std::vector<float>& value, std::vector<float>& scratch) {
  const Shader shader = make_shader(sensor);
  const int n = int(s.size());
  ShadeSpan span;
  span.count = n;
  span.px = s.px.data(), span.py = s.py.data(), span.pz = s.pz.data();
  span.nx = s.nx.data(), span.ny = s.ny.data(), span.nz = s.nz.data();
  value.resize(3 * std::size_t(n));
  shade_span(shader, span, value.data());
  if (blended) {
    scratch.resize(3 * std::size_t(n));
    span.nx = s.gx.data(), span.ny = s.gy.data(), span.nz = s.gz.data();
    shade_span(shader, span, scratch.data());
    for (std::size_t i = 0; i < value.size(); ++i) value[i] = gain * (value[i] - scratch[i]);
  }
  for (std::size_t i = 0; i < value.size(); ++i)
    value[i] = std::clamp(s.base[i] + 255.0f * value[i], 0.0f, 255.0f);
}

struct Cost {
  double robust = 0;   // sum of the Huber loss
  double squares = 0;  // sum of the squared residuals
};

Cost cost_of(const std::vector<float>& value, const Samples& s, double huber) {
  Cost c;
  for (std::size_t i = 0; i < value.size(); ++i) {
    const double r = double(value[i]) - s.seen[i];
    const double a = std::abs(r);
    c.squares += r * r;
    c.robust += a <= huber ? 0.5 * r * r : huber * (a - 0.5 * huber);
  }
  return c;
}

}  // namespace

struct ShadingFit::State {
  SensorModel start;
  bool blended = false;
  float gain = 1.0f;
  ShadingFitOptions options;
  GelRays rays;
  ImageF gel_normals;
  ChangeFilter filter{0.0};  // blended: the change, Wiener-filtered for the blend's blur
  Samples samples;
};

ShadingFit::ShadingFit(const SensorModel& start, bool blended, ShadingFitOptions options)
    : state_(std::make_unique<State>()) {
  check_sensor_model(start, "ShadingFit: sensor " + start.name);
  State& s = *state_;
  s.start = start;
  s.options = options;
  s.blended = blended;
  s.gain = blended ? float(start.shading.background_gain) : 1.0f;
  if (!(s.gain > 0)) {
    throw InputError("shading.background_gain " + std::to_string(start.shading.background_gain) +
                     ": a blended frame shows none of the shading's change to fit");
  }
  if (start.lights.empty()) throw InputError("lights: the sensor has no light to fit");
  s.rays = make_gel_rays(start.camera, start.gel);
  s.gel_normals = undeformed_gel_normals(s.rays);
  if (blended) s.filter = ChangeFilter(s.rays.blend_blur_px(start.shading));
}

ShadingFit::~ShadingFit() = default;
ShadingFit::ShadingFit(ShadingFit&&) noexcept = default;
ShadingFit& ShadingFit::operator=(ShadingFit&&) noexcept = default;

std::size_t ShadingFit::pixels() const { return state_->samples.size(); }

std::size_t ShadingFit::add_frame(const ImageU8& color, const ImageU8& reference,
                                  const ImageF& normals) {
  State& s = *state_;
  const int w = s.rays.width, h = s.rays.height;
  check_sensor_image("colour frame", color, w, h);
  check_sensor_image("reference image", reference, w, h);
  check_sensor_image("normal image", normals, w, h);
  const float min_cos = float(std::cos(s.options.min_turn_rad));
  Samples& out = s.samples;
  const std::size_t first = out.size();
  std::vector<int> labelled;
  for (int i = 0; i < w * h; ++i) {
    const float* n = &normals.data[3 * std::size_t(i)];
    const float* g = &s.gel_normals.data[3 * std::size_t(i)];
    if (!std::isfinite(n[0]) || !std::isfinite(n[1]) || !std::isfinite(n[2])) continue;
    const float norm = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (!(norm > 0.5f && norm < 1.5f)) continue;  // not a normal: no label there
    if ((n[0] * g[0] + n[1] * g[1] + n[2] * g[2]) / norm > min_cos) continue;
    float seen[3], base[3];
    for (int c = 0; c < 3; ++c) {
      const std::size_t at = 3 * std::size_t(i) + c;
      seen[c] = color.data[at];
      base[c] = s.blended ? reference.data[at] : 0.0f;
    }
    out.push(s.rays.point(i, 0.0f), Eigen::Vector3f(n[0], n[1], n[2]) / norm,
             Eigen::Vector3f(g[0], g[1], g[2]), seen, base);
    labelled.push_back(i);
  }
  // Blended, the frame's change filtered for the blend's blur, as ShadingInversion reads it; a
  // channel the camera clipped keeps its value, which only bounds the model.
  if (s.blended) {
    std::vector<float> change;
    s.filter.change_at(color, reference, labelled, change);
    for (std::size_t j = 0; j < labelled.size(); ++j)
      for (int c = 0; c < 3; ++c) {
        const std::uint8_t v = color.data[3 * std::size_t(labelled[j]) + c];
        const std::size_t at = 3 * (first + j) + c;
        if (v > 0 && v < 255)
          out.seen[at] = std::clamp(out.base[at] + change[3 * j + c], 0.0f, 255.0f);
      }
  }
  return labelled.size();
}

ShadingFitResult ShadingFit::solve(const std::function<void(int, double)>& progress) const {
  const State& s = *state_;
  if (s.samples.size() == 0) {
    throw InputError("no labelled pixel whose normal turns " +
                     std::to_string(s.options.min_turn_rad) +
                     " rad or more from the undeformed gel's: nothing to fit the lights to (give "
                     "presses, with their normals)");
  }
  // Every stride-th pixel, so that at most max_pixels are fitted.
  const std::size_t stride =
      std::max<std::size_t>(1, (s.samples.size() + s.options.max_pixels - 1) /
                                   std::max<std::size_t>(1, s.options.max_pixels));
  Samples fit;
  for (std::size_t i = 0; i < s.samples.size(); i += stride) fit.push(s.samples, i);
  const std::size_t channels = fit.seen.size();
  const std::size_t lights = s.start.lights.size();
  std::vector<double> theta = parameters_of(s.start);
  // The ambient share, last, only where the frames show the shading itself.
  const int np = int(theta.size()) - (s.blended ? 1 : 0);

  std::vector<float> value, scratch, stepped;
  predict(s.start, s.blended, s.gain, fit, value, scratch);
  Cost cost = cost_of(value, fit, s.options.huber_levels);
  ShadingFitResult result;
  result.pixels = fit.size();
  result.channels = channels;
  result.rms_start_levels = std::sqrt(cost.squares / double(channels));

  double lambda = 1e-3;
  std::vector<std::vector<float>> columns(np);
  for (int it = 1; it <= s.options.max_iterations; ++it) {
    // Huber's scale follows the residual down to huber_levels: while the start's lights are far
    // off, most residuals are large, and a small scale would read them all as outliers.
    const double rms = std::sqrt(cost.squares / double(channels));
    const double huber = std::max(s.options.huber_levels, 3.0 * rms);
    cost = cost_of(value, fit, huber);
    // Forward differences of the model's values in each parameter.
    for (int j = 0; j < np; ++j) {
      std::vector<double> t = theta;
      const double h =
          (j < int(kPerLight * lights) && j % kPerLight < 3) ? kPositionStep : kScaleStep;
      t[j] += h;
      predict(sensor_of(s.start, t), s.blended, s.gain, fit, stepped, scratch);
      columns[j].resize(stepped.size());
      for (std::size_t i = 0; i < stepped.size(); ++i)
        columns[j][i] = float((double(stepped[i]) - value[i]) / h);
    }
    // Gauss-Newton's system, each residual weighted as Huber's loss has it at its current value.
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(np, np);
    Eigen::VectorXd g = Eigen::VectorXd::Zero(np);
    std::vector<double> row(np);
    for (std::size_t i = 0; i < value.size(); ++i) {
      const double r = double(value[i]) - fit.seen[i];
      const double w = std::abs(r) <= huber ? 1.0 : huber / std::abs(r);
      for (int a = 0; a < np; ++a) row[a] = columns[a][i];
      for (int a = 0; a < np; ++a) {
        g[a] += w * row[a] * r;
        for (int b = 0; b <= a; ++b) H(a, b) += w * row[a] * row[b];
      }
    }
    H = H.selfadjointView<Eigen::Lower>();
    bool improved = false;
    double decrease = 0;
    while (lambda < 1e10) {
      Eigen::MatrixXd damped = H;
      for (int a = 0; a < np; ++a) damped(a, a) += lambda * H(a, a) + 1e-12;
      const Eigen::VectorXd delta = damped.ldlt().solve(-g);
      std::vector<double> trial = theta;
      for (int a = 0; a < np; ++a) trial[a] += std::isfinite(delta[a]) ? delta[a] : 0.0;
      keep_feasible(trial, s.start);
      predict(sensor_of(s.start, trial), s.blended, s.gain, fit, stepped, scratch);
      const Cost c = cost_of(stepped, fit, huber);
      if (c.robust < cost.robust) {
        decrease = (cost.robust - c.robust) / std::max(cost.robust, 1e-30);
        theta = trial;
        value.swap(stepped);
        cost = c;
        lambda = std::max(lambda / 3.0, 1e-9);
        improved = true;
        break;
      }
      lambda *= 4.0;
    }
    result.iterations = it;
    if (progress) progress(it, std::sqrt(cost.squares / double(channels)));
    if (!improved || decrease < kConvergedDecrease) {
      result.converged = true;
      break;
    }
  }
  result.sensor = sensor_of(s.start, theta);
  result.rms_levels = std::sqrt(cost.squares / double(channels));
  return result;
}

}  // namespace pg
