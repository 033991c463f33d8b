#!/usr/bin/env bash
# Reproduces the learned-normals models (docs/learned_normals.md). Needs a build (scripts/build.sh).
#
#   scripts/train_normals.sh           the default model, models/normals_unet.pt: a U-Net trained
#                                      on the repository's random-press scenes of the sphere, the
#                                      cube, a stud-like cylinder, a torus, an ellipsoid and a
#                                      rounded plate (scenes/normals/*_train.json, rendered as
#                                      written: elastic gel, shadows, the synthetic background, but
#                                      without the camera noise, which the training adds afresh
#                                      each epoch at a random sigma of 0-10 levels; and again on
#                                      the rigid gel; never the toy brick or the toy human, the
#                                      benchmark's unseen objects; validated on noisy renders); and
#                                      models/normals_mlp.pt, the per-pixel MLP baseline, on the
#                                      sphere and cube presses only
#   scripts/train_normals.sh --table   the paper's Table I: U-Net, ResNet and MLP trained on the
#                                      same presses rendered with the real DIGIT background
#                                      (../shared/data), evaluated on held-out sphere and cube
#                                      presses and the unseen toy brick and toy human, beside the
#                                      shading's inverse (eval-normals --model shading); writes
#                                      out/normals_table/table.md
#
# Environment: THREADS (Torch threads, default 1: on a 2-core machine shared with anything else,
# a second OpenMP thread makes training several times slower), EPOCHS (default 25 for the
# default U-Net's 600 images, 100 for the table's 100), MLP_EPOCHS (default 60, the MLP baseline's
# 200 images).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
tacsim="$root/build/tools/tacsim"
patchgraph="$root/build/tools/patchgraph"
threads="${THREADS:-1}"
out="$root/out/normals_data"
background="$root/../shared/data/digit/bg_digit_240_320.jpg"

# render NAME [tacsim args...]: scenes/normals/NAME.json -> $out/<variant>/NAME
render() {
  local name="$1" variant="$2"
  shift 2
  "$tacsim" render "$root/scenes/normals/$name.json" --out "$out/$variant/$name" \
    --outputs color,normal,mask --quiet "$@" > /dev/null
}

if [[ "${1:-}" != "--table" ]]; then
  # The repository's scenes render both gels: the benchmark and default scenes TACTO's rigid one,
  # the rest the elastic one. The default model sees both (the same presses, twice).
  # The U-Net's training frames are rendered without noise too: --noise-augment adds the camera's
  # noise, fresh each epoch and of a random sigma, so the model reads quieter cameras as well
  # (trained on the noisy renders alone it read noise-free frames 2-3x worse; the MLP baseline
  # below still trains on those).
  train=(sphere_train cube_train stud_train torus_train ellipsoid_train plate_train)
  for s in "${train[@]}" sphere_val cube_val toy_brick_val toy_human_val; do
    render "$s" synthetic
    render "$s" synthetic_rigid --elastic off
  done
  for s in "${train[@]}"; do
    render "$s" clean --noise off
    render "$s" clean_rigid --elastic off --noise off
  done
  d="$out/synthetic"
  r="$out/synthetic_rigid"
  data=()
  for s in "${train[@]}"; do data+=("$out/clean/$s" "$out/clean_rigid/$s"); done
  "$patchgraph" train-normals --arch unet --depth 5 --width 12 --epochs "${EPOCHS:-25}" --seed 1 \
    --contact-weight 4 --noise-augment 10 --threads "$threads" \
    --data "${data[@]}" --val "$d/sphere_val" "$d/cube_val" --out "$root/models/normals_unet.pt"
  rm -f "$root/models/normals_unet.pt.ckpt"
  # The per-pixel MLP baseline, for the normals-source rows of the benchmark: still on the sphere
  # and the cube only (60 epochs), as the paper's baseline and as benchmarks.md measured it.
  "$patchgraph" train-normals --arch mlp --hidden 32 --lr 1e-3 --epochs "${MLP_EPOCHS:-60}" --seed 1 \
    --contact-weight 4 --threads "$threads" --quiet \
    --data "$d/sphere_train" "$d/cube_train" "$r/sphere_train" "$r/cube_train" \
    --val "$d/sphere_val" "$d/cube_val" --out "$root/models/normals_mlp.pt"
  rm -f "$root/models/normals_mlp.pt.ckpt"
  "$patchgraph" eval-normals --model "$root/models/normals_unet.pt" --quiet \
    --data "$d/sphere_val" "$d/cube_val" "$d/toy_brick_val" "$d/toy_human_val" \
           "$r/sphere_val" "$r/cube_val" "$r/toy_brick_val" "$r/toy_human_val"
  exit 0
fi

if [[ ! -f "$background" ]]; then
  echo "error: $background not found (the real DIGIT background of the Table I renders)" >&2
  exit 1
fi
for s in sphere_train cube_train sphere_val cube_val toy_brick_val toy_human_val; do
  render "$s" real --background "$background"
done
d="$out/real"
table="$root/out/normals_table"
mkdir -p "$table"
# The MLP's L2 gradients are small: it learns at 1e-3 (2e-4 crawls).
declare -A arch_args=([unet]="--depth 5 --width 16" [resnet]="--depth 4 --width 8"
                      [mlp]="--hidden 32 --lr 1e-3")
for arch in unet resnet mlp; do
  # shellcheck disable=SC2086
  "$patchgraph" train-normals --arch "$arch" ${arch_args[$arch]} --epochs "${EPOCHS:-100}" --seed 1 \
    --threads "$threads" --data "$d/sphere_train" "$d/cube_train" --val "$d/sphere_val" "$d/cube_val" \
    --out "$table/$arch.pt" --quiet | tail -n 2
  "$patchgraph" eval-normals --model "$table/$arch.pt" --threads 1 --quiet \
    --data "$d/sphere_val" "$d/cube_val" "$d/toy_brick_val" "$d/toy_human_val" \
    --json "$table/$arch.json"
done
# The reference without a network: the renders' own shading inverted pixel by pixel.
"$patchgraph" eval-normals --model shading --quiet \
  --data "$d/sphere_val" "$d/cube_val" "$d/toy_brick_val" "$d/toy_human_val" \
  --json "$table/shading.json"
/usr/bin/python3 - "$table" <<'PY'
import json, sys, os
table = sys.argv[1]
names = ["sphere_val", "cube_val", "toy_brick_val", "toy_human_val"]
lines = ["| model | " + " | ".join(n.replace("_val", "") for n in names) + " | ms/frame |",
         "|---|" + "---|" * (len(names) + 1)]
for arch in ["unet", "resnet", "mlp", "shading"]:
    r = {os.path.basename(x["dataset"]): x for x in json.load(open(f"{table}/{arch}.json"))["results"]}
    cells = [f'{r[n]["mse_image"]*1e3:.2f} / {r[n]["mse_contact"]*1e3:.1f} / {r[n]["angle_contact_deg"]:.1f}°' for n in names]
    ms = sorted(r[n]["ms_per_frame"] for n in names)[len(names) // 2]
    lines.append(f"| {arch} | " + " | ".join(cells) + f" | {ms:.2f} |")
open(f"{table}/table.md", "w").write("\n".join(lines) + "\n")
print("\n".join(lines))
PY
