"""``wgpu-rt infer``: run an ONNX network on a .npy tensor with the WGSL engine."""

HELP = "run an ONNX model (NCHW float32 .npy in, .npy out) on the GPU with the WGSL engine"


def add_arguments(parser) -> None:
    parser.add_argument("model", help="ONNX file (ops: Conv, ConvTranspose, MaxPool, Resize, Concat, "
                        "Add, Mul, Relu, LeakyRelu, Sigmoid, Clip)")
    parser.add_argument("--input", required=True, help=".npy array, (N, C, H, W) or (C, H, W)")
    parser.add_argument("--output", required=True, help=".npy file to write (same rank as the input)")
    parser.add_argument("--precision", choices=("auto", "fp32", "fp16"), default="auto",
                        help="activation storage type (fp16 needs the shader-f16 feature; auto: fp16 on "
                             "discrete GPUs that have it, else fp32)")


def run(args) -> int:
    import numpy as np

    from ..errors import ModelError
    from ..io import atomic_output, check_output_path
    from ..nn import WgslModel

    output = check_output_path(args.output, "--output", (".npy",))
    try:
        x = np.load(args.input, allow_pickle=False)
    except (OSError, ValueError) as err:
        raise ModelError(f"{args.input}: cannot read the input array ({err})") from None
    if not np.issubdtype(x.dtype, np.number):
        raise ModelError(f"{args.input}: input array has dtype {x.dtype}, expected a numeric type")
    if x.size == 0:
        raise ModelError(f"{args.input}: input array of shape {x.shape} is empty")
    model = WgslModel(args.model, precision=args.precision)
    y = model(x.astype(np.float32))
    with atomic_output(output) as tmp, open(tmp, "wb") as file:
        np.save(file, y)   # a file object, since np.save would add ".npy" to a path
    plan = model.plan(*x.shape[-2:])
    print(f"{args.model} ({model.precision.name}): {x.shape} -> {y.shape}, peak activation memory "
          f"{plan.peak_bytes / 2**20:.2f} MiB -> {output}")
    return 0
