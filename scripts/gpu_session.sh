#!/usr/bin/env bash
# The measurements only a lent GPU can give (issues 13 and 12 at their scale); results go to $OUT (the
# device tool brings them back). A session has 15 minutes of device time, starts included, so two
# calls do it (session 14 on an H200: the first 358 s, the second 26 s; BENCHMARKS.md §12):
#
#   bash ../shared/device/prepare --peers          # here, once per session
#   mkdir -p .meshes && cp ../shared/meshes/stanford-bunny.obj .meshes/   # .meshes in .git/info/exclude
#   run: carry [".device", ".device-peers/peer-oidn.tar.xz", ".meshes"],
#        command ". .device/setup.sh; D=$OUT; OUT=/tmp/gs/r1 ARCHIVE=$D/r1.tgz DEADLINE=380 PART_LIMIT=170
#                 bash scripts/gpu_session.sh nn tests frame heldout"
#   run: carry [".device", ".device-peers/peer-mitsuba.tar.xz", ".meshes"], at once (the machine stays
#        warm for 30 s), command ". .device/setup.sh; D=$OUT; OUT=/tmp/gs/r2 ARCHIVE=$D/r2.tgz
#                 bash scripts/gpu_session.sh trace"
#
# Session 22 (H200, BENCHMARKS.md §21) took: nn + frame + heldout_render 390 s, trace 67 s, heldout 238 s
# (heldout_denoise needs more than 120 s: give it PART_LIMIT=200). Session 23 (§22): tests + frame + nn
# 278 s (tests 157 s), train 288 s (its renders 218 s; the fine-tune was cut to 0.7 of its 3 minutes,
# since fixed). Sessions 24 and 25 had no GPU. Session 26 (§25, H200): call 1 with the Mitsuba peer,
# DEADLINE=270 PART_LIMIT=160 TEST_WORKERS=12 `tests trace frame nn_widths` 277 s (tests 126 s, trace 72,
# frame 62); call 2 with the OIDN peer `train` (renders 108 s, fine-tune 201 s) then `train_eval` (held-out
# render 49 s, scoring 43 s) 411 s; the device time ran out after that. Session 27 had no GPU. Next: call 1
# with the Mitsuba peer, DEADLINE=240 PART_LIMIT=160 TEST_WORKERS=12, timeout_s 400: `tests nn_widths
# frame` (the Mitsuba cross-checks on the CUDA variant; the 8-channel tile on the narrowed networks, and
# everywhere in the shipped one (conv tiling staged-narrow); the f16 tile, math f16-acc; the targeted pass
# with the tile-ordered work list, its build timed alone, batches of 2^21 items and items of one sample;
# ~270 s); call 2 at once,
# timeout_s 540, the shipped widths at scale (issue 12's per-scene bar; session 27, §26), OIDN peer carried:
#   . .device/setup.sh; D=$OUT; export OUT=/tmp/gs/r2 ARCHIVE=$D/r2.tgz; SHARDS=12 TRAIN_WORLDS=160
#   TRAIN_BATCH=32 TRAIN_LR=2e-4 TRAIN_MINUTES=3.5 TRAIN_FLAGS=--permute-colours PART_LIMIT=270 bash
#   scripts/gpu_session.sh train; DEADLINE=100 PART_LIMIT=120 bash scripts/gpu_session.sh train_eval
# (~480 s; the renders are estimates: a render part stopped at PART_LIMIT leaves the views it finished,
# listed, for the training). Until session 27 the fine-tunes' 256² views trained at 96-px crops
# (batches mixed with the 96² worlds, §26). Session 28 had no GPU; since then the denoiser reads its
# input white-balanced (§27), in training as in every scoring part, so call 2's fine-tune learns it.
# Session 29 had no GPU; since then a path that escapes takes the background's radiance as albedo (§28),
# so every view the parts render (guide_albedo 2) has it, and call 2 trains on it for the first time.
# Session 30 had no GPU; since then a sun's and a sky's power, by which next-event estimation picks
# lights, counts through the region the camera frames (§29): four held-out dusk worlds lose the fireflies
# that filled their inputs and their golds, so `heldout` scores them against the truth for the first time.
# Session 31 had no GPU; since then each shading point picks lights by their estimated irradiance there
# (§30: up to 16 emitter groups looped over for each light sample, 9-34 % more time a sample on lavapipe
# where a scene has several): `trace` and `frame` give the first GPU numbers of that cost (cornell has
# one group and compiles without it; the worlds of `heldout` have several), and call 2's renders train on
# the cleaner inputs (guide_albedo 3: an emitter's albedo at least 0.5 grey).
# Session 32 (H200, §31) ran call 2 first (OIDN peer, timeout_s 570: 560 s): train_render 114 s (160
# worlds at 256², SHARDS=12), train_render_builtin 22, train_render_small 83, train 242 (12280 steps of 32
# crops, 61.7 steps/s), heldout_render 68; train_eval then failed on a fresh dataset's config (fixed
# since), so the model was scored on lavapipe. Call 1 (Mitsuba peer, DEADLINE=150 PART_LIMIT=120
# TEST_WORKERS=14): the suite reached ~95 % in 120 s with two failures whose names the cut-off output
# lost (now -v: each result is on its own line as it comes); `frame` then ran up to the deadline.
# Next (~870 s with one start): call 1 as session 32's, the OIDN peer carried, timeout_s 590, with
# TRAIN_BUILTIN_VIEWS=16 (the built-in views, 64 instead of 32: session 32's fine-tune lost up to 0.8 dB
# on them), TRAIN_WORLDS=128 and TRAIN_MINUTES=3 (the two scorings add ~90 s; ~580 s in all) — its renders are the first with lamps in view in the training worlds (worlds_version 2), it
# fine-tunes the shipped blend, and train_eval scores new and shipped on 4096-spp gold (issue 12's
# measurement of record); then at once, the Mitsuba peer carried, timeout_s 210:
#   . .device/setup.sh; D=$OUT; export OUT=/tmp/gs/r1 ARCHIVE=$D/r1.tgz; PART_LIMIT=160 TEST_WORKERS=14
#   bash scripts/gpu_session.sh half_math tests
# (since session 32, f16-acc is the discrete-GPU default on lavapipe's evidence and the H200's 6.51 ms
# against 7.48; half_math measures its images against onnxruntime's on NVIDIA, ~30 s).
# Sessions 33–36 had no GPU. Since session 36 the shipped denoiser is that blend fine-tuned three times on two
# CPU cores on lamps-in-view worlds (75, then all 150; the last with --log-mse 0.05) and 24 built-in views at
# 128² (§33–§35: +0.26 / +0.47 dB at 1 / 4 spp on the held-out family against 4096-spp gold); call 1's
# fine-tune starts from it (TRAIN_INIT's default). Sessions 37–39 had no GPU. Since session 39 half the training
# worlds are painted with textures as vertex colours (worlds_version 3, §38): call 1's renders are the first at
# scale with textures (18 painted worlds on two CPU cores left the textured `painted` scene level at 4 spp), so
# train_eval should also score `painted` (bench_spp.py --scenes painted) beside the held-out family.
# Session 40 had no GPU; it found the denoiser's ceiling (§39: a converged 1024-spp render comes back at 43–45
# dB where OIDN keeps 50–56), which is what holds it back from 16 spp: after a fine-tune at scale, also run
# benchmarks/bench_passthrough.py (the model's --models; ~1 s a scene there once the inputs are rendered).
# Session 41 had no GPU; since then `wgpu-rt train` packs the denoiser's input with the exposure step by
# default (each frame's irradiance brought to one key, §40) and writes that into the ONNX file, which
# `--auto-exposure auto` follows when the model runs; the shipped model is a 100-minute CPU fine-tune with
# it (§40), so call 1's fine-tune continues in the same convention.
# Sessions 42–44 had no GPU. Since session 44 the converge pass (the hand-over above 1 spp, and temporal mode's
# static camera) averages over a 15×15 window, 225 taps of three likeness weights where it had 49 (§43: 6× its
# lavapipe time); `frame`'s converge_cost part times it alone at 1080p, to set against the network's.
# Sessions 45–47 had no GPU. Since session 47 a frame whose packed denoiser input is wider than one storage binding
# denoises in bands of rows (frame/bands.py, §46); a GPU binds gigabytes, so there only frames far past 4K take
# them, and `tests` checks them under a shrunken limit. Session 48 had no GPU; since then the training worlds are
# worlds_version 6 (§47: a quarter of the cameras through a thin lens, half the skies as environment maps, three
# in ten matte materials coated as plastic); session 49 made it 7 (§48: normal maps on some worlds' floors and
# walls), session 50 8 (§49: half the coats rough, some glass tinted, cut-out screens in view) and session 51 9
# (§50: some glass absorbing inside), session 52 10 (§51: worn metal, metal-rough maps on some matte surfaces),
# so call 1's renders are the first with any of them (the screens' and the
# absorbing glass's golds render through Mitsuba's volpath); since session 51 the albedo seen through mirrors and
# glass is tinted by their colour (guide albedo 4, §50), so older datasets' albedo differs there;
# train_check scores shipped and new on the scenes of those features too (FEATURE_SCENES: `painted`,
# benchmarks/scenes/plaza-lens.toml, examples/sky-courtyard.toml, examples/still-life.toml (rough coats since
# session 50), examples/leaf-screen.toml (cut-outs), examples/coloured-glass.toml (absorbing glass, session 51) and
# examples/meshes/gallery.glb (a glTF file's own camera and lights, session 51) and examples/worn-metal.toml
# (metal-rough maps, session 52);
# bench_spp.py at 256² against Mitsuba's 4096-spp gold, as BENCHMARKS.md §47–§50 scored them on lavapipe).
# Parts: tests (the whole suite, CI=true, on TEST_WORKERS workers, default 8), nn (profile of the shipped
# denoiser at 1080p as the default picks and in fp32, engine steps against torch cuDNN and OIDN CUDA),
# half_math (the denoised images of each half-precision math against onnxruntime's),
# nn_widths (the same architecture at other widths, untrained, profiled at 1080p), nn_variants (§21's:
# with naga's bounds checks, with each weight fetch and as the autotuner picks), trace
# (samples/s against Mitsuba cuda_ad_rgb with the threaded and the wide BVH and the measured choice; closest-hit rays/s of each
# walk on 100k random triangles and the bunny; cornell also with bounds checks; what the watertight tests
# cost), frame (fused frame, adaptive targeted pass, moving vs static: the `moving` scene and the
# bunny), heldout (issue 12's evidence at its scale: 24 held-out worlds at 256² with 4096-spp gold,
# ours "balanced"/"high" against OIDN balanced/high over 3 noise realizations, brute force up to 256
# spp, ours again without the low band, chroma hold and post filter and without the post filter alone,
# and the product path against spp at 256²), train (the shipped denoiser fine-tuned for
# TRAIN_MINUTES on training worlds rendered at 256² with built-in views and 96² worlds mixed in, the
# model in $OUT/model; DEADLINE unset, PART_LIMIT=280, ARCHIVE set), train_eval (that model, or TRAINED=DIR,
# scored on the held-out worlds against OIDN), train_check (train_eval,
# then shipped and new on §14's checks at 256² and 128² and on FEATURE_SCENES; in a second call at once, while
# the machine is warm, or after carrying the model back in as TRAINED). Both render the held-out worlds first
# unless they are there. SIZE (default 1080p) shrinks
# everything for a dry run on lavapipe: SIZE=small. Each part stops after PART_LIMIT seconds (default
# 300), and parts that would start after DEADLINE seconds (default: none) are skipped, so a call keeps
# inside the device time it was given. A folder .meshes (ignored by git, named in `carry`) stands in for
# ../shared/meshes, which does not travel: the bunny rows (trace, moving) need its stanford-bunny.obj.
# With ARCHIVE=FILE.tgz the results so far are packed into FILE after every part (the device tool brings
# back 8 files at most).
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-out/gpu-session}
mkdir -p "$OUT"
if [ -d .meshes ] && [ ! -e ../shared/meshes ]; then mkdir -p ../shared && cp -r .meshes ../shared/meshes; fi
small=$([ "${SIZE:-1080p}" = small ] && echo 1 || echo 0)
W=$([ $small = 1 ] && echo 64 || echo 1920); H=$([ $small = 1 ] && echo 64 || echo 1080)
SQUARE=$([ $small = 1 ] && echo 64 || echo 1024)   # the square-only benchmarks (bench_trace, bench_moving)
NN=$([ $small = 1 ] && echo 256 || echo 1080p)
WORLDS=$([ $small = 1 ] && echo 2 || echo 24); VIEW=$([ $small = 1 ] && echo 32 || echo 256)
GOLD=$([ $small = 1 ] && echo 64 || echo 4096)
# parts train and train_check, one call each (session 22 on an H200: the 24 held-out views with 4096-spp
# gold in 76–85 s; the rest estimated): held-out render 80 s (once), training worlds ~150 s (+ ~40 s of
# built-in and 96² views), training TRAIN_MINUTES; then scoring ~40 s, §14's checks ~60 s each
TRAIN_WORLDS=${TRAIN_WORLDS:-$([ $small = 1 ] && echo 4 || echo 80)}
TRAIN_GOLD=$([ $small = 1 ] && echo 32 || echo 1024)
TRAIN_BATCH=${TRAIN_BATCH:-8}; TRAIN_LR=${TRAIN_LR:-1e-4}
TRAIN_MINUTES=${TRAIN_MINUTES:-$([ $small = 1 ] && echo 0.5 || echo 2.5)}
# TRAIN_INIT: the ONNX the fine-tune starts from (default the shipped denoiser; an earlier session's
# $OUT/model/denoiser.onnx, carried in, continues its training). TRAIN_FLAGS: more `wgpu-rt train` flags
# (e.g. --permute-colours, §23). TRAIN_WIDTHS: the fine-tune's U-Net widths; narrower ones start from
# the shipped model's heaviest channels (§22: "12 24 48 96 96", 0.57× its FLOPs), wider ones as the shipped
# model with the new channels unread (§45: "32 32 64 128 128", 1.81× its FLOPs). TRAIN_WORLDS: training
# worlds at 256² (and as many at 96²). TRAIN_BATCH, TRAIN_LR: §25's CUDA steps took 21 ms at batch 8
# (48 steps/s), while the U-Net's work in a step (~67 GFLOP forward and backward, crops of ~192²) is a
# few percent of that on an H200: the step's time is the host launching kernels, so a larger batch
# should train on more crops in about the same time (not yet measured); --validate-every 250, since a
# validation scores every held-out view's metrics on the host (~0.1 s a 256² view here, §26) and a large
# batch's epoch is a handful of steps; --epochs 4000 leaves the length to
# TRAIN_MINUTES (§25's run of batch 8 already reached 373 of its 400 epochs). With the estimates above,
# ~9 min in all
SMALL_VIEW=$([ $small = 1 ] && echo 32 || echo 96)   # worlds at the old training size, mixed into the fine-tune
CHECK_VIEW=$([ $small = 1 ] && echo 48 || echo 128); CHECK_GOLD=$([ $small = 1 ] && echo 32 || echo 1024)
CHECK_SCENES="cornell cornell-glossy sun-room world-2147483661 world-2147483667 world-2147483660 world-2147483665
    world-2147483670 world-2147483656 world-2147483648 world-2147483651 world-2147483652 world-2147483654"
CHECK_SCENES_SMALL="world-2147483648 world-2147483651 world-2147483653 cornell cornell-glossy sun-room
    world-2147483660 world-2147483661"
FEATURE_SCENES="painted benchmarks/scenes/plaza-lens.toml examples/sky-courtyard.toml examples/still-life.toml
    examples/leaf-screen.toml examples/coloured-glass.toml examples/meshes/gallery.glb examples/worn-metal.toml"
FEATURE_VIEW=$([ $small = 1 ] && echo 32 || echo 256)
TRACE_SPP=$([ $small = 1 ] && echo 4 || echo 64)   # at 16 spp 1024² the fixed costs of a render weigh in

part() {   # part NAME COMMAND...: run, keep its output, go on after a failure
    local name=$1; shift
    if [ -n "${DEADLINE:-}" ] && [ $SECONDS -ge "$DEADLINE" ]; then
        echo "== $name: skipped (past DEADLINE=$DEADLINE s)" | tee -a "$OUT/summary.txt"; return
    fi
    echo "== $name: $*" | tee -a "$OUT/summary.txt"
    local started=$SECONDS
    timeout "${PART_LIMIT:-300}" "$@" > "$OUT/$name.txt" 2>&1
    echo "   exit $? after $((SECONDS - started)) s" | tee -a "$OUT/summary.txt"
    archive
}

archive() {   # with ARCHIVE set, the results so far packed into it
    if [ -n "${ARCHIVE:-}" ]; then tar -czf "$ARCHIVE" -C "$(dirname "$OUT")" "$(basename "$OUT")"; fi
}

# render_dataset NAME DATASET-ARGS...: one part rendering a dataset in SHARDS processes at once (default
# 4: scripts/render_sharded.sh)
SHARDS=${SHARDS:-4}
render_dataset() {
    local name=$1; shift
    part "$name" bash scripts/render_sharded.sh "$SHARDS" "$@"
}

HELDOUT=data/worlds-heldout-$VIEW
render_heldout() {   # the held-out worlds, the test set of parts heldout and train
    render_dataset heldout_render --worlds $WORLDS --family held_out --size $VIEW --spp 1,4,16,64 \
        --gold $GOLD --sequence-fraction 0 --out $HELDOUT --quiet
}

nvidia-smi > "$OUT/nvidia-smi.txt" 2>&1 || true
for what in "$@"; do
    case $what in
    tests)
        root=$PWD
        workers=$(python3 -c "import xdist" 2>/dev/null && echo "-n ${TEST_WORKERS:-8}" || echo "")
        part tests bash -c "cd /tmp && CI=true python3 -m pytest '$root/tests' -v -rs $workers -p no:cacheprovider" ;;
    nn)
        profile="wgpu-rt profile models/denoiser.onnx --size ${W}x${H}"   # word-split on purpose
        # the default on a discrete GPU with shader-f16 (fp16 storage, f16-acc math: §31), then fp32 beside it
        part profile_auto $profile
        part profile_fp32 $profile --precision fp32
        part bench_nn python3 benchmarks/bench_nn.py --model models/denoiser.onnx --sizes $NN \
            --steps staged fp16-math fp16-acc --repeats 5 ;;
    half_math)   # session 32: the denoised images in each math against onnxruntime's (§26 measured lavapipe's)
        part half_math python3 benchmarks/bench_half_math.py --size ${VIEW}x${VIEW} --scenes cornell \
            cornell-glossy sun-room world-2147483648 world-2147483651 world-2147483662 world-2147483667 ;;
    nn_widths)   # issue 12 item 5 / issue 13's denoiser target: the shipped architecture at other widths
                 # (untrained: the speed is the architecture's), profiled as the default picks; session 46's
                 # wider full-resolution level (§45) beside the narrower ones
        for widths in "16 32 64 128 128" "32 32 64 128 128" "12 24 48 96 96" "8 16 32 64 64"; do
            name=unet_$(echo $widths | tr ' ' _)
            part export_$name env PYTHONSAFEPATH=1 python3 -c "import sys; from wgpu_rt.train.networks import UNet, export_onnx
export_onnx(UNet(widths=tuple(map(int, sys.argv[2:])), bottom_merge='add'), sys.argv[1])" "$OUT/$name.onnx" $widths
            part profile_$name wgpu-rt profile "$OUT/$name.onnx" --size ${W}x${H}
        done
        # session 26: the shipped denoiser with 8-channel tiles everywhere (twice the invocations: the
        # low-resolution layers that fill less than a wave), at 1080p and on the low band's quarter canvas
        part profile_narrow wgpu-rt profile models/denoiser.onnx --size ${W}x${H} --conv-tiling staged-narrow
        part profile_narrow_quarter wgpu-rt profile models/denoiser.onnx --size $((W / 4))x$((H / 4)) \
            --conv-tiling staged-narrow
        # session 27: the 3×3 tiles summed in f16 as well (half the accumulator registers, no conversions;
        # on lavapipe the shipped denoiser's images stay within 76–83 dB of onnxruntime's, §26)
        part profile_f16acc wgpu-rt profile models/denoiser.onnx --size ${W}x${H} --precision fp16 --math f16-acc
        part profile_f16acc_8 wgpu-rt profile "$OUT/unet_8_16_32_64_64.onnx" --size ${W}x${H} --precision fp16 \
            --math f16-acc ;;
    nn_variants)   # §21's comparisons: bounds checks, the padded canvas, each weight fetch, the autotuner
        profile="wgpu-rt profile models/denoiser.onnx --size ${W}x${H}"
        part profile_fp32_checked env WGPU_RT_BOUNDS_CHECKS=1 $profile --precision fp32
        part profile_fp16_canvas wgpu-rt profile models/denoiser.onnx --size ${W}x$(( (H + 15) / 16 * 16 )) \
            --precision fp16
        part profile_fp32_direct $profile --precision fp32 --weight-fetch direct
        part profile_fp32_staged_weights $profile --precision fp32 --conv-tiling staged-weights
        # what the autotuner picks per layer among tilings, layouts and fetches (its cache is fresh here)
        part profile_fp32_autotuned env WGPU_RT_AUTOTUNE=1 $profile --precision fp32
        # session 22: every layer of that profile ran ~3.7× slower than un-tuned, while bench_nn ran the
        # same choices in 9.6 ms; the same again from the cache tells a slow GPU state from a profiler bug
        part profile_fp32_autotuned_cached env WGPU_RT_AUTOTUNE=1 $profile --precision fp32
        part bench_nn_variants python3 benchmarks/bench_nn.py --model models/denoiser.onnx --sizes $NN \
            --steps staged staged-weights direct-weights fp16 fp16-math fp16-acc autotuned --repeats 5 ;;
    trace)
        # session 19: each scene with the threaded binary BVH and the 4-wide one (wgsl/accel/walk_wide.wgsl)
        # session 25: each wide layout also over the tree with small leaves; samples/s no longer count the BVH build
        small_leaves="wide+small-leaves wide8+small-leaves wide+small-leaves+rows wide8+small-leaves+rows"
        part trace_bunny python3 benchmarks/bench_trace.py --scene bunny --size $SQUARE --spp $TRACE_SPP --layouts threaded wide wide8 threaded+rows wide+rows wide8+rows $small_leaves auto
        part trace_cornell python3 benchmarks/bench_trace.py --scene cornell --size $SQUARE --spp $TRACE_SPP --layouts threaded wide wide8 threaded+rows wide+rows wide8+rows wide+small-leaves+rows auto
        part trace_glossy python3 benchmarks/bench_trace.py --scene cornell-glossy --size $SQUARE --spp $TRACE_SPP --layouts threaded wide wide8 threaded+rows wide+rows wide8+rows $small_leaves auto
        # session 31: twenty lamps clustered into 16 emitter groups, each light sample loops over them
        part trace_corridor python3 benchmarks/bench_trace.py --scene benchmarks/scenes/corridor-lamps.toml --size $SQUARE --spp $TRACE_SPP --layouts auto
        part bvh_rays python3 benchmarks/bench_bvh.py --sizes 100000
        part trace_cornell_checked env WGPU_RT_BOUNDS_CHECKS=1 python3 benchmarks/bench_trace.py --scene cornell --size $SQUARE --spp $TRACE_SPP
        part watertight python3 benchmarks/bench_watertight.py --size $SQUARE --spp $TRACE_SPP ;;
    frame)
        part pipeline python3 benchmarks/bench_pipeline.py --scene cornell --size ${W}x${H} --frames 32 --temporal
        # session 21: a caller's own 5 ms a frame should hide behind the next frame's device work
        part pipeline_host python3 benchmarks/bench_pipeline.py --scene cornell --size ${W}x${H} --frames 32 --temporal --host-ms 5
        # session 23: the low band's frames cost ~14 ms more wall than the others; its two networks
        # run on the half- and quarter-resolution canvases, profiled here on their own
        part profile_half wgpu-rt profile models/denoiser.onnx --size $((W / 2))x$((H / 2))
        part profile_quarter wgpu-rt profile models/denoiser.onnx --size $((W / 4))x$((H / 4))
        # session 26: the list's build timed alone, and batches of the default size beside 2^21 items;
        # session 27: items of one sample each beside the default 8 (a pixel's samples on neighbouring
        # invocations instead of one invocation's loop)
        part adaptive_cost python3 benchmarks/bench_adaptive.py --pass-cost --size ${W}x${H} --budgets 4 \
            --scenes cornell sun-room --repeats 5 --batch-items 0 2097152 --item-samples 0 1
        # session 44: the hand-over's 15×15 window (§43), the pass alone
        part converge_cost python3 benchmarks/bench_converge.py --pass-cost --size ${W}x${H} --repeats 7
        part moving python3 benchmarks/bench_moving.py --scene moving --size $SQUARE --frames 40 --denoise
        part moving_bunny python3 benchmarks/bench_moving.py --scene bunny --size $SQUARE --frames 40 --denoise ;;
    heldout)
        render_heldout
        part heldout_denoise python3 benchmarks/bench_denoise.py --data $HELDOUT --per-view --noise-seeds 3 \
            --extra-spp 256 --quality balanced high --oidn-quality balanced high
        # §16 / §17: the low band (auto: on at 256²), the chroma hold and the post filter are on by default;
        # the same without all three (§12's product), then without the post filter alone
        part heldout_denoise_bare python3 benchmarks/bench_denoise.py --data $HELDOUT --per-view \
            --noise-seeds 3 --quality balanced --oidn-quality balanced --low-band off --chroma off --post-filter off
        part heldout_denoise_no_post_filter python3 benchmarks/bench_denoise.py --data $HELDOUT --per-view \
            --noise-seeds 3 --quality balanced --oidn-quality balanced --post-filter off
        part heldout_spp python3 benchmarks/bench_spp.py --size $VIEW --spp 1 2 4 16 64 256 --gold-spp $GOLD \
            --scenes cornell cornell-glossy sun-room world-2147483648 world-2147483649 world-2147483650 ;;
    train)   # §12 found the 96²-trained network 2.45 dB behind OIDN at 256², so this fine-tunes the shipped
             # one on training worlds rendered at 256², on CUDA (train_check scores it)
        # built-in views at the same size and worlds at 96² (SMALL_VIEW) join them: on lavapipe (§14) a fine-tune on
        # 192² worlds alone lost up to 0.4 dB on the built-ins and 0.2 at 128²
        data=data/worlds-train-$VIEW
        render_dataset train_render --worlds $TRAIN_WORLDS --family training --size $VIEW \
            --spp 1,2,4,16,64 --noisy-copies 2 --gold $TRAIN_GOLD --sequence-fraction 0 --seed 14 --out $data --quiet
        render_dataset train_render_builtin --scenes cornell cornell-glossy sun-room moving \
            --views ${TRAIN_BUILTIN_VIEWS:-8} \
            --size $VIEW --spp 1,2,4,16,64 --noisy-copies 2 --gold $TRAIN_GOLD --sequence-fraction 0 --seed 18 \
            --out data/builtin-$VIEW --quiet
        render_dataset train_render_small --worlds $TRAIN_WORLDS --family training --size $SMALL_VIEW \
            --spp 1,2,4,16,64 --noisy-copies 2 --gold $TRAIN_GOLD --sequence-fraction 0 --seed 19 \
            --out data/worlds-train-small --quiet
        part train wgpu-rt train denoiser --data $data --extra-data data/builtin-$VIEW data/worlds-train-small \
            --init-from ${TRAIN_INIT:-models/denoiser.onnx} --widths ${TRAIN_WIDTHS:-16 32 64 128 128} \
            --bottom-merge add --epochs 4000 --minutes $TRAIN_MINUTES --batch $TRAIN_BATCH --crop $((VIEW / 2)) $VIEW \
            --lr $TRAIN_LR \
            --curriculum any --ssim-space display --lowpass 2 --validate-every 250 --device auto \
            --out "$OUT/model" --checkpoints "/tmp/train-checkpoints-$$" --quiet ${TRAIN_FLAGS:-}
        cp models/error_predictor.onnx models/confidence.onnx "$OUT/model/"   # bench_denoise reads a whole set
        archive ;;
    train_eval|train_check)   # the model of part train (TRAINED, default: $OUT/model, the same call's) scored on
                              # the held-out worlds; train_check adds §14's checks: a call of its own
        trained=${TRAINED:-$OUT/model}
        [ -f "$trained/denoiser.onnx" ] || { echo "$what: no $trained/denoiser.onnx (run part train first, or set TRAINED)"; exit 2; }
        [ -d "$HELDOUT" ] || render_heldout
        part train_eval python3 benchmarks/bench_denoise.py --data $HELDOUT --models "$trained" \
            --per-view --noise-seeds 3 --oidn-quality balanced
        # session 32: the shipped set on the same views and noise, a comparison within one run
        part train_eval_shipped python3 benchmarks/bench_denoise.py --data $HELDOUT --models models \
            --per-view --noise-seeds 3 --oidn-quality balanced
        [ $what = train_check ] || continue
        # §14's checks, where the CPU fine-tunes lost (built-ins, 128² at 4 spp, …660's pane): shipped and new
        for set in models "$trained"; do
            name=$([ "$set" = models ] && echo shipped || echo new)
            part check_${name}_$VIEW python3 benchmarks/bench_aux.py --size $VIEW --gold-spp $CHECK_GOLD \
                --gold-cache /tmp/gold --aux 4 --delta-factor 2 --worlds 0 --models "$set" --scenes $CHECK_SCENES
            part check_${name}_$CHECK_VIEW python3 benchmarks/bench_spp.py --size $CHECK_VIEW --spp 1 4 \
                --gold-spp $GOLD --gold-cache /tmp/gold --seeds 2 --models "$set" --scenes $CHECK_SCENES_SMALL
            part features_${name} python3 benchmarks/bench_spp.py --size $FEATURE_VIEW --spp 1 4 16 --seeds 2 \
                --gold-renderer mitsuba --gold-spp $GOLD --gold-cache /tmp/gold --oidn-quality balanced \
                --models "$set" --scenes $FEATURE_SCENES
        done ;;
    *) echo "unknown part $what (tests, nn, half_math, nn_widths, nn_variants, trace, frame, heldout, train," \
            "train_eval, train_check)"; exit 2 ;;
    esac
done
