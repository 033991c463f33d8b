#include "pg/core/json_fields.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <set>
#include <sstream>

#include "pg/core/file_io.h"
#include "pg/core/se3.h"

namespace pg {

namespace {

// nlohmann reports the byte offset just past the error; turn it into a 1-based line and column.
void line_and_column(const std::string& text, std::size_t byte, int& line, int& column) {
  line = 1;
  column = 1;
  const std::size_t end = std::min(byte == 0 ? 0 : byte - 1, text.size());
  for (std::size_t i = 0; i < end; ++i) {
    if (text[i] == '\n') {
      ++line;
      column = 1;
    } else {
      ++column;
    }
  }
}

}  // namespace

nlohmann::json parse_json_text(const std::string& text, const std::string& name) {
  // A key given twice in one object: nlohmann keeps the last without a word, so a scene's second
  // "frames" would silently win over its first. Named by its path (objects[1].trajectory...),
  // as the fields' own errors are.
  struct Level {
    bool array = false;
    std::string key;  // an object's key being read
    int index = 0;    // an array's element being read
    std::set<std::string> keys;
  };
  std::vector<Level> levels;  // the objects and arrays being parsed, innermost last
  std::string duplicate;      // its path
  const auto path_to = [&](const std::string& key) {
    std::string p;
    for (std::size_t i = 0; i + 1 < levels.size(); ++i) {
      p += levels[i].array ? "[" + std::to_string(levels[i].index) + "]"
                           : (p.empty() ? "" : ".") + levels[i].key;
    }
    return p + (p.empty() ? "" : ".") + key;
  };
  const nlohmann::json::parser_callback_t check_keys = [&](int, nlohmann::json::parse_event_t event,
                                                           nlohmann::json& parsed) {
    using Event = nlohmann::json::parse_event_t;
    if (event == Event::object_start || event == Event::array_start) {
      levels.emplace_back();
      levels.back().array = event == Event::array_start;
    } else if (event == Event::object_end || event == Event::array_end) {
      if (!levels.empty()) levels.pop_back();
      if (!levels.empty() && levels.back().array) ++levels.back().index;
    } else if (event == Event::value) {
      if (!levels.empty() && levels.back().array) ++levels.back().index;
    } else if (event == Event::key && !levels.empty()) {
      const std::string key = parsed.get<std::string>();
      levels.back().key = key;
      if (!levels.back().keys.insert(key).second && duplicate.empty()) duplicate = path_to(key);
    }
    return true;
  };
  try {
    nlohmann::json j = nlohmann::json::parse(text, check_keys);
    if (!duplicate.empty()) {
      throw InputError(name + ": " + duplicate +
                       ": given twice in one object (only one value can hold)");
    }
    return j;
  } catch (const nlohmann::json::parse_error& e) {
    int line = 0, column = 0;
    line_and_column(text, e.byte, line, column);
    std::string what = e.what();
    // Drop nlohmann's own "[json.exception.parse_error.101] parse error at line 1, column 2: ".
    const auto colon = what.find(": ", what.find("parse error"));
    if (colon != std::string::npos) what = what.substr(colon + 2);
    throw InputError(name + ":" + std::to_string(line) + ":" + std::to_string(column) +
                     ": malformed JSON: " + what);
  } catch (const nlohmann::json::exception& e) {
    // Not a syntax error but, e.g., "number overflow parsing '1e400'" (out_of_range.406): a
    // number beyond the range of a double, which nlohmann reports without the file or position.
    throw InputError(name + ": malformed JSON: " + excerpt(without_json_tag(e.what()), 80));
  }
}

std::string without_json_tag(const std::string& what) {
  const auto tag_end = what.find("] ");
  return what.rfind("[json.exception.", 0) == 0 && tag_end != std::string::npos
             ? what.substr(tag_end + 2)
             : what;
}

nlohmann::json parse_json_file(const std::string& path) {
  require_regular_file(path, "a JSON file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot read the file (missing or not readable)");
  std::stringstream buffer;
  buffer << in.rdbuf();
  return parse_json_text(buffer.str(), path);
}

std::string json_type_name(const nlohmann::json& j) {
  if (j.is_number()) return "a number";
  if (j.is_string()) return "a string";
  if (j.is_boolean()) return "a boolean";
  if (j.is_array()) return "an array";
  if (j.is_object()) return "an object";
  if (j.is_null()) return "null";
  return j.type_name();
}

JsonFields::JsonFields(const nlohmann::json& j, std::string where)
    : j_(j), where_(std::move(where)) {
  if (!j_.is_object()) {
    throw InputError(where_ + ": expected an object, got " + json_type_name(j_));
  }
}

bool JsonFields::has(const std::string& key) const { return j_.contains(key); }

std::string JsonFields::field(const std::string& key) const {
  // "file.json: a.b" style: the first level after the file name follows ": ".
  const bool at_top = where_.find(": ") == std::string::npos;
  return where_ + (at_top ? ": " : ".") + key;
}

const nlohmann::json& JsonFields::at(const std::string& key) {
  if (!has(key)) throw InputError(field(key) + ": missing required field");
  read_.insert(key);
  return j_.at(key);
}

void JsonFields::type_error(const std::string& key, const char* expected,
                            const nlohmann::json& v) const {
  throw InputError(field(key) + ": expected " + expected + ", got " + json_type_name(v));
}

Eigen::VectorXd JsonFields::number_array(const std::string& key, const char* expected,
                                         const nlohmann::json& v, std::size_t n) const {
  if (!v.is_array()) type_error(key, expected, v);
  if (v.size() != n) {
    throw InputError(field(key) + ": expected " + expected + ", got " + std::to_string(v.size()) +
                     (v.size() == 1 ? " element" : " elements"));
  }
  Eigen::VectorXd out(n);
  for (std::size_t i = 0; i < n; ++i) {
    if (!v[i].is_number()) {
      throw InputError(field(key) + ": expected " + expected + ", element " + std::to_string(i) +
                       " is " + json_type_name(v[i]));
    }
    out[Eigen::Index(i)] = v[i].get<double>();
  }
  return out;
}

template <>
double JsonFields::convert<double>(const nlohmann::json& v, const std::string& key) const {
  if (!v.is_number()) type_error(key, "a number", v);
  const double d = v.get<double>();
  if (!std::isfinite(d)) throw InputError(field(key) + ": expected a finite number");
  return d;
}

namespace {

// A whole number written with a fraction (4.0, as a generator that carries numbers as floats
// writes it) is that integer; up to 2^53, where doubles hold every integer.
bool whole_number(const nlohmann::json& v, long long& out) {
  if (v.is_number_unsigned()) {  // beyond a long long it had wrapped: 2^64 - 1 read as -1
    const std::uint64_t u = v.get<std::uint64_t>();
    out = u > std::uint64_t(LLONG_MAX) ? LLONG_MAX : static_cast<long long>(u);
    return true;
  }
  if (v.is_number_integer()) {
    out = v.get<long long>();
    return true;
  }
  if (!v.is_number_float()) return false;
  const double d = v.get<double>();
  if (!(std::abs(d) <= 9007199254740992.0) || d != std::floor(d)) return false;
  out = static_cast<long long>(d);
  return true;
}

// A whole number written with a fraction or an exponent, at any size (1e20).
bool whole_float(const nlohmann::json& v) {
  if (!v.is_number_float()) return false;
  const double d = v.get<double>();
  return std::isfinite(d) && d == std::floor(d);
}

}  // namespace

JsonFileKind json_file_kind(const nlohmann::json& j) {
  if (!j.is_object()) return JsonFileKind::kOther;
  const auto has = [&](const char* key) { return j.contains(key); };
  const auto format = j.find("format");
  if (format != j.end() && *format == "patchgraph-dataset") return JsonFileKind::kDataset;
  if (has("method") && has("translation_rmse_m")) return JsonFileKind::kTrackSummary;
  if (has("objects") || (has("sensors") && j.at("sensors").is_array())) return JsonFileKind::kScene;
  if (has("camera") || has("gel") || has("lights") || has("shading") || has("preset")) {
    return JsonFileKind::kSensor;
  }
  bool config = !j.empty();
  for (const auto& item : j.items()) {
    config = config && (item.key() == "depth" || item.key() == "mask" || item.key() == "icp");
  }
  if (config) return JsonFileKind::kTrackerConfig;
  return JsonFileKind::kOther;
}

namespace {

const char* describe(JsonFileKind kind) {
  switch (kind) {
    case JsonFileKind::kScene:
      return "a scene file";
    case JsonFileKind::kSensor:
      return "a sensor file";
    case JsonFileKind::kTrackerConfig:
      return "a tracker config (--config)";
    case JsonFileKind::kDataset:
      return "a dataset's description (dataset.json)";
    case JsonFileKind::kTrackSummary:
      return "a track run's summary.json";
    case JsonFileKind::kOther:
      break;
  }
  return "a JSON file of another kind";
}

}  // namespace

void check_json_file_kind(const nlohmann::json& j, const std::string& path, JsonFileKind wanted) {
  const JsonFileKind kind = json_file_kind(j);
  if (kind == JsonFileKind::kOther || kind == wanted) return;
  throw InputError(path + ": is " + describe(kind) + ", not " + describe(wanted));
}

void JsonFields::integer_error(const std::string& key, const char* expected,
                               const nlohmann::json& v) const {
  if (v.is_number()) {
    throw InputError(field(key) + ": expected " + expected + ", got " + v.dump());
  }
  type_error(key, expected, v);
}

template <>
int JsonFields::convert<int>(const nlohmann::json& v, const std::string& key) const {
  long long i = 0;
  if (!whole_number(v, i)) {
    if (!whole_float(v)) integer_error(key, "an integer", v);
    i = LLONG_MAX;  // beyond 2^53, so beyond an int
  }
  if (i < -2147483647LL || i > 2147483647LL) {
    throw InputError(field(key) + ": integer out of range (-2147483647 to 2147483647), got " +
                     v.dump());
  }
  return static_cast<int>(i);
}

template <>
std::uint64_t JsonFields::convert<std::uint64_t>(const nlohmann::json& v,
                                                 const std::string& key) const {
  if (v.is_number_unsigned()) return v.get<std::uint64_t>();
  long long i = 0;
  const bool whole = whole_number(v, i);
  if (!whole && whole_float(v) && v.get<double>() >= 18446744073709551616.0) {  // 2^64
    throw InputError(field(key) + ": integer out of range (0 to 18446744073709551615), got " +
                     v.dump());
  }
  if (!whole && whole_float(v) && v.get<double>() > 0) {
    throw InputError(field(key) + ": got " + v.dump() +
                     "; beyond 2^53 a number written with a fraction or an exponent does not "
                     "hold every integer: write its digits");
  }
  if (!whole || i < 0) integer_error(key, "a non-negative integer", v);
  return static_cast<std::uint64_t>(i);
}

template <>
bool JsonFields::convert<bool>(const nlohmann::json& v, const std::string& key) const {
  if (!v.is_boolean()) type_error(key, "true or false", v);
  return v.get<bool>();
}

template <>
std::string JsonFields::convert<std::string>(const nlohmann::json& v,
                                             const std::string& key) const {
  if (!v.is_string()) type_error(key, "a string", v);
  return v.get<std::string>();
}

template <>
Eigen::Vector3d JsonFields::convert<Eigen::Vector3d>(const nlohmann::json& v,
                                                     const std::string& key) const {
  const Eigen::Vector3d out = number_array(key, "an array of 3 numbers", v, 3);
  if (!out.allFinite()) throw InputError(field(key) + ": expected finite numbers");
  return out;
}

template <>
Eigen::Quaterniond JsonFields::convert<Eigen::Quaterniond>(const nlohmann::json& v,
                                                           const std::string& key) const {
  const Eigen::Vector4d xyzw = number_array(key, "an array of 4 numbers [x, y, z, w]", v, 4);
  Eigen::Quaterniond q;
  if (!unit_quaternion(xyzw, q)) throw InputError(field(key) + ": must be finite and non-zero");
  return q;
}

template <>
std::vector<std::string> JsonFields::convert<std::vector<std::string>>(
    const nlohmann::json& v, const std::string& key) const {
  if (!v.is_array()) type_error(key, "an array of strings", v);
  std::vector<std::string> out;
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (!v[i].is_string()) {
      throw InputError(field(key) + ": expected an array of strings, element " + std::to_string(i) +
                       " is " + json_type_name(v[i]));
    }
    out.push_back(v[i].get<std::string>());
  }
  return out;
}

double JsonFields::required_number_in(const std::string& key, double lo, double hi) {
  const double d = required<double>(key);
  if (d < lo || d > hi) {
    std::ostringstream msg;
    msg << field(key) << ": value " << d << " is out of range [" << lo << ", " << hi << "]";
    throw InputError(msg.str());
  }
  return d;
}

double JsonFields::number_in(const std::string& key, double lo, double hi, double fallback) {
  return has(key) ? required_number_in(key, lo, hi) : fallback;
}

namespace {

// `v` (the field `where`) unless a component lies beyond +-bound: "each <what> must be within".
Eigen::Vector3d within(const Eigen::Vector3d& v, double bound, const std::string& where,
                       const char* what, const char* unit) {
  if (v.cwiseAbs().maxCoeff() > bound) {
    std::ostringstream msg;
    msg << where << ": [" << v.x() << ", " << v.y() << ", " << v.z() << "] is out of range: each "
        << what << " must be within +-" << bound << " " << unit;
    throw InputError(msg.str());
  }
  return v;
}

}  // namespace

Eigen::Vector3d JsonFields::required_position(const std::string& key) {
  return within(required<Eigen::Vector3d>(key), kMaxPositionM, field(key), "coordinate", "m");
}

Eigen::Vector3d JsonFields::position(const std::string& key, const Eigen::Vector3d& fallback) {
  return has(key) ? required_position(key) : fallback;
}

Eigen::Vector3d JsonFields::required_rpy(const std::string& key) {
  return within(required<Eigen::Vector3d>(key), kMaxAngleRad, field(key), "angle", "rad");
}

Eigen::Vector3d JsonFields::rpy(const std::string& key, const Eigen::Vector3d& fallback) {
  return has(key) ? required_rpy(key) : fallback;
}

void JsonFields::finish() const {
  for (const auto& item : j_.items()) {
    if (!read_.count(item.key())) throw InputError(field(item.key()) + ": unknown key");
  }
}

namespace {

void format_json(std::ostream& out, const nlohmann::ordered_json& j, std::size_t indent,
                 std::size_t width) {
  using nlohmann::ordered_json;
  std::function<std::string(const ordered_json&)> inline_form = [&](const ordered_json& v) {
    if (!v.is_structured()) return v.dump();
    std::string s = v.is_array() ? "[" : "{";
    bool first = true;
    for (auto it = v.begin(); it != v.end(); ++it, first = false) {
      if (!first) s += ", ";
      if (v.is_object()) s += ordered_json(it.key()).dump() + ": ";
      s += inline_form(*it);
    }
    return s + (v.is_array() ? "]" : "}");
  };
  const std::string flat = inline_form(j);
  if (!j.is_structured() || j.empty() || indent + flat.size() <= width) {
    out << flat;
    return;
  }
  out << (j.is_array() ? "[\n" : "{\n");
  bool first = true;
  for (auto it = j.begin(); it != j.end(); ++it, first = false) {
    if (!first) out << ",\n";
    out << std::string(indent + 2, ' ');
    if (j.is_object()) out << ordered_json(it.key()).dump() << ": ";
    format_json(out, *it, indent + 2, width);
  }
  out << "\n" << std::string(indent, ' ') << (j.is_array() ? "]" : "}");
}

}  // namespace

std::string format_json(const nlohmann::ordered_json& j, std::size_t width) {
  std::ostringstream out;
  format_json(out, j, 0, width);
  return out.str();
}

}  // namespace pg
