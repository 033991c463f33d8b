#pragma once
// The gel-relative label frame (NormalModelInfo::gel_relative). Internal to pg_learn; free of
// Torch, so that tests can check it directly.
#include "pg/core/image.h"
#include "pg/core/sensor.h"

namespace pg::learn {

// The undeformed gel's normals of a sensor (W x H x 3), and the rotation of one normal n between
// S and the gel frame at a pixel whose gel normal is g (the minimal rotation from +z to g):
// to_gel maps S -> gel frame, else gel frame -> S. In place.
ImageF gel_normals(const SensorModel& sensor);
void rotate_gel_frame(const float* g, float* n, bool to_gel);
// Whether two gel_normals images are the same gel (to 1e-6 per component).
bool same_gel(const ImageF& a, const ImageF& b);

}  // namespace pg::learn
