"""The three networks, named once: each one's ONNX file and model card (shipped in this resource package,
``wgpu_rt.models``), its input channels and what it is for.

The name is the Python spelling everywhere (keyword arguments, dictionary keys, file stems); the command
line writes it with dashes (``wgpu-rt train error-predictor``), as it does for subcommands.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path


@dataclass(frozen=True)
class Network:
    name: str
    input_channels: int
    purpose: str

    @property
    def onnx(self) -> str:
        return f"{self.name}.onnx"

    @property
    def card(self) -> str:
        return f"{self.name}.md"

    @property
    def cli_name(self) -> str:
        return self.name.replace("_", "-")

    def path(self, folder: str | Path | None = None) -> Path:
        """The ONNX file in ``folder`` (default: the shipped models)."""
        return (Path(folder) if folder else Path(str(resources.files(__name__)))) / self.onnx


DENOISER = Network("denoiser", 11, "noisy colour + albedo/normal/depth + sample count → clean colour")
ERROR_PREDICTOR = Network("error_predictor", 3, "1-spp probe → where error will be (adaptive sampling)")
CONFIDENCE = Network("confidence", 8, "current + reprojected frame → how far to trust history (temporal)")
NETWORKS = {network.name: network for network in (DENOISER, ERROR_PREDICTOR, CONFIDENCE)}


def network_named(name: str) -> Network:
    """The network called ``name`` in either spelling (``error_predictor`` or ``error-predictor``)."""
    try:
        return NETWORKS[name.replace("-", "_")]
    except KeyError:
        raise KeyError(f"unknown network {name!r}; expected one of "
                       f"{', '.join(n.cli_name for n in NETWORKS.values())}") from None
