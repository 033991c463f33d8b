// Text-format mesh readers (OBJ, OFF) and the tokenizer the text readers share.
//
// OBJ and OFF are read here rather than through OpenMesh because OpenMesh 9 silently drops faces
// with out-of-range indices and whole vertices it cannot parse ("nan"), which shifts every later
// index; load_mesh() must report both as errors instead.
#include <charconv>
#include <cstdlib>
#include <string>

#include "mesh_formats.h"
#include "pg/core/error.h"

namespace pg::mesh_formats {
namespace {

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }

std::string quoted(const Token& token) { return "'" + excerpt(token.text) + "'"; }

}  // namespace

void add_polygon(RawMesh& mesh, const std::vector<std::int64_t>& polygon, int line) {
  for (size_t k = 1; k + 1 < polygon.size(); ++k) {
    mesh.triangles.push_back({polygon[0], polygon[k], polygon[k + 1]});
    if (line > 0) mesh.triangle_lines.push_back(line);
  }
}

bool TokenStream::next(Token& token) {
  while (pos_ < text_.size() && (text_[pos_] == '\n' || is_space(text_[pos_]))) {
    if (text_[pos_++] == '\n') ++line_;
  }
  if (pos_ == text_.size()) return false;
  const size_t begin = pos_;
  while (pos_ < text_.size() && text_[pos_] != '\n' && !is_space(text_[pos_])) ++pos_;
  token = {text_.substr(begin, pos_ - begin), line_};
  return true;
}

bool LineTokenizer::next(std::vector<Token>& tokens) {
  tokens.clear();
  int comment_line = 0;
  Token token;
  while (has_pending_ || stream_.next(token)) {
    if (has_pending_) {
      token = pending_;
      has_pending_ = false;
    }
    if (!tokens.empty() && token.line != tokens.front().line) {
      pending_ = token;
      has_pending_ = true;
      return true;
    }
    if (token.line == comment_line) continue;
    if (token.text.front() == comment_) {
      comment_line = token.line;
      continue;
    }
    tokens.push_back(token);
  }
  return !tokens.empty();
}

double parse_double(const Token& token, const char* what) {
  std::string_view s = token.text;
  if (s.size() > 1 && s.front() == '+') s.remove_prefix(1);  // from_chars rejects a leading '+'
  double value = 0.0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), value);
  if (ec == std::errc::result_out_of_range) {
    // from_chars leaves `value` untouched on overflow; keep the overflow visible as inf/0 so the
    // finiteness check reports the vertex.
    value = std::strtod(std::string(s).c_str(), nullptr);
  } else if (ec != std::errc() || end != s.data() + s.size()) {
    throw FormatError("line " + std::to_string(token.line) + ": expected a number for " + what +
                      ", found " + quoted(token));
  }
  return value;
}

std::int64_t parse_int(const Token& token, const char* what) {
  std::string_view s = token.text;
  if (s.size() > 1 && s.front() == '+') s.remove_prefix(1);
  std::int64_t value = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), value);
  if (ec != std::errc() || end != s.data() + s.size()) {
    throw FormatError("line " + std::to_string(token.line) + ": expected an integer for " + what +
                      ", found " + quoted(token));
  }
  return value;
}

// OBJ: `v x y z [w | r g b]` and `f v1[/vt][/vn] v2 ... vn` (1-based, negative = relative to the
// vertices read so far); every other statement (vt, vn, o, g, s, usemtl, l, p, ...) is ignored.
RawMesh parse_obj(std::string_view text) {
  RawMesh mesh;
  mesh.index_base = 1;
  std::vector<std::int64_t> polygon;
  LineTokenizer lines(text);
  std::vector<Token> tokens;
  while (lines.next(tokens)) {
    const std::string_view keyword = tokens[0].text;
    const int line = tokens[0].line;
    if (keyword == "v") {
      if (tokens.size() < 4) {
        throw FormatError("line " + std::to_string(line) + ": vertex needs 3 coordinates");
      }
      mesh.vertices.emplace_back(parse_double(tokens[1], "vertex x"),
                                 parse_double(tokens[2], "vertex y"),
                                 parse_double(tokens[3], "vertex z"));
    } else if (keyword == "f") {
      if (tokens.size() < 4) {
        throw FormatError("line " + std::to_string(line) + ": face needs at least 3 vertices");
      }
      polygon.clear();
      for (size_t k = 1; k < tokens.size(); ++k) {
        Token index_token = tokens[k];
        index_token.text = index_token.text.substr(0, index_token.text.find('/'));
        const std::int64_t index = parse_int(index_token, "a face's vertex index");
        // A negative index counts back from the last vertex read: named here, as the file gives
        // it, when it reaches before the first.
        if (index < 0 && -index > static_cast<std::int64_t>(mesh.vertices.size())) {
          throw FormatError("line " + std::to_string(line) + ": face vertex index " +
                            std::to_string(index) + " counts back from the last vertex read, but " +
                            std::to_string(mesh.vertices.size()) + " have been read");
        }
        // 1-based; 0 is invalid and becomes -1, which validation reports as out of range.
        polygon.push_back(index < 0 ? static_cast<std::int64_t>(mesh.vertices.size()) + index
                                    : index - 1);
      }
      add_polygon(mesh, polygon, line);
    }
  }
  return mesh;
}

// OFF: a header keyword ending in "OFF" (OFF, COFF, NOFF, CNOFF, STOFF, ...), the counts
// `nv nf [ne]` (on the header line or the next one), nv vertex lines (x y z first, then optional
// normal/colour/texture values) and nf face lines `n i0 ... i(n-1) [colour]`, 0-based.
RawMesh parse_off(std::string_view text) {
  LineTokenizer lines(text);
  std::vector<Token> tokens;
  if (!lines.next(tokens)) throw FormatError("empty file (expected an OFF header)");
  const std::string keyword(tokens[0].text);
  const std::string header_line = "line " + std::to_string(tokens[0].line) + ": ";
  if (keyword.size() < 3 || keyword.compare(keyword.size() - 3, 3, "OFF") != 0) {
    throw FormatError(header_line + "expected an OFF header, found '" + excerpt(keyword) + "'");
  }
  if (keyword.find('4') != std::string::npos || keyword.find('n') != std::string::npos) {
    throw FormatError("4D and n-dimensional OFF ('" + excerpt(keyword) + "') are not supported");
  }
  tokens.erase(tokens.begin());
  if (!tokens.empty() && tokens[0].text == "BINARY") {
    throw FormatError("binary OFF is not supported (convert it to ASCII OFF, PLY or GLB)");
  }
  if (tokens.empty() && !lines.next(tokens)) {
    throw FormatError("missing vertex/face counts after the header");
  }
  if (tokens.size() < 2) {
    throw FormatError("line " + std::to_string(tokens[0].line) +
                      ": expected vertex and face counts");
  }
  const std::int64_t num_vertices = parse_int(tokens[0], "the vertex count");
  const std::int64_t num_faces = parse_int(tokens[1], "the face count");
  if (num_vertices < 0 || num_faces < 0) {
    throw FormatError("line " + std::to_string(tokens[0].line) + ": negative count");
  }
  const auto next_line = [&](std::int64_t i, std::int64_t n, const char* what) {
    if (!lines.next(tokens)) {
      throw FormatError("the header declares " + std::to_string(n) + " " + what +
                        ", but the file ends after " + std::to_string(i));
    }
  };

  RawMesh mesh;
  for (std::int64_t v = 0; v < num_vertices; ++v) {
    next_line(v, num_vertices, "vertices");
    if (tokens.size() < 3) {
      throw FormatError("line " + std::to_string(tokens[0].line) + ": vertex needs 3 coordinates");
    }
    mesh.vertices.emplace_back(parse_double(tokens[0], "vertex x"),
                               parse_double(tokens[1], "vertex y"),
                               parse_double(tokens[2], "vertex z"));
  }
  std::vector<std::int64_t> polygon;
  for (std::int64_t f = 0; f < num_faces; ++f) {
    next_line(f, num_faces, "faces");
    const int line = tokens[0].line;
    const std::int64_t n = parse_int(tokens[0], "a face's vertex count");
    if (n < 3 || static_cast<size_t>(n) + 1 > tokens.size()) {
      throw FormatError("line " + std::to_string(line) + ": face declares " + std::to_string(n) +
                        " vertices; expected at least 3, each with an index on the line");
    }
    polygon.clear();
    for (std::int64_t k = 1; k <= n; ++k) {
      polygon.push_back(parse_int(tokens[static_cast<size_t>(k)], "a face's vertex index"));
    }
    add_polygon(mesh, polygon, line);
  }
  return mesh;
}

}  // namespace pg::mesh_formats
