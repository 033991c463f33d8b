#include "label_ball.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <vector>

#include "../common/cli_main.h"
#include "../common/progress.h"
#include "pg/core/csv.h"
#include "pg/core/dataset.h"
#include "pg/core/error.h"
#include "pg/core/file_io.h"
#include "pg/core/gel_rays.h"
#include "pg/core/image_change.h"
#include "pg/learn/ball_press.h"
#include "pg/sim/primitives.h"
#include "pg/sim/renderer.h"

namespace pg {

namespace fs = std::filesystem;

namespace {

// A circle given by hand for one frame (none: the frame shows no press), and the line of the
// circles file that gave it, for the warning when the circle cannot place the ball.
struct GivenCircle {
  std::optional<Eigen::Vector3d> circle;  // u, v, radius [px]
  int line = 0;
};

// --circles: a CSV with a header naming at least frame, u_px, v_px and radius_px (the columns of
// the circles.csv label-ball writes; others are ignored). A row's three circle cells are all
// numbers (radius > 0) or all empty (no press in that frame); a row with empty circle cells
// whose status column says "skipped" (as label-ball wrote it) is as if not listed, one with a
// circle filled in takes it; empty cells under found or given are refused (a cleared circle); a
// status column holds found, given, no_press, skipped or nothing.
// Frames not listed are searched.
std::map<int, GivenCircle> read_circles(const std::string& path, const GelRays& rays, int frames) {
  require_regular_file(path, "a CSV file (--circles)");
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open (--circles)");
  std::string line;
  if (!std::getline(in, line)) throw InputError(path + ": empty; expected a header line");
  clean_csv_line(line, true);
  const std::vector<std::string> header = csv_cells(line);
  const char* names[4] = {"frame", "u_px", "v_px", "radius_px"};
  int column[4];
  for (int k = 0; k < 4; ++k) {
    const auto it = std::find(header.begin(), header.end(), names[k]);
    if (it == header.end()) {
      throw InputError(path + ": line 1: no column " + std::string(names[k]) +
                       " (expected frame,u_px,v_px,radius_px)");
    }
    column[k] = int(it - header.begin());
  }
  const auto status_it = std::find(header.begin(), header.end(), "status");
  const int status = status_it == header.end() ? -1 : int(status_it - header.begin());
  std::map<int, GivenCircle> circles;
  for (int number = 2; std::getline(in, line); ++number) {
    clean_csv_line(line, false);
    if (line.find_first_not_of(" \t") == std::string::npos) continue;
    const std::vector<std::string> cells = csv_cells(line);
    const auto cell = [&](int c) { return c < int(cells.size()) ? cells[std::size_t(c)] : ""; };
    const std::string at = path + ": line " + std::to_string(number) + ": ";
    // More cells than the header: a decimal comma (17,589 read as 17 and a cell 589) would
    // shift the circle's numbers without a word. (Fewer: the row's last cells left out, empty.)
    if (cells.size() > header.size()) {
      throw InputError(at + std::to_string(cells.size()) + " cells, the header has " +
                       std::to_string(header.size()) +
                       " (a decimal comma? numbers take a point: 17.5)");
    }
    const char* statuses[] = {"", "found", "given", "no_press", "skipped"};
    if (status >= 0 &&
        std::find(std::begin(statuses), std::end(statuses), cell(status)) == std::end(statuses)) {
      throw InputError(at + "status: '" + excerpt(cell(status)) +
                       "' is none of found, given, no_press, skipped (or empty)");
    }
    double v[4];
    bool empty[4];
    for (int k = 0; k < 4; ++k) {
      const std::string text = cell(column[k]);
      empty[k] = text.empty();
      const std::optional<double> number_in = decimal_number(text);
      if (!empty[k] && (!number_in || !std::isfinite(*number_in))) {
        throw InputError(at + names[k] + ": '" + excerpt(text) +
                         "' is not a finite decimal number");
      }
      v[k] = empty[k] ? 0.0 : *number_in;
    }
    if (empty[0] || v[0] != std::floor(v[0]) || v[0] < 0 || v[0] >= frames) {
      throw InputError(at + "frame: '" + cell(column[0]) + "' is not a frame of the dataset (0-" +
                       std::to_string(frames - 1) + ")");
    }
    const int frame = int(v[0]);
    if (circles.count(frame)) {
      throw InputError(at + "frame " + std::to_string(frame) + " is given twice");
    }
    if (empty[1] && empty[2] && empty[3]) {
      // A skipped frame as label-ball wrote it is searched again, not a frame without a press.
      if (status >= 0 && cell(status) == "skipped") continue;
      // A press whose circle was cleared: meant as "search again" or as "no press"? Either
      // guess would turn a press into wrong labels.
      if (status >= 0 && (cell(status) == "found" || cell(status) == "given")) {
        throw InputError(at + "status " + cell(status) +
                         " with the circle's cells empty: fill in u_px, v_px and radius_px, or "
                         "set the status to no_press (no press in the frame) or skipped (search "
                         "it again)");
      }
      circles[frame] = GivenCircle{std::nullopt, number};
      continue;
    }
    for (int k = 1; k < 4; ++k) {
      if (empty[k]) {
        throw InputError(at + names[k] +
                         " is empty: give u_px, v_px and radius_px, or none of "
                         "them for a frame without a press");
      }
    }
    if (status >= 0 && cell(status) == "no_press") {
      throw InputError(at +
                       "status no_press with a circle: empty the circle's cells for a frame "
                       "without a press, or set the status to given to use the circle");
    }
    if (!(v[3] > 0)) throw InputError(at + "radius_px: " + format_number(v[3]) + " is not > 0");
    const Eigen::Vector2d centre(v[1], v[2]);
    const Eigen::Vector2d nearest = centre.cwiseMax(Eigen::Vector2d::Zero())
                                        .cwiseMin(Eigen::Vector2d(rays.width - 1, rays.height - 1));
    if ((nearest - centre).norm() >= v[3]) {
      throw InputError(at + "the circle lies outside the " + std::to_string(rays.width) + "x" +
                       std::to_string(rays.height) + " image");
    }
    circles[frame] = GivenCircle{Eigen::Vector3d(v[1], v[2], v[3]), number};
  }
  return circles;
}

// What became of one frame.
struct FrameLabel {
  enum Kind { kPress, kNoPress, kSkipped } kind = kSkipped;
  bool given = false;  // from --circles
  BallPress press;
  double shading_ratio = std::numeric_limits<double>::quiet_NaN();  // BallShading (a press)
};

// How much the frame changes over the labelled ball's middle against what the sensor's model
// renders for that ball there (its lights, shading and background, no noise): the summed
// absolute colour change over the middle (within 0.75 of the circle's radius) of the frame
// against its reference, over that of the render against its no-contact image. A press of the
// ball reads about 1 (0.99-1.12 on the repository's renders of ball presses, the real DIGIT
// background's included); a press of something steeper than the ball's cap (a corner, an edge,
// a stud, a smaller ball) changes the colour more than the ball would: 2-3.1 (the cube corner of
// scenes/default.json 3.1, cube, stud and ellipsoid presses 2.0-2.4 in the median). A real
// sensor's frames have its own contrast, which the model's may not match.
class BallShading {
 public:
  BallShading(const DatasetInfo& info, double radius_m) {
    SensorModel sensor = info.sensor;
    sensor.noise.sigma = 0;
    RenderSettings settings;
    settings.normal = settings.depth = settings.mask = false;
    settings.noise = false;
    settings.shadows = info.render_known && info.shadows;
    std::error_code ec;
    // A render over a real background recorded its image; one moved since, or a recording,
    // is rendered on the model's own.
    if (info.render_known && fs::is_regular_file(info.background, ec)) {
      settings.background = info.background;
    }
    const std::vector<std::shared_ptr<const ObjectShape>> ball = {
        std::make_shared<ObjectShape>(make_uv_sphere(float(radius_m), 48, 96))};
    // A check, not the labelling: a background image that no longer reads is left out.
    try {
      renderer_ = std::make_unique<SensorRenderer>(sensor, ball, settings);
    } catch (const InputError&) {
      settings.background.clear();
      renderer_ = std::make_unique<SensorRenderer>(sensor, ball, settings);
    }
  }

  double ratio(const ImageU8& color, const ImageU8& reference, const BallPress& press) const {
    const RenderedFrame ball = renderer_->render({SE3::Translation(press.centre_m)}, 0);
    const ImageU8& none = renderer_->background_color_u8();
    double measured = 0, modelled = 0;
    for (int y = 0; y < color.height; ++y) {
      for (int x = 0; x < color.width; ++x) {
        if ((Eigen::Vector2d(x, y) - press.centre_px).norm() > 0.75 * press.radius_px) continue;
        for (int c = 0; c < 3; ++c) {
          measured += std::abs(int(color.at(x, y, c)) - int(reference.at(x, y, c)));
          modelled += std::abs(int(ball.images.color.at(x, y, c)) - int(none.at(x, y, c)));
        }
      }
    }
    return modelled > 0 ? measured / modelled : std::numeric_limits<double>::quiet_NaN();
  }

 private:
  std::unique_ptr<SensorRenderer> renderer_;
};
// Presses whose median BallShading ratio is above this are warned about.
constexpr double kSteeperThanTheBall = 1.5;

// Presses at many places leave each pixel untouched in most frames. Pixels that differ from the
// reference in nearly every frame are the reference's own: a press in it (or other lighting),
// against which every label would be measured. Counted on at most 31 frames, evenly spaced,
// as the frames are read for their presses.
class ReferenceChange {
 public:
  ReferenceChange(const ImageU8& reference, int frames)
      : reference_(reference),
        frames_(frames),
        step_((frames + 30) / 31),
        times_(std::size_t(reference.width) * reference.height, 0) {}

  void add(int frame, const ImageU8& color) {
    if (frame % step_ != 0) return;
    ++sampled_;
    for_each_changed_pixel(color, reference_, [&](int x, int y) {
      ++times_[std::size_t(y) * reference_.width + x];
      return true;
    });
  }

  // The pixels changed in at least 80 % of the sampled frames (0 for fewer than 5 frames).
  int persistent_pixels() const {
    if (frames_ < 5) return 0;
    return int(
        std::count_if(times_.begin(), times_.end(), [&](int n) { return n >= 0.8 * sampled_; }));
  }

 private:
  const ImageU8& reference_;
  int frames_, step_, sampled_ = 0;
  std::vector<int> times_;
};

std::string circles_csv(const std::vector<FrameLabel>& labels) {
  std::string text =
      "frame,labelled_frame,status,u_px,v_px,radius_px,centre_x_m,centre_y_m,centre_z_m,"
      "depth_m,rms_px,fit,shading_ratio,reason\n";
  int labelled = 0;
  char row[512];
  for (std::size_t f = 0; f < labels.size(); ++f) {
    const FrameLabel& l = labels[f];
    const char* status = l.kind == FrameLabel::kPress     ? (l.given ? "given" : "found")
                         : l.kind == FrameLabel::kNoPress ? "no_press"
                                                          : "skipped";
    const std::string index = l.kind == FrameLabel::kSkipped ? "" : std::to_string(labelled++);
    if (l.kind == FrameLabel::kPress) {
      const BallPress& p = l.press;
      // A given circle's fit RMS would measure it against itself: left empty.
      const std::string rms = l.given ? "" : format_number(p.rms_px, "%.3f");
      const std::string ratio =
          std::isfinite(l.shading_ratio) ? format_number(l.shading_ratio, "%.3f") : "";
      std::snprintf(row, sizeof(row), "%zu,%s,%s,%.3f,%.3f,%.3f,%.7g,%.7g,%.7g,%.6g,%s,%s,%s,\n", f,
                    index.c_str(), status, p.centre_px.x(), p.centre_px.y(), p.radius_px,
                    p.centre_m.x(), p.centre_m.y(), p.centre_m.z(), p.depth_m, rms.c_str(),
                    p.shading_fit ? "shading" : "circle", ratio.c_str());
    } else {
      std::snprintf(row, sizeof(row), "%zu,%s,%s,,,,,,,,,,,%s\n", f, index.c_str(), status,
                    csv_field(l.press.reason).c_str());
    }
    text += row;
  }
  return text;
}

}  // namespace

CLI::App* add_label_ball_command(CLI::App& app, LabelBallArgs& a) {
  CLI::App* cmd = app.add_subcommand(
      "label-ball",
      "Label frames of ball presses with the ball's normals: a real sensor's training data");
  cmd->add_option("dataset", a.dataset,
                  "Dataset of the presses, with colour images and a no-contact reference "
                  "(patchgraph recording, or a render)")
      ->required();
  cmd->add_option("--diameter", a.diameter, "The ball's diameter [m] (a 1/2 inch ball: 0.0127)")
      ->required()
      ->check(CLI::Validator(
          [](std::string& text) -> std::string {
            double value = 0;
            if (!CLI::detail::lexical_cast(text, value)) return "not a number: " + text;
            if (value >= 1e-4 && value <= 0.2) return {};
            return "must be from 0.0001 to 0.2 [m] (a 1/2 inch ball: 0.0127), got " + text;
          },
          "METRES"));
  cmd->add_option("--circles", a.circles,
                  "CSV of contact circles given by hand: frame,u_px,v_px,radius_px (the "
                  "circles.csv a run writes, corrected); empty circle cells: no press in that "
                  "frame (status no_press or an empty status; skipped: search it again)");
  cmd->add_option("--out,-o", a.out, "The labelled dataset (color, normal, depth, mask)")
      ->required();
  cmd->add_option("--gel", a.gel,
                  "The gel the labels model: elastic (the sensor's elastic model: rim rounded, "
                  "sink-in around the contact) or rigid (TACTO's; the paper's ball labels); "
                  "default: as the dataset's sensor says (sensor gel.elastic.enabled)")
      ->check(CLI::IsMember({"elastic", "rigid"}));
  cmd->add_flag("--quiet,-q", a.quiet, "No progress line");
  return cmd;
}

int run_label_ball(const LabelBallArgs& a) {
  check_output_is_not_input(a.out, a.dataset, "the dataset");
  // Before the search for presses (minutes on a long recording), not after it.
  DatasetWriter::check_folder(a.out, DatasetMaker::kLabelBall);
  const Dataset d = Dataset::open(a.dataset);
  if (!d.info().has_output("color")) {
    throw InputError(a.dataset + "/dataset.json: outputs: no colour images to find presses in");
  }
  GelModel gel = d.info().sensor.gel;
  if (!a.gel.empty()) gel.elastic.enabled = a.gel == "elastic";
  const SensorModel& sensor = d.info().sensor;
  const ImageU8 reference = d.background();
  for (const std::string& w :
       reference_warnings(reference, "the no-contact reference of " + a.dataset)) {
    std::fprintf(stderr, "warning: %s\n", w.c_str());
  }
  const GelRays rays = make_gel_rays(sensor.camera, sensor.gel);
  const std::map<int, GivenCircle> given =
      a.circles.empty() ? std::map<int, GivenCircle>{} : read_circles(a.circles, rays, d.frames());
  const double radius = 0.5 * a.diameter;
  // A ball far wider than the gel, and than any calibration ball (5 cm), is no calibration
  // ball: a slip of units (127 mm for 12.7)? Its presses would still be labelled, as shallow
  // caps of a huge sphere.
  const double gel_size = std::max(sensor.gel.width_m, sensor.gel.height_m);
  if (a.diameter > 2 * gel_size && a.diameter > 0.05) {
    std::fprintf(stderr,
                 "warning: --diameter %s m: a ball of %.0f mm, over twice the %.0f x %.0f mm "
                 "gel; is that its diameter in metres?\n",
                 format_number(a.diameter).c_str(), a.diameter * 1e3, sensor.gel.width_m * 1e3,
                 sensor.gel.height_m * 1e3);
  }

  // Every frame's press first (reading every colour image), so that nothing is written when no
  // frame has one.
  std::vector<FrameLabel> labels(std::size_t(d.frames()));
  int presses = 0, no_press = 0;
  ReferenceChange reference_change(reference, d.frames());
  const BallShading shading(d.info(), radius);
  // A render blended onto a real background shows the change blurred by the blend's Gaussian,
  // which the predicted frame then takes too. Not a recording: a real camera's blur is its
  // optics', which the sensor file's background_blur_m does not measure, and a blur assumed
  // where the frames have none misplaces the ball (presses rendered on the synthetic background
  // and imported by `recording`: 11 deg held out through the lights fitted to such labels,
  // against 4.3 without it).
  const double blend_blur_px =
      d.info().background.empty() ? 0.0 : rays.blend_blur_px(sensor.shading);
  try {
    const StopOnSignals stop;
    Progress progress("finding presses", d.frames(), !a.quiet);
    for (int f = 0; f < d.frames(); ++f) {
      const ImageU8 color = d.color(f);
      reference_change.add(f, color);
      FrameLabel& l = labels[std::size_t(f)];
      const auto it = given.find(f);
      l.given = it != given.end();
      if (l.given && !it->second.circle) {
        l.kind = FrameLabel::kNoPress;
        l.press.reason = "no press (--circles)";
      } else if (l.given) {
        const Eigen::Vector3d& c = *it->second.circle;
        l.press = ball_press_from_circle(color, reference, rays, c.head<2>(), c.z(), radius, gel,
                                         blend_blur_px);
        if (!l.press.found) {
          l.press.reason =
              "--circles line " + std::to_string(it->second.line) + ": " + l.press.reason;
        }
        l.kind = l.press.found ? FrameLabel::kPress : FrameLabel::kSkipped;
      } else {
        l.press = find_ball_press(color, reference, rays, radius, gel, blend_blur_px);
        l.kind = l.press.found       ? FrameLabel::kPress
                 : l.press.no_change ? FrameLabel::kNoPress
                                     : FrameLabel::kSkipped;
      }
      if (l.kind == FrameLabel::kPress) l.shading_ratio = shading.ratio(color, reference, l.press);
      presses += l.kind == FrameLabel::kPress;
      no_press += l.kind == FrameLabel::kNoPress;
      progress.update(f + 1);
    }
  } catch (const Stopped& e) {
    throw e.with_note("while finding the presses; nothing written");
  }
  const int persistent = reference_change.persistent_pixels();
  if (persistent >= kMinPressPixels) {
    std::fprintf(stderr,
                 "warning: %d px of the no-contact reference of %s differ from at least 80 %% "
                 "of its frames: does it show a press itself, or other lighting? (Unless most "
                 "presses are at one place.)\n",
                 persistent, a.dataset.c_str());
  }
  if (presses == 0) {
    const bool all_given = std::all_of(labels.begin(), labels.end(), [](const FrameLabel& l) {
      return l.given && l.kind == FrameLabel::kNoPress;
    });
    if (all_given) {
      throw InputError(a.circles + ": every frame of " + a.dataset +
                       " is given as one without a press: nothing to label");
    }
    const auto first = std::find_if(labels.begin(), labels.end(), [](const FrameLabel& l) {
      return l.kind == FrameLabel::kSkipped;
    });
    throw InputError(a.dataset + ": no ball press found in any of its " +
                     std::to_string(d.frames()) + " frames" +
                     (first != labels.end()
                          ? " (frame " + std::to_string(first - labels.begin()) + ": " +
                                first->press.reason + ")"
                          : " (none shows a change from the no-contact reference)"));
  }

  DatasetInfo info = d.info();
  info.frames = presses + no_press;
  info.outputs = {"color", "normal", "depth", "mask"};
  info.scene.clear();
  info.object_name = "ball";
  info.object_mesh.clear();
  info.object_scale = 1.0;
  info.sensor.gel = gel;  // the gel the labels model
  const bool out_existed = fs::exists(a.out);
  try {
    const StopOnSignals stop;
    DatasetWriter writer(a.out, info, DatasetMaker::kLabelBall);
    writer.write_background(reference);
    const ImageF flat = undeformed_gel_normals(rays);
    Progress progress("labelling", info.frames, !a.quiet);
    int written = 0;
    for (int f = 0; f < d.frames(); ++f) {
      const FrameLabel& l = labels[std::size_t(f)];
      if (l.kind == FrameLabel::kSkipped) continue;
      FramePose pose = d.poses()[std::size_t(f)];
      pose.frame = written;
      // The ball's centre is known, its orientation is not: no object pose.
      pose.T_world_object = SE3();
      pose.object_known = false;
      pose.contact = l.kind == FrameLabel::kPress;
      pose.contact_known = true;
      FrameImages images;
      images.color = d.color(f);
      if (l.kind == FrameLabel::kPress) {
        BallLabels ball = ball_labels(rays, l.press.centre_m, radius, gel.elastic);
        images.normal = std::move(ball.normal);
        images.depth = std::move(ball.depth);
        images.mask = std::move(ball.mask);
      } else {
        images.normal = flat;
        images.depth = ImageF(rays.width, rays.height, 1, 0.0f);
        images.mask = ImageU8(rays.width, rays.height, 1, 0);
      }
      writer.write_frame(pose, images);
      progress.update(++written);
    }
    writer.finish();
    write_text_atomically((fs::path(a.out) / "circles.csv").string(), circles_csv(labels));
  } catch (...) {
    rethrow_after_dataset_write(a.out, out_existed);
  }
  const int skipped = d.frames() - presses - no_press;
  std::vector<double> rms, depth;
  int by_shading = 0;
  for (const FrameLabel& l : labels) {
    if (l.kind != FrameLabel::kPress) continue;
    if (!l.given) rms.push_back(l.press.rms_px);  // a given circle's would measure it on itself
    depth.push_back(l.press.depth_m * 1e3);
    by_shading += l.press.shading_fit;
  }
  std::sort(rms.begin(), rms.end());
  std::sort(depth.begin(), depth.end());
  const std::string fit = rms.empty()
                              ? ""
                              : ", circle fit " + format_number(rms[rms.size() / 2], "%.2f") +
                                    " px RMS median of the found";
  std::printf(
      "%d frames of %s: %d %s labelled (%.2f-%.2f mm deep%s, %d placed by the shading, %s "
      "gel), %d without contact, %d skipped -> %s (circles.csv: each frame's circle or reason)\n",
      d.frames(), a.dataset.c_str(), presses, presses == 1 ? "press" : "presses", depth.front(),
      depth.back(), fit.c_str(), by_shading, gel.elastic.enabled ? "elastic" : "rigid", no_press,
      skipped, a.out.c_str());
  for (std::size_t f = 0; f < labels.size(); ++f) {
    const FrameLabel& l = labels[f];
    if (l.kind == FrameLabel::kPress && l.given && !l.press.shading_fit) {
      std::fprintf(stderr,
                   "warning: frame %zu: the given circle's ball is placed through the circle "
                   "alone: the frame's shading inside it does not place it (does the frame show "
                   "that press?)\n",
                   f);
    }
  }
  int shown = 0;
  for (std::size_t f = 0; f < labels.size() && shown < 5; ++f) {
    if (labels[f].kind != FrameLabel::kSkipped) continue;
    std::fprintf(stderr, "warning: frame %zu skipped: %s\n", f, labels[f].press.reason.c_str());
    ++shown;
  }
  if (skipped > shown) std::fprintf(stderr, "warning: %d more skipped\n", skipped - shown);
  // Presses that change the colour more than the ball would: not (all) of the ball.
  std::vector<double> ratios;
  for (const FrameLabel& l : labels) {
    if (l.kind == FrameLabel::kPress && std::isfinite(l.shading_ratio))
      ratios.push_back(l.shading_ratio);
  }
  std::sort(ratios.begin(), ratios.end());
  if (!ratios.empty() && ratios[ratios.size() / 2] > kSteeperThanTheBall) {
    const int steeper = int(std::count_if(ratios.begin(), ratios.end(),
                                          [](double r) { return r > kSteeperThanTheBall; }));
    std::fprintf(stderr,
                 "warning: %d of the %zu presses change the colour more than %s times as much as "
                 "the sensor's model shows for a ball of diameter %s mm there (median %.2f; "
                 "circles.csv's shading_ratio, about 1 for that ball's presses): are they all "
                 "of that ball? A press of something steeper (a corner, an edge, a smaller ball) "
                 "is labelled with the ball's shallower slopes%s\n",
                 steeper, ratios.size(), format_number(kSteeperThanTheBall).c_str(),
                 format_number(a.diameter * 1e3).c_str(), ratios[ratios.size() / 2],
                 d.info().render_known ? "" : "; or the sensor has more contrast than its model");
  }
  // Presses too wide for the ball: with a diameter given wrong (its radius, say), the presses
  // narrow enough to pass are labelled with the wrong ball too.
  const int too_wide = int(std::count_if(labels.begin(), labels.end(), [](const FrameLabel& l) {
    return l.kind == FrameLabel::kSkipped &&
           l.press.reason.find("is the diameter right?") != std::string::npos;
  }));
  if (presses > 0 && too_wide >= 3 && 4 * too_wide >= presses + too_wide) {
    std::fprintf(stderr,
                 "warning: %d of the %d presses are wider than a ball of diameter %s mm makes: "
                 "if --diameter is wrong, the %d labelled are labelled with the wrong ball too "
                 "(too deep for a smaller ball); check it is the ball's diameter, in metres\n",
                 too_wide, presses + too_wide, format_number(a.diameter * 1e3).c_str(), presses);
  }
  // A reference that shows a press itself: frames where the ball is elsewhere show two changes
  // (skipped), and the reference's own press is found, the same circle in frame after frame.
  // Separate hand presses never land within a pixel of each other three times (a ball held still
  // over consecutive frames is one press: runs of frames count once).
  const auto same_circle = [&](std::size_t f, std::size_t g) {
    const FrameLabel &l = labels[f], &m = labels[g];
    return l.kind == FrameLabel::kPress && !l.given && m.kind == FrameLabel::kPress && !m.given &&
           (m.press.centre_px - l.press.centre_px).norm() < 1.0 &&
           std::abs(m.press.radius_px - l.press.radius_px) < 1.0;
  };
  for (std::size_t f = 0; f < labels.size(); ++f) {
    const FrameLabel& l = labels[f];
    if (l.kind != FrameLabel::kPress || l.given) continue;
    std::string same;
    int count = 0;
    for (std::size_t g = 0; g < labels.size(); ++g) {
      if (!same_circle(f, g) || (g > 0 && same_circle(f, g - 1))) continue;  // a run's first
      same += (count++ ? ", " : "") + std::to_string(g);
    }
    if (count >= 3) {
      std::fprintf(stderr,
                   "warning: frames %s (and any of their runs) show the same circle (%.1f, "
                   "%.1f px, radius %.1f px) to within a pixel: does the no-contact reference "
                   "show a press itself? Its press would be found in every frame whose own press "
                   "lies elsewhere%s\n",
                   same.c_str(), l.press.centre_px.x(), l.press.centre_px.y(), l.press.radius_px,
                   skipped > presses ? ", and most frames are skipped, as here" : "");
      break;
    }
  }
  return kExitOk;
}

}  // namespace pg
