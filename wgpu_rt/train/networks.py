"""The three networks, defined in torch (training only) and exported to ONNX for the WGSL engine.

- ``UNet``: the denoiser. Input: 11 channels, NCHW — log1p(noisy HDR RGB / ((albedo + 0.01) · the frame's
  white-balance gain)), albedo RGB,
  normals mapped to [0, 1], normalized depth, 1/sqrt(spp) (wgpu_rt.frame.pack.pack_denoiser_input).
  Output: log1p of the clean irradiance (the pipeline applies expm1 and multiplies by (albedo + 0.01) · gain:
  wgpu_rt.frame.pack/unpack). Levels of
  ``widths`` channels, each a double 3×3 conv + ReLU; 2×2 max-pool down; 2×2 stride-2 transposed conv
  up; skips concatenated on channels and merged by a double 3×3 conv; a 1×1 conv to RGB. With
  ``bottom_merge="add"`` the deepest level's upsampled output is instead added to the skip above it, no
  merge convolutions there: a level that widens the receptive field at a sixth of what a concat level
  costs (1080p, widths 16-32-64-128 + 128: 158.7 GFLOP against 187.6 with concat, 152.8 without the
  level). A fine-tune one level deeper starts with that transposed conv at zero, as the shallower model.
  With ``residual`` the 1×1 conv (zero-initialised) predicts a correction added to the input's log1p
  colour (a fixed 1×1 conv selects those channels, then an Add), so the untrained network is the identity. In a short run on 1-spp inputs it fit the training
  set worse than direct prediction (loss 0.41 vs 0.27 after 165 steps), so it is off by default.
  H and W must be multiples of 2**(levels-1) (the engine pads and crops).
- ``ErrorPredictor``: 1-spp log1p RGB → a [0, 1] heatmap of where error will be (3×3 convs, sigmoid).
- ``ConfidencePredictor``: current RGB, reprojected history RGB, current depth, reprojected previous
  depth (8 channels) → confidence in [0, 1] that the reprojected history is still valid for the pixel
  (1 = keep history: the temporal pass blends with alpha = mix(1, 0.01, confidence), the
  confidence ramped up from a floor: see TemporalSettings.confidence_floor). Its training
  target is 1 minus the mask where the warped gold frame t disagrees with gold frame t+1.

Only the ops the engine lowers are used (Conv, Relu, Sigmoid, MaxPool, ConvTranspose, Concat, Add).
"""

from __future__ import annotations

from pathlib import Path

import torch
import torch.nn.functional as F
from torch import nn

from ..models import CONFIDENCE, DENOISER, ERROR_PREDICTOR

ONNX_OPSET = 17
BOTTOM_MERGES = ("concat", "add")


def _double_conv(cin: int, cout: int) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(cin, cout, 3, padding=1), nn.ReLU(inplace=True),
                         nn.Conv2d(cout, cout, 3, padding=1), nn.ReLU(inplace=True))


class UNet(nn.Module):
    def __init__(self, in_channels: int = DENOISER.input_channels, out_channels: int = 3,
                 widths: tuple[int, ...] = (32, 64, 128), residual: bool = False, bottom_merge: str = "concat"):
        super().__init__()
        if bottom_merge not in BOTTOM_MERGES:
            raise ValueError(f"bottom_merge must be one of {BOTTOM_MERGES}, got {bottom_merge!r}")
        self.widths = tuple(widths)
        self.residual = residual
        self.bottom_merge = bottom_merge
        self.down = nn.ModuleList()
        cin = in_channels
        for w in widths:
            self.down.append(_double_conv(cin, w))
            cin = w
        self.pool = nn.MaxPool2d(2)
        self.up = nn.ModuleList()
        self.merge = nn.ModuleList()
        for w_hi, w_lo in zip(widths[::-1][:-1], widths[::-1][1:]):
            self.up.append(nn.ConvTranspose2d(w_hi, w_lo, 2, stride=2))
            adds = bottom_merge == "add" and not self.merge
            self.merge.append(nn.Identity() if adds else _double_conv(2 * w_lo, w_lo))
        self.head = nn.Conv2d(widths[0], out_channels, 1)
        if residual:
            # A constant (untrained) 1×1 conv picking the first ``out_channels`` input channels: exported
            # as a Conv with fixed weights, as the engine has no Slice.
            selector = torch.zeros(out_channels, in_channels, 1, 1)
            selector[range(out_channels), range(out_channels)] = 1.0
            self.register_buffer("input_selector", selector)
            nn.init.zeros_(self.head.weight)     # start exactly at the identity
            nn.init.zeros_(self.head.bias)

    @property
    def multiple(self) -> int:
        """H and W must be multiples of this."""
        return 2 ** (len(self.widths) - 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        shortcut = F.conv2d(x, self.input_selector) if self.residual else None
        skips = []
        for i, block in enumerate(self.down):
            if i:
                x = self.pool(x)
            x = block(x)
            skips.append(x)
        for level, (up, merge, skip) in enumerate(zip(self.up, self.merge, skips[-2::-1])):
            if level == 0 and self.bottom_merge == "add":
                x = skip + up(x)
            else:
                x = merge(torch.cat([up(x), skip], dim=1))
        return self.head(x) + shortcut if self.residual else self.head(x)


class _HeatmapCNN(nn.Module):
    """3×3 conv + ReLU layers of ``hidden`` channels, then a 3×3 conv to one sigmoid channel."""

    def __init__(self, in_channels: int, hidden: int = 16, layers: int = 2):
        super().__init__()
        self.hidden, self.layers = hidden, layers
        body, cin = [], in_channels
        for _ in range(layers):
            body += [nn.Conv2d(cin, hidden, 3, padding=1), nn.ReLU(inplace=True)]
            cin = hidden
        self.body = nn.Sequential(*body, nn.Conv2d(cin, 1, 3, padding=1), nn.Sigmoid())

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.body(x)


class ErrorPredictor(_HeatmapCNN):
    def __init__(self, hidden: int = 16, layers: int = 2):
        super().__init__(ERROR_PREDICTOR.input_channels, hidden, layers)


class ConfidencePredictor(_HeatmapCNN):
    """Two hidden layers of 32 (≈12k parameters, 7×7 receptive field): trained on data/dataset's 18
    pairs and scored on the pixels it decides (history passing the temporal tests) of its 8 held-out
    pairs against a 512-spp mask, one layer of 16 reached ROC AUC 0.78–0.79 and this 0.84–0.86 (two
    seeds each); 3 layers of 16 or 32 were no better."""

    def __init__(self, hidden: int = 32, layers: int = 2):
        super().__init__(CONFIDENCE.input_channels, hidden, layers)


def input_channels(model: nn.Module) -> int:
    first = next(m for m in model.modules() if isinstance(m, nn.Conv2d))
    return first.in_channels


def export_onnx(model: nn.Module, path: str | Path, height: int = 64, width: int = 64,
                metadata: dict[str, str] | None = None) -> Path:
    """Write ``model`` to ONNX (opset 17) with dynamic batch, height and width, and ``metadata`` as the
    file's metadata_props (how its input was packed: frame/denoise_chain.py's INPUT_EXPOSURE)."""
    from ..io import atomic_output

    path = Path(path)
    model = model.eval()
    example = torch.zeros(1, input_channels(model), height, width)
    with atomic_output(path) as tmp:
        torch.onnx.export(
            model, (example,), str(tmp), input_names=["input"], output_names=["output"],
            opset_version=ONNX_OPSET, dynamo=False,
            dynamic_axes={"input": {0: "batch", 2: "height", 3: "width"},
                          "output": {0: "batch", 2: "height", 3: "width"}})
        if metadata:
            import onnx

            exported = onnx.load(str(tmp))
            for key, value in metadata.items():
                exported.metadata_props.add(key=key, value=value)
            onnx.save(exported, str(tmp))
    return path


SEED_NETWORKS = {DENOISER: UNet, ERROR_PREDICTOR: ErrorPredictor, CONFIDENCE: ConfidencePredictor}


def export_seed_models(folder: str | Path, seed: int = 0, **denoiser_options) -> Path:
    """Untrained networks (torch's default initialisation, seeded) exported under the file names the
    frame pipeline loads: for exercising the pipeline's mechanics (tests, benchmark dry runs) before
    trained models exist. ``denoiser_options`` go to ``UNet`` (e.g. small ``widths`` for fast tests)."""
    folder = Path(folder)
    torch.manual_seed(seed)
    for network, module in SEED_NETWORKS.items():
        export_onnx(module(**denoiser_options) if module is UNet else module(), network.path(folder))
    return folder
