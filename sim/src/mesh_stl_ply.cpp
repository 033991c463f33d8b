// STL (binary and ASCII) and PLY (ascii, binary little/big endian) readers.
//
// Read here rather than through OpenMesh because OpenMesh 9 silently drops faces with repeated or
// out-of-range indices and garbles every vertex of an ASCII PLY once one coordinate is "nan";
// load_mesh() needs to see such content to count or report it.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>

#include "mesh_formats.h"
#include "pg/core/error.h"

namespace pg::mesh_formats {
namespace {

// ---------------------------------------------------------------------------------------------
// Byte access with explicit endianness, so the readers do not depend on the host's byte order.

std::uint64_t read_uint(std::string_view bytes, size_t pos, int size, bool big_endian) {
  std::uint64_t value = 0;
  for (int k = 0; k < size; ++k) {
    const int byte_index = big_endian ? k : size - 1 - k;
    value = (value << 8) | static_cast<unsigned char>(bytes[pos + static_cast<size_t>(byte_index)]);
  }
  return value;
}

float read_float32(std::string_view bytes, size_t pos, bool big_endian) {
  const auto bits = static_cast<std::uint32_t>(read_uint(bytes, pos, 4, big_endian));
  float value;
  std::memcpy(&value, &bits, sizeof value);
  return value;
}

// STL stores every triangle with its own three corners; weld corners with identical coordinates
// (bitwise, -0 folded into +0) so that a closed STL loads as a closed indexed mesh.
class VertexWelder {
 public:
  explicit VertexWelder(RawMesh& mesh) : mesh_(mesh) {}

  std::int64_t add(Eigen::Vector3d p) {
    p.array() += 0.0;  // -0.0 + 0.0 == +0.0
    const auto next = static_cast<std::int64_t>(mesh_.vertices.size());
    const std::int64_t index = points_.find_or_add(p, next);
    if (index == next) mesh_.vertices.push_back(p);
    return index;
  }

 private:
  RawMesh& mesh_;
  PointIndex<double> points_;
};

RawMesh parse_binary_stl(std::string_view bytes, std::uint64_t num_triangles) {
  RawMesh mesh;
  VertexWelder welder(mesh);
  // Record: normal (3 float32), 3 corners (9 float32), 2-byte attribute count.
  for (std::uint64_t t = 0; t < num_triangles; ++t) {
    const size_t record = 84 + 50 * t;
    std::vector<std::int64_t> corners;
    for (int c = 0; c < 3; ++c) {
      Eigen::Vector3d p;
      for (int a = 0; a < 3; ++a) {
        p[a] = read_float32(bytes, record + 12 + 12 * static_cast<size_t>(c) + 4 * a, false);
      }
      corners.push_back(welder.add(p));
    }
    add_polygon(mesh, corners, 0);
  }
  return mesh;
}

// ASCII STL's keywords, in any case: some exporters write them in capitals (SOLID, VERTEX).
bool keyword_is(std::string_view text, std::string_view keyword) {
  return text.size() == keyword.size() &&
         std::equal(text.begin(), text.end(), keyword.begin(), [](char a, char b) {
           return std::tolower(static_cast<unsigned char>(a)) == b;
         });
}

// facet normal nx ny nz / outer loop / vertex x y z (x3) / endloop / endfacet; only the vertex
// lines matter (the normals are implied by the winding).
RawMesh parse_ascii_stl(std::string_view text) {
  RawMesh mesh;
  VertexWelder welder(mesh);
  TokenStream tokens(text);
  Token token;
  std::vector<std::int64_t> loop;
  while (tokens.next(token)) {
    if (keyword_is(token.text, "vertex")) {
      Token xyz[3];
      if (!tokens.next(xyz[0]) || !tokens.next(xyz[1]) || !tokens.next(xyz[2])) {
        throw FormatError("line " + std::to_string(token.line) + ": vertex needs 3 coordinates");
      }
      loop.push_back(welder.add({parse_double(xyz[0], "vertex x"), parse_double(xyz[1], "vertex y"),
                                 parse_double(xyz[2], "vertex z")}));
    } else if (keyword_is(token.text, "endloop")) {
      if (loop.size() < 3) {
        throw FormatError("line " + std::to_string(token.line) +
                          ": facet loop has fewer than 3 vertices");
      }
      add_polygon(mesh, loop, token.line);
      loop.clear();
    }
  }
  if (!loop.empty()) throw FormatError("the last facet's loop has no 'endloop'");
  return mesh;
}

// ---------------------------------------------------------------------------------------------
// PLY

enum class PlyType { kInt8, kUInt8, kInt16, kUInt16, kInt32, kUInt32, kFloat32, kFloat64 };

struct PlyProperty {
  std::string name;
  PlyType type = PlyType::kFloat32;
  bool is_list = false;
  PlyType count_type = PlyType::kUInt8;  // lists only
};

struct PlyElement {
  std::string name;
  std::int64_t count = 0;
  std::vector<PlyProperty> properties;
};

PlyType ply_type(const Token& token) {
  static const std::pair<const char*, PlyType> kNames[] = {
      {"char", PlyType::kInt8},      {"int8", PlyType::kInt8},       {"uchar", PlyType::kUInt8},
      {"uint8", PlyType::kUInt8},    {"short", PlyType::kInt16},     {"int16", PlyType::kInt16},
      {"ushort", PlyType::kUInt16},  {"uint16", PlyType::kUInt16},   {"int", PlyType::kInt32},
      {"int32", PlyType::kInt32},    {"uint", PlyType::kUInt32},     {"uint32", PlyType::kUInt32},
      {"float", PlyType::kFloat32},  {"float32", PlyType::kFloat32}, {"double", PlyType::kFloat64},
      {"float64", PlyType::kFloat64}};
  for (const auto& [name, type] : kNames) {
    if (token.text == name) return type;
  }
  throw FormatError("line " + std::to_string(token.line) + ": unknown PLY type '" +
                    excerpt(token.text) + "'");
}

// Reads the body's values one at a time, whatever the encoding.
class PlyValueReader {
 public:
  // `lines_before_body` shifts ASCII line numbers so messages count lines from the file's start.
  PlyValueReader(std::string_view body, const std::string& format, int lines_before_body)
      : body_(body), tokens_(body, lines_before_body + 1) {
    if (format == "ascii") {
      ascii_ = true;
    } else if (format == "binary_little_endian" || format == "binary_big_endian") {
      big_endian_ = format == "binary_big_endian";
    } else {
      throw FormatError("unknown PLY format '" + excerpt(format) + "'");
    }
  }

  void set_context(const std::string& element) { element_ = element; }

  double read(PlyType type) {
    if (ascii_) {
      Token token;
      if (!tokens_.next(token)) throw end_of_data();
      return parse_double(token, "a PLY value");
    }
    static constexpr int kSizes[] = {1, 1, 2, 2, 4, 4, 4, 8};
    const int size = kSizes[static_cast<int>(type)];
    if (pos_ + static_cast<size_t>(size) > body_.size()) throw end_of_data();
    const std::uint64_t bits = read_uint(body_, pos_, size, big_endian_);
    pos_ += static_cast<size_t>(size);
    switch (type) {
      case PlyType::kInt8:
        return static_cast<std::int8_t>(bits);
      case PlyType::kInt16:
        return static_cast<std::int16_t>(bits);
      case PlyType::kInt32:
        return static_cast<std::int32_t>(bits);
      case PlyType::kFloat32: {
        const auto bits32 = static_cast<std::uint32_t>(bits);
        float value;
        std::memcpy(&value, &bits32, sizeof value);
        return value;
      }
      case PlyType::kFloat64: {
        double value;
        std::memcpy(&value, &bits, sizeof value);
        return value;
      }
      default:
        return static_cast<double>(bits);  // unsigned types
    }
  }

  std::int64_t read_integer(PlyType type, const char* what) {
    const double value = read(type);
    if (!(std::abs(value) < 9e15) || value != std::floor(value)) {
      throw FormatError("element '" + excerpt(element_) + "': " + what + " is not an integer");
    }
    return static_cast<std::int64_t>(value);
  }

 private:
  FormatError end_of_data() const {
    return FormatError("the data ends early, inside element '" + excerpt(element_) + "'");
  }

  std::string_view body_;
  bool ascii_ = false;
  bool big_endian_ = false;
  TokenStream tokens_;  // ascii only
  size_t pos_ = 0;
  std::string element_;
};

}  // namespace

RawMesh parse_stl(std::string_view bytes) {
  if (bytes.size() >= 84) {
    const std::uint64_t num_triangles = read_uint(bytes, 80, 4, false);
    if (84 + 50 * num_triangles == bytes.size()) return parse_binary_stl(bytes, num_triangles);
  }
  const size_t first = bytes.find_first_not_of(" \t\r\n");
  if (first != std::string_view::npos && keyword_is(bytes.substr(first, 5), "solid")) {
    return parse_ascii_stl(bytes);
  }
  throw FormatError("neither binary STL (the size " + std::to_string(bytes.size()) +
                    " bytes does not match 84 + 50 x the triangle count in the header) nor ASCII "
                    "STL (no leading 'solid')");
}

RawMesh parse_ply(std::string_view bytes) {
  const size_t header_end = bytes.find("end_header");
  const size_t body_begin = bytes.find('\n', header_end);
  if (bytes.substr(0, 3) != "ply" || header_end == std::string_view::npos ||
      body_begin == std::string_view::npos) {
    throw FormatError("not a PLY file (expected 'ply' ... 'end_header')");
  }
  std::string format;
  std::vector<PlyElement> elements;
  LineTokenizer header(bytes.substr(0, header_end), '\0');
  std::vector<Token> tokens;
  while (header.next(tokens)) {
    const std::string_view keyword = tokens[0].text;
    const std::string where = "line " + std::to_string(tokens[0].line) + ": ";
    if (keyword == "format" && tokens.size() >= 2) {
      format = tokens[1].text;
    } else if (keyword == "element" && tokens.size() >= 3) {
      elements.push_back({std::string(tokens[1].text), parse_int(tokens[2], "element count"), {}});
      if (elements.back().count < 0) throw FormatError(where + "negative element count");
    } else if (keyword == "property" && tokens.size() >= 3) {
      if (elements.empty()) throw FormatError(where + "property before any element");
      PlyProperty property;
      if (tokens[1].text == "list" && tokens.size() >= 5) {
        property = {std::string(tokens[4].text), ply_type(tokens[3]), true, ply_type(tokens[2])};
      } else {
        property = {std::string(tokens[2].text), ply_type(tokens[1]), false, PlyType::kUInt8};
      }
      elements.back().properties.push_back(property);
    } else if (keyword != "ply" && keyword != "comment" && keyword != "obj_info") {
      throw FormatError(where + "unexpected PLY header line starting with '" + excerpt(keyword) +
                        "'");
    }
  }

  const auto header_lines = static_cast<int>(
      std::count(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(body_begin) + 1, '\n'));
  PlyValueReader reader(bytes.substr(body_begin + 1), format, header_lines);
  RawMesh mesh;
  bool has_vertices = false;
  std::vector<std::int64_t> polygon;
  for (const PlyElement& element : elements) {
    reader.set_context(element.name);
    const bool is_vertex = element.name == "vertex";
    const bool is_face = element.name == "face";
    int xyz[3] = {-1, -1, -1};
    for (size_t p = 0; p < element.properties.size(); ++p) {
      const PlyProperty& property = element.properties[p];
      for (int a = 0; a < 3; ++a) {
        if (is_vertex && !property.is_list && property.name == std::string(1, char('x' + a))) {
          xyz[a] = static_cast<int>(p);
        }
      }
    }
    if (is_vertex) {
      if (xyz[0] < 0 || xyz[1] < 0 || xyz[2] < 0) {
        throw FormatError("element 'vertex' lacks one of the scalar properties x, y, z");
      }
      has_vertices = true;
    }
    for (std::int64_t i = 0; i < element.count; ++i) {
      Eigen::Vector3d p = Eigen::Vector3d::Zero();
      for (size_t k = 0; k < element.properties.size(); ++k) {
        const PlyProperty& property = element.properties[k];
        if (!property.is_list) {
          const double value = reader.read(property.type);
          for (int a = 0; a < 3; ++a) {
            if (is_vertex && xyz[a] == static_cast<int>(k)) p[a] = value;
          }
          continue;
        }
        const std::int64_t n = reader.read_integer(property.count_type, "a list length");
        const bool is_indices =
            is_face && (property.name == "vertex_indices" || property.name == "vertex_index");
        if (n < 0) {
          throw FormatError("element '" + excerpt(element.name) + "': negative list length");
        }
        polygon.clear();
        for (std::int64_t j = 0; j < n; ++j) {
          if (is_indices) {
            polygon.push_back(reader.read_integer(property.type, "a vertex index"));
          } else {
            reader.read(property.type);
          }
        }
        if (is_indices && n < 3) {
          throw FormatError("face " + std::to_string(i) + " has " + std::to_string(n) +
                            " vertices; expected at least 3");
        }
        if (is_indices) add_polygon(mesh, polygon, 0);
      }
      if (is_vertex) mesh.vertices.push_back(p);
    }
  }
  if (!has_vertices) throw FormatError("no 'vertex' element");
  return mesh;
}

}  // namespace pg::mesh_formats
