"""Subcommands of ``wgpu-rt``: one module each (see wgpu_rt.cli for the contract)."""
