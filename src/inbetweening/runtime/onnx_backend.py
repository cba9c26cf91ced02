"""The ONNX backend: the exported window graph (:class:`~inbetweening.runtime.torch_backend.WindowPath`) run by ONNX
Runtime — what the Blender extension fills with, no PyTorch."""
from __future__ import annotations

import json
import os

import numpy as np

from .model import ModelError, ModelInfo

__all__ = ["OnnxBackend"]


class OnnxBackend:
    """An exported window model (``.onnx``, its metadata in ``metadata_props``) on ONNX Runtime's CPU provider.

    The graph runs as exported, without ONNX Runtime's graph optimisations: they take about two thirds of a session's
    start (0.52 s against 0.17 s CPU for a shipped model, three of them in ``predict``) and won nothing per window
    (21.1 against 21.2 ms median; BENCHMARKS.md "predict start-up")."""

    def __init__(self, path: str, threads: int = 1):
        if not path or not os.path.isfile(path):
            raise ModelError(f"model file not found: {path!r}")
        try:
            import onnxruntime as ort
        except ImportError as e:  # pragma: no cover - the extension bundles it
            raise ModelError(f"onnxruntime is not available: {e}") from None
        opts = ort.SessionOptions()
        opts.intra_op_num_threads = int(threads)
        opts.inter_op_num_threads = 1
        opts.log_severity_level = 3
        opts.graph_optimization_level = ort.GraphOptimizationLevel.ORT_DISABLE_ALL
        name = os.path.basename(path)
        try:
            self.session = ort.InferenceSession(path, opts, providers=["CPUExecutionProvider"])
            raw = self.session.get_modelmeta().custom_metadata_map
            meta = {k: json.loads(v) for k, v in raw.items()}
        except Exception as e:  # onnxruntime raises its own exception types
            raise ModelError(f"{name} is not a readable ONNX model ({str(e).splitlines()[0][:200]})") from None
        self.info = ModelInfo.from_metadata(meta, name)
        self.path, self.meta = path, meta
        self.inputs = {i.name for i in self.session.get_inputs()}
        self.calls = 0

    def predict(self, root, local_q, known, weight, contacts=True):  # one graph: the contact costs nothing apart
        self.calls += 1
        feeds = {"root": np.ascontiguousarray(root, dtype=np.float64),
                 "local_q": np.ascontiguousarray(local_q, dtype=np.float64),
                 "known": np.ascontiguousarray(known, dtype=bool)}
        if "weight" in self.inputs:
            feeds["weight"] = np.ascontiguousarray(np.ones(known.shape, np.float32) if weight is None else weight,
                                                   dtype=np.float32)
        out = self.session.run(None, feeds)
        return out[0], out[1], out[2] if len(out) > 2 else None
