#!/usr/bin/env bash
# render_sharded.sh N DATASET-ARGS...: `wgpu-rt dataset DATASET-ARGS` in N processes at once (shards i/N),
# then once unsharded, which renders nothing and rebuilds the manifest from every view (shards that end
# together could each have written one missing the other's last view). A view's scene set-up, BVH build,
# shader compile and EXR writes are host work, which a GPU machine's many cores share out this way.
set -uo pipefail
shards=$1; shift
pids=()
for ((i = 0; i < shards; i++)); do
    wgpu-rt dataset "$@" --shard "$i/$shards" & pids+=($!)
done
failed=0
for pid in "${pids[@]}"; do wait "$pid" || failed=1; done
[ $failed = 0 ] || { echo "render_sharded.sh: a shard failed; rerun to finish the views it left" >&2; exit 1; }
wgpu-rt dataset "$@"
