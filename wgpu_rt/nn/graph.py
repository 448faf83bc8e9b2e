"""ONNX → a list of engine layers: validation, constant folding of initializers, activation fusion,
concat aliasing and shape inference.

The loader accepts exactly the ops the kernels implement (see ``SUPPORTED_OPS``); anything else is a
``ModelError`` naming the node. A ``Layer`` is one kernel launch family (conv, 1×1 GEMM, transposed
conv, max-pool, resize, elementwise, concat); an activation that directly follows a conv, transposed
conv or elementwise node whose output nobody else reads is folded into that layer's epilogue, so
Conv+ReLU and Conv+Sigmoid are one dispatch.

A 2×2 max pool whose input a conv produces (and no other pool of that output is folded already) is
computed in that conv's epilogue: the conv writes both its output and the pooled tensor, and the
MaxPool layer, kept in ``layers`` for shapes, is not dispatched (``NetworkGraph.epilogue_pools``). This
needs no single consumer: the full-resolution output (a U-Net's skip) is stored as before.

An Add of two tensors, one of them a transposed conv's output that nothing else reads (a U-Net whose
deepest level is added to the skip above it), is computed in that transposed conv's epilogue: it stores
its output plus the other tensor straight into the Add's output (``NetworkGraph.epilogue_adds``; the Add
layer, kept for shapes, is not dispatched).

Concat is free: each input that starts on a 4-channel boundary (and, unless it is the last input, spans
whole 4-channel blocks) is written by its producer straight into its channel slice of the concatenated
tensor ("aliased"); only misaligned inputs, graph inputs already placed elsewhere and inputs whose
producer also reads that same tensor are copied by a ``copy_channels`` dispatch.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path

import numpy as np

from ..errors import ModelError

SUPPORTED_OPS = ("Conv", "Relu", "LeakyRelu", "Sigmoid", "Clip", "MaxPool", "ConvTranspose", "Resize",
                 "Concat", "Add", "Mul", "Constant")
ACTIVATION_OPS = ("Relu", "LeakyRelu", "Sigmoid", "Clip")
FLOAT_MAX = float(np.finfo(np.float32).max)


@dataclass(frozen=True)
class Activation:
    """An epilogue activation: kind 0 none, 1 ReLU, 2 LeakyReLU(alpha), 3 sigmoid, 4 clip(lo, hi)."""

    kind: int = 0
    alpha: float = 0.0
    lo: float = -FLOAT_MAX
    hi: float = FLOAT_MAX


NO_ACTIVATION = Activation()


@dataclass
class Layer:
    """One lowered node (plus a fused activation). ``kind`` picks the kernel family."""

    kind: str  # conv | gemm | conv_transpose | maxpool | resize | elementwise | concat
    name: str
    inputs: list[str]
    output: str
    activation: Activation = NO_ACTIVATION
    weight: np.ndarray | None = None  # (Cout, Cin, KH, KW); transposed convs are stored the same way
    bias: np.ndarray | None = None  # (Cout,)
    stride: int = 1
    pads: tuple[int, int, int, int] = (0, 0, 0, 0)  # top, left, bottom, right
    op: int = 0  # elementwise: 0 add, 1 multiply
    constant: np.ndarray | None = None  # elementwise: per-channel operand (C,) broadcast over H, W

    @property
    def flops_per_pixel(self) -> int:
        """Multiply-adds ×2 per output pixel (for the benchmark's GFLOP/s)."""
        if self.weight is None:
            return 0
        cout, cin, kh, kw = self.weight.shape
        return 2 * cout * cin * (1 if self.kind == "conv_transpose" else kh * kw)


@dataclass
class Shape:
    channels: int
    height: int
    width: int


@dataclass
class NetworkGraph:
    """A validated, lowered network with one NCHW input and one NCHW output."""

    path: str
    input_name: str
    input_channels: int
    output_name: str
    layers: list[Layer]
    # the ONNX file's metadata_props (e.g. how its input was packed, frame/denoise_chain.py's INPUT_EXPOSURE)
    metadata: dict[str, str] = field(default_factory=dict)
    # tensor -> (concat tensor it is written into, channel offset); resolved to a root by ``placement``
    aliases: dict[str, tuple[str, int]] = field(default_factory=dict)
    # concat layer name -> inputs copied at the concat (not aliased)
    concat_copies: dict[str, list[str]] = field(default_factory=dict)
    # conv layer name -> the MaxPool layer its epilogue computes (that layer is not dispatched)
    epilogue_pools: dict[str, Layer] = field(default_factory=dict)
    # transposed conv layer name -> the Add layer its epilogue computes (that layer is not dispatched)
    epilogue_adds: dict[str, Layer] = field(default_factory=dict)

    def in_epilogue(self, layer: Layer) -> bool:
        """Whether ``layer`` (a MaxPool or an Add) is computed in its producer's epilogue."""
        return any(folded is layer for folded in (*self.epilogue_pools.values(), *self.epilogue_adds.values()))

    def stored_output(self, layer: Layer) -> str:
        """The tensor ``layer``'s dispatches store: the folded Add's output, else its own."""
        add = self.epilogue_adds.get(layer.name)
        return layer.output if add is None else add.output

    def residual(self, layer: Layer) -> str | None:
        """The tensor ``layer``'s epilogue adds to its output (the folded Add's other input), or None."""
        add = self.epilogue_adds.get(layer.name)
        return None if add is None else next(name for name in add.inputs if name != layer.output)

    def head_body(self, head: Layer) -> Layer | None:
        """The conv that could run ``head`` in its epilogue, or None: ``head`` must be a 1×1 conv without
        activation, and its input a conv's output that nothing else reads, that is not inside a concat
        and whose conv pools nothing in its epilogue (whether the conv's kernel can take it is the
        kernel's question: kernels.Conv3x3Kernel.takes_head)."""
        source = head.inputs[0]
        body = next((layer for layer in self.layers if layer.output == source), None)
        if (head.kind != "gemm" or head.activation != NO_ACTIVATION or body is None or body.kind != "conv"
                or body.name in self.epilogue_pools or source == self.output_name
                or self.placement(source)[0] != source
                or any(source in layer.inputs for layer in self.layers if layer is not head)):
            return None
        return body

    @property
    def multiple(self) -> int:
        """The canvas H and W are padded to a multiple of this (the deepest downscale factor)."""
        scale = {self.input_name: Fraction(1)}
        deepest = Fraction(1)
        for layer in self.layers:
            base = scale[layer.inputs[0]]
            if layer.kind in ("conv", "gemm"):
                base = base * layer.stride
            elif layer.kind == "maxpool":
                base = base * 2
            elif layer.kind in ("conv_transpose", "resize"):
                base = base / 2
            scale[layer.output] = base
            deepest = max(deepest, base)
        return math.ceil(deepest)

    @property
    def receptive_radius(self) -> int:
        """How many input pixels beyond itself any output pixel can depend on (an upper bound): a frame
        cut into bands with this many context rows on each side gives exactly the whole-frame result."""
        scale = {self.input_name: Fraction(1)}
        radius = {self.input_name: Fraction(0)}
        for layer in self.layers:
            base = scale[layer.inputs[0]]
            reach = max(radius[name] for name in layer.inputs)
            if layer.kind in ("conv", "gemm"):
                # output row y reads input rows y·stride - top .. y·stride - top + kh - 1 (same for columns)
                top, left = layer.pads[:2]
                kh, kw = layer.weight.shape[2:]
                reach += max(top, kh - 1 - top, left, kw - 1 - left) * base
                base = base * layer.stride
            elif layer.kind == "maxpool":
                reach += base
                base = base * 2
            elif layer.kind in ("conv_transpose", "resize"):
                reach += base
                base = base / 2
            scale[layer.output], radius[layer.output] = base, reach
        return math.ceil(max(radius.values()))

    def placement(self, tensor: str) -> tuple[str, int]:
        """(root tensor whose buffer holds ``tensor``, channel offset inside it)."""
        offset = 0
        while tensor in self.aliases:
            tensor, extra = self.aliases[tensor]
            offset += extra
        return tensor, offset

    def infer_channels(self) -> dict[str, int]:
        """Channels of every tensor (they do not depend on H and W)."""
        return _channel_counts(self)

    def infer_shapes(self, height: int, width: int) -> dict[str, Shape]:
        """Every tensor's shape for an input of height×width; raises ShapeMismatch where ONNX would."""
        shapes = {self.input_name: Shape(self.input_channels, height, width)}
        for layer in self.layers:
            first = shapes[layer.inputs[0]]
            if layer.kind in ("conv", "gemm"):
                cout, _, kh, kw = layer.weight.shape
                top, left, bottom, right = layer.pads
                out = Shape(cout, (first.height + top + bottom - kh) // layer.stride + 1,
                            (first.width + left + right - kw) // layer.stride + 1)
            elif layer.kind == "conv_transpose":
                out = Shape(layer.weight.shape[0], 2 * first.height, 2 * first.width)
            elif layer.kind == "maxpool":
                out = Shape(first.channels, first.height // 2, first.width // 2)
            elif layer.kind == "resize":
                out = Shape(first.channels, 2 * first.height, 2 * first.width)
            elif layer.kind == "concat":
                parts = [shapes[name] for name in layer.inputs]
                if any((p.height, p.width) != (first.height, first.width) for p in parts):
                    raise ShapeMismatch(f"{layer.name}: Concat inputs differ in H×W: "
                                        f"{[(p.height, p.width) for p in parts]}")
                out = Shape(sum(p.channels for p in parts), first.height, first.width)
            else:  # elementwise
                out = Shape(first.channels, first.height, first.width)
                if layer.constant is None and len(layer.inputs) == 2:
                    other = shapes[layer.inputs[1]]
                    if (other.channels, other.height, other.width) != (out.channels, out.height, out.width):
                        raise ShapeMismatch(f"{layer.name}: operand shapes differ: {first} vs {other}")
            if out.height < 1 or out.width < 1:
                raise ShapeMismatch(f"{layer.name}: output would be {out.height}×{out.width}")
            if layer.kind in ("conv", "gemm") and first.channels != layer.weight.shape[1]:
                raise ModelError(f"{self.path}: node {layer.name!r} expects {layer.weight.shape[1]} input "
                                 f"channels but gets {first.channels}")
            shapes[layer.output] = out
        return shapes


class ShapeMismatch(Exception):
    """The graph does not fit together at this size (the engine then pads to ``multiple``)."""


def read_onnx(path: str | Path):
    """The checked ONNX model at ``path``; a missing or invalid file is a ModelError naming it."""
    import onnx

    path = str(path)
    if not Path(path).is_file():
        raise ModelError(f"{path}: ONNX model file not found")
    try:
        model = onnx.load(path)
        onnx.checker.check_model(model)
    except Exception as err:  # onnx raises DecodeError, ValidationError, ... for a bad file
        raise ModelError(f"{path}: not a valid ONNX model ({type(err).__name__}: {err})") from None
    return model


def load_graph(path: str | Path) -> NetworkGraph:
    """Read and lower the ONNX file at ``path``; every problem is a ModelError naming the file/node."""
    from onnx import numpy_helper

    path = str(path)
    model = read_onnx(path)
    graph = model.graph
    constants = {init.name: numpy_helper.to_array(init) for init in graph.initializer}
    inputs = [i for i in graph.input if i.name not in constants]
    if len(inputs) != 1 or len(graph.output) != 1:
        raise ModelError(f"{path}: the engine runs graphs with one input and one output "
                         f"(found {len(inputs)} and {len(graph.output)})")
    dims = inputs[0].type.tensor_type.shape.dim
    if len(dims) != 4 or not dims[1].HasField("dim_value"):
        raise ModelError(f"{path}: input {inputs[0].name!r} must be NCHW with a fixed channel count")
    readers: dict[str, int] = {}
    for node in graph.node:
        for name in node.input:
            readers[name] = readers.get(name, 0) + 1
    lowering = _Lowering(path, constants, inputs[0].name, graph.output[0].name, readers)
    for node in graph.node:
        lowering.lower(node, numpy_helper)
    network = NetworkGraph(path, inputs[0].name, dims[1].dim_value, graph.output[0].name, lowering.layers,
                           metadata={prop.key: prop.value for prop in model.metadata_props})
    _fold_pools(network)
    _plan_concats(network)
    _fold_adds(network)
    return network


class _Lowering:
    """Turns nodes into layers in order, folding activations into the layer that produced their input."""

    def __init__(self, path: str, constants: dict, input_name: str, output_name: str,
                 readers: dict[str, int]):
        self.path, self.constants, self.output_name = path, constants, output_name
        self.input_name, self.readers = input_name, readers
        self.layers: list[Layer] = []
        self.producer: dict[str, Layer] = {}

    def error(self, node, message: str) -> ModelError:
        return ModelError(f"{self.path}: node {node.name or '(unnamed)'!r} ({node.op_type}): {message}")

    def constant(self, node, index: int, what: str, optional: bool = False):
        if index >= len(node.input) or not node.input[index]:
            if optional:
                return None
            raise self.error(node, f"missing {what}")
        name = node.input[index]
        if name not in self.constants:
            raise self.error(node, f"{what} {name!r} must be a constant initializer")
        return self.constants[name]

    def lower(self, node, numpy_helper) -> None:
        op = node.op_type
        if op not in SUPPORTED_OPS:
            raise self.error(node, f"unsupported op; the engine lowers {', '.join(SUPPORTED_OPS[:-1])}")
        attrs = {a.name: _attribute(a, numpy_helper) for a in node.attribute}
        if op == "Constant":
            if "value" not in attrs:
                raise self.error(node, "only Constant nodes with a 'value' tensor are supported")
            self.constants[node.output[0]] = attrs["value"]
            return
        tensors = [name for name in node.input if name and name not in self.constants]
        for name in tensors:
            if name not in self.producer and name != self.input_name:
                raise self.error(node, f"input {name!r} is produced by no earlier node")
        if op in ACTIVATION_OPS:
            self.lower_activation(node, attrs)
        elif op == "Conv":
            self.lower_conv(node, attrs)
        elif op == "ConvTranspose":
            self.lower_conv_transpose(node, attrs)
        elif op == "MaxPool":
            if (list(attrs.get("kernel_shape", [])) != [2, 2] or list(attrs.get("strides", [1, 1])) != [2, 2]
                    or any(attrs.get("pads", [0])) or attrs.get("ceil_mode", 0)
                    or any(d != 1 for d in attrs.get("dilations", [1]))
                    or attrs.get("auto_pad", "NOTSET") != "NOTSET"):
                raise self.error(node, "only 2×2 stride-2 unpadded max pooling is supported")
            self.add(Layer("maxpool", node.name, [node.input[0]], node.output[0]))
        elif op == "Resize":
            self.lower_resize(node, attrs)
        elif op == "Concat":
            if attrs.get("axis") not in (1, -3):
                raise self.error(node, f"only channel concat (axis 1) is supported, not axis {attrs.get('axis')}")
            self.add(Layer("concat", node.name, list(node.input), node.output[0]))
        else:  # Add, Mul
            self.lower_binary(node)

    def add(self, layer: Layer) -> None:
        self.layers.append(layer)
        self.producer[layer.output] = layer

    def lower_activation(self, node, attrs) -> None:
        op = node.op_type
        if op == "Relu":
            activation = Activation(1)
        elif op == "LeakyRelu":
            activation = Activation(2, alpha=float(attrs.get("alpha", 0.01)))
        elif op == "Sigmoid":
            activation = Activation(3)
        else:
            lo = self.constant(node, 1, "min", optional=True)
            hi = self.constant(node, 2, "max", optional=True)
            lo = float(attrs.get("min", -FLOAT_MAX) if lo is None else lo)
            hi = float(attrs.get("max", FLOAT_MAX) if hi is None else hi)
            activation = Activation(4, lo=max(lo, -FLOAT_MAX), hi=min(hi, FLOAT_MAX))
        source = node.input[0]
        producer = self.producer.get(source)
        fusable = (producer is not None and producer.kind in ("conv", "gemm", "conv_transpose", "elementwise")
                   and producer.activation == NO_ACTIVATION and self.readers[source] == 1
                   and source != self.output_name)
        if fusable:
            del self.producer[source]
            producer.activation = activation
            producer.output = node.output[0]
            self.producer[producer.output] = producer
        else:
            self.add(Layer("elementwise", node.name, [source], node.output[0], activation=activation))

    def lower_conv(self, node, attrs) -> None:
        weight = self.constant(node, 1, "weight").astype(np.float32)
        bias = self.constant(node, 2, "bias", optional=True)
        if weight.ndim != 4:
            raise self.error(node, f"only 2-D convolutions are supported (weight shape {weight.shape})")
        if attrs.get("group", 1) != 1:
            raise self.error(node, f"grouped convolution (group={attrs['group']}) is not supported")
        if any(d != 1 for d in attrs.get("dilations", [1])):
            raise self.error(node, f"dilated convolution {attrs['dilations']} is not supported")
        if attrs.get("auto_pad", "NOTSET") != "NOTSET":
            raise self.error(node, f"auto_pad={attrs['auto_pad']} is not supported; export explicit pads")
        strides = list(attrs.get("strides", [1, 1]))
        if len(set(strides)) != 1 or strides[0] not in (1, 2):
            raise self.error(node, f"strides {strides} are not supported (1 or 2, equal in H and W)")
        top, left, bottom, right = (list(attrs.get("pads", [0, 0, 0, 0])) + [0, 0, 0, 0])[:4]
        kh, kw = weight.shape[2:]
        kind = "gemm" if (kh, kw, strides[0], top, left, bottom, right) == (1, 1, 1, 0, 0, 0, 0) else "conv"
        bias = np.zeros(weight.shape[0], np.float32) if bias is None else bias.astype(np.float32)
        self.add(Layer(kind, node.name, [node.input[0]], node.output[0], weight=weight, bias=bias,
                       stride=strides[0], pads=(top, left, bottom, right)))

    def lower_conv_transpose(self, node, attrs) -> None:
        weight = self.constant(node, 1, "weight").astype(np.float32)
        bias = self.constant(node, 2, "bias", optional=True)
        plain = (weight.ndim == 4 and weight.shape[2:] == (2, 2)
                 and list(attrs.get("strides", [1, 1])) == [2, 2] and not any(attrs.get("pads", [0]))
                 and not any(attrs.get("output_padding", [0])) and attrs.get("group", 1) == 1
                 and all(d == 1 for d in attrs.get("dilations", [1])) and "output_shape" not in attrs
                 and attrs.get("auto_pad", "NOTSET") == "NOTSET")
        if not plain:
            raise self.error(node, "only 2×2 stride-2 unpadded transposed convolution is supported")
        weight = np.ascontiguousarray(weight.transpose(1, 0, 2, 3))  # (Cin, Cout, 2, 2) -> (Cout, Cin, 2, 2)
        bias = np.zeros(weight.shape[0], np.float32) if bias is None else bias.astype(np.float32)
        self.add(Layer("conv_transpose", node.name, [node.input[0]], node.output[0], weight=weight, bias=bias))

    def lower_resize(self, node, attrs) -> None:
        if attrs.get("mode", "nearest") != "nearest":
            raise self.error(node, f"only nearest resizing is supported, not {attrs['mode']!r}")
        if attrs.get("coordinate_transformation_mode", "half_pixel") in ("align_corners", "tf_crop_and_resize"):
            raise self.error(node, "coordinate_transformation_mode "
                             f"{attrs['coordinate_transformation_mode']!r} is not supported")
        scales = self.constant(node, 2, "scales", optional=True)
        if scales is None or list(np.asarray(scales, np.float64)) != [1.0, 1.0, 2.0, 2.0]:
            raise self.error(node, "only ×2 upsampling given by constant scales [1, 1, 2, 2] is supported")
        self.add(Layer("resize", node.name, [node.input[0]], node.output[0]))

    def lower_binary(self, node) -> None:
        op = 0 if node.op_type == "Add" else 1
        names = list(node.input)
        constant_names = [n for n in names if n in self.constants]
        if len(constant_names) == 2:
            raise self.error(node, "both operands are constants (fold them before export)")
        if not constant_names:
            self.add(Layer("elementwise", node.name, names, node.output[0], op=op))
            return
        tensor = next(n for n in names if n not in self.constants)
        value = np.asarray(self.constants[constant_names[0]], np.float32)
        if value.size != 1 and (value.ndim > 4 or value.shape[-2:] != (1, 1) or value.ndim < 3
                                or any(d != 1 for d in value.shape[:-3])):
            raise self.error(node, f"constant operand of shape {value.shape} does not broadcast per "
                             "channel; only scalars and (C, 1, 1) constants are supported")
        self.add(Layer("elementwise", node.name, [tensor], node.output[0], op=op, constant=value.reshape(-1)))


def _attribute(attribute, numpy_helper):
    import onnx

    kind = attribute.type
    if kind == onnx.AttributeProto.INT:
        return attribute.i
    if kind == onnx.AttributeProto.FLOAT:
        return attribute.f
    if kind == onnx.AttributeProto.INTS:
        return list(attribute.ints)
    if kind == onnx.AttributeProto.FLOATS:
        return list(attribute.floats)
    if kind == onnx.AttributeProto.STRING:
        return attribute.s.decode()
    if kind == onnx.AttributeProto.TENSOR:
        return numpy_helper.to_array(attribute.t)
    return None


def _fold_pools(network: NetworkGraph) -> None:
    """Give each MaxPool whose input a conv produces to that conv's epilogue (one pool per conv)."""
    producers = {layer.output: layer for layer in network.layers}
    for layer in network.layers:
        producer = producers.get(layer.inputs[0])
        if (layer.kind == "maxpool" and producer is not None and producer.kind == "conv"
                and producer.name not in network.epilogue_pools):
            network.epilogue_pools[producer.name] = layer


def _fold_adds(network: NetworkGraph) -> None:
    """Give each Add of two tensors (no activation), one of them the output of a transposed conv that
    nothing else reads, to that transposed conv's epilogue; not where a tensor it reads shares the buffer
    the Add writes (a binding may not be both read and written), nor for the graph's output."""
    producers = {layer.output: layer for layer in network.layers}
    readers: dict[str, int] = {}
    for layer in network.layers:
        for name in layer.inputs:
            readers[name] = readers.get(name, 0) + 1
    for layer in network.layers:
        if (layer.kind != "elementwise" or layer.op != 0 or len(layer.inputs) != 2
                or layer.activation != NO_ACTIVATION or layer.output == network.output_name):
            continue
        for name in layer.inputs:  # (x + x reads x twice: not folded)
            producer = producers.get(name)
            if (producer is None or producer.kind != "conv_transpose" or readers[name] != 1
                    or name == network.output_name or network.placement(name)[0] != name):
                continue
            other = next(n for n in layer.inputs if n != name)
            written = network.placement(layer.output)[0]
            if all(network.placement(n)[0] != written for n in (*producer.inputs, other)):
                network.epilogue_adds[producer.name] = layer
                break


def _plan_concats(network: NetworkGraph) -> None:
    """Decide which concat inputs are written in place (see module docstring) and which are copied."""
    channels = _channel_counts(network)
    producers = {layer.output: layer for layer in network.layers}
    by_name = {layer.name: layer for layer in network.layers}
    producers.update({pool.output: by_name[conv] for conv, pool in network.epilogue_pools.items()})
    for layer in network.layers:
        if layer.kind != "concat":
            continue
        copies, offset = [], 0
        for position, name in enumerate(layer.inputs):
            last = position == len(layer.inputs) - 1
            aligned = offset % 4 == 0 and (channels[name] % 4 == 0 or last)
            if aligned and name not in network.aliases and name != network.input_name:
                network.aliases[name] = (layer.output, offset)
            else:
                copies.append(name)
            offset += channels[name]
        network.concat_copies[layer.name] = copies
    # A producer that reads the concat buffer it would write into cannot share it (one binding may not
    # be both read and written); such outputs fall back to a copy.
    changed = True
    while changed:
        changed = False
        for name in list(network.aliases):
            producer = producers.get(name)
            if producer is None:
                continue
            root = network.placement(name)[0]
            if any(network.placement(i)[0] == root for i in producer.inputs):
                concat = next(layer for layer in network.layers if layer.output == network.aliases[name][0])
                del network.aliases[name]
                network.concat_copies[concat.name].append(name)
                changed = True


def _channel_counts(network: "NetworkGraph") -> dict[str, int]:
    """Channels of every tensor (they do not depend on H and W)."""
    counts = {network.input_name: network.input_channels}
    for layer in network.layers:
        if layer.kind == "concat":
            counts[layer.output] = sum(counts[name] for name in layer.inputs)
        elif layer.weight is not None:
            counts[layer.output] = layer.weight.shape[0]
        else:
            counts[layer.output] = counts[layer.inputs[0]]
    return counts
