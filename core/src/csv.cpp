#include "pg/core/csv.h"

#include <cstdlib>

namespace pg {

void clean_csv_line(std::string& line, bool header) {
  if (!line.empty() && line.back() == '\r') line.pop_back();
  if (header && line.rfind("\xEF\xBB\xBF", 0) == 0) line.erase(0, 3);
}

std::vector<std::string> csv_cells(const std::string& line) {
  std::vector<std::string> cells(1);
  bool quoted = false, cell_start = true;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char ch = line[i];
    if (quoted) {
      if (ch != '"') {
        cells.back() += ch;
      } else if (i + 1 < line.size() && line[i + 1] == '"') {
        cells.back() += '"';
        ++i;
      } else {
        quoted = false;
      }
    } else if (ch == ',') {
      cells.emplace_back();
      cell_start = true;
      continue;
    } else if (ch == '"' && cell_start) {
      quoted = true;
    } else if (ch != '\r') {
      cells.back() += ch;
    }
    cell_start = false;
  }
  return cells;
}

std::optional<double> decimal_number(const std::string& cell) {
  if (cell.empty() || cell.find_first_of("xXpP \t") != std::string::npos) return std::nullopt;
  char* end = nullptr;
  const double v = std::strtod(cell.c_str(), &end);
  if (end != cell.c_str() + cell.size()) return std::nullopt;
  return v;
}

}  // namespace pg
