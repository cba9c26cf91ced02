"""Write the generated target character of RESULTS.md section 9: the shipped model's 21-joint skeleton re-proportioned,
renamed (UE mannequin names), with a second spine bone, twist bones under the arms, two fingers per hand and a static
``root`` bone above the hips, in metres and Z up (tests/characters.py), standing in its T-pose rest.

    python benchmarks/retarget_rig.py results/retarget/generated_rig.bvh
"""
import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from characters import character  # noqa: E402
from inbetweening.data.bvh_writer import write_bvh  # noqa: E402
from inbetweening.geometry.quaternion import qinv, qmul  # noqa: E402
from inbetweening.geometry.skeleton import Skeleton  # noqa: E402
from inbetweening.predictor.checkpoint import read_checkpoint  # noqa: E402
from inbetweening.runtime.tpose import tpose  # noqa: E402

SCALE = {"legs": 1.15, "Spine": 0.85, "Chest": 1.1, "UpperArm_L": 1.15, "UpperArm_R": 1.15, "LowerArm_L": 0.9,
         "LowerArm_R": 0.9, "Neck": 1.15}


def main(out: str) -> None:
    sk = Skeleton.from_dict(read_checkpoint(ROOT / "models" / "bn2_reference" / "model.ckpt")["hyper_parameters"]["skeleton"])
    t = tpose(sk, {n: i for i, n in enumerate(sk.names)})
    local = np.array([t[0]] + [qmul(qinv(t[sk.parents[j]]), t[j]) for j in range(1, sk.num_joints)])
    bvh, _ = character(sk, np.array([[0.0, 95.0, 0.0]]), local[None], scale=SCALE)
    write_bvh(bvh, out)
    print(f"{out}: {len(bvh.names)} joints")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", help="the BVH file to write")
    main(ap.parse_args().out)
