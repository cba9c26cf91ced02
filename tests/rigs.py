"""Another rig, generated for the tests: BVH files unlike every built-in dataset's.

The synthetic motion (:func:`inbetweening.data.synthetic.generate_clip`) on a Blender-style skeleton: other joint
names (``thigh.L``, ``spine.001``...), fewer joints (no toes), a motionless top joint ``Armature``, metres,
``XYZ`` rotation order, Z up, 60 fps, and a root whose local frame is turned so that the character faces its local
-Y.  Written without the project's conversion code (plain rotation matrices and Euler angles here), so a test of the
conversion is not a test of the conversion against itself.

The truth a test checks the derived spec against: :data:`TRUE`.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from inbetweening.data.bvh import BVH
from inbetweening.data.bvh_writer import write_bvh
from inbetweening.data.synthetic import END_SITES, NAMES, OFFSETS, PARENTS, generate_clip
from inbetweening.geometry.quaternion import euler_to_quat_np, qmul, qrot, quat_to_euler_np

RENAME = {
    "Hips": "hips", "LeftUpLeg": "thigh.L", "LeftLeg": "shin.L", "LeftFoot": "foot.L",
    "RightUpLeg": "thigh.R", "RightLeg": "shin.R", "RightFoot": "foot.R", "Spine": "spine", "Spine1": "spine.001",
    "Spine2": "spine.002", "Neck": "neck", "Head": "head", "LeftShoulder": "shoulder.L", "LeftArm": "upper_arm.L",
    "LeftForeArm": "forearm.L", "LeftHand": "hand.L", "RightShoulder": "shoulder.R", "RightArm": "upper_arm.R",
    "RightForeArm": "forearm.R", "RightHand": "hand.R",
}  # LeftToe and RightToe are dropped: the feet are leaves
FPS = 60.0
METRES = 0.01  # file units per cm
TRUE = {"up_axis": "z", "unit": "m", "unit_cm": 100.0, "fps": FPS, "forward_axis": [0.0, -1.0, 0.0],
        "feet": ["foot.L", "foot.R"], "folded": "Armature", "joints": len(RENAME)}

_Q_UP = euler_to_quat_np(np.array([90.0, 0.0, 0.0]), "xyz")  # Y up -> Z up: +90 degrees about X
_Q_ROOT = euler_to_quat_np(np.array([-90.0, 0.0, 0.0]), "xyz")  # the root's local frame: its local -Y = synthetic +Z
_Q_ROOT_INV = _Q_ROOT * np.array([1.0, -1.0, -1.0, -1.0])


def other_rig(local_q: np.ndarray, root: np.ndarray) -> BVH:
    """The synthetic motion ``local_q (T, 22, 4), root (T, 3)`` (Y up, cm) as a BVH of the other rig."""
    t = len(root)
    keep = [NAMES.index(n) for n in RENAME]
    parents = [-1] + [keep.index(PARENTS[j]) + 1 for j in keep[1:]]  # +1: Armature on top
    offsets = OFFSETS[keep].copy()
    offsets[0] = 0.0  # the root's position channels carry the translation
    q = local_q[:, keep].copy()
    # the world turned to Z up and the root's own frame turned by _Q_ROOT; the root's children compensate
    q[:, 0] = qmul(qmul(np.broadcast_to(_Q_UP, (t, 4)), q[:, 0]), np.broadcast_to(_Q_ROOT, (t, 4)))
    for k in [k for k, j in enumerate(keep) if PARENTS[j] == 0]:
        q[:, k] = qmul(np.broadcast_to(_Q_ROOT_INV, (t, 4)), q[:, k])
        offsets[k] = qrot(_Q_ROOT_INV, offsets[k])
    root_z = qrot(np.broadcast_to(_Q_UP, (t, 4)), root) * METRES
    names = ["Armature", *RENAME.values()]
    chans = [("Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation")] * 2
    chans += [("Xrotation", "Yrotation", "Zrotation")] * (len(names) - 2)
    eul = quat_to_euler_np(q, "xyz").reshape(t, -1)
    motion = np.concatenate([np.zeros((t, 6)), root_z, eul], axis=1)
    ends = {names.index(RENAME[NAMES[j]]): np.asarray(v, float) * METRES for j, v in END_SITES.items()
            if NAMES[j] in RENAME}
    for foot, toe in (("foot.L", "LeftToe"), ("foot.R", "RightToe")):
        ends[names.index(foot)] = OFFSETS[NAMES.index(toe)] * METRES
    return BVH(names, np.array([-1, *[p if p >= 0 else 0 for p in parents]]),
               np.concatenate([np.zeros((1, 3)), offsets * METRES]), chans, ends, 1.0 / FPS, motion,
               source="other_rig")


def write_other_rig(folder: Path, n_files: int = 12, frames: tuple[int, int] = (200, 260), seed: int = 3) -> Path:
    """``n_files`` BVH files of the other rig (``take_NN.bvh``) in ``folder``; returns it."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    for i in range(n_files):
        q, r = generate_clip(rng, int(rng.integers(*frames)), fps=FPS)
        write_bvh(other_rig(q, r), folder / f"take_{i:02d}.bvh")
    return folder
