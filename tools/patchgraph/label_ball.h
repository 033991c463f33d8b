#pragma once
// patchgraph label-ball: training labels for a real sensor from presses of a ball of known size.
#include <CLI/CLI.hpp>
#include <string>

namespace pg {

struct LabelBallArgs {
  std::string dataset;  // frames of ball presses (a recording, or a render's colour images)
  double diameter = 0;  // the ball's [m]
  std::string circles;  // CSV of circles given by hand (frame,u_px,v_px,radius_px), optional
  std::string out;      // the labelled dataset
  // The gel the labels model: "elastic" (the dataset's sensor's elastic model), "rigid", or empty
  // for what the dataset's sensor says (gel.elastic.enabled).
  std::string gel;
  bool quiet = false;
};

CLI::App* add_label_ball_command(CLI::App& app, LabelBallArgs& args);
int run_label_ball(const LabelBallArgs& args);

}  // namespace pg
