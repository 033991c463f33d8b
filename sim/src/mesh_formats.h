#pragma once
// Private to pg_sim: the per-format mesh readers. Each reader returns the file's content as a
// RawMesh, unvalidated (indices may be out of range, vertices may be NaN, triangles may be
// degenerate); load_mesh() validates it in one place, so every format gets the same checks.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

namespace pg::mesh_formats {

// A reader's complaint about the file's content; load_mesh() prefixes the path and rethrows it as
// pg::InputError.
struct FormatError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct RawMesh {
  std::vector<Eigen::Vector3d> vertices;               // file units, node transforms applied
  std::vector<std::array<std::int64_t, 3>> triangles;  // 0-based vertex indices, unchecked
  std::vector<int> triangle_lines;  // 1-based source line per triangle (text formats), else empty
  int index_base = 0;               // how the file counts vertices (1 for OBJ), for messages
};

// Identical points (or index triples), bitwise (-0 folded into +0): find_or_add(p, next) returns
// the index first given with a point equal to p, or records `next` for p and returns it. Welds
// STL's corners and every format's split vertices, and finds repeated triangles.
template <typename Scalar>
class PointIndex {
 public:
  std::int64_t find_or_add(Eigen::Matrix<Scalar, 3, 1> p, std::int64_t next) {
    p.array() += Scalar(0);  // -0 + 0 == +0
    Key key{};
    std::memcpy(key.data(), p.data(), sizeof(Scalar) * 3);
    return index_.emplace(key, next).first->second;
  }

 private:
  using Key = std::array<std::uint64_t, 3>;  // three doubles, or three floats or ints and zeros
  struct KeyHash {
    size_t operator()(const Key& k) const {
      return std::hash<std::uint64_t>()(k[0] ^ (k[1] * 0x9e3779b97f4a7c15ULL) ^
                                        (k[2] * 0xc2b2ae3d27d4eb4fULL));
    }
  };
  std::unordered_map<Key, std::int64_t, KeyHash> index_;
};

// Fan-triangulates a polygon (assumed convex, as OBJ/OFF/PLY writers produce) into `mesh`.
// `line` (0 if unknown) is recorded per triangle when the mesh tracks source lines.
void add_polygon(RawMesh& mesh, const std::vector<std::int64_t>& polygon, int line);

// A whitespace-separated token and the 1-based line it sits on.
struct Token {
  std::string_view text;
  int line = 0;
};

// The whitespace-separated tokens of a text, one at a time ('\r' counts as whitespace), so that
// large files are not held twice in memory.
class TokenStream {
 public:
  explicit TokenStream(std::string_view text, int first_line = 1)
      : text_(text), line_(first_line) {}
  bool next(Token& token);  // false at the end of the text

 private:
  std::string_view text_;
  size_t pos_ = 0;
  int line_;
};

// The tokens of a text line by line, skipping blank lines and, on each line, everything from a
// token that starts with `comment` on.
class LineTokenizer {
 public:
  explicit LineTokenizer(std::string_view text, char comment = '#')
      : stream_(text), comment_(comment) {}
  bool next(std::vector<Token>& tokens);  // false (and no tokens) at the end of the text

 private:
  TokenStream stream_;
  Token pending_;  // first token of the next line, already read
  bool has_pending_ = false;
  char comment_;
};

double parse_double(const Token& token, const char* what);  // accepts nan/inf (checked later)
std::int64_t parse_int(const Token& token, const char* what);

RawMesh parse_obj(std::string_view text);
RawMesh parse_off(std::string_view text);
RawMesh parse_stl(std::string_view bytes);  // binary or ASCII, told apart by size and 'solid'
RawMesh parse_ply(std::string_view bytes);  // ascii, binary_little_endian, binary_big_endian
RawMesh read_gltf(const std::string& path, bool binary);

}  // namespace pg::mesh_formats
