"""The Python API: :class:`~inbetweening.api.inbetweener.Inbetweener` (fill a BVH clip's keyframes) and the export of a
trained model (:mod:`.export`: ONNX graphs, inference-only checkpoints)."""
