#pragma once
// Reading the CSV files a user may write or save from a spreadsheet (poses.csv, circles).
#include <optional>
#include <string>
#include <vector>

namespace pg {

// A line as read: its '\r' (a file saved on Windows) dropped, and with `header`, a spreadsheet's
// UTF-8 byte-order mark before it.
void clean_csv_line(std::string& line, bool header);
// The cells of a line split on its commas, so that an empty last cell counts. A cell that starts
// with a double quote runs to its closing quote, commas and all, with "" for a quote inside
// (RFC 4180, as the tools write text cells: label-ball's reasons); a line ending inside a quote
// ends the cell there.
std::vector<std::string> csv_cells(const std::string& line);
// A cell's decimal number; none for anything else (strtod alone would also read hexadecimal,
// "0x10" as 16, and skip spaces). Infinite and NaN cells are numbers here: check std::isfinite.
std::optional<double> decimal_number(const std::string& cell);

}  // namespace pg
