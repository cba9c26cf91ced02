"""A procedurally generated, LAFAN-like dataset: smooth varied locomotion on a 22-joint skeleton.

Every clip is written as a real BVH file in the LAFAN1 layout (root: 6 channels, other joints:
``Zrotation Yrotation Xrotation``), named ``synthNNN_subjectK.bvh``, so the dataset goes through
exactly the same reader, split (subject5 = test) and benchmark code as LAFAN1.  The root faces
its local +Z (forward axis ``(0, 0, 1)``); Y is up; units are centimetres.

Motion per clip (all from one seeded generator): the root travels along a curving path at a
varying speed (idle, walk or run), bobbing with the gait; legs, arms and spine swing periodically
with the gait phase; every joint also carries slow random periodic rotations.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from inbetweening.data.bvh import BVH
from inbetweening.data.bvh_writer import write_bvh
from inbetweening.geometry.quaternion import euler_to_quat_np, qmul, quat_to_euler_np

NAMES = (
    "Hips", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToe", "RightUpLeg", "RightLeg", "RightFoot", "RightToe",
    "Spine", "Spine1", "Spine2", "Neck", "Head", "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand",
    "RightShoulder", "RightArm", "RightForeArm", "RightHand",
)
PARENTS = (-1, 0, 1, 2, 3, 0, 5, 6, 7, 0, 9, 10, 11, 12, 11, 14, 15, 16, 11, 18, 19, 20)
OFFSETS = np.array([
    [0, 0, 0], [10, -5, 0], [0, -43, 0], [0, -42, 0], [0, -6, 14], [-10, -5, 0], [0, -43, 0], [0, -42, 0],
    [0, -6, 14], [0, 10, 0], [0, 12, 0], [0, 12, 0], [0, 14, 0], [0, 10, 2], [4, 10, 0], [14, 0, 0],
    [28, 0, 0], [25, 0, 0], [-4, 10, 0], [-14, 0, 0], [-28, 0, 0], [-25, 0, 0],
], dtype=np.float64)
END_SITES = {4: [0, 0, 5], 8: [0, 0, 5], 13: [0, 12, 0], 17: [10, 0, 0], 21: [-10, 0, 0]}
HIP_HEIGHT = 95.0
FPS = 30.0


def _axis_quat(angle_deg: np.ndarray, axis: str) -> np.ndarray:
    """Rotation about one axis.  ``(T,) -> (T, 4)``."""
    zeros = np.zeros_like(angle_deg)
    e = {"x": (angle_deg, zeros, zeros), "y": (zeros, angle_deg, zeros), "z": (zeros, zeros, angle_deg)}[axis]
    return euler_to_quat_np(np.stack(e, -1), "xyz")


def _smooth_noise(rng: np.random.Generator, t: np.ndarray, amp: float, n: int = 3) -> np.ndarray:
    """Sum of ``n`` slow sinusoids with random frequency/phase.  ``(T,) -> (T,)`` degrees."""
    out = np.zeros_like(t)
    for _ in range(n):
        out += rng.uniform(0.3, 1.0) * amp * np.sin(2 * np.pi * rng.uniform(0.1, 0.8) * t + rng.uniform(0, 2 * np.pi))
    return out / n


def generate_clip(rng: np.random.Generator, num_frames: int, fps: float = FPS) -> tuple[np.ndarray, np.ndarray]:
    """One clip at ``fps`` frames per second: local quaternions ``(T, 22, 4)`` and root positions ``(T, 3)``."""
    t = np.arange(num_frames) / fps
    kind = rng.choice(["idle", "walk", "walk", "run"])
    base_speed = {"idle": 5.0, "walk": rng.uniform(90, 160), "run": rng.uniform(250, 400)}[kind]
    speed = base_speed * (1 + 0.35 * np.sin(2 * np.pi * rng.uniform(0.05, 0.3) * t + rng.uniform(0, 6.3)))
    speed = np.clip(speed, 0.0, None)
    cadence = {"idle": 0.4, "walk": 0.9, "run": 1.4}[kind] * rng.uniform(0.9, 1.15)
    phase = 2 * np.pi * np.cumsum(np.full_like(t, cadence / fps)) + rng.uniform(0, 2 * np.pi)
    heading = (
        rng.uniform(-180, 180)
        + rng.uniform(-90, 90) * np.sin(2 * np.pi * rng.uniform(0.03, 0.2) * t + rng.uniform(0, 6.3))
        + rng.uniform(-25, 25) * t
    )
    rad = np.radians(heading)
    vel = np.stack([np.sin(rad), np.zeros_like(rad), np.cos(rad)], -1) * speed[:, None] / fps
    root = np.cumsum(vel, 0) + np.array([rng.uniform(-200, 200), 0.0, rng.uniform(-200, 200)])
    gait = {"idle": 0.05, "walk": 1.0, "run": 1.6}[kind]
    root[:, 1] = HIP_HEIGHT - (8 if kind == "run" else 2) + 2.5 * gait * np.sin(2 * phase)

    j = len(NAMES)
    q = np.zeros((num_frames, j, 4))
    q[..., 0] = 1.0
    lean = (8 if kind == "run" else 3) * gait
    q[:, 0] = qmul(_axis_quat(heading, "y"), qmul(_axis_quat(lean + _smooth_noise(rng, t, 3), "x"),
                                                  _axis_quat(3 * gait * np.sin(phase) + _smooth_noise(rng, t, 3), "z")))
    leg, knee = 30 * gait * rng.uniform(0.8, 1.2), 45 * gait * rng.uniform(0.8, 1.2)
    for side, sgn in ((1, 1.0), (5, -1.0)):
        swing = sgn * np.sin(phase)
        q[:, side] = _axis_quat(-leg * swing + _smooth_noise(rng, t, 4), "x")
        q[:, side + 1] = _axis_quat(knee * np.clip(np.sin(phase * 1.0 + sgn * 1.2 + (sgn < 0) * np.pi), 0, None)
                                    + 5 + _smooth_noise(rng, t, 3), "x")
        q[:, side + 2] = _axis_quat(-10 * gait * np.cos(phase + (sgn < 0) * np.pi) + _smooth_noise(rng, t, 4), "x")
        q[:, side + 3] = _axis_quat(_smooth_noise(rng, t, 8), "x")
    for k in (9, 10, 11):
        q[:, k] = qmul(_axis_quat(4 * gait * np.sin(phase) + _smooth_noise(rng, t, 4), "y"),
                       _axis_quat(_smooth_noise(rng, t, 5), "x"))
    q[:, 12] = _axis_quat(_smooth_noise(rng, t, 8), "x")
    q[:, 13] = qmul(_axis_quat(_smooth_noise(rng, t, 30), "y"), _axis_quat(_smooth_noise(rng, t, 12), "x"))
    arm = 35 * gait * rng.uniform(0.7, 1.3)
    for side, sgn in ((14, 1.0), (18, -1.0)):
        q[:, side] = _axis_quat(_smooth_noise(rng, t, 5), "z")
        down = sgn * (-70 + _smooth_noise(rng, t, 10))
        q[:, side + 1] = qmul(_axis_quat(down, "z"), _axis_quat(arm * sgn * np.sin(phase) + _smooth_noise(rng, t, 10), "x"))
        q[:, side + 2] = _axis_quat(sgn * (20 + 15 * gait + _smooth_noise(rng, t, 15)), "y")
        q[:, side + 3] = _axis_quat(_smooth_noise(rng, t, 15), "z")
    return q, root


def make_bvh(local_q: np.ndarray, root: np.ndarray) -> BVH:
    """LAFAN-layout BVH of a synthetic clip (root 6 channels, others ZYX rotations)."""
    t = local_q.shape[0]
    channels = [("Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation")]
    channels += [("Zrotation", "Yrotation", "Xrotation")] * (len(NAMES) - 1)
    eul = quat_to_euler_np(local_q, "zyx")  # (T, J, 3)
    motion = np.concatenate([root, eul.reshape(t, -1)], axis=1)
    offsets = OFFSETS.copy()
    offsets[0] = [0.0, HIP_HEIGHT, 0.0]
    return BVH(
        names=list(NAMES), parents=np.array(PARENTS, dtype=np.int64), offsets=offsets, channels=channels,
        end_sites={k: np.array(v, dtype=np.float64) for k, v in END_SITES.items()}, frame_time=1.0 / FPS,
        motion=motion, source="synthetic",
    )


def generate_dataset(
    root_dir: str | Path, num_clips: int = 40, min_frames: int = 240, max_frames: int = 360, seed: int = 0,
    num_subjects: int = 5,
) -> Path:
    """Write ``num_clips`` BVH files (deterministic from ``seed``) and return their folder.

    Clip ``i`` belongs to subject ``i % num_subjects + 1``; subject5 is the LAFAN1 test subject.
    An existing complete folder for the same parameters is reused.
    """
    if num_clips < num_subjects or min_frames < 66 or max_frames < min_frames:
        raise ValueError(
            f"synthetic: need num_clips >= {num_subjects} and 66 <= min_frames <= max_frames "
            f"(got {num_clips}, {min_frames}, {max_frames})"
        )
    params = {"num_clips": num_clips, "min_frames": min_frames, "max_frames": max_frames, "seed": seed,
              "num_subjects": num_subjects, "v": 1}
    tag = hashlib.sha1(json.dumps(params, sort_keys=True).encode()).hexdigest()[:10]
    out = Path(root_dir) / f"seed{seed}-{tag}"
    if (out / "COMPLETE").exists():
        return out
    # write into a private folder, then rename: parallel sweep jobs never see a half-written dataset
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=out.name + ".", dir=out.parent))
    rng = np.random.default_rng(seed)
    for i in range(num_clips):
        n = int(rng.integers(min_frames, max_frames + 1))
        q, r = generate_clip(rng, n)
        write_bvh(make_bvh(q, r), tmp / f"synth{i:03d}_subject{i % num_subjects + 1}.bvh")
    (tmp / "COMPLETE").write_text(json.dumps(params))
    try:
        os.rename(tmp, out)
    except OSError:  # another process finished first
        shutil.rmtree(tmp, ignore_errors=True)
    return out
