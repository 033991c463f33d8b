// The tracker config file: defaults, overrides, a JSON round trip, and errors that name the field.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "pg/core/error.h"
#include "pg/core/json_fields.h"
#include "pg/tracker/tracker_config.h"

namespace pg {
namespace {

std::string error_of(const std::string& text) {
  try {
    tracker_config_from_json(parse_json_text(text, "cfg.json"), "cfg.json");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(TrackerConfig, EmptyObjectGivesTheDefaults) {
  const TrackerConfig c = tracker_config_from_json(nlohmann::json::object(), "cfg.json");
  EXPECT_EQ(c.depth.crop, DepthOptions().crop);
  EXPECT_EQ(c.mask.min_depth_m, MaskOptions().min_depth_m);
  EXPECT_EQ(c.icp.max_iterations, IcpOptions().max_iterations);
  EXPECT_EQ(c.icp.kernel, IcpOptions().kernel);
}

TEST(TrackerConfig, OverridesAndRoundTrips) {
  const TrackerConfig c =
      tracker_config_from_json(parse_json_text(R"({"depth": {"crop": false, "crop_margin_px": 6,
                                    "integration": "averaged"},
                          "mask": {"min_depth_m": 5e-5},
                          "icp": {"kernel": "tukey", "kernel_scale_m": 2e-4, "voxel_size_m": 1e-4,
                                  "coarse_points": 0, "coarse_step_m": 2e-5,
                                  "symmetric": false, "cycle_extent_m": 0}})",
                                               "cfg.json"),
                               "cfg.json");
  // The overrides, read from the file and again through the writer (a field the writer left out
  // would pass a comparison of two writings, not this).
  const auto expect_overrides = [](const TrackerConfig& t, const char* which) {
    SCOPED_TRACE(which);
    EXPECT_FALSE(t.depth.crop);
    EXPECT_EQ(t.depth.crop_margin_px, 6);
    EXPECT_EQ(t.depth.integration, DepthIntegration::kAveraged);
    EXPECT_DOUBLE_EQ(t.mask.min_depth_m, 5e-5);
    EXPECT_EQ(t.icp.kernel, RobustKernel::kTukey);
    EXPECT_DOUBLE_EQ(t.icp.kernel_scale_m, 2e-4);
    EXPECT_DOUBLE_EQ(t.icp.voxel_size_m, 1e-4);
    EXPECT_EQ(t.icp.coarse_points, 0);
    EXPECT_DOUBLE_EQ(t.icp.coarse_step_m, 2e-5);
    EXPECT_FALSE(t.icp.symmetric);
    EXPECT_EQ(t.icp.cycle_extent_m, 0.0);
  };
  EXPECT_EQ(DepthOptions().integration, DepthIntegration::kParity);
  EXPECT_TRUE(IcpOptions().symmetric);
  expect_overrides(c, "parsed");
  const TrackerConfig back = tracker_config_from_json(tracker_config_to_json(c), "round trip");
  EXPECT_EQ(tracker_config_to_json(back), tracker_config_to_json(c));
  expect_overrides(back, "written and read back");
}

TEST(TrackerConfig, ErrorsNameTheFileAndField) {
  EXPECT_NE(error_of(R"({"dept": {}})").find("cfg.json: dept"), std::string::npos)
      << error_of(R"({"dept": {}})");
  EXPECT_NE(error_of(R"({"icp": {"max_iter": 3}})").find("cfg.json: icp.max_iter"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"icp": {"kernel": "cauchy"}})").find("icp.kernel"), std::string::npos);
  EXPECT_NE(error_of(R"({"mask": {"min_depth_m": "x"}})").find("mask.min_depth_m"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"depth": {"crop_margin_px": 0}})").find("depth.crop_margin_px"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"icp": {"max_correspondence_m": -1}})").find("max_correspondence_m"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"icp": {"coarse_points": -1}})").find("icp.coarse_points"),
            std::string::npos);
  EXPECT_NE(error_of(R"({"icp": {"symmetric": 1}})").find("icp.symmetric"), std::string::npos)
      << error_of(R"({"icp": {"symmetric": 1}})");
  EXPECT_NE(error_of(R"({"depth": {"integration": "poisson"}})").find("depth.integration"),
            std::string::npos)
      << error_of(R"({"depth": {"integration": "poisson"}})");
  EXPECT_THROW(load_tracker_config("/nonexistent/tracker.json"), InputError);
  // A JSON file of another of the project's kinds is named as what it is (it had read as its
  // first key: "format: unknown key").
  EXPECT_NE(error_of(R"({"format": "patchgraph-dataset", "frames": 3})")
                .find("cfg.json: is a dataset's description (dataset.json), not a tracker config"),
            std::string::npos)
      << error_of(R"({"format": "patchgraph-dataset", "frames": 3})");
  EXPECT_NE(error_of(R"({"preset": "digit", "noise": {"sigma": 2}})")
                .find("cfg.json: is a sensor file, not a tracker config"),
            std::string::npos);
  // Below a micrometre the voxel grid's keys overflowed: tracking lost, with no error.
  EXPECT_NE(error_of(R"({"icp": {"voxel_size_m": 1e-20}})")
                .find("icp.voxel_size_m: must be 0 (off) or from 1e-6 to 1 m"),
            std::string::npos)
      << error_of(R"({"icp": {"voxel_size_m": 1e-20}})");
}

}  // namespace
}  // namespace pg
