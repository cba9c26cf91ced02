"""The model's skeleton's natural pose, read off its training data: the table
:data:`inbetweening.runtime.tpose.MODEL_POSE` (the pose its T-pose is built from when retargeting, so that its bones'
twists are the ones its data has; its zero pose has none of them).

    python benchmarks/model_pose.py [--data ../shared/datasets/bandai-namco-2.zip] [--clips 300]

Bandai-Namco-2's standard training split only (take numbers not divisible by 10), every 5th frame of ``--clips``
clips in name order: per joint the mean of its local rotations (the hips': the identity, its heading is no pose);
prints the table, the offsets' directions of the skeleton it holds for, and how high the ankles stand over the floor
(:data:`~inbetweening.runtime.retarget.MODEL_ANKLE`: a rig's floor is put there).
"""
from __future__ import annotations

import argparse
import sys
import zipfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(ROOT.parent / "shared" / "datasets" / "bandai-namco-2.zip"))
    ap.add_argument("--clips", type=int, default=300)
    ap.add_argument("--ckpt", default=str(ROOT / "models" / "bn2_reference" / "model.ckpt"))
    args = ap.parse_args(argv)
    from inbetweening.data.bvh import parse_bvh
    from inbetweening.data.clips import clip_in_skeleton
    from inbetweening.data.specs import bandai_namco_split
    from inbetweening.runtime.torch_backend import TorchBackend
    from inbetweening.runtime.tpose import mean_pose

    sk = TorchBackend.from_checkpoint(args.ckpt).info.skeleton
    qs, ankles = [], []
    feet = [sk.names.index("Foot_L"), sk.names.index("Foot_R")]
    with zipfile.ZipFile(args.data) as z:
        names = sorted(n for n in z.namelist() if n.endswith(".bvh") and bandai_namco_split(Path(n).name) == "train")
        for n in names[: args.clips]:
            _, root, q = clip_in_skeleton(parse_bvh(z.read(n).decode(), n), sk)
            qs.append(q[::5])
            ankles.append(float(sk.pose(root, q)[1][:, feet, 1].min()))
    pose = mean_pose(np.concatenate(qs))
    print(f"MODEL_ANKLE = {float(np.median(ankles)):.3f}  # the lowest ankle of a clip, median over the clips (cm)")
    print(f"# {len(qs)} training clips, {sum(len(q) for q in qs)} frames")
    print("MODEL_POSE = {")
    for n, q in zip(sk.names, pose):
        print(f'    "{n}": ({q[0]:.5f}, {q[1]:.5f}, {q[2]:.5f}, {q[3]:.5f}),')
    print("}")
    off = sk.offsets / np.maximum(np.linalg.norm(sk.offsets, axis=-1, keepdims=True), 1e-12)
    print("MODEL_REST = {  # the offsets' directions")
    for n, o in zip(sk.names[1:], off[1:]):
        print(f'    "{n}": ({o[0]:.4f}, {o[1]:.4f}, {o[2]:.4f}),')
    print("}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
