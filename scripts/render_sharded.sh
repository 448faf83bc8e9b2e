#!/usr/bin/env bash
# render_sharded.sh N DATASET-ARGS...: `wgpu-rt dataset DATASET-ARGS` in N processes at once (shards i/N),
# then once unsharded, which renders nothing and rebuilds the manifest from every view (shards that end
# together could each have written one missing the other's last view). A view's scene set-up, BVH build,
# shader compile and EXR writes are host work, which a GPU machine's many cores share out this way.
set -uo pipefail
shards=$1; shift
pids=()
# stopped (gpu_session.sh's part limit sends SIGTERM): stop the shards too, each of which lists the views it
# finished in the manifest as it exits, rather than leave them rendering into the next part's time
trap 'kill -TERM "${pids[@]}" 2>/dev/null; wait; exit 143' TERM
for ((i = 0; i < shards; i++)); do
    wgpu-rt dataset "$@" --shard "$i/$shards" & pids+=($!)
done
failed=0
for pid in "${pids[@]}"; do wait "$pid" || failed=1; done
[ $failed = 0 ] || { echo "render_sharded.sh: a shard failed; rerun to finish the views it left" >&2; exit 1; }
wgpu-rt dataset "$@"
