"""``python -m wgpu_rt`` is the ``wgpu-rt`` command."""

import sys

from .cli import main

sys.exit(main())
