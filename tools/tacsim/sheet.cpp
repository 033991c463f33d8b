#include "sheet.h"

#include <algorithm>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "../common/cli_main.h"
#include "pg/sim/scene_renderer.h"

namespace pg {

namespace {

void paste(ImageU8& sheet, const ImageU8& tile, int x0, int y0) {
  // The layout sizes every cell to fit its tile; one that does not is a bug, not a heap overrun.
  if (x0 < 0 || y0 < 0 || x0 + tile.width > sheet.width || y0 + tile.height > sheet.height) {
    throw std::logic_error("sheet: a " + std::to_string(tile.width) + "x" +
                           std::to_string(tile.height) + " tile does not fit at (" +
                           std::to_string(x0) + ", " + std::to_string(y0) + ")");
  }
  for (int y = 0; y < tile.height; ++y)
    for (int x = 0; x < tile.width; ++x)
      for (int c = 0; c < 3; ++c) sheet.at(x0 + x, y0 + y, c) = tile.at(x, y, tile.channels == 3 ? c : 0);
}

ImageU8 to_u8(const ImageF& image, float scale, float offset) {
  ImageU8 out(image.width, image.height, image.channels);
  for (std::size_t i = 0; i < image.data.size(); ++i) {
    out.data[i] = std::uint8_t(std::clamp(image.data[i] * scale + offset, 0.0f, 1.0f) * 255.0f + 0.5f);
  }
  return out;
}

}  // namespace

int run_sheet(const SheetArgs& args) {
  check_image_output(args.out);  // before rendering every scene
  check_output_file(args.out, {FileKind::kPng, FileKind::kExr, FileKind::kJpeg, FileKind::kBinary});
  std::vector<std::vector<ImageU8>> columns;
  for (const auto& path : args.scenes) {
    Scene scene = load_scene(path);
    RenderOverrides overrides;
    overrides.background = args.background;  // synthetic and none as in the scene
    overrides.outputs = {"color", "normal", "depth"};
    overrides.width = args.width;
    overrides.height = args.height;
    const SceneRenderer renderer(scene, overrides);
    const int frame = std::min(args.frame, scene.frames - 1);
    const RenderedFrame f = renderer.render_frame(frame)[0];
    const float deepest = std::max(1e-9f, *std::max_element(f.images.depth.data.begin(),
                                                            f.images.depth.data.end()));
    columns.push_back({f.images.color, to_u8(f.images.normal, 0.5f, 0.5f),
                       to_u8(f.images.depth, 1.0f / deepest, 0.0f)});
    std::printf("%s: frame %d, contact %s, deepest %.3f mm\n", path.c_str(), frame,
                f.stats.contact ? "yes" : "no", deepest * 1e3);
  }
  // Scenes may use sensors of different image sizes (digit 120x160, gelsight_mini 240x320): every
  // cell is as large as the largest image, and a smaller one sits centred in its cell.
  int w = 0, h = 0;
  for (const auto& column : columns) {
    w = std::max(w, column[0].width);
    h = std::max(h, column[0].height);
  }
  const int gap = 4, n = int(columns.size());
  ImageU8 sheet(n * w + (n - 1) * gap, 3 * h + 2 * gap, 3, 255);
  for (int i = 0; i < n; ++i) {
    for (int r = 0; r < 3; ++r) {
      const ImageU8& tile = columns[i][r];
      paste(sheet, tile, i * (w + gap) + (w - tile.width) / 2,
            r * (h + gap) + (h - tile.height) / 2);
    }
  }
  write_image(args.out, sheet);
  std::printf("wrote %s (%dx%d)\n", args.out.c_str(), sheet.width, sheet.height);
  return 0;
}

}  // namespace pg
