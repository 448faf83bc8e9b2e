#!/usr/bin/env bash
# The exact recipe behind models/{denoiser,error_predictor,confidence}.onnx: render a small dataset on
# this machine's adapter (lavapipe, 2 CPU cores), train the three networks with CPU torch, export them
# with model cards into models/. Resumable: rerun after an interruption and finished work is kept.
# Sized to finish in ~70 minutes on 2 cores; scale VIEWS/SIZE/GOLD/EPOCHS up on a bigger machine.
set -euo pipefail
cd "$(dirname "$0")/.."

DATA=${DATA:-data/dataset}      # /data/ and /out/ are git-ignored
EXTRA_DATA=${EXTRA_DATA:-data/dataset-extra}   # more denoiser training views (stills, another seed)
EXTRA_VIEWS=${EXTRA_VIEWS:-12}  # per scene: 10 train, 1 val, 1 test (the test views are never used)
CHECKPOINTS=${CHECKPOINTS:-out/checkpoints}
VIEWS=${VIEWS:-8}           # per scene: 6 train, 1 val, 1 test (held-out torus shape)
SIZE=${SIZE:-128}
GOLD=${GOLD:-128}
NICE="nice -n 10"

$NICE wgpu-rt dataset --scenes cornell cornell-glossy sun-room moving --views "$VIEWS" --size "$SIZE" \
    --spp 1,4,16 --gold "$GOLD" --sequence-fraction 0.3 --out "$DATA"
$NICE wgpu-rt dataset --scenes cornell cornell-glossy sun-room moving --views "$EXTRA_VIEWS" --size "$SIZE" \
    --spp 1,4,16 --gold "$GOLD" --sequence-fraction 0 --seed 1 --out "$EXTRA_DATA"

TRAIN="$NICE wgpu-rt train --data $DATA --out models --checkpoints $CHECKPOINTS --resume"
time $TRAIN denoiser --extra-data "$EXTRA_DATA" --epochs "${DENOISER_EPOCHS:-110}" --batch 4 --crop 64 128 \
    --widths 16 32 64 --lr 2e-3 --curriculum 16 4 1 1 --ssim-space display
time $TRAIN error-predictor --epochs "${HEATMAP_EPOCHS:-60}" --batch 4 --crop 64 128 --lr 3e-3
time $TRAIN confidence --epochs "${HEATMAP_EPOCHS:-60}" --batch 4 --crop 64 128 --lr 3e-3
