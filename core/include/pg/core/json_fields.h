#pragma once
// Reading JSON config and scene files with errors that name the file and the field.
//
//   JsonFields f(json, "scene.json: objects[0]");
//   double s = f.optional<double>("scale", 1.0);
//   f.finish();  // any key not read above is an "unknown key" error
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

#include "pg/core/error.h"

namespace pg {

// Bound on every position coordinate read from a file (scenes, sensor configs, poses.csv) [m].
// A tactile scene spans centimetres and a robot's world a few metres; a kilometre leaves room for
// any real setup while keeping the arithmetic on positions (differences, squares, interpolation)
// far from overflow, so a typo like 1e300 is refused up front instead of ending as inf/NaN poses.
constexpr double kMaxPositionM = 1e3;
// A quaternion read from a file (poses.csv) within this of unit length is normalised; beyond, it
// is refused.
constexpr double kUnitQuaternionTolerance = 1e-3;
// Bound on every roll, pitch and yaw read from a file [rad]: 159 turns leave room for any
// multi-turn waypoint; beyond, a typo like 1e300 has no meaningful sine.
constexpr double kMaxAngleRad = 1e3;

// Parses a JSON file. Throws InputError "PATH:LINE:COLUMN: message" on malformed JSON,
// "PATH: message" on a number too large for a double and "PATH: cannot read" for a missing file.
nlohmann::json parse_json_file(const std::string& path);
// Same for text already in memory; `name` stands for the file in messages.
nlohmann::json parse_json_text(const std::string& text, const std::string& name);
// nlohmann's message without its "[json.exception.parse_error.101] " tag (also in the messages
// of libraries that parse with it, e.g. tinygltf).
std::string without_json_tag(const std::string& what);

std::string json_type_name(const nlohmann::json& j);

// The project's kinds of JSON file, told apart by their top-level keys, so that one given where
// another is read is named as what it is rather than by its first unexpected key.
enum class JsonFileKind { kOther, kScene, kSensor, kTrackerConfig, kDataset, kTrackSummary };
JsonFileKind json_file_kind(const nlohmann::json& j);
// Throws InputError "PATH: is a dataset's description (dataset.json), not a scene file" when `j`,
// read from `path`, is a file of a kind other than `wanted` (one of no known kind passes).
void check_json_file_kind(const nlohmann::json& j, const std::string& path, JsonFileKind wanted);

// JSON text as the repository's scene files read: one line per array element or object member,
// indented by two, unless the whole value fits in `width` columns (so a waypoint or a pose is
// one line). Keys keep their order.
std::string format_json(const nlohmann::ordered_json& j, std::size_t width = 120);

// x rounded to a multiple of 1 / per_unit, for a file's numbers: dividing by the exact integer
// per_unit gives the double nearest the decimal, so the file shows it with few digits (+ 0.0
// turns -0 into 0).
inline double round_to(double x, double per_unit) {
  return std::round(x * per_unit) / per_unit + 0.0;
}

class JsonFields {
 public:
  // `where` prefixes every message, e.g. "scenes/a.json: objects[1]". Throws if j is no object.
  JsonFields(const nlohmann::json& j, std::string where);

  bool has(const std::string& key) const;
  // The raw value of a key (which counts as read); throws if it is missing.
  const nlohmann::json& at(const std::string& key);
  // "where.key" (or "where: key" at the top), for messages about a sub-field.
  std::string field(const std::string& key) const;

  template <typename T>
  T required(const std::string& key) {
    return convert<T>(at(key), key);
  }
  template <typename T>
  T optional(const std::string& key, const T& fallback) {
    return has(key) ? required<T>(key) : fallback;
  }
  // A number in [lo, hi]; the error names the key and the range.
  double number_in(const std::string& key, double lo, double hi, double fallback);
  double required_number_in(const std::string& key, double lo, double hi);
  // A position [m]: 3 finite numbers, each within +-kMaxPositionM; the error names the key.
  Eigen::Vector3d position(const std::string& key, const Eigen::Vector3d& fallback);
  Eigen::Vector3d required_position(const std::string& key);
  // Roll, pitch and yaw [rad]: 3 finite numbers, each within +-kMaxAngleRad.
  Eigen::Vector3d rpy(const std::string& key, const Eigen::Vector3d& fallback);
  Eigen::Vector3d required_rpy(const std::string& key);

  // Throws InputError naming the first key that was never read.
  void finish() const;

 private:
  template <typename T>
  T convert(const nlohmann::json& v, const std::string& key) const;
  [[noreturn]] void type_error(const std::string& key, const char* expected,
                               const nlohmann::json& v) const;
  // type_error, with a number that is not whole given as it is ("got 2.5").
  [[noreturn]] void integer_error(const std::string& key, const char* expected,
                                  const nlohmann::json& v) const;
  // The numbers of `v`, an array of `n` numbers; else throws, saying what is wrong.
  Eigen::VectorXd number_array(const std::string& key, const char* expected,
                               const nlohmann::json& v, std::size_t n) const;

  const nlohmann::json& j_;
  std::string where_;
  std::set<std::string> read_;
};

template <>
double JsonFields::convert<double>(const nlohmann::json& v, const std::string& key) const;
template <>
int JsonFields::convert<int>(const nlohmann::json& v, const std::string& key) const;
template <>
bool JsonFields::convert<bool>(const nlohmann::json& v, const std::string& key) const;
template <>
std::string JsonFields::convert<std::string>(const nlohmann::json& v, const std::string& key) const;
template <>
Eigen::Vector3d JsonFields::convert<Eigen::Vector3d>(const nlohmann::json& v,
                                                     const std::string& key) const;
template <>
std::vector<std::string> JsonFields::convert<std::vector<std::string>>(
    const nlohmann::json& v, const std::string& key) const;
// [x, y, z, w], any finite non-zero scale; returned normalised.
template <>
Eigen::Quaterniond JsonFields::convert<Eigen::Quaterniond>(const nlohmann::json& v,
                                                           const std::string& key) const;
template <>
std::uint64_t JsonFields::convert<std::uint64_t>(const nlohmann::json& v,
                                                 const std::string& key) const;

}  // namespace pg
