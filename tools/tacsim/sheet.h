#pragma once
#include <string>
#include <vector>

namespace pg {

struct SheetArgs {
  std::vector<std::string> scenes;
  std::string out;
  int frame = 0;
  int width = 0, height = 0;  // 0: the scenes' own
  std::string background;     // optional real background image for every scene
};

// Renders one frame of each scene and tiles them: a column per scene, rows colour, normals
// (encoded (n + 1) / 2) and indentation (white = deepest in that frame). Cells take the largest
// image size; a smaller image is centred in its cell.
int run_sheet(const SheetArgs& args);

}  // namespace pg
