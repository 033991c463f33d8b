// pg/learn/normal_model.h for a program built without LibTorch (pg_learn_absent,
// learn/CMakeLists.txt): `patchgraph-core` runs every command that needs a network in
// `patchgraph-torch` instead (tools/patchgraph/main.cpp), so reaching one of these is a bug.
#include <stdexcept>
#include <string>

#include "pg/learn/normal_model.h"

namespace pg {
namespace {

[[noreturn]] void absent(const char* what) {
  throw std::logic_error(std::string(what) +
                         ": this program is built without LibTorch; networks run in "
                         "patchgraph-torch (an internal error: please report it)");
}

}  // namespace

struct NormalEstimator::Impl {};

std::string describe(const NetworkSpec&) { absent("describe"); }
std::string frame_background(const DatasetInfo&) { absent("frame_background"); }
NormalEstimator NormalEstimator::load(const std::string&, int) { absent("NormalEstimator::load"); }
NormalEstimator::NormalEstimator(NormalEstimator&&) noexcept = default;
NormalEstimator& NormalEstimator::operator=(NormalEstimator&&) noexcept = default;
NormalEstimator::~NormalEstimator() = default;
ImageF NormalEstimator::predict(const ImageU8&, const ImageU8&) const { absent("predict"); }
void NormalEstimator::set_phases(int) { absent("set_phases"); }
int NormalEstimator::phases() const { absent("phases"); }
const NormalModelInfo& NormalEstimator::info() const { absent("info"); }
const std::string& NormalEstimator::path() const { absent("path"); }
long NormalEstimator::parameter_count() const { absent("parameter_count"); }
void NormalEstimator::check_sensor(const SensorModel&, const std::string&) const {
  absent("check_sensor");
}
std::string NormalEstimator::sensor_difference(const SensorModel&) const {
  absent("sensor_difference");
}
std::string NormalEstimator::background_difference(const DatasetInfo&) const {
  absent("background_difference");
}
std::string optics_difference(const SensorModel&, const SensorModel&) {
  absent("optics_difference");
}
void check_evaluation_data(const NormalEstimator&, const std::vector<std::string>&) {
  absent("check_evaluation_data");
}
NormalMetrics evaluate_normals(const NormalEstimator&, const std::vector<std::string>&,
                               const std::function<void(int, int)>&) {
  absent("evaluate_normals");
}
void check_evaluation_data(const std::vector<std::string>&) { absent("check_evaluation_data"); }
NormalMetrics evaluate_normals(const NormalsReader&, const std::string&,
                               const std::vector<std::string>&,
                               const std::function<void(int, int)>&) {
  absent("evaluate_normals");
}
std::string training_settings_json(const TrainOptions&) { absent("training_settings_json"); }
void train_normals(const TrainOptions&, const std::function<void(const EpochReport&)>&,
                   const std::function<void(int, int, int)>&) {
  absent("train_normals");
}

}  // namespace pg
