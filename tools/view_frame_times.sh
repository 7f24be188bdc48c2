#!/usr/bin/env bash
# Frame times of `lensbake view` at 800x600: every model, 1, 4 and 16 samples per pixel per frame,
# on the CPU twin and on the GPU wgpu finds (lavapipe here: WGPU_BACKEND=vulkan). Each run waits
# for its table (baked model), renders 3 frames headless and reports their mean; prints CSV.
# Usage: tools/view_frame_times.sh [lensbake binary] > notebooks-out/view/frame_times.csv
set -euo pipefail
bin="${1:-lensbake}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
printf 'wait-bake\nframes 3\nquit\n' > "$work/script.txt"
echo "backend,backend_used,model,spp_per_frame,frames,mean_ms_per_frame"
for backend in cpu gpu; do
  for model in thin thick seidel traced baked; do
    for n in 1 4 16; do
      out="$("$bin" view --lens dgauss-50mm --width 800 --height 600 --offscreen \
        --backend "$backend" --model "$model" --spp-per-frame "$n" --spp $((3 * n)) \
        --tables-root "$work/tables" --script "$work/script.txt")"
      adapter="$(printf '%s\n' "$out" | sed -n 's/^backend: //p' | head -1)"
      ms="$(printf '%s\n' "$out" | sed -n 's/.*, \([0-9.]*\) ms per rendered frame (mean)$/\1/p')"
      echo "$backend,\"$adapter\",$model,$n,3,$ms"
    done
  done
done
