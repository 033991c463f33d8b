#pragma once
// The training checkpoint OUT.ckpt: what it holds (the networks, their optimisers, the history,
// the run's settings), writing and reading it, and the rules that keep a resumed run the run it
// continues.
#include <torch/torch.h>

#include <array>
#include <nlohmann/json.hpp>
#include <string>

#include "networks.h"
#include "pg/learn/normal_model.h"

namespace pg::learn {

// The training's own objects a checkpoint saves and restores; the discriminator and its
// optimiser are null without the GAN loss.
struct TrainingState {
  Generator& generator;
  torch::optim::Adam& generator_optimizer;
  PatchDiscriminator* discriminator;
  torch::optim::Adam* discriminator_optimizer;
  nlohmann::json& history;  // one epoch_json per epoch done
  // The input normalisation the weights train under (from the training data, or the --init
  // model's): a resumed run must find the same.
  const std::array<float, 3>& input_mean;
  const std::array<float, 3>& input_std;
  // A hash of the training frames' labels (normals and masks): a resumed run must find the same
  // (a label-ball run into the same folder changes them and not the colour frames).
  const std::string& labels_hash;
};

// A path as one file is always named (symbolic links and ".." resolved), or as given.
std::string canonical_or_given(const std::string& path);

// The settings that make a training run what it is (learning rate, batch, seed, loss weights,
// augmentation, data, validation data, starting model), by their train-normals option names:
// held in the checkpoint, so that a resumed run keeps them, and (but the data) in the model file.
nlohmann::json run_settings(const TrainOptions& o);

// Throws InputError before any work when OUT.ckpt cannot be the checkpoint (a folder), or when a
// new run (no --resume) would replace at its first save a checkpoint of an unfinished run (a
// forgotten --resume) or of a run of unrecorded length; a finished run's is replaced.
void check_checkpoint_place(const TrainOptions& o);

// Writes the checkpoint of `epochs_done` epochs through a temporary file.
void save_checkpoint(const TrainOptions& o, int epochs_done, const TrainingState& state);

// Restores `state` from OUT.ckpt and returns the epochs it holds. Throws InputError naming the
// checkpoint when it is missing or damaged, another network's, or of another run's settings
// (run_settings), or past o.epochs, or when the input normalisation differs from the one it was
// trained under (the data folders' frames, or the --init model file, changed in between).
int load_checkpoint(const TrainOptions& o, TrainingState& state);

}  // namespace pg::learn
