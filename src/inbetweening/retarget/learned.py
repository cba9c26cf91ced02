"""The learned retargeter at run time: a ``task=retarget`` checkpoint (its network, its feature statistics, the
source skeleton and the target rig it was trained for) applied to a source motion (:class:`LearnedRetarget`)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from inbetweening.data.bvh import BVH, parse_bvh
from inbetweening.geometry.skeleton import Skeleton
from inbetweening.models import build_retargeter
from inbetweening.predictor.checkpoint import CheckpointError, read_checkpoint
from inbetweening.runtime.model import InbetweenError

from .rig import TargetRig

__all__ = ["LearnedRetarget", "check_target"]


def check_target(rig: TargetRig, bvh: BVH, where: str, trained: str = "the checkpoint") -> None:
    """``bvh`` must have the hierarchy (joint names and parents) of the rig ``trained`` for; one
    :class:`InbetweenError` naming both otherwise."""
    names, parents = rig.name_parents
    if tuple(bvh.names) != names or tuple(int(p) for p in bvh.parents) != parents:
        diff = sorted(set(bvh.names) ^ set(names))
        raise InbetweenError(f"{where}: {bvh.source} is not the target rig {trained} was trained for "
                             f"({len(bvh.names)} joints against {len(names)}; "
                             f"{'differing joints ' + ', '.join(diff[:4]) if diff else 'other parents'})")


class LearnedRetarget:
    """The network ``net`` on features normalised by ``norm`` (``x_mean``, ``x_std``, ``y_mean``, ``y_std``) between
    the source and ``rig``."""

    def __init__(self, net: torch.nn.Module, norm: dict, rig: TargetRig, fps: float):
        self.net, self.rig, self.fps = net.eval(), rig, float(fps)
        self.norm = {k: np.asarray(v, np.float32) for k, v in norm.items()}

    @staticmethod
    def rig_of(hp: dict) -> TargetRig:
        """The target rig a checkpoint's hyperparameters name (its hierarchy and reference frame, as BVH text)."""
        source = Skeleton.from_dict(hp["skeleton"])  # the source skeleton
        return TargetRig(parse_bvh(hp["rig_bvh"], hp.get("rig_name", "target_rig")), source, hp["forward"])

    @classmethod
    def from_checkpoint(cls, path: str | Path) -> LearnedRetarget:
        ckpt = read_checkpoint(path)
        hp = ckpt.get("hyper_parameters", {})
        if "rig_bvh" not in hp:
            raise CheckpointError(f"ckpt_path: {path} is not a retargeting checkpoint (task=retarget)")
        rig = cls.rig_of(hp)
        net = build_retargeter(hp["model"], rig.source_dim(), rig.target_dim())
        state = {k[len("net."):]: v for k, v in ckpt["state_dict"].items() if k.startswith("net.")}
        net.load_state_dict(state)
        return cls(net, hp["norm"], rig, hp["fps"])

    def __call__(self, root: np.ndarray, local_q: np.ndarray):
        """The source's ``root (F, 3), local_q (F, Js, 4)`` -> the target's ``local_q, local_p`` and the position
        head's joint positions (:meth:`TargetRig.decode`)."""
        n = self.norm
        x = (self.rig.encode_source(root, local_q) - n["x_mean"]) / n["x_std"]
        with torch.no_grad():
            y = self.net(torch.from_numpy(x)[None].float())[0].numpy()
        return self.rig.decode(y * n["y_std"] + n["y_mean"], root, local_q)
