"""Shipped ONNX models and their model cards (resource package: see wgpu_rt.models_path)."""
