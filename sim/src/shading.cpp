#include "shading.h"

#include <algorithm>
#include <cmath>

#include "pg/core/random.h"

#if defined(__AVX2__) || defined(__AVX512BW__)
#include <immintrin.h>
#endif

namespace pg {

std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

Shader make_shader(const SensorModel& sensor) {
  Shader s;
  s.model = sensor.shading;
  s.camera = Eigen::Vector3f(0, 0, float(-sensor.camera.distance_m));
  for (const auto& l : sensor.lights) {
    ShadingLight sl;
    sl.position = l.position_m.cast<float>();
    sl.color = (l.color * l.intensity * sensor.shading.exposure).cast<float>();
    sl.d0_sq = std::max(1e-12f, sl.position.squaredNorm());
    s.lights.push_back(sl);
  }
  return s;
}

namespace {

// The vector loops of shade_span, as functions of restrict-qualified arrays so that the compiler
// vectorises them without run-time alias checks.

// Unit vectors from the points p to the camera c.
void view_directions(int n, const float* __restrict px, const float* __restrict py,
                     const float* __restrict pz, const Eigen::Vector3f& c, float* __restrict vx,
                     float* __restrict vy, float* __restrict vz) {
  const float cx = c.x(), cy = c.y(), cz = c.z();
  for (int i = 0; i < n; ++i) {
    const float x = cx - px[i], y = cy - py[i], z = cz - pz[i];
    const float inv = 1.0f / std::sqrt(x * x + y * y + z * z);
    vx[i] = x * inv;
    vy[i] = y * inv;
    vz[i] = z * inv;
  }
}

// One light at points p with outward normals n, seen along v: the Lambert term, the Blinn-Phong
// base (n.h, zero where the light is behind the surface) and the fall-off (d0 / d)^2.
void light_terms(int n, const ShadeSpan& in, const float* __restrict vx, const float* __restrict vy,
                 const float* __restrict vz, const ShadingLight& light, float* __restrict lambert,
                 float* __restrict base, float* __restrict falloff) {
  const float* __restrict px = in.px;
  const float* __restrict py = in.py;
  const float* __restrict pz = in.pz;
  const float* __restrict nx = in.nx;
  const float* __restrict ny = in.ny;
  const float* __restrict nz = in.nz;
  const float lx0 = light.position.x(), ly0 = light.position.y(), lz0 = light.position.z();
  const float d0_sq = light.d0_sq;
  for (int i = 0; i < n; ++i) {
    float lx = lx0 - px[i], ly = ly0 - py[i], lz = lz0 - pz[i];
    const float d_sq = lx * lx + ly * ly + lz * lz;
    const float inv = 1.0f / std::sqrt(d_sq);
    lx *= inv;
    ly *= inv;
    lz *= inv;
    // The coating faces the camera: its normal is -n.
    const float ndotl = -(nx[i] * lx + ny[i] * ly + nz[i] * lz);
    const float hx = lx + vx[i], hy = ly + vy[i], hz = lz + vz[i];
    const float ndoth =
        -(nx[i] * hx + ny[i] * hy + nz[i] * hz) / std::sqrt(hx * hx + hy * hy + hz * hz);
    lambert[i] = std::max(0.0f, ndotl);
    base[i] = ndotl > 0.0f ? std::max(0.0f, ndoth) : 0.0f;
    falloff[i] = d0_sq / d_sq;
  }
}

// base^e by binary powering, each step a vector loop; base is overwritten.
void power(int n, int e, float* __restrict base, float* __restrict out) {
  for (int i = 0; i < n; ++i) out[i] = 1.0f;
  for (; e > 0; e >>= 1) {
    if (e & 1) {
      for (int i = 0; i < n; ++i) out[i] *= base[i];
    }
    for (int i = 0; i < n; ++i) base[i] *= base[i];
  }
}

// acc += colour * (ambient + visibility * (diffuse * lambert + specular * spec)) * fall-off.
void accumulate(int n, const ShadingModel& m, const Eigen::Vector3f& color,
                const float* __restrict visibility, const float* __restrict lambert,
                const float* __restrict spec, const float* __restrict falloff,
                float* __restrict acc_r, float* __restrict acc_g, float* __restrict acc_b) {
  const float ambient = float(m.ambient), diffuse = float(m.diffuse), specular = float(m.specular);
  const float r = color.x(), g = color.y(), b = color.z();
  for (int i = 0; i < n; ++i) {
    const float v = visibility ? visibility[i] : 1.0f;
    const float w = (ambient + v * (diffuse * lambert[i] + specular * spec[i])) * falloff[i];
    acc_r[i] += r * w;
    acc_g[i] += g * w;
    acc_b[i] += b * w;
  }
}

void interleave(int n, const float* __restrict r, const float* __restrict g,
                const float* __restrict b, float* __restrict rgb) {
  for (int i = 0; i < n; ++i) {
    rgb[3 * i] = r[i];
    rgb[3 * i + 1] = g[i];
    rgb[3 * i + 2] = b[i];
  }
}

}  // namespace

void shade_span(const Shader& shader, const ShadeSpan& in, float* rgb) {
  const int n = in.count;
  thread_local std::vector<float> buf;
  buf.assign(std::size_t(n) * 10, 0.0f);
  float* vx = buf.data();
  float *vy = vx + n, *vz = vy + n, *acc_r = vz + n, *acc_g = acc_r + n, *acc_b = acc_g + n;
  float *lambert = acc_b + n, *base = lambert + n, *falloff = base + n, *spec = falloff + n;
  view_directions(n, in.px, in.py, in.pz, shader.camera, vx, vy, vz);
  for (std::size_t k = 0; k < shader.lights.size(); ++k) {
    light_terms(n, in, vx, vy, vz, shader.lights[k], lambert, base, falloff);
    power(n, shader.model.shininess, base, spec);
    const float* vis = in.visibility ? in.visibility + std::size_t(k) * n : nullptr;
    accumulate(n, shader.model, shader.lights[k].color, vis, lambert, spec, falloff, acc_r, acc_g,
               acc_b);
  }
  interleave(n, acc_r, acc_g, acc_b, rgb);
}

namespace {

// Unit normal samples, the same on every platform: Box-Muller on a fixed splitmix64 stream.
const std::vector<float>& unit_normal_samples() {
  static const std::vector<float> samples = [] {
    std::vector<float> s(std::size_t(1) << 20);
    std::uint64_t state = 0x5eed;
    auto uniform = [&] { return open_unit(state = splitmix64(state)); };
    for (std::size_t i = 0; i < s.size(); i += 2) {
      const double u1 = uniform(), u2 = uniform();
      const auto [a, b] = box_muller(u1, u2);
      s[i] = float(a);
      s[i + 1] = float(b);
    }
    return s;
  }();
  return samples;
}

}  // namespace

NoiseTable::NoiseTable(float sigma) {
  const std::vector<float>& unit = unit_normal_samples();
  float largest = 0.0f;
  for (float v : unit) largest = std::max(largest, std::abs(v));
  // As many fractional bits as 16 bits hold for the values (up to 255) and the largest sample
  // (127 steps); the step odd, so that value + noise takes every fraction of a level alike.
  auto step_for = [&](int bits) {
    return int(std::ceil(sigma * largest * float(1 << bits) / 127.0f)) | 1;
  };
  bits_ = 7;
  while (bits_ > 0 && 127 * step_for(bits_) > 32767) --bits_;
  step_ = step_for(bits_);
  const float scale = sigma * float(1 << bits_) / float(step_);
  samples_.resize(unit.size());
  for (std::size_t i = 0; i < unit.size(); ++i) {
    samples_[i] = std::int8_t(std::clamp(std::lround(scale * unit[i]), -127l, 127l));
  }
}

namespace {

// out = clamp((value + sample * step + half) >> bits, 0, 255): floor, so it rounds to nearest.
// value + half and sample * step fit 16 bits (NoiseTable's constructor chose bits and step so),
// and a sum beyond them clamps to the same end as a 16-bit saturating add does: the vector loops
// add with saturation in 16-bit lanes and give exactly the scalar loop's result.
void add_noise(const std::int16_t* __restrict in, const std::int8_t* __restrict noise,
               std::uint8_t* __restrict out, std::size_t n, int step, int bits) {
  const int half = (1 << bits) >> 1;
  std::size_t k = 0;
#if defined(__AVX512BW__)
  const __m512i v_half = _mm512_set1_epi16(std::int16_t(half));
  const __m512i v_step = _mm512_set1_epi16(std::int16_t(step));
  const __m128i shift = _mm_cvtsi32_si128(bits);
  const __m512i zero = _mm512_setzero_si512();
  for (; k + 32 <= n; k += 32) {
    const __m512i v = _mm512_add_epi16(_mm512_loadu_si512(in + k), v_half);
    const __m256i s8 = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(noise + k));
    const __m512i s = _mm512_mullo_epi16(_mm512_cvtepi8_epi16(s8), v_step);
    const __m512i sum = _mm512_max_epi16(_mm512_sra_epi16(_mm512_adds_epi16(v, s), shift), zero);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out + k), _mm512_cvtusepi16_epi8(sum));
  }
#elif defined(__AVX2__)
  const __m256i v_half = _mm256_set1_epi16(std::int16_t(half));
  const __m256i v_step = _mm256_set1_epi16(std::int16_t(step));
  const __m128i shift = _mm_cvtsi32_si128(bits);
  for (; k + 16 <= n; k += 16) {
    const __m256i v =
        _mm256_add_epi16(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(in + k)), v_half);
    const __m128i s8 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(noise + k));
    const __m256i s = _mm256_mullo_epi16(_mm256_cvtepi8_epi16(s8), v_step);
    const __m256i sum = _mm256_sra_epi16(_mm256_adds_epi16(v, s), shift);
    // Pack with unsigned saturation (within 128-bit lanes), then gather the two lanes' halves.
    const __m256i packed = _mm256_permute4x64_epi64(_mm256_packus_epi16(sum, sum), 0x08);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + k), _mm256_castsi256_si128(packed));
  }
#endif
  for (; k < n; ++k) {
    const int v = (int(in[k]) + int(noise[k]) * step + half) >> bits;
    out[k] = std::uint8_t(std::clamp(v, 0, 255));
  }
}

}  // namespace

void NoiseTable::apply(const std::int16_t* values, std::uint8_t* out, std::size_t n,
                       std::uint64_t seed, std::size_t position) const {
  // Sequential reads from a seeded offset: frames see shifted copies of one long stream, so a
  // pixel's noise is independent from frame to frame, and the reads stay cache-friendly. A frame
  // of more values than the table (above 349 525 RGB pixels) reads each further table's length
  // from another seeded offset: wrapping around had repeated the noise within the frame.
  const std::size_t size = samples_.size();
  for (std::size_t i = 0; i < n;) {
    const std::size_t at = position + i, lap = at / size;
    const std::uint64_t start = lap == 0 ? splitmix64(seed) : splitmix64(splitmix64(seed) + lap);
    const std::size_t offset = (std::size_t(start) + at) & (size - 1);
    const std::size_t run = std::min({n - i, size - offset, (lap + 1) * size - at});
    add_noise(values + i, samples_.data() + offset, out + i, run, step_, bits_);
    i += run;
  }
}

}  // namespace pg
