#pragma once
// Renders a whole scene: every sensor, every frame, into the dataset format.
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "pg/sim/renderer.h"
#include "pg/sim/scene.h"

namespace pg {

// Command-line style overrides of what the scene file asks for.
struct RenderOverrides {
  std::vector<std::string> outputs;  // empty: the scene's
  int width = 0, height = 0;         // 0: the sensors' own
  std::string background;            // a real background image for every sensor ("": the scene's)
  std::optional<bool> shadows;       // unset: the scene's
  std::optional<bool> noise;         // the camera noise on/off; unset: the scene's
  std::optional<bool> elastic;       // every sensor's elastic gel model on/off; unset: the scene's
  int frames = 0;                    // the scene's first this many frames; 0: all of them
};

class SceneRenderer {
 public:
  // Loads the meshes (InputError naming the mesh file) and builds one renderer per sensor. Throws
  // InputError for overrides no option could give (an unknown output, a negative size) and a
  // tracked_object that is not one of the scene's objects.
  SceneRenderer(Scene scene, const RenderOverrides& overrides = {});

  const Scene& scene() const { return scene_; }
  // Throws std::out_of_range for a sensor the scene does not have.
  const SensorRenderer& sensor(int i) const { return *sensors_.at(std::size_t(i)); }
  int sensor_count() const { return int(sensors_.size()); }
  // Object i's shape (its mesh at the scene's scale); std::out_of_range past the objects.
  const ObjectShape& object_shape(int i) const { return *shapes_.at(std::size_t(i)); }

  // Object poses in sensor i's frame at `frame`. Throws std::out_of_range for a sensor or frame
  // (0 to scene().frames - 1) the scene does not have.
  std::vector<SE3> object_poses_in_sensor(int sensor, int frame) const;
  // One rendered frame per sensor (std::out_of_range as above). Thread-safe.
  std::vector<RenderedFrame> render_frame(int frame) const;
  // The seed of sensor i's noise at `frame`, from the scene's seed.
  std::uint64_t noise_seed(int sensor, int frame) const;

 private:
  Scene scene_;
  std::vector<std::shared_ptr<const ObjectShape>> shapes_;
  std::vector<std::unique_ptr<SensorRenderer>> sensors_;
};

// What touched one sensor's gel over a render: its dataset's contact is taken for the tracked
// object's.
struct SensorContact {
  int contact_frames = 0;    // frames in which something touched this sensor's gel
  int untracked_frames = 0;  // of those, frames in which only other objects did
  int shared_frames = 0;     // frames in which another object touched it along with the tracked
  std::vector<int> others;   // the other objects that touched it (scene indices, ascending)
};

struct RenderSummary {
  int frames = 0;
  int contact_frames = 0;  // frames where some sensor saw contact
  int clamped_frames = 0;  // frames with penetration beyond the gel's max indentation
  std::vector<SensorContact> sensor_contact;  // one per sensor
  double seconds = 0;
  std::vector<std::string> dataset_dirs;  // one per sensor
  // Datasets of an earlier render into the folder (its sensors.json) of sensors this scene does
  // not have: left as they were, no longer listed.
  std::vector<std::string> earlier_sensor_dirs;
  std::uintmax_t bytes_estimate = 0;  // estimate_dataset_bytes (0: not known)
  // Frames rendered at once when the available memory held fewer than the threads (0: not
  // limited).
  int frames_in_flight = 0;
  std::uintmax_t frame_memory_bytes = 0;  // a frame in flight's, about (kFrameBytesPerPixel)
};

// The memory a frame in flight takes, a pixel of each sensor: its images, the renderer's buffers
// and the files' encoding (measured with every output at 1024 x 1024 and 2048 x 2048 px: 112
// bytes a pixel for each frame more at once).
inline constexpr std::uintmax_t kFrameBytesPerPixel = 120;
// And what the renderer holds for each pixel of its sensors (the same renders, and two sensors
// of 8192 x 8192 px: 72-94 bytes); SceneRenderer refuses a scene whose renderer and one frame
// would not fit the available memory.
inline constexpr std::uintmax_t kRendererBytesPerPixel = 100;

// How many of `frames` to render at once, at most `concurrency`: as many as `available_bytes` of
// memory hold, at kFrameBytesPerPixel over the sensors' `pixels` each (0: not one; all that are
// wanted when the memory is not known).
int frames_in_flight(std::uintmax_t pixels, int frames, int concurrency,
                     std::optional<std::uintmax_t> available_bytes);

// Progress callback: (frames done, frames total).
using ProgressFn = std::function<void(int, int)>;

// The bytes a render writes, about: the middle frame's files (written to a scratch folder and
// measured; a frame in contact takes more than one without) times the frames, and the files each
// dataset holds once. 0 when the scratch folder cannot be written.
std::uintmax_t estimate_dataset_bytes(const SceneRenderer& renderer);

// Writes OUT (one sensor) or OUT/<sensor name>/ (several sensors) in the dataset format. Throws
// InputError before writing anything when a folder holds something else than a dataset, the
// disk has less free space than estimate_dataset_bytes (counting the frames of an earlier
// dataset the render replaces), or the available memory does not hold one frame
// (frames_in_flight).
RenderSummary render_scene_to_dataset(const SceneRenderer& renderer, const std::string& out_dir,
                                      const ProgressFn& progress = nullptr);

// "" when the tracked object alone touched each sensor's gel in every contact frame of a render;
// else the warnings (one a line), naming the scene, the sensor (of several) and the objects: of
// the frames where only other objects touch a sensor's gel, and of those where another touches it
// along with the tracked one. A tracker reading a sensor's dataset takes every contact for the
// tracked object's (its poses are that object's), so another object's touch would be registered
// as its motion. tacsim render and patchgraph bench print it.
std::string untracked_contact_warning(const RenderSummary& summary, const Scene& scene);

}  // namespace pg
