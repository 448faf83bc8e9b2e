#!/usr/bin/env bash
# The exact recipe behind models/{denoiser,error_predictor,confidence}.onnx: render a small dataset on
# this machine's adapter (lavapipe, 2 CPU cores), train the three networks with CPU torch, export them
# with model cards into models/. Resumable: rerun after an interruption and finished work is kept.
# About 8.5 hours on 2 shared cores (renders ~2 h, denoiser 48 min + three fine-tunes of 25, 27 and 39 min,
# the two small networks minutes, then ~10 min of generated-world renders and a 47-min fine-tune on them,
# then ~55 min of renders at several spp and two 13-min fine-tunes for the sample-count input, then ~40
# min of generated-world sequences and a 2-min confidence model on them, then 23 min of world renders and
# ~20- and 14-min fine-tunes of a denoiser one level deeper);
# scale VIEWS/SIZE/GOLD/EPOCHS up on a bigger machine. The shipped denoiser went one step further, which
# needs a GPU: this script's denoiser fine-tuned on CUDA (`scripts/gpu_session.sh train`, the H200 settings
# in BENCHMARKS.md §31), then `wgpu-rt blend OUT/denoiser.onnx FINE_TUNED.onnx --weight 0.5` (its card says so).
set -euo pipefail
cd "$(dirname "$0")/.."

DATA=${DATA:-data/dataset}      # /data/ and /out/ are git-ignored
EXTRA_DATA=${EXTRA_DATA:-data/dataset-extra}   # more denoiser training views (stills, seeds 1 to 4)
EXTRA_DATA2=${EXTRA_DATA2:-data/dataset-extra2}
EXTRA_DATA3=${EXTRA_DATA3:-data/dataset-extra3}
EXTRA_DATA4=${EXTRA_DATA4:-data/dataset-extra4}   # gold at 4 × GOLD spp: cleaner targets
EXTRA_DATA8=${EXTRA_DATA8:-data/dataset-extra8}   # for the last fine-tune: gold at 2 × GOLD spp
EXTRA_DATA9=${EXTRA_DATA9:-data/dataset-extra9}
WORLDS_DATA=${WORLDS_DATA:-data/worlds-train}       # round 4: generated worlds (training family)
BUILTIN_DATA=${BUILTIN_DATA:-data/builtin-train}   # round 4: built-in views at the worlds' size
WORLDS_SPP_DATA=${WORLDS_SPP_DATA:-data/worlds-spp}     # round 5: worlds at 1-64 spp
WORLDS_SPP_DATA2=${WORLDS_SPP_DATA2:-data/worlds-spp2}
BUILTIN_SPP_DATA=${BUILTIN_SPP_DATA:-data/builtin-spp}  # round 5: built-in views at 1-64 spp
WORLDS_SEQ_DATA=${WORLDS_SEQ_DATA:-data/worlds-seq}     # round 6: generated-world sequences (confidence)
BUILTIN_SEQ_DATA=${BUILTIN_SEQ_DATA:-data/builtin-seq}
WORLDS_SPP_DATA3=${WORLDS_SPP_DATA3:-data/worlds-spp3}  # round 7: 96 more worlds at 1-64 spp
COPIES=${COPIES:-16}            # independent 1-spp renders per frame for the last fine-tune
EXTRA_VIEWS=${EXTRA_VIEWS:-12}  # per scene: 10 train, 1 val, 1 test (the test views are never used)
SEQ_DATA=${SEQ_DATA:-data/dataset-seq}   # + seed: confidence-model sequences (seeds 5 and 6)
CHECKPOINTS=${CHECKPOINTS:-out/checkpoints}
OUT=${OUT:-models}          # where the .onnx files and model cards go
VIEWS=${VIEWS:-8}           # per scene: 6 train, 1 val, 1 test (held-out torus shape)
SIZE=${SIZE:-128}
GOLD=${GOLD:-128}
NICE="nice -n 10"
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-1}   # torch threads: 1, as the 2 cores are shared

render_shards() {   # the first five shards with $1 independent 1-spp renders per frame
    $NICE wgpu-rt dataset --scenes cornell cornell-glossy sun-room moving --views "$VIEWS" --size "$SIZE" \
        --spp 1,4,16 --gold "$GOLD" --sequence-fraction 0.3 --noisy-copies "$1" --out "$DATA"
    for seed_gold_folder in "1 1 $EXTRA_DATA" "2 1 $EXTRA_DATA2" "3 1 $EXTRA_DATA3" "4 4 $EXTRA_DATA4"; do
        set -- "$1" $seed_gold_folder
        $NICE wgpu-rt dataset --scenes cornell cornell-glossy sun-room moving --views "$EXTRA_VIEWS" --size "$SIZE" \
            --spp 1,4,16 --gold $(($3 * GOLD)) --sequence-fraction 0 --seed "$2" --noisy-copies "$1" --out "$4"
    done
}
render_shards 1

TRAIN="$NICE wgpu-rt train --data $DATA --out $OUT --checkpoints $CHECKPOINTS --resume"
time $TRAIN denoiser --extra-data "$EXTRA_DATA" "$EXTRA_DATA2" "$EXTRA_DATA3" "$EXTRA_DATA4" \
    --epochs "${DENOISER_EPOCHS:-300}" --batch 4 --crop 64 128 --widths 16 32 64 128 --lr 2e-3 \
    --curriculum 16 4 1 1 --ssim-space display --validate-every 10
# Fine-tune at 1 spp, twice, each round from the last one's weights with a fresh warm-up + cosine schedule
# (a warm restart; peak LR 5e-4, then 3e-4), all epochs at the spp the runtime denoises. The last card
# credits every run. Two torch threads: nothing else runs meanwhile (~25 min a round).
previous="$CHECKPOINTS/denoiser.pt"
for round_lr in "1 5e-4" "2 3e-4"; do
    set -- $round_lr
    time OMP_NUM_THREADS=2 $TRAIN denoiser --extra-data "$EXTRA_DATA" "$EXTRA_DATA2" "$EXTRA_DATA3" "$EXTRA_DATA4" \
        --checkpoints "$CHECKPOINTS/denoiser-1spp-$1" --init-from "$previous" \
        --epochs "${FINETUNE_EPOCHS:-300}" --batch 4 --crop 64 128 --widths 16 32 64 128 --lr "$2" \
        --curriculum 1 --ssim-space display --validate-every 10
    previous="$CHECKPOINTS/denoiser-1spp-$1/denoiser.pt"
done
# Round 3: every frame gets COPIES independent 1-spp renders (a view's one 1-spp noise realization was seen
# 750 times in the runs above; now each draw takes one of 16) and two more shards join (264 training views).
# The copies are added to the finished shards (only the copies render: ~1 min a shard), as they were for
# the shipped model; a fresh run could pass --noisy-copies to the first renders instead. The error
# predictor below draws the copies too.
render_shards "$COPIES"
for seed_folder in "8 $EXTRA_DATA8" "9 $EXTRA_DATA9"; do
    set -- $seed_folder
    $NICE wgpu-rt dataset --scenes cornell cornell-glossy sun-room moving --views "$EXTRA_VIEWS" --size "$SIZE" \
        --spp 1,4,16 --gold $((2 * GOLD)) --sequence-fraction 0 --seed "$1" --noisy-copies "$COPIES" --out "$2"
done
time OMP_NUM_THREADS=2 $TRAIN denoiser \
    --extra-data "$EXTRA_DATA" "$EXTRA_DATA2" "$EXTRA_DATA3" "$EXTRA_DATA4" "$EXTRA_DATA8" "$EXTRA_DATA9" \
    --checkpoints "$CHECKPOINTS/denoiser-1spp-3" --init-from "$previous" \
    --epochs "${FINETUNE_EPOCHS:-300}" --batch 4 --crop 64 128 --widths 16 32 64 128 --lr 5e-4 \
    --curriculum 1 --ssim-space display --validate-every 10
# Since session 42 `wgpu-rt train` trains every network with the exposure step (--auto-exposure on, the default):
# this predictor reads its probe, the confidence models below their frames, at one key. The shipped predictor is
# this step's (rendered and trained anew so, BENCHMARKS.md §41); the shipped confidence model was trained before
# and reads its frames as they are (its file says nothing).
time $TRAIN error-predictor --epochs "${HEATMAP_EPOCHS:-60}" --batch 4 --crop 64 128 --lr 3e-3
# The confidence model learns on what the temporal pass feeds it, the *denoised* frame: $OUT/denoiser.onnx
# (above) makes it, so this runs after the denoiser. Its frame pairs: DATA's, plus two datasets of nothing
# but sequences (only 1 spp and gold are needed): 66 training pairs instead of 18.
for seed in 5 6; do
    $NICE wgpu-rt dataset --scenes cornell cornell-glossy sun-room moving --views 5 --size "$SIZE" --spp 1 \
        --gold "$GOLD" --sequence-fraction 1 --seed "$seed" --out "$SEQ_DATA$seed"
done
time $TRAIN confidence --extra-data "${SEQ_DATA}5" "${SEQ_DATA}6" --epochs "${HEATMAP_EPOCHS:-60}" --batch 4 \
    --crop 64 128 --lr 3e-3
# Round 4, after the confidence model (which learned on round 3's output, as the shipped one did): the
# denoiser fine-tuned from its exported weights on 64 generated worlds plus built-in views at 96², the
# built-in views listed twice (twice the weight), so that unseen scenes gain without the built-ins losing.
$NICE wgpu-rt dataset --worlds 64 --family training --size 96 --spp 1 --noisy-copies 4 --gold 256 \
    --sequence-fraction 0 --seed 0 --out "$WORLDS_DATA" --quiet
$NICE wgpu-rt dataset --scenes cornell cornell-glossy sun-room moving --views 12 --size 96 --spp 1 --noisy-copies 4 \
    --gold 256 --sequence-fraction 0 --seed 11 --out "$BUILTIN_DATA" --quiet
time $NICE wgpu-rt train denoiser --data "$BUILTIN_DATA" --extra-data "$BUILTIN_DATA" "$WORLDS_DATA" --out "$OUT" \
    --checkpoints "$CHECKPOINTS/denoiser-worlds" --resume --init-from "$OUT/denoiser.onnx" \
    --epochs "${WORLDS_EPOCHS:-500}" --batch 4 --crop 64 96 --widths 16 32 64 128 --lr 1e-4 --curriculum 1 \
    --ssim-space display --validate-every 50
# Round 5: the sample-count input. The denoiser now reads 1/sqrt(spp) as an 11th plane; the round-4 model
# (10 inputs) is its start, with zero weights on the new plane, so it starts as that model. 192 more
# generated worlds and 32 built-in views rendered at 1-64 spp, and every crop draws one of its view's
# sample counts (--curriculum any). Two fine-tunes, 13 min each on two threads.
$NICE wgpu-rt dataset --worlds 96 --family training --size 96 --spp 1,2,4,8,16,64 --noisy-copies 2 --gold 512 \
    --sequence-fraction 0 --seed 1 --out "$WORLDS_SPP_DATA" --quiet
$NICE wgpu-rt dataset --worlds 96 --family training --size 96 --spp 1,2,4,16,64 --noisy-copies 3 --gold 512 \
    --sequence-fraction 0 --seed 2 --out "$WORLDS_SPP_DATA2" --quiet
$NICE wgpu-rt dataset --scenes cornell cornell-glossy sun-room moving --views 8 --size 96 --spp 1,4,16,64 \
    --gold 1024 --sequence-fraction 0 --seed 21 --out "$BUILTIN_SPP_DATA" --quiet
time OMP_NUM_THREADS=2 $NICE wgpu-rt train denoiser --data "$BUILTIN_DATA" --extra-data "$BUILTIN_DATA" "$WORLDS_DATA" \
    "$WORLDS_SPP_DATA" --out "$CHECKPOINTS/denoiser-spp" --checkpoints "$CHECKPOINTS/denoiser-spp" --resume \
    --init-from "$OUT/denoiser.onnx" --epochs 200 --batch 4 --crop 64 96 --widths 16 32 64 128 --lr 1e-4 \
    --curriculum any --ssim-space display --validate-every 25
time OMP_NUM_THREADS=2 $NICE wgpu-rt train denoiser --data "$BUILTIN_SPP_DATA" --extra-data "$BUILTIN_DATA" \
    "$WORLDS_DATA" "$WORLDS_SPP_DATA" "$WORLDS_SPP_DATA2" --out "$OUT" --checkpoints "$CHECKPOINTS/denoiser-spp2" \
    --resume --init-from "$CHECKPOINTS/denoiser-spp/denoiser.onnx" --epochs 150 --batch 4 --crop 64 96 \
    --widths 16 32 64 128 --lr 2e-4 --curriculum any --ssim-space display --validate-every 25
# Round 6: the confidence model again, now on what the round-5 denoiser makes of 48 generated-world
# sequences (3 frames each) and 20 built-in ones, at 96² (its earlier data: built-in sequences only).
$NICE wgpu-rt dataset --worlds 48 --family training --size 96 --spp 1 --gold 256 --sequence-fraction 1 --seed 7 \
    --out "$WORLDS_SEQ_DATA" --quiet
$NICE wgpu-rt dataset --scenes cornell cornell-glossy sun-room moving --views 5 --size 96 --spp 1 --gold 128 \
    --sequence-fraction 1 --seed 5 --out "$BUILTIN_SEQ_DATA" --quiet
time $NICE wgpu-rt train confidence --data "$WORLDS_SEQ_DATA" --extra-data "$BUILTIN_SEQ_DATA" --out "$OUT" \
    --checkpoints "$CHECKPOINTS/confidence-worlds" --resume --epochs 60 --batch 4 --crop 64 128 --lr 3e-3
# Round 7: the denoiser one U-Net level deeper (a fifth level of 128 channels at 1/16 resolution, added to
# the level above rather than concatenated and merged: +3.9 % FLOPs at 1080p). The fine-tune from the
# round-5 model starts as exactly that model (the new level's transposed conv at zero); 96 more worlds;
# 150 epochs, ~20 min on two threads (a second round measured no gain); then 120 epochs more with a loss term
# on 8×8 block means (--lowpass 2), 14 min. The confidence model stays round 6's.
$NICE wgpu-rt dataset --worlds 96 --family training --size 96 --spp 1,2,4,16,64 --noisy-copies 3 --gold 512 \
    --sequence-fraction 0 --seed 3 --out "$WORLDS_SPP_DATA3" --quiet
time OMP_NUM_THREADS=2 $NICE wgpu-rt train denoiser --data "$BUILTIN_SPP_DATA" --extra-data "$BUILTIN_DATA" \
    "$WORLDS_DATA" "$WORLDS_SPP_DATA" "$WORLDS_SPP_DATA2" "$WORLDS_SPP_DATA3" --out "$OUT" \
    --checkpoints "$CHECKPOINTS/denoiser-deeper" --resume --init-from "$OUT/denoiser.onnx" \
    --widths 16 32 64 128 128 --bottom-merge add --epochs 150 --batch 4 --crop 64 96 --lr 1e-4 --seed 3 \
    --curriculum any --ssim-space display --validate-every 25
time OMP_NUM_THREADS=2 $NICE wgpu-rt train denoiser --data "$BUILTIN_SPP_DATA" --extra-data "$BUILTIN_DATA" \
    "$WORLDS_DATA" "$WORLDS_SPP_DATA" "$WORLDS_SPP_DATA2" "$WORLDS_SPP_DATA3" --out "$OUT" \
    --checkpoints "$CHECKPOINTS/denoiser-lowpass" --resume --init-from "$OUT/denoiser.onnx" \
    --widths 16 32 64 128 128 --bottom-merge add --epochs 120 --batch 4 --crop 64 96 --lr 1e-4 --seed 5 \
    --lowpass 2 --curriculum any --ssim-space display --validate-every 30
