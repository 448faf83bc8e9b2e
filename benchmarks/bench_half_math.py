"""What half precision costs the denoiser's images: each scene rendered at 1 spp (colour, albedo, normal,
depth), denoised by the chain `wgpu-rt denoise` runs (wgpu_rt.frame.denoise.denoise with its defaults: low
band, chroma hold, post filter, here through their numpy references for every network) around
onnxruntime (fp32, the reference) and around the WGSL engine with fp16 activations in each math of the 3×3
convolutions (wgpu_rt.nn.model.MATHS: "f32", "f16" with each
kernel row's products summed in half precision, "f16-acc" with the sums over input channels in half
precision as well). Per scene and math: the largest |difference| of the network's output (log1p
irradiance) from onnxruntime's, and the PSNR of the denoised image against onnxruntime's denoised image
(display-mapped as every score here: wgpu_rt.metrics.psnr). The parity tests bound the first on random
input; this says what it means on renders, where the image is scored against a gold 35–45 dB away.

    python3 benchmarks/bench_half_math.py [--size 128] [--scenes cornell sun-room world-2147483667 ...]
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from common import image_size, load_scenes, print_header

from wgpu_rt import metrics
from wgpu_rt.frame.denoise import denoise
from wgpu_rt.models import DENOISER
from wgpu_rt.nn.model import MATHS
from wgpu_rt.renderer import Renderer


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--size", type=image_size, default=(128, 128), help="WIDTHxHEIGHT (default 128x128)")
    parser.add_argument("--scenes", nargs="+", default=["cornell", "cornell-glossy", "sun-room",
                                                        "world-2147483663", "world-2147483667"])
    parser.add_argument("--maths", nargs="+", choices=MATHS, default=list(MATHS))
    args = parser.parse_args()
    print_header(args)

    import onnxruntime

    from wgpu_rt.gpu import get_context
    from wgpu_rt.nn import WgslModel

    if not get_context().has_f16:
        print(f"{get_context().label} has no shader-f16: nothing to compare")
        return 0
    path = str(DENOISER.path())
    session = onnxruntime.InferenceSession(path, providers=["CPUExecutionProvider"])
    models = {math: WgslModel(path, "fp16", math=math) for math in args.maths}

    def runner(run):
        run.input_channels = DENOISER.input_channels   # denoise() packs that many planes
        return run

    width, height = args.size
    print(f"{width}x{height}, 1 spp; per math: max |Δ output| (log1p) / PSNR of the image against onnxruntime's, dB")
    print("| scene | " + " | ".join(f"fp16, {math} math" for math in args.maths) + " |")
    print("|---|" + "---|" * len(args.maths))
    worst = {math: (0.0, np.inf) for math in args.maths}
    for scene in load_scenes(args.scenes):
        result = next(iter(Renderer(scene, spp=1, size=(width, height), aovs=("albedo", "normal", "depth"),
                                    progress=False).frames([0])))
        planes = (result.color, result.aovs["albedo"], result.aovs["normal"], result.aovs["depth"])
        packed = {}

        def reference(x):
            packed["x"] = x
            return session.run(None, {"input": x})[0]

        reference_image = denoise(runner(reference), *planes)
        reference_output = session.run(None, {"input": packed["x"]})[0]
        cells = []
        for math, model in models.items():
            difference = float(np.abs(model(packed["x"]) - reference_output).max())
            psnr = metrics.psnr(reference_image, denoise(runner(lambda x, model=model: model(x)), *planes))
            worst[math] = (max(worst[math][0], difference), min(worst[math][1], psnr))
            cells.append(f"{difference:.2e} / {psnr:.1f}")
        print(f"| {scene.name} | " + " | ".join(cells) + " |")
        sys.stdout.flush()
    print("| worst | " + " | ".join(f"{d:.2e} / {p:.1f}" for d, p in worst.values()) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
