"""What the learned retargeter's tests share: the source skeleton (the shipped model's 21 joints, read from its
checkpoint: no dataset needed), walk-like source clips, target rigs (a CMU-like hierarchy generated here, a character
with extra spine, twist and finger bones from tests/characters.py), and a tiny trained checkpoint."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from characters import character, model_walk
from inbetweening.data.bvh import BVH
from inbetweening.data.clips import Clip
from inbetweening.geometry.skeleton import Skeleton
from inbetweening.predictor.checkpoint import read_checkpoint
from inbetweening.runtime.tpose import tpose

ROOT = Path(__file__).resolve().parents[1]
CMU = Path("/usr/share/assimp/models/BVH/01_01.bvh")
CMU_NAMES = {"Hips": "Hips", "Spine": "LowerBack", "Chest": "Spine1", "Neck": "Neck", "Head": "Head",
             "Shoulder_L": "LeftShoulder", "UpperArm_L": "LeftArm", "LowerArm_L": "LeftForeArm", "Hand_L": "LeftHand",
             "Shoulder_R": "RightShoulder", "UpperArm_R": "RightArm", "LowerArm_R": "RightForeArm",
             "Hand_R": "RightHand", "UpperLeg_L": "LeftUpLeg", "LowerLeg_L": "LeftLeg", "Foot_L": "LeftFoot",
             "Toes_L": "LeftToeBase", "UpperLeg_R": "RightUpLeg", "LowerLeg_R": "RightLeg", "Foot_R": "RightFoot",
             "Toes_R": "RightToeBase"}


def source_skeleton() -> Skeleton:
    hp = read_checkpoint(ROOT / "models" / "bn2_reference" / "model.ckpt")["hyper_parameters"]
    return Skeleton.from_dict(hp["skeleton"])


def source_clips(sk: Skeleton, n: int = 4, frames: int = 80) -> list[Clip]:
    """``n`` walk-like clips named as Bandai-Namco's (``dataset-2_<content>_<style>_<take>``)."""
    out = []
    for i in range(n):
        root, q = model_walk(sk, frames, seed=i)
        out.append(Clip(f"dataset-2_{('walk', 'run', 'wave-left-hand')[i % 3]}_active_{i:03d}", q, root))
    return out


def rig_of(sk: Skeleton, kind: str) -> BVH:
    """A target rig standing in its rest pose (one frame): ``"cmu"`` (CMU names, Y up, no extra bones, longer legs)
    or ``"extras"`` (UE names, a second spine bone, twist and finger bones, a static root above the hips, metres,
    Z up, other proportions)."""
    t = tpose(sk, {n: i for i, n in enumerate(sk.names)})
    from inbetweening.geometry.quaternion import qinv, qmul

    local = np.array([t[0]] + [qmul(qinv(t[sk.parents[j]]), t[j]) for j in range(1, sk.num_joints)])
    if kind == "cmu":
        bvh, _ = character(sk, np.array([[0.0, 95.0, 0.0]]), local[None], names=CMU_NAMES, extras=False, unit=1 / 2.54,
                           z_up=False, scale={"legs": 1.1})
    else:
        bvh, _ = character(sk, np.array([[0.0, 95.0, 0.0]]), local[None], scale={"legs": 1.15, "Spine": 0.85,
                                                                                  "UpperArm_L": 1.15, "UpperArm_R": 1.15})
    return bvh


def tiny_checkpoint(path: Path, sk: Skeleton, kind: str = "cmu", steps: int = 0) -> Path:
    """A retargeting checkpoint of a tiny network for ``rig_of(sk, kind)`` (``steps`` Adam steps on two clips), saved as
    ``torch.save`` of its state dict and hyperparameters (what Lightning's checkpoint holds and the readers read)."""
    import torch

    from inbetweening.data.bvh_writer import format_bvh
    from inbetweening.models.retarget_lstm import RetargetLSTM
    from inbetweening.retarget.data import make_pairs, stats
    from inbetweening.retarget.module import RetargetModule
    from inbetweening.retarget.rig import TargetRig

    torch.manual_seed(0)
    bvh = rig_of(sk, kind)
    rig = TargetRig(bvh, sk)
    pairs = make_pairs(rig, source_clips(sk, 2))
    (xm, xs), (ym, ys) = stats([p.x for p in pairs]), stats([p.y for p in pairs])
    norm = {"x_mean": xm.tolist(), "x_std": xs.tolist(), "y_mean": ym.tolist(), "y_std": ys.tolist()}
    module = RetargetModule(model={"name": "retarget_lstm", **RetargetLSTM.TINY}, loss={"mse": 1.0, "smooth": 0.5,
                            "bone": 0.5}, smooth_kernel=[1, 4, 6, 4, 1], optim={}, skeleton=sk.to_dict(),
                            forward=[0.0, 0.0, 1.0], rig_bvh=format_bvh(bvh), rig_name=f"{kind}.bvh", fps=30.0,
                            norm=norm, split={"contents": ["walk", "run"], "train_fraction": 0.6})
    if steps:
        x = torch.from_numpy((np.stack([p.x for p in pairs]) - xm) / xs).float()
        y = torch.from_numpy((np.stack([p.y for p in pairs]) - ym) / ys).float()
        opt = torch.optim.Adam(module.parameters(), 2e-2)
        for _ in range(steps):
            opt.zero_grad()
            module.losses(module(x), y)["loss"].backward()
            opt.step()
    torch.save({"state_dict": module.state_dict(), "hyper_parameters": dict(module.hparams)}, path)
    return path
