"""The torch backend: a trained :class:`~inbetweening.predictor.predictor.Predictor` as the runtime's network.

:class:`WindowPath` is the computation both backends run on canonical windows — features (FK), mask, network, the
do-no-harm blend with the runtime's weights, decode, predicted contact — in PyTorch here, and exported as one ONNX graph
for the other backend (:func:`inbetweening.api.export.export_window_onnx`), so the two cannot drift apart.
:func:`window_metadata` describes the model for both (:class:`~inbetweening.runtime.model.ModelInfo`).

This is the one module of the runtime that imports PyTorch (it is not bundled into the Blender extension).
"""
from __future__ import annotations

import copy
import json
from pathlib import Path

import torch

from .model import WINDOW_FORMAT, ModelInfo

__all__ = ["TorchBackend", "WindowPath", "window_metadata"]


class WindowPath(torch.nn.Module):
    """``(root (B, T, 3), local_q (B, T, J, 4), known (B, T, J), weight (B, T, J)) -> (root, local_q[, contact])``:
    the predictor's path for windows already in their canonical frame, float64 in and out (``contact`` float32, for
    representations with contact channels).  Unknown input values are never read.  ``weight``: the network's share of
    its correction to the interpolation per value (the do-no-harm blend, :meth:`Predictor.blended`); used only by a
    predictor that carries a blend (``None``: the network as it is)."""

    def __init__(self, predictor):
        super().__init__()
        self.predictor = predictor

    def forward(self, root, local_q, known, weight=None):
        feats = self.predictor.representation.encode(root, local_q).to(torch.float32)
        return self.from_features(feats, known, weight)

    def from_features(self, feats, known, weight=None):
        """The same from features (``Predictor.encode`` of the windows)."""
        p = self.predictor
        pred, interp = p.network_forward(feats, known, blend=False)
        if weight is not None and p.blend is not None:
            pred = p.blended(pred, interp, known, weights=weight)
        root, q = p.decode(pred)
        contact = p.representation.contacts(pred)
        return (root, q) if contact is None else (root, q, contact)


def window_metadata(predictor, trained_gap: int | None = None) -> dict[str, str]:
    """What the runtime needs to know of ``predictor`` (JSON strings, the ONNX graph's ``metadata_props``): the
    predictor's own :meth:`~inbetweening.predictor.predictor.Predictor.metadata` plus ``format``, ``inputs``,
    ``outputs``, ``trained_gap`` (the longest transition generated in one window; default ``train_window - n_past -
    1``), ``frame_centre`` (``known`` or ``last``: where the canonical frame's origin is), ``contact`` (the feet and
    contact rule) and ``convention`` (the training files' up axis and unit)."""
    meta = predictor.metadata(["root", "local_q", "known", "weight"])
    gap = trained_gap or predictor.train_window - predictor.n_past - 1
    outputs = ["root_out", "local_q_out"] + (["contact_out"] if "contact" in predictor.representation.channels() else [])
    meta.update({"format": json.dumps(WINDOW_FORMAT), "outputs": json.dumps(outputs),
                 "trained_gap": json.dumps(int(gap)),
                 "frame_centre": json.dumps("last" if predictor.centre == "last" else "known"),
                 "contact": json.dumps(predictor.contact.to_dict()),
                 "convention": json.dumps(predictor.convention.to_dict())})
    return meta


class TorchBackend:
    """The runtime's backend for a predictor (or a training module: its predictor), on its device."""

    def __init__(self, model, trained_gap: int | None = None):
        self.module = model.eval()
        self.predictor = getattr(model, "predictor", model)
        self.path = WindowPath(self.predictor)
        meta = {k: json.loads(v) for k, v in window_metadata(self.predictor, trained_gap).items()}
        self.info = ModelInfo.from_metadata(meta)
        self.calls = 0

    @classmethod
    def from_checkpoint(cls, path: str | Path, device: str | torch.device = "cpu") -> TorchBackend:
        """A checkpoint's predictor (``CheckpointError`` for missing or wrong files), with the longest gap its data
        module trained on."""
        from inbetweening.predictor.checkpoint import load_predictor, read_checkpoint, trained_gap

        ckpt = read_checkpoint(str(path))
        return cls(load_predictor(str(path), device, ckpt=ckpt), trained_gap(ckpt))

    def predict(self, root, local_q, known, weight, contacts=True):  # one graph: the contact costs nothing apart
        self.calls += 1
        p = self.predictor
        with torch.inference_mode():
            feats = p.encode(root, local_q)  # the numpy FK path on CPU (the same numbers, faster)
            known_t = torch.as_tensor(known, device=feats.device)
            w = None if weight is None else torch.as_tensor(weight, device=feats.device)
            out = self.path.from_features(feats, known_t, w)
        arrays = [o.cpu().numpy() for o in out]
        return arrays[0], arrays[1], arrays[2] if len(arrays) > 2 else None

    def adapted(self, groups, steps: int, lr: float) -> TorchBackend:
        """A copy of this backend whose network took ``steps`` Adam steps (learning rate ``lr``, full batch) on
        ``groups``: ``(root (B, T, 3), local_q (B, T, J, 4), known (B, T, J), hidden (B,))`` canonical windows of one
        length each, the truth at frame ``hidden[i]`` of window ``i`` (unknown to the network); the loss is the L1 of
        the prediction's features there (the training loss, at the hidden keys).  Test-time adaptation
        (:mod:`.adapt`); this backend is left as it was."""
        pred = copy.deepcopy(self.predictor)
        pred.eval()  # normalisation statistics stay; gradients flow all the same
        pred.net.requires_grad_(True)  # whatever the loaded checkpoint's flags: every weight adapts
        opt = torch.optim.Adam(pred.net.parameters(), lr=float(lr))
        with torch.inference_mode(False), torch.enable_grad():
            batches = []
            for root, local_q, known, hidden in groups:
                feats = pred.encode(root, local_q)
                rows = torch.arange(len(hidden), device=feats.device)
                at = torch.as_tensor(hidden, device=feats.device)
                batches.append((feats, torch.as_tensor(known, device=feats.device), rows, at, feats[rows, at]))
            for _ in range(int(steps)):
                opt.zero_grad(set_to_none=True)
                loss = sum((pred.network_forward(f, k, blend=False)[0][r, h] - t).abs().mean()
                           for f, k, r, h, t in batches) / len(batches)
                loss.backward()
                opt.step()
        pred.requires_grad_(False)
        return TorchBackend(pred, self.info.trained_gap)
